//! A drift model from a static record, as `driftless train` makes it: the record's drift
//! separated causally ([`super::separation`]), the network and the baselines trained on the
//! first part, every predictor scored on the held-out part right after it, and the stillness
//! thresholds calibrated on the training part.

use super::baselines::{self, Ar, Mean, Persistence, Predictor, Score};
use super::lowband::LowBand;
use super::model::{Baselines, DriftModel, Provenance, Separation, FORMAT, VERSION};
use super::rbf::Rbf;
use super::separation::{separate_causal, train_end};
use super::stillness::StillnessConfig;
use super::training::{self, TrainConfig, TrainError};
use crate::units::RateUnit;

/// How a model is fitted to a record.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSpec {
    /// How the drift is separated from the rate.
    pub separation: Separation,
    /// The network's training settings.
    pub training: TrainConfig,
    /// Training samples, from the record's start.
    pub train: usize,
    /// Held-out samples right after the training ones, for the scores.
    pub test: usize,
    /// Free-running horizon of the multi-step score, samples.
    pub horizon: usize,
    /// Stillness window, samples.
    pub still_window: usize,
    /// Stillness thresholds = this x the largest statistics on the training part (exit), 2x
    /// (enter).
    pub still_margin: f64,
}

/// Why a record gives no model.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The record is shorter than the training and test samples.
    #[error("{samples} samples, but {needed} are trained on and held out")]
    Short {
        /// Samples in the record.
        samples: usize,
        /// Training plus test samples.
        needed: usize,
    },
    /// The separation's settings are refused.
    #[error("{0}")]
    Separation(String),
    /// Too few training samples for the network once the warm-up and the lag are left out.
    #[error(
        "{train} training samples are too little data for {lags} lags and {centres} centres after \
         the {warm_up}-sample warm-up and the {lag}-sample denoiser lag (need at least {needed})"
    )]
    TooLittleData {
        /// Training samples.
        train: usize,
        /// Lagged inputs.
        lags: usize,
        /// Centres.
        centres: usize,
        /// The separation's warm-up, samples.
        warm_up: usize,
        /// The denoiser's lag, samples.
        lag: usize,
        /// Training samples needed.
        needed: usize,
    },
    /// The network cannot be trained.
    #[error(transparent)]
    Training(#[from] TrainError),
    /// The training drift is constant: the AR baseline has no solution.
    #[error("the training drift is constant: AR baseline has no solution")]
    ConstantDrift,
}

/// What a record gives: the network, its baselines, their scores on the held-out part, and the
/// live compensator's settings.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// Samples at the start whose drift is still a start-up transient (not trained on).
    pub warm_up: usize,
    /// The end (exclusive) of the drift trained on: the training samples less the denoiser's
    /// look-ahead ([`train_end`]).
    pub train_end: usize,
    /// The network.
    pub network: Rbf,
    /// AR(p) and the mean on the same training drift.
    pub baselines: Baselines,
    /// One-step and free-running scores on the held-out part: persistence, mean, AR(p), RBF.
    pub scores: Vec<Score>,
    /// Largest free-running step, units per sample (twice the training drift's largest).
    pub max_step: f64,
    /// Stillness thresholds calibrated on the training part.
    pub stillness: StillnessConfig,
}

