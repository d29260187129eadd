//! The static noise the motion is added to: a log's rates after the part the Allan fit
//! characterises, or the simulator's noise; and the noise terms the estimators are given. With
//! an accelerometer, its static specific force too (the log's own, gravity, noise and bias
//! included, or the simulated sensor's), time-aligned with the rates.

use super::NavEvalError;
use crate::allan::{allan, chi2::ONE_SIGMA, fit_terms, AllanPoint, Kind, NoiseFit, TauGrid};
use crate::drift::bias::{
    own_accel_terms, own_terms, AccelTerms as FilterAccelTerms, BiasTerms, ColumnFit,
};
use crate::rate_log::RateLog;
use crate::sim::force::{specific_force, AccelTerms, Accelerometer, Attitude};
use crate::sim::{SimConfig, SimError, Simulator};

/// The static noise: one series per axis, deg/s, and where the windows may start.
#[derive(Debug, Clone)]
pub struct Source {
    /// What it is: the log's path, or `simulated SENSOR`.
    pub name: String,
    /// Sample rate, Hz.
    pub rate: f64,
    /// One series per axis: its name and its rates, deg/s.
    pub axes: Vec<(String, Vec<f64>)>,
    /// The first sample a window may start at: a log's windows come after the part the Allan
    /// fit characterises ([`Source::fit_terms`]), so they are held out.
    pub first_window: usize,
    /// The simulator's configuration when simulated: its true noise model gives the floor
    /// method ([`crate::nav::Method::Floor`]).
    pub floor: Option<SimConfig>,
    /// The accelerometer's static specific force at each sample (m/s²; the sensor at rest, so
    /// gravity with the accelerometer's noise and bias), when the source has one. The motion's
    /// own force is added per case ([`crate::nav::force`]).
    pub accel: Option<Vec<[f64; 3]>>,
}

impl Source {
    /// A log's rates (a bag's, rad/s, in deg/s) at `rate` Hz: its first `characterise` rows are
    /// the part the fit characterises, the windows of `window` samples come after. Refused when
    /// it has no room for one window.
    pub fn from_log(
        log: RateLog,
        rate: f64,
        characterise: usize,
        window: usize,
    ) -> Result<Source, NavEvalError> {
        let mut table = log.table;
        let path = table.path.clone();
        if log.origin.bag.is_some() {
            // A bag's rates are rad/s; the navigation and its terms here are in deg/s.
            for c in &mut table.columns {
                c.iter_mut().for_each(|v| *v = v.to_degrees());
            }
        }
        let rows = table.rows();
        if rows < characterise + window {
            return Err(NavEvalError::Input(format!(
                "{}: {rows} rows, but the characterisation ({characterise}) and one window ({window}) need {}",
                path.display(),
                characterise + window
            )));
        }
        Ok(Source {
            name: path.display().to_string(),
            rate,
            axes: table.names.into_iter().zip(table.columns).collect(),
            first_window: characterise,
            floor: None,
            accel: None,
        })
    }

    /// The same source with the accelerometer's static specific force, m/s², one per sample
    /// (refused unless there is one for every sample of the rates).
    pub fn with_accel(mut self, accel: Vec<[f64; 3]>) -> Result<Source, NavEvalError> {
        let rows = self.axes.first().map_or(0, |(_, y)| y.len());
        if accel.len() != rows {
            return Err(NavEvalError::Input(format!(
                "{}: {} accelerometer samples for {rows} rate samples",
                self.name,
                accel.len()
            )));
        }
        self.accel = Some(accel);
        Ok(self)
    }

