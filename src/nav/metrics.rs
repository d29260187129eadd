//! What a navigator sees of a corrected rate: the heading error, the integral of (corrected -
//! true rate), and summaries of it over many windows.
//!
//! The integral is the rectangle rule, `h[k] = sum_{i <= k} (c[i] - truth[i]) dt`: what a strapdown
//! integrator at the sample rate accumulates (any other rule differs by less than one sample's
//! step).

/// Heading figures of one window (degrees, deg/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HeadingMetrics {
    /// Heading error at the end of the window, deg (signed).
    pub final_deg: f64,
    /// RMS over time of the heading error, deg.
    pub rms_deg: f64,
    /// Largest |heading error|, deg.
    pub max_deg: f64,
    /// RMS of the rate error (corrected - truth), deg/s.
    pub rms_rate: f64,
}

/// The heading error figures accumulated one sample at a time (no allocation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingAccumulator {
    dt: f64,
    heading: f64,
    sum_h2: f64,
    sum_e2: f64,
    max: f64,
    n: u64,
}

impl HeadingAccumulator {
    /// An empty accumulator for samples `dt` seconds apart.
    pub fn new(dt: f64) -> Self {
        HeadingAccumulator {
            dt,
            heading: 0.0,
            sum_h2: 0.0,
            sum_e2: 0.0,
            max: 0.0,
            n: 0,
        }
    }

    /// Add one corrected sample and its truth (deg/s); returns the heading error so far (deg).
    pub fn push(&mut self, corrected: f64, truth: f64) -> f64 {
        let e = corrected - truth;
        self.heading += e * self.dt;
        self.sum_h2 += self.heading * self.heading;
        self.sum_e2 += e * e;
        self.max = self.max.max(self.heading.abs());
        self.n += 1;
        self.heading
    }

    /// The figures so far (all zero before any sample).
    pub fn metrics(&self) -> HeadingMetrics {
        let n = self.n.max(1) as f64;
        HeadingMetrics {
            final_deg: self.heading,
            rms_deg: (self.sum_h2 / n).sqrt(),
            max_deg: self.max,
            rms_rate: (self.sum_e2 / n).sqrt(),
        }
    }
}

/// The heading error series (deg) of a corrected rate against the truth (deg/s), `dt` s apart;
/// as long as the shorter input.
pub fn heading_error(corrected: &[f64], truth: &[f64], dt: f64) -> Vec<f64> {
    let mut acc = HeadingAccumulator::new(dt);
    corrected
        .iter()
        .zip(truth)
        .map(|(&c, &t)| acc.push(c, t))
        .collect()
}

/// The heading figures of a corrected rate against the truth, `dt` s apart.
pub fn heading_metrics(corrected: &[f64], truth: &[f64], dt: f64) -> HeadingMetrics {
    let mut acc = HeadingAccumulator::new(dt);
    for (&c, &t) in corrected.iter().zip(truth) {
        acc.push(c, t);
    }
    acc.metrics()
}

/// Median and worst (largest) of a set of values (NaN ignored).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Median (mean of the middle two for an even count); NaN when empty.
    pub median: f64,
    /// The 90th percentile (nearest rank); NaN when empty.
    pub p90: f64,
    /// Largest value; NaN when empty.
    pub worst: f64,
    /// Number of values summarised.
    pub count: usize,
}

/// The median and worst of `values` (NaN entries left out).
pub fn summarize(values: &[f64]) -> Summary {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    v.sort_by(f64::total_cmp);
    let count = v.len();
    if count == 0 {
        return Summary {
            median: f64::NAN,
            p90: f64::NAN,
            worst: f64::NAN,
            count,
        };
    }
    let median = if count % 2 == 1 {
        v[count / 2]
    } else {
        0.5 * (v[count / 2 - 1] + v[count / 2])
    };
    // Nearest rank: the smallest value with at least 90% of them at or below it.
    let p90 = v[((0.9 * count as f64).ceil() as usize).clamp(1, count) - 1];
    Summary {
        median,
        p90,
        worst: v[count - 1],
        count,
    }
}

/// Per-window ratios `values[i] / reference[i]` (NaN where the reference is 0 or either is NaN).
pub fn ratios(values: &[f64], reference: &[f64]) -> Vec<f64> {
    values
        .iter()
        .zip(reference)
        .map(|(&v, &r)| if r == 0.0 { f64::NAN } else { v / r })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_rate_error_integrates_to_a_ramp() {
        // Error 0.1 deg/s for 100 samples at dt 0.1: heading 0.01 k, final 1 deg.
        let truth = vec![5.0; 100];
        let c: Vec<f64> = truth.iter().map(|t| t + 0.1).collect();
        let h = heading_error(&c, &truth, 0.1);
        assert!((h[99] - 1.0).abs() < 1e-12);
        let m = heading_metrics(&c, &truth, 0.1);
        assert!((m.final_deg - 1.0).abs() < 1e-12);
        assert!((m.max_deg - 1.0).abs() < 1e-12);
        assert!((m.rms_rate - 0.1).abs() < 1e-12);
        // RMS of 0.01 k, k = 1..100: 0.01 sqrt(sum k^2 / 100).
        let expect = 0.01 * ((100.0 * 101.0 * 201.0 / 6.0) / 100.0f64).sqrt();
        assert!((m.rms_deg - expect).abs() < 1e-12);
    }

    #[test]
    fn summaries_and_ratios() {
        let s = summarize(&[3.0, 1.0, f64::NAN, 2.0, 10.0]);
        assert_eq!((s.median, s.p90, s.worst, s.count), (2.5, 10.0, 10.0, 4));
        // Nearest rank: of 1..=20, 90% lie at or below 18.
        let s = summarize(&(1..=20).map(f64::from).collect::<Vec<_>>());
        assert_eq!(s.p90, 18.0);
        let s = summarize(&[]);
        assert!(s.median.is_nan() && s.count == 0);
        let r = ratios(&[1.0, 2.0, 3.0], &[2.0, 0.0, 3.0]);
        assert_eq!(r[0], 0.5);
        assert!(r[1].is_nan());
        assert_eq!(r[2], 1.0);
    }
}
