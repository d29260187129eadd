//! A record's whole Allan analysis, as `driftless allan` reports it: the deviation curve with
//! intervals on the grid asked for, the octave OADEV curve (in the sensor's base unit, deg/s or
//! m/s^2) that the IEEE 952 fit and the read-offs use, the fit and the read-offs. A curve says how far it has got as it goes
//! ([`Progress`]): a long grid on a long record takes minutes. Several records' analyses pool
//! into one ([`pool_analyses`]).

use super::chi2;
use super::deviation::{self, add_intervals, AllanError, AllanPoint, Kind, TauGrid};
use super::fit::{fit_terms, read_offs, FitError, NoiseFit, TermFit};
use super::pool::{self, LogCurve};

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

/// Several records' analyses pooled ([`pool_analyses`]).
#[derive(Debug, Clone)]
pub struct PooledAnalysis {
    /// The pooled analysis: `samples` those of every record, the curves pooled per tau, the fit
    /// and the read-offs of the pooled octave curve.
    pub analysis: Analysis,
    /// Per point of [`Analysis::points`], how many records reached its tau.
    pub logs: Vec<usize>,
}

/// The analyses of several records of one column (one rate, `kind` on one grid, as [`analyse`]
/// gave them) pooled per tau ([`pool::pool`]), never joined: the fit and the read-offs run on the
/// pooled octave curve.
pub fn pool_analyses(kind: Kind, logs: &[Analysis]) -> PooledAnalysis {
    let ci = chi2::ONE_SIGMA;
    let curves = |octave: bool| -> Vec<LogCurve<'_>> {
        logs.iter()
            .map(|a| LogCurve {
                points: if octave { &a.octave } else { &a.points },
                phase_len: a.samples + 1,
            })
            .collect()
    };
    let asked = pool::pool(kind, &curves(false), ci);
    let octave = pool::pool(Kind::Oadev, &curves(true), ci).points;
    PooledAnalysis {
        analysis: Analysis {
            samples: logs.iter().map(|a| a.samples).sum(),
            points: asked.points,
            fit: fit_terms(&octave, ci),
            read_offs: read_offs(&octave),
            octave,
        },
        logs: asked.logs,
    }
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

    /// One record pooled is that record's analysis; a record and its copy give its curve and
    /// its terms with narrower intervals.
    #[test]
    fn pooled_analyses_keep_one_record_and_narrow_with_more() {
        let y = noise(20_000);
        let a = analyse(&y, 100.0, Kind::Hdev, &TauGrid::Octave, 2.0, &mut |_| {}).unwrap();
        let one = pool_analyses(Kind::Hdev, std::slice::from_ref(&a));
        assert_eq!(one.analysis.points, a.points);
        assert_eq!(one.analysis.samples, a.samples);
        let close = |u: f64, v: f64| (u - v).abs() <= 1e-12 * v.abs();
        for (p, q) in one.analysis.octave.iter().zip(&a.octave) {
            assert!(close(p.dev, q.dev) && close(p.lo, q.lo) && close(p.hi, q.hi));
        }
        let two = pool_analyses(Kind::Hdev, &[a.clone(), a.clone()]);
        assert_eq!(two.analysis.samples, 40_000);
        assert!(two.logs.iter().all(|&k| k == 2));
        let (n1, n2) = (
            a.fit.as_ref().unwrap().get(Term::N).estimate.unwrap(),
            two.analysis
                .fit
                .as_ref()
                .unwrap()
                .get(Term::N)
                .estimate
                .unwrap(),
        );
        // The same curve, but twice the degrees of freedom weigh (and identify) its points anew.
        assert!(
            (n1.value - n2.value).abs() < 0.01 * n1.value,
            "{n1:?} vs {n2:?}"
        );
        assert!(n2.hi - n2.lo < n1.hi - n1.lo, "{n1:?} vs {n2:?}");
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