/// Fit a model to `x` (a static record: its first `spec.train` samples are trained on, the
/// next `spec.test` held out); `progress` hears the fraction done, 0 to 1.
pub fn fit_model(
    x: &[f64],
    spec: &FitSpec,
    progress: &mut dyn FnMut(f64),
) -> Result<Fitted, FitError> {
    let (t0, t1) = (spec.train, spec.train + spec.test);
    if x.len() < t1 {
        return Err(FitError::Short {
            samples: x.len(),
            needed: t1,
        });
    }
    let (denoise, lowband) = (&spec.separation.denoise, &spec.separation.lowband);
    let cfg = &spec.training;
    // Separation: causal, over the training and test ranges only.
    let sep = separate_causal(&x[..t1], denoise, lowband).map_err(FitError::Separation)?;
    progress(0.1);
    let warm = sep.warm_up;
    let t_end = train_end(spec.train, denoise);
    let needed = warm + training::samples_needed(cfg.lags, cfg.centres) + denoise.lag;
    if spec.train < needed {
        return Err(FitError::TooLittleData {
            train: spec.train,
            lags: cfg.lags,
            centres: cfg.centres,
            warm_up: warm,
            lag: denoise.lag,
            needed,
        });
    }
    let train_drift = &sep.drift[warm..t_end];
    let network = training::train(train_drift, cfg, &mut |f| progress(0.1 + 0.9 * f))?;
    let ar = Ar::fit(train_drift, cfg.lags).ok_or(FitError::ConstantDrift)?;
    let mean = train_drift.iter().sum::<f64>() / train_drift.len() as f64;
    let scores: Vec<Score> = [
        ("persistence", &Persistence as &dyn Predictor),
        ("mean", &Mean(mean)),
        (&format!("AR({})", cfg.lags), &ar),
        (&format!("RBF({} centres)", cfg.centres), &network),
    ]
    .iter()
    .map(|(name, p)| baselines::score(name, *p, &sep.drift, t0, t1, spec.horizon))
    .collect();
    let max_step = 2.0
        * train_drift
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max)
            .max(1e-12);
    let stillness = StillnessConfig::calibrate(
        &sep.denoised[..t_end],
        &sep.drift[..t_end],
        spec.still_window,
        LowBand::new(&lowband.wavelet, lowband.level)
            .map_err(|e| FitError::Separation(e.to_string()))?
            .span(),
        spec.still_margin,
    );
    Ok(Fitted {
        warm_up: warm,
        train_end: t_end,
        network,
        baselines: Baselines { ar, mean },
        scores,
        max_step,
        stillness,
    })
}

impl Fitted {
    /// The model file's content: this fit of `spec` at `rate_hz`, on the column `axis` in
    /// `units`, from `provenance`.
    pub fn into_model(
        self,
        spec: &FitSpec,
        rate_hz: f64,
        axis: String,
        units: RateUnit,
        provenance: Provenance,
    ) -> DriftModel {
        DriftModel {
            format: FORMAT.into(),
            version: VERSION,
            rate_hz,
            axis,
            units,
            separation: spec.separation.clone(),
            stillness: self.stillness,
            max_step: self.max_step,
            network: self.network,
            baselines: self.baselines,
            training: spec.training.clone(),
            scores: self.scores,
            provenance,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drift::model::{DenoiseSettings, LowbandSettings};

    fn spec(train: usize, test: usize) -> FitSpec {
        FitSpec {
            separation: Separation {
                denoise: DenoiseSettings {
                    wavelet: "db6".into(),
                    level: 5,
                    threshold: "improved".into(),
                    window: 1024,
                    lag: 33,
                },
                lowband: LowbandSettings {
                    wavelet: "db6".into(),
                    level: 5,
                },
            },
            training: TrainConfig::default(),
            train,
            test,
            horizon: 100,
            still_window: 50,
            still_margin: 1.5,
        }
    }

    fn record(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| 0.4 + 0.01 * (k as f64 / 700.0).sin())
            .collect()
    }

    #[test]
    fn a_record_shorter_than_its_ranges_is_refused() {
        let e = fit_model(&record(100), &spec(90, 20), &mut |_| {}).unwrap_err();
        assert!(matches!(
            e,
            FitError::Short {
                samples: 100,
                needed: 110
            }
        ));
    }

    #[test]
    fn too_few_training_samples_after_the_warm_up_say_how_many_are_needed() {
        let mut heard = Vec::new();
        let e = fit_model(&record(1500), &spec(1200, 300), &mut |f| heard.push(f)).unwrap_err();
        let FitError::TooLittleData {
            train,
            warm_up,
            needed,
            ..
        } = e
        else {
            panic!("{e}");
        };
        assert_eq!(train, 1200);
        assert!(warm_up >= 1024 && needed > train, "{warm_up} {needed}");
        assert_eq!(
            heard,
            [0.1],
            "the separation is done, the training never started"
        );
    }
}
