//! The heading benchmark: run every method on one window (measured rate, truth, oracle stops)
//! and summarise many windows against a reference method.
//!
//! Pure: slices in, figures out. The caller builds the windows (a real static record plus a
//! [`super::profiles`] motion, or the simulator) and decides which are held out.

use super::baselines::{BiasEstimator, Raw, Tracked, Zaru};
use super::metrics::{summarize, HeadingAccumulator, HeadingMetrics, Summary};
use crate::drift::bias::{
    stillness_from_terms, BiasError, BiasModel, BiasTerms, BiasTracker, LearnWalk, TrackerConfig,
};
use crate::wavelet::stream::{StreamConfig, StreamingDenoiser};
use crate::wavelet::WaveletError;
use std::fmt::Write as _;

/// A method of correcting the rate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Nothing subtracted.
    Raw,
    /// Mean of the first (oracle) stop, held.
    PowerOn,
    /// ZARU on the oracle's stops.
    ZaruOracle,
    /// ZARU on the detector's stops (the tracker's detector and thresholds, no delay window).
    ZaruDetected,
    /// [`Method::ZaruDetected`] on the streaming-denoised rate (as [`Method::KfDenoised`]).
    ZaruDenoised,
    /// The bias Kalman filter with its own detector and delay window (the new estimator).
    KfDetected,
    /// The same filter gated by the oracle's stops, no delay: what a navigator with a stop
    /// signal from the vehicle gets. It learns its walk from those stops
    /// ([`crate::drift::bias::LearnWalk::GivenStops`]).
    KfOracle,
    /// [`Method::KfOracle`] keeping the configured walk (what learning it gains).
    KfOracleFixed,
    /// [`Method::KfDetected`] plus heading hold: output 0 while the detector says still.
    KfHold,
    /// [`Method::KfDetected`] on the streaming-denoised rate (its output is the denoised rate
    /// minus the bias; each denoised sample is compared with the truth of the sample it stands
    /// for, as a navigator time-stamping the daemon's output would).
    KfDenoised,
    /// The physical floor: a filter with the true noise model ([`Setup::floor`]) and the
    /// oracle's stops, no delay.
    Floor,
}

impl Method {
    /// Every method, in table order.
    pub const ALL: [Method; 11] = [
        Method::Raw,
        Method::PowerOn,
        Method::ZaruOracle,
        Method::ZaruDetected,
        Method::ZaruDenoised,
        Method::KfDetected,
        Method::KfOracle,
        Method::KfOracleFixed,
        Method::KfHold,
        Method::KfDenoised,
        Method::Floor,
    ];

    /// Short label for tables.
    pub fn label(self) -> &'static str {
        match self {
            Method::Raw => "raw",
            Method::PowerOn => "power-on",
            Method::ZaruOracle => "ZARU oracle",
            Method::ZaruDetected => "ZARU detected",
            Method::ZaruDenoised => "ZARU detected, denoised",
            Method::KfDetected => "KF detected",
            Method::KfOracle => "KF oracle",
            Method::KfOracleFixed => "KF oracle, configured walk",
            Method::KfHold => "KF detected + hold",
            Method::KfDenoised => "KF detected, denoised",
            Method::Floor => "floor (true model, oracle)",
        }
    }
}

