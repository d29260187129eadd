//! [`AccelTerms`]: the accelerometer's noise terms a stage reads beside the gyro's, for a
//! stillness test that uses both sensors: its white noise (velocity random walk) and its bias
//! instability. `driftless allan --stage` measures them on a still record
//! ([`super::own_accel_terms`]); without a record, the ADIS16405 data sheet's
//! ([`AccelTerms::ADIS16405`]).
//!
//! Base units as [`crate::allan::units::Sensor::Accel`] has them: N in m/s/sqrt(s) (the same
//! number as a white acceleration noise density in m/s^2/sqrt(Hz), two-sided), B in m/s^2.

use super::BiasError;
use crate::units::STANDARD_GRAVITY;

/// An accelerometer's noise terms, one set for every axis, base units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelTerms {
    /// Velocity random walk N, m/s/sqrt(s).
    pub vrw: f64,
    /// Bias instability B, m/s^2.
    pub b: f64,
}

/// m/s/sqrt(h) per m/s/sqrt(s): what `accel_vrw` is written in.
pub const VRW_PER_HOUR: f64 = 60.0;

/// mg per m/s^2: what `accel_bias_instability` is written in.
pub const MG_PER_M_S2: f64 = 1000.0 / STANDARD_GRAVITY;

/// The ADIS16405 data sheet's accelerometer velocity random walk, m/s/sqrt(h) (the figure
/// NaveGo's ADIS16405 profile takes too). Not fitted to our log: a default no test data chose.
pub const ADIS16405_VRW_PER_HOUR: f64 = 0.2;

/// The ADIS16405 data sheet's accelerometer bias instability B, mg: its in-run bias stability
/// of 0.2 mg is the Allan deviation's floor, which is 0.664 B ([`super::B_FLOOR`]), so B is
/// 0.2 / 0.664 = 0.30 mg, rounded.
pub const ADIS16405_BIAS_INSTABILITY_MG: f64 = 0.3;

impl AccelTerms {
    /// The ADIS16405 data sheet's accelerometer ([`ADIS16405_VRW_PER_HOUR`],
    /// [`ADIS16405_BIAS_INSTABILITY_MG`]).
    pub const ADIS16405: AccelTerms = AccelTerms {
        vrw: ADIS16405_VRW_PER_HOUR / VRW_PER_HOUR,
        b: ADIS16405_BIAS_INSTABILITY_MG / MG_PER_M_S2,
    };

    /// From the units a pipeline file gives: N in m/s/sqrt(h), B in mg.
    pub fn from_stage_units(vrw_per_hour: f64, b_mg: f64) -> AccelTerms {
        AccelTerms {
            vrw: vrw_per_hour / VRW_PER_HOUR,
            b: b_mg / MG_PER_M_S2,
        }
    }

    /// Check: N finite and > 0 (a still accelerometer always shows noise), B finite and >= 0.
    pub fn check(&self) -> Result<(), BiasError> {
        if !(self.vrw.is_finite() && self.vrw > 0.0) {
            return Err(BiasError::BadTerm("accelerometer N", self.vrw));
        }
        if !(self.b.is_finite() && self.b >= 0.0) {
            return Err(BiasError::BadTerm("accelerometer B", self.b));
        }
        Ok(())
    }

    /// The 1-sigma white noise of one sample at `rate_hz`, m/s^2: N sqrt(rate), the white
    /// noise's low-frequency level as one sample's deviation (a band-limited sensor's own
    /// samples scatter somewhat less). What `GyroSample::accel_std` carries.
    pub fn white_std(&self, rate_hz: f64) -> f64 {
        self.vrw * rate_hz.sqrt()
    }

    /// The terms as keys of a stage table, in the units pipeline files use (one `key = value`
    /// per line: `accel_vrw` m/s/sqrt(h), `accel_bias_instability` mg).
    pub fn stage_keys(&self) -> String {
        format!(
            "accel_vrw = {:e}\naccel_bias_instability = {:e}",
            self.vrw * VRW_PER_HOUR,
            self.b * MG_PER_M_S2
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_units_round_trip_and_the_white_std_follows_the_rate() {
        let t = AccelTerms::from_stage_units(0.3, 0.4);
        assert!((t.vrw * VRW_PER_HOUR - 0.3).abs() < 1e-15);
        assert!((t.b * MG_PER_M_S2 - 0.4).abs() < 1e-15);
        // 0.3 m/s/sqrt(h) = 0.005 m/s/sqrt(s): 0.05 m/s^2 per sample at 100 Hz.
        assert!((t.white_std(100.0) - 0.05).abs() < 1e-15);
        assert!((t.white_std(400.0) - 0.1).abs() < 1e-15);
        assert_eq!(
            t.stage_keys(),
            "accel_vrw = 3e-1\naccel_bias_instability = 4e-1"
        );
        assert!(t.check().is_ok());
        assert!(AccelTerms::ADIS16405.check().is_ok());
        assert!(AccelTerms { vrw: 0.0, b: 0.0 }.check().is_err());
        assert!(AccelTerms {
            vrw: 1.0,
            b: f64::NAN
        }
        .check()
        .is_err());
    }

    #[test]
    fn the_data_sheet_default_is_in_the_data_sheet_units() {
        let t = AccelTerms::ADIS16405;
        assert!((t.vrw * 60.0 - 0.2).abs() < 1e-12);
        // The data sheet's floor of 0.2 mg as B: 0.2 / 0.664 mg, 0.00295 m/s^2.
        let b = 0.2e-3 * 9.80665 / super::super::B_FLOOR;
        assert!((t.b / b - 1.0).abs() < 0.005, "{} vs {b}", t.b);
    }
}
