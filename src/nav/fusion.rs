//! x-io Fusion's gyroscope bias algorithm (`FusionBias`, the one its AHRS ships; Python package
//! `imufusion`), as deployed: the yardstick of a bias correction that many products run.
//!
//! Written from its published algorithm (Fusion v1.3, `Fusion/FusionBias.c`): subtract the
//! offset; when any axis of the result exceeds the stationary threshold (3 deg/s), reset a
//! timer; once every axis has stayed below it for the stationary period (3 s), each further
//! sample moves the offset towards the rate by a first-order low-pass of 0.02 Hz
//! (`offset += rate * 2 pi 0.02 / sample_rate`). It looks at all three axes at once: one turning
//! axis stops the learning of the others. The arithmetic is single precision in the same order
//! as the C library, so the output equals `imufusion`'s bit for bit
//! (`tests/fusion_vs_imufusion.rs`, fixture made by `scripts/gen_fusion_fixture.py` with
//! imufusion 1.3.3).

/// The low-pass cutoff of the offset, Hz (a constant of the C library).
pub const CUTOFF_HZ: f32 = 0.02;

/// The library's default stationary threshold, deg/s.
pub const DEFAULT_THRESHOLD_DEGPS: f32 = 3.0;

/// The library's default stationary period, s.
pub const DEFAULT_PERIOD_S: f32 = 3.0;

/// One `FusionBias` instance: three axes, deg/s.
#[derive(Debug, Clone, PartialEq)]
pub struct FusionBias {
    threshold: f32,
    coefficient: f32,
    timeout: u32,
    timer: u32,
    offset: [f32; 3],
}

impl FusionBias {
    /// With the library's default settings at `sample_rate` Hz.
    pub fn new(sample_rate: f64) -> Self {
        Self::with_settings(sample_rate, DEFAULT_THRESHOLD_DEGPS, DEFAULT_PERIOD_S)
    }

    /// With explicit settings (`FusionBiasSettings`): the rate in Hz, the stationary threshold
    /// in deg/s and the stationary period in s.
    pub fn with_settings(sample_rate: f64, threshold: f32, period_s: f32) -> Self {
        let rate = sample_rate as f32;
        FusionBias {
            threshold,
            // The C library's expression, in its order: 2.0f * (float) M_PI * CUTOFF * (1 / rate).
            coefficient: 2.0 * std::f32::consts::PI * CUTOFF_HZ * (1.0 / rate),
            // (uint32_t) (period * rate): truncated, as the C cast does.
            timeout: (period_s * rate) as u32,
            timer: 0,
            offset: [0.0; 3],
        }
    }

    /// Take one sample (deg/s, x y z) and return it corrected by the offset held before it.
    pub fn update(&mut self, gyro: [f64; 3]) -> [f64; 3] {
        let g = [
            gyro[0] as f32 - self.offset[0],
            gyro[1] as f32 - self.offset[1],
            gyro[2] as f32 - self.offset[2],
        ];
        let out = g.map(f64::from);
        if g.iter().any(|v| v.abs() > self.threshold) {
            self.timer = 0;
            return out;
        }
        if self.timer < self.timeout {
            self.timer += 1;
            return out;
        }
        for (o, v) in self.offset.iter_mut().zip(g) {
            *o += v * self.coefficient;
        }
        out
    }

    /// The offset it holds now, deg/s.
    pub fn offset(&self) -> [f64; 3] {
        self.offset.map(f64::from)
    }
}

/// Corrected rates (deg/s) of up to three axes through one `FusionBias` at `sample_rate`:
/// `axes[a][k]` is axis a's sample k (equal lengths); a missing axis reads as still (0).
pub fn correct(axes: &[&[f64]], sample_rate: f64) -> Vec<Vec<f64>> {
    let n = axes.first().map_or(0, |x| x.len());
    let mut f = FusionBias::new(sample_rate);
    let mut out = vec![Vec::with_capacity(n); axes.len().min(3)];
    for k in 0..n {
        let mut g = [0.0; 3];
        for (a, x) in axes.iter().take(3).enumerate() {
            g[a] = x[k];
        }
        let c = f.update(g);
        for (a, o) in out.iter_mut().enumerate() {
            o.push(c[a]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learns_only_after_the_period_and_only_while_every_axis_is_still() {
        let mut f = FusionBias::new(100.0);
        // 3 s of still samples: the timer runs, the offset stays 0.
        for _ in 0..300 {
            assert_eq!(f.update([0.5, 0.0, 0.0]), [0.5, 0.0, 0.0]);
        }
        assert_eq!(f.offset(), [0.0; 3]);
        // From then on the offset follows the rate.
        f.update([0.5, 0.0, 0.0]);
        assert!(f.offset()[0] > 0.0);
        let learnt = f.offset()[0];
        // One axis turning stops the learning of all and restarts the period.
        f.update([0.5, 0.0, 10.0]);
        f.update([0.5, 0.0, 0.0]);
        assert_eq!(f.offset()[0], learnt);
        // Given long enough, the offset converges on the bias (time constant 1 / (2 pi 0.02) s).
        for _ in 0..100 * 60 {
            f.update([0.5, -0.25, 0.0]);
        }
        assert!((f.offset()[0] - 0.5).abs() < 1e-3, "{:?}", f.offset());
        assert!((f.offset()[1] + 0.25).abs() < 1e-3, "{:?}", f.offset());
    }

    #[test]
    fn a_missing_axis_reads_as_still() {
        let x = vec![1.0; 1000];
        let out = correct(&[&x], 100.0);
        assert_eq!(out.len(), 1);
        assert!(out[0][999] < 1.0);
    }
}