/// Why a window cannot be evaluated.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// Inputs of different lengths, or empty.
    #[error("measured ({0}), truth ({1}) and still ({2}) must be non-empty and of equal length")]
    Lengths(usize, usize, usize),
    /// The floor was asked for without a model.
    #[error("the floor needs the true noise model (Setup::floor)")]
    NoFloor,
    /// A bad bias model or tracker setting.
    #[error(transparent)]
    Bias(#[from] BiasError),
    /// A bad denoiser setting.
    #[error(transparent)]
    Wavelet(#[from] WaveletError),
    /// A bad odometry setting.
    #[error("odometry: {0}")]
    Odometry(String),
}

/// Everything the methods are built from; no per-window tuning.
#[derive(Debug, Clone)]
pub struct Setup {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Noise terms for the filter and the detector.
    pub terms: BiasTerms,
    /// The tracker's gating and model settings.
    pub tracker: TrackerConfig,
    /// Shortest stop (s) ZARU and power-on trust.
    pub zaru_min_s: f64,
    /// The true noise model, for [`Method::Floor`] (simulator only).
    pub floor: Option<BiasModel>,
    /// The denoiser of [`Method::KfDenoised`].
    pub denoiser: StreamConfig,
    /// Samples every method runs before the heading is judged: the integration starts there
    /// (0: from the first sample, start-up included).
    pub judge_from: usize,
}

impl Setup {
    /// Terms and rate, the default tracker, ZARU from 1 s, no floor, the default denoiser.
    pub fn new(terms: BiasTerms, rate_hz: f64) -> Self {
        Setup {
            rate_hz,
            terms,
            tracker: TrackerConfig::default(),
            zaru_min_s: 1.0,
            floor: None,
            denoiser: StreamConfig::default(),
            judge_from: 0,
        }
    }
}

fn run(
    est: &mut dyn BiasEstimator,
    measured: &[f64],
    truth: &[f64],
    still: &[bool],
    dt: f64,
    hold: bool,
    judge_from: usize,
) -> HeadingMetrics {
    let mut acc = HeadingAccumulator::new(dt);
    for (k, ((&x, &t), &s)) in measured.iter().zip(truth).zip(still).enumerate() {
        let b = est.push(x, s);
        let c = if hold && est.still() { 0.0 } else { x - b };
        if k >= judge_from {
            acc.push(c, t);
        }
    }
    acc.metrics()
}

/// The streaming-denoised rate, sample k standing for measured sample k (lag removed).
fn denoise(measured: &[f64], setup: &Setup) -> Result<Vec<f64>, EvalError> {
    let mut d = StreamingDenoiser::new(&setup.denoiser)?;
    let mut y: Vec<f64> = measured.iter().filter_map(|&x| d.push(x)).collect();
    while let Some(v) = d.flush() {
        y.push(v);
    }
    Ok(y)
}

/// The heading figures of each of `methods` on one window: `measured` rate (deg/s), the
/// `truth` under it and the oracle's `still` flags, every method starting fresh at the first
/// sample.
pub fn evaluate(
    measured: &[f64],
    truth: &[f64],
    still: &[bool],
    setup: &Setup,
    methods: &[Method],
) -> Result<Vec<HeadingMetrics>, EvalError> {
    let n = measured.len();
    if n == 0 || truth.len() != n || still.len() != n {
        return Err(EvalError::Lengths(n, truth.len(), still.len()));
    }
    let rate = setup.rate_hz;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(BiasError::BadRate(rate).into());
    }
    let dt = 1.0 / rate;
    let judge = |est: &mut dyn BiasEstimator, input: &[f64], hold: bool| {
        run(est, input, truth, still, dt, hold, setup.judge_from)
    };
    let min = ((setup.zaru_min_s.max(0.0) * rate).round() as usize).max(1);
    let tracker = || BiasTracker::new(&setup.terms, rate, &setup.tracker);
    // The true stops need neither a delay nor a backfill.
    let oracle_cfg = TrackerConfig {
        delay_s: 0.0,
        backfill_s: 0.0,
        ..setup.tracker
    };
    let mut out = Vec::with_capacity(methods.len());
    for &m in methods {
        let metrics = match m {
            Method::Raw => judge(&mut Raw, measured, false),
            Method::PowerOn => judge(&mut Zaru::power_on(min), measured, false),
            Method::ZaruOracle => judge(&mut Zaru::oracle(min), measured, false),
            Method::ZaruDetected | Method::ZaruDenoised => {
                let cfg = stillness_from_terms(&setup.terms, rate, &setup.tracker)?;
                let denoised;
                let input = if m == Method::ZaruDenoised {
                    denoised = denoise(measured, setup)?;
                    &denoised
                } else {
                    measured
                };
                judge(&mut Zaru::detected(min, cfg), input, false)
            }
            Method::KfDetected | Method::KfHold => judge(
                &mut Tracked::detected(tracker()?),
                measured,
                m == Method::KfHold,
            ),
            Method::KfOracle | Method::KfOracleFixed => judge(
                &mut Tracked::oracle(BiasTracker::new(
                    &setup.terms,
                    rate,
                    &TrackerConfig {
                        learn_walk: if m == Method::KfOracle {
                            oracle_cfg.learn_walk
                        } else {
                            LearnWalk::Off
                        },
                        ..oracle_cfg
                    },
                )?),
                measured,
                false,
            ),
            Method::KfDenoised => judge(
                &mut Tracked::detected(tracker()?),
                &denoise(measured, setup)?,
                false,
            ),
            Method::Floor => {
                let model = setup.floor.clone().ok_or(EvalError::NoFloor)?;
                let t = BiasTracker::with_model(model, &setup.terms, rate, &oracle_cfg)?;
                judge(&mut Tracked::oracle(t), measured, false)
            }
        };
        out.push(metrics);
    }
    Ok(out)
}

/// One method's figures over many windows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MethodSummary {
    /// The method.
    pub method: Method,
    /// RMS heading error, deg.
    pub rms: Summary,
    /// |final heading error|, deg.
    pub final_abs: Summary,
    /// Max |heading error|, deg.
    pub max: Summary,
    /// RMS rate error, deg/s.
    pub rms_rate: Summary,
    /// Per-window ratio of the RMS heading error to the reference method's.
    pub rms_ratio: Summary,
    /// The same against the reference's RMS or [`RATIO_FLOOR_DEG`], whichever is larger: where
    /// the reference's error is smaller, a window is noise, and its ratio says nothing (the
    /// worst windows and the p90 are judged on this).
    pub rms_ratio_floored: Summary,
    /// Per-window ratio of |final heading error| to the reference's (noisy where the
    /// reference's final error happens to cross zero; read with the medians).
    pub final_ratio: Summary,
}

