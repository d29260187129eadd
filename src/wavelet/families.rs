//! Orthogonal wavelet filters with PyWavelets' coefficients (see `scripts/gen_filters.py`).

use super::filters::REC_LO;
use super::WaveletError;

/// An orthogonal wavelet: its four filters, as PyWavelets defines them.
#[derive(Debug, Clone, PartialEq)]
pub struct Wavelet {
    name: &'static str,
    dec_lo: Vec<f64>,
    dec_hi: Vec<f64>,
    rec_lo: Vec<f64>,
    rec_hi: Vec<f64>,
}

impl Wavelet {
    /// The wavelet called `name`: `haar`, `db1`..`db20`, `sym2`..`sym20` or `coif1`..`coif17`.
    pub fn by_name(name: &str) -> Result<Wavelet, WaveletError> {
        let (name, rec_lo) = REC_LO
            .iter()
            .find(|(n, _)| *n == name)
            .ok_or_else(|| WaveletError::UnknownWavelet(name.to_string()))?;
        let f = rec_lo.len();
        // These identities hold bit for bit in PyWavelets (checked by the generator script).
        let rec_hi: Vec<f64> = (0..f)
            .map(|k| {
                let v = rec_lo[f - 1 - k];
                if k % 2 == 0 {
                    v
                } else {
                    -v
                }
            })
            .collect();
        Ok(Wavelet {
            name,
            dec_lo: rec_lo.iter().rev().copied().collect(),
            dec_hi: rec_hi.iter().rev().copied().collect(),
            rec_lo: rec_lo.to_vec(),
            rec_hi,
        })
    }

    /// Every valid wavelet name.
    pub fn names() -> impl Iterator<Item = &'static str> {
        REC_LO.iter().map(|(n, _)| *n)
    }

    /// The wavelet's name, e.g. `db6`.
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// Filter length F (`2 * N` for dbN).
    pub fn filter_len(&self) -> usize {
        self.rec_lo.len()
    }

    /// Decomposition low-pass filter.
    pub fn dec_lo(&self) -> &[f64] {
        &self.dec_lo
    }

    /// Decomposition high-pass filter.
    pub fn dec_hi(&self) -> &[f64] {
        &self.dec_hi
    }

    /// Reconstruction low-pass filter.
    pub fn rec_lo(&self) -> &[f64] {
        &self.rec_lo
    }

    /// Reconstruction high-pass filter.
    pub fn rec_hi(&self) -> &[f64] {
        &self.rec_hi
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn families_are_complete() {
        assert_eq!(Wavelet::names().count(), 1 + 20 + 19 + 17);
        for n in Wavelet::names() {
            let w = Wavelet::by_name(n).unwrap();
            let f = w.filter_len();
            // Orthonormal: unit energy, sum sqrt(2), orthogonal to even shifts. PyWavelets' own
            // sym filters hold this only to 1.5e-11 (sym20), so that is the bound.
            let energy: f64 = w.rec_lo().iter().map(|v| v * v).sum();
            assert!((energy - 1.0).abs() < 2e-11, "{n}: energy {energy}");
            let sum: f64 = w.dec_lo().iter().sum();
            assert!((sum - 2f64.sqrt()).abs() < 2e-11, "{n}: sum {sum}");
            for s in (2..f).step_by(2) {
                let c: f64 = (0..f - s).map(|k| w.rec_lo()[k] * w.rec_lo()[k + s]).sum();
                assert!(c.abs() < 2e-11, "{n}: shift {s} correlation {c}");
            }
        }
        assert_eq!(Wavelet::by_name("db6").unwrap().filter_len(), 12);
        assert_eq!(Wavelet::by_name("coif17").unwrap().filter_len(), 102);
    }

    #[test]
    fn unknown_name_lists_families() {
        let e = Wavelet::by_name("db99").unwrap_err().to_string();
        assert!(e.contains("db1..db20") && e.contains("'db99'"), "{e}");
    }
}
