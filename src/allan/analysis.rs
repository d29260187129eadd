//! A record's whole Allan analysis, as `driftless allan` reports it: the deviation curve with
//! intervals on the grid asked for, the octave OADEV curve (in the sensor's base unit, deg/s or
//! m/s^2) that the IEEE 952 fit and the read-offs use, the fit and the read-offs. A curve says how far it has got as it goes
//! ([`Progress`]): a long grid on a long record takes minutes.

use super::chi2;
use super::deviation::{self, add_intervals, AllanError, AllanPoint, Kind, TauGrid};
use super::fit::{fit_terms, read_offs, FitError, NoiseFit, TermFit};

/// Which curve a [`Progress`] report is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Curve {
    /// The deviation asked for, on its grid.
    Asked,
    /// The octave OADEV the fit needs, when the curve asked for is not it.
    OctaveForFit,
}

/// How far an analysis has got.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// A curve starts.
    Start {
        /// Which.
        curve: Curve,
        /// Its averaging factors.
        steps: usize,
        /// Terms it sums in all ([`work`]): what it costs.
        terms: f64,
    },
    /// `n` more averaging factors of the curve are done.
    Step(usize),
    /// The curve is done.
    Done,
}

/// One record's analysis.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// Samples in the record.
    pub samples: usize,
    /// The deviation asked for, with intervals, in the record's units.
    pub points: Vec<AllanPoint>,
    /// The octave OADEV points the fit and the read-offs use, in the base unit (deg/s, m/s^2).
    pub octave: Vec<AllanPoint>,
    /// The IEEE 952 fit of [`Analysis::octave`], or why there is none.
    pub fit: Result<NoiseFit, FitError>,
    /// The slope-line read-offs of [`Analysis::octave`].
    pub read_offs: Vec<TermFit>,
}

/// Terms summed over the averaging factors `ms` of a record of `phase_len` phase points.
pub fn work(kind: Kind, phase_len: usize, ms: &[usize]) -> f64 {
    ms.iter()
        .map(|&m| deviation::terms(kind, phase_len, m) as f64)
        .sum()
}

/// The analysis of the samples `y` at `rate` Hz: `kind` on `grid` in the record's units, the
/// fit and the read-offs in the sensor's base unit (`to_base`: deg/s or m/s^2 per unit of `y`,
/// [`super::SampleUnit::to_base`]). `progress` hears each curve's start, steps and end.
pub fn analyse(
    y: &[f64],
    rate: f64,
    kind: Kind,
    grid: &TauGrid,
    to_base: f64,
    progress: &mut dyn FnMut(Progress),
) -> Result<Analysis, AllanError> {
    let ci = chi2::ONE_SIGMA;
    let too_short = AllanError::TooShort {
        samples: y.len(),
        kind,
        needed: if kind == Kind::Hdev { 4 } else { 3 },
    };
    if y.len() < 3 {
        return Err(too_short);
    }
    let x = deviation::frequency_to_phase(y, rate);
    let mut curve = |curve: Curve, kind: Kind, grid: &TauGrid| {
        let ms = deviation::averaging_factors(grid, x.len(), rate);
        progress(Progress::Start {
            curve,
            steps: ms.len(),
            terms: work(kind, x.len(), &ms),
        });
        let mut out = Vec::with_capacity(ms.len());
        // A few factors at a time, so a long curve reports as it goes.
        for chunk in ms.chunks(8) {
            let devs = deviation::deviations(kind, &x, rate, chunk);
            for (&m, (dev, n)) in chunk.iter().zip(devs) {
                if n > 1 {
                    out.push(AllanPoint::bare(m, rate, dev, n));
                }
            }
            progress(Progress::Step(chunk.len()));
        }
        progress(Progress::Done);
        add_intervals(kind, &mut out, x.len(), ci);
        out
    };
    let points = curve(Curve::Asked, kind, grid);
    if points.is_empty() {
        return Err(too_short);
    }
    let octave = if kind == Kind::Oadev && *grid == TauGrid::Octave {
        points.clone()
    } else {
        curve(Curve::OctaveForFit, Kind::Oadev, &TauGrid::Octave)
    };
    let in_base: Vec<AllanPoint> = octave
        .iter()
        .map(|p| AllanPoint {
            dev: p.dev * to_base,
            lo: p.lo * to_base,
            hi: p.hi * to_base,
            ..*p
        })
        .collect();
    Ok(Analysis {
        samples: y.len(),
        points,
        fit: fit_terms(&in_base, ci),
        read_offs: read_offs(&in_base),
        octave: in_base,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::fit::MIN_NU;
    use crate::allan::{allan, Term};

    fn noise(n: usize) -> Vec<f64> {
        // A deterministic, noise-like record (no crate RNG needed here).
        let mut s = 12345u64;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn the_octave_curve_is_the_one_allan_gives_and_each_curve_reports() {
        let y = noise(20_000);
        let mut heard = Vec::new();
        let a = analyse(&y, 100.0, Kind::Mdev, &TauGrid::Decade, 2.0, &mut |p| {
            heard.push(p)
        })
        .unwrap();
        let octave = allan(&y, 100.0, Kind::Oadev, &TauGrid::Octave, chi2::ONE_SIGMA).unwrap();
        assert_eq!(a.octave.len(), octave.len());
        for (p, q) in a.octave.iter().zip(&octave) {
            assert_eq!((p.tau, p.dev, p.hi), (q.tau, 2.0 * q.dev, 2.0 * q.hi));
        }
        let starts: Vec<Curve> = heard
            .iter()
            .filter_map(|p| match p {
                Progress::Start { curve, .. } => Some(*curve),
                _ => None,
            })
            .collect();
        assert_eq!(starts, [Curve::Asked, Curve::OctaveForFit]);
        assert_eq!(heard.iter().filter(|p| **p == Progress::Done).count(), 2);
        assert!(a.fit.as_ref().unwrap().get(Term::N).estimate.is_some());
        assert_eq!(a.samples, 20_000);
    }

    #[test]
    fn a_term_short_of_significance_says_how_long_a_record_would_do() {
        let mut t = TermFit {
            term: Term::N,
            estimate: None,
            reason: None,
            sigmas: Some((MIN_NU / 2.0).sqrt() / 2.0),
        };
        // Half the significance needed: four times the length, and a quarter more.
        assert_eq!(t.record_to_identify(10.0), Some(50.0));
        t.sigmas = None;
        assert_eq!(t.record_to_identify(10.0), None);
    }
}