/// The least reference RMS heading error a ratio is taken against, deg (issue 40: below it, a
/// window's error is noise).
pub const RATIO_FLOOR_DEG: f64 = 0.5;

/// Summaries of each method over windows: `results[w][i]` is method `methods[i]` on window w.
/// Ratios are per window against `reference` (NaN if it is not among `methods`).
pub fn summarize_methods(
    methods: &[Method],
    results: &[Vec<HeadingMetrics>],
    reference: Method,
) -> Vec<MethodSummary> {
    let col = |i: usize, f: fn(&HeadingMetrics) -> f64| -> Vec<f64> {
        results.iter().filter_map(|r| r.get(i).map(f)).collect()
    };
    let r = methods.iter().position(|&m| m == reference);
    methods
        .iter()
        .enumerate()
        .map(|(i, &method)| {
            let ratio = |f: fn(&HeadingMetrics) -> f64, floor: f64| -> Summary {
                let v: Vec<f64> = results
                    .iter()
                    .map(|w| match (r, w.get(i)) {
                        (Some(r), Some(m)) => {
                            let d = w.get(r).map_or(f64::NAN, f).max(floor);
                            if d == 0.0 {
                                f64::NAN
                            } else {
                                f(m) / d
                            }
                        }
                        _ => f64::NAN,
                    })
                    .collect();
                summarize(&v)
            };
            MethodSummary {
                method,
                rms: summarize(&col(i, |m| m.rms_deg)),
                final_abs: summarize(&col(i, |m| m.final_deg.abs())),
                max: summarize(&col(i, |m| m.max_deg)),
                rms_rate: summarize(&col(i, |m| m.rms_rate)),
                rms_ratio: ratio(|m| m.rms_deg, 0.0),
                rms_ratio_floored: ratio(|m| m.rms_deg, RATIO_FLOOR_DEG),
                final_ratio: ratio(|m| m.final_deg.abs(), 0.0),
            }
        })
        .collect()
}

/// A Markdown table of summaries: RMS and |final| heading error (median / worst, deg), the
/// per-window RMS ratio to the reference (median / worst) and to the floored reference
/// ([`RATIO_FLOOR_DEG`]: p90 / worst).
pub fn format_table(title: &str, rows: &[MethodSummary]) -> String {
    let labels: Vec<&str> = rows.iter().map(|r| r.method.label()).collect();
    format_table_labelled(title, rows, &labels)
}

/// [`format_table`] with the rows named by `labels` (methods that are not a [`Method`], such as
/// a pipeline's stages).
pub fn format_table_labelled(title: &str, rows: &[MethodSummary], labels: &[&str]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| {title} | RMS heading med | RMS worst | final med | final worst | RMS/ref med | RMS/ref worst | RMS/floored ref p90 | RMS/floored ref worst | final/ref med |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (r, label) in rows.iter().zip(labels) {
        let _ = writeln!(
            s,
            "| {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            label,
            r.rms.median,
            r.rms.worst,
            r.final_abs.median,
            r.final_abs.worst,
            r.rms_ratio.median,
            r.rms_ratio.worst,
            r.rms_ratio_floored.p90,
            r.rms_ratio_floored.worst,
            r.final_ratio.median
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nav::profiles::{generate, Profile};

    #[test]
    fn a_noiseless_bias_is_removed_by_every_stop_method() {
        let m = generate(Profile::StopAndGo, 100.0, 300.0, 2).unwrap();
        let measured: Vec<f64> = m.truth.iter().map(|t| t + 0.3).collect();
        let terms = BiasTerms::profile("adis16405").unwrap();
        let setup = Setup::new(terms, 100.0);
        let methods = [
            Method::Raw,
            Method::PowerOn,
            Method::ZaruOracle,
            Method::ZaruDetected,
            Method::KfDetected,
            Method::KfOracle,
        ];
        let r = evaluate(&measured, &m.truth, &m.still, &setup, &methods).unwrap();
        // Raw: 0.3 deg/s for 300 s.
        assert!((r[0].final_deg - 90.0).abs() < 1e-6, "{:?}", r[0]);
        for (i, x) in r.iter().enumerate().skip(1) {
            assert!(x.final_deg.abs() < 2.0, "{:?}: {x:?}", methods[i]);
        }
        let rows = summarize_methods(&methods, &[r.clone(), r], Method::ZaruOracle);
        assert_eq!(rows[2].rms_ratio.median, 1.0);
        assert!(format_table("t", &rows).contains("| KF oracle |"));
        assert!(matches!(
            evaluate(&measured[1..], &m.truth, &m.still, &setup, &methods),
            Err(EvalError::Lengths(..))
        ));
        assert!(matches!(
            evaluate(&measured, &m.truth, &m.still, &setup, &[Method::Floor]),
            Err(EvalError::NoFloor)
        ));
    }
}