    /// `samples` samples per axis of the simulator's noise for `cfg` (at its rate, with its
    /// axes), named after `sensor`; with the sensor's accelerometer, if it has one
    /// ([`AccelTerms::profile`]), at rest and level (its streams of the same seed).
    pub fn simulated(sensor: &str, cfg: &SimConfig, samples: usize) -> Result<Source, SimError> {
        let mut axes: Vec<(String, Vec<f64>)> = (0..cfg.axes)
            .map(|a| (format!("sim axis {a}"), Vec::with_capacity(samples)))
            .collect();
        let mut sim = Simulator::new(cfg)?;
        for _ in 0..samples {
            let s = sim.next_sample();
            for (a, (_, y)) in axes.iter_mut().enumerate() {
                y.push(s.measured[a]);
            }
        }
        let accel = match AccelTerms::profile(sensor)? {
            Some(terms) => {
                let mut acc = Accelerometer::new(&terms, cfg.rate_hz, cfg.seed)?;
                let rest = specific_force(&Attitude::LEVEL, [0.0; 3]);
                Some((0..samples).map(|_| acc.measure(rest)).collect())
            }
            None => None,
        };
        Ok(Source {
            name: format!("simulated {sensor}"),
            rate: cfg.rate_hz,
            axes,
            first_window: 0,
            floor: Some(cfg.clone()),
            accel,
        })
    }

    /// The noise terms of the characterisation part: what `driftless allan --stage` writes for
    /// that record (one set for every axis), with the output step `lsb`, deg/s.
    pub fn fit_terms(&self, lsb: f64) -> Result<BiasTerms, NavEvalError> {
        let characterise = self.first_window;
        let mut fitted = Vec::with_capacity(self.axes.len());
        for (name, y) in &self.axes {
            let (fit, points) = self.fit_column(name, &y[..characterise])?;
            fitted.push((name.as_str(), fit, points));
        }
        let columns: Vec<ColumnFit> = fitted
            .iter()
            .map(|(name, fit, points)| ColumnFit { name, fit, points })
            .collect();
        let own = own_terms(&columns, lsb)
            .map_err(|e| NavEvalError::Input(format!("{}: {e}", self.name)))?;
        Ok(own.terms)
    }

    /// The accelerometer's noise terms of the characterisation part, when the source has one:
    /// what `driftless allan --accel-column ... --stage` writes for that record (one set for
    /// every axis, fitted in m/s²).
    pub fn fit_accel_terms(&self) -> Result<Option<FilterAccelTerms>, NavEvalError> {
        let Some(accel) = &self.accel else {
            return Ok(None);
        };
        let characterise = self.first_window;
        let mut fitted = Vec::with_capacity(3);
        for (a, name) in ["accel x", "accel y", "accel z"].into_iter().enumerate() {
            let y: Vec<f64> = accel[..characterise].iter().map(|f| f[a]).collect();
            let (fit, points) = self.fit_column(name, &y)?;
            fitted.push((name, fit, points));
        }
        let columns: Vec<ColumnFit> = fitted
            .iter()
            .map(|(name, fit, points)| ColumnFit { name, fit, points })
            .collect();
        let own = own_accel_terms(&columns)
            .map_err(|e| NavEvalError::Input(format!("{}: {e}", self.name)))?;
        Ok(Some(own.terms))
    }

    /// One column's Allan deviation (the characterisation part `y`) and its IEEE 952 fit, as
    /// `driftless allan` computes them.
    fn fit_column(
        &self,
        name: &str,
        y: &[f64],
    ) -> Result<(NoiseFit, Vec<AllanPoint>), NavEvalError> {
        let points = allan(y, self.rate, Kind::Oadev, &TauGrid::Octave, ONE_SIGMA)
            .map_err(|e| NavEvalError::Input(format!("{}: {name}: {e}", self.name)))?;
        let fit = fit_terms(&points, ONE_SIGMA).map_err(|e| {
            NavEvalError::Input(format!(
                "{}: {name}: no noise terms from the first {} rows ({e}); give --terms adis16405 or a longer --characterise",
                self.name,
                y.len()
            ))
        })?;
        Ok((fit, points))
    }

    /// Whole windows of `window` samples per axis after [`Source::first_window`].
    pub fn windows(&self, window: usize) -> usize {
        (self.axes[0].1.len() - self.first_window) / window
    }
}
