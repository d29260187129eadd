//! Units: the unit of a record's samples (a gyro's rate or an accelerometer's specific force, in
//! the units of [`crate::units`]), and the display units and names of the IEEE Std 952 terms of
//! each [`Sensor`].
//!
//! Inside [`crate::allan::fit`] every term is in the sensor's base units, built from its base
//! unit and s. A gyro's (deviation in deg/s): Q deg, N deg/sqrt(s), B deg/s, K deg/s/sqrt(s),
//! R deg/s^2. An accelerometer's (deviation in m/s^2): Q m/s, N m/s/sqrt(s), B m/s^2,
//! K m/s^2/sqrt(s), R m/s^3. The fit is the same; only the names and units differ.

use std::fmt;
use std::str::FromStr;

use crate::units::{AccelUnit, RateUnit, STANDARD_GRAVITY};

/// Which sensor a record comes from: it names the terms and gives their units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sensor {
    /// A gyroscope: rates, base unit deg/s.
    #[default]
    Gyro,
    /// An accelerometer: specific force, base unit m/s^2.
    Accel,
}

impl Sensor {
    /// The word used in outputs (`"gyro"`, `"accel"`).
    pub fn word(self) -> &'static str {
        match self {
            Sensor::Gyro => "gyro",
            Sensor::Accel => "accel",
        }
    }

    /// What `term` is called for this sensor (IEEE Std 952 for a gyro, IEEE Std 1293's
    /// counterparts for an accelerometer).
    pub fn term_name(self, term: Term) -> &'static str {
        match (self, term) {
            (Sensor::Gyro, Term::Q) => "quantisation noise",
            (Sensor::Gyro, Term::N) => "angle random walk",
            (Sensor::Gyro, Term::K) => "rate random walk",
            (Sensor::Gyro, Term::R) => "rate ramp",
            (Sensor::Accel, Term::Q) => "velocity quantisation",
            (Sensor::Accel, Term::N) => "velocity random walk",
            (Sensor::Accel, Term::K) => "acceleration random walk",
            (Sensor::Accel, Term::R) => "acceleration ramp",
            (_, Term::B) => "bias instability",
        }
    }

    /// The base unit the fit works in for `term` (deviation in the sensor's base unit, tau in s).
    pub fn base_unit(self, term: Term) -> &'static str {
        match self {
            Sensor::Gyro => match term {
                Term::Q => "deg",
                Term::N => "deg/sqrt(s)",
                Term::B => "deg/s",
                Term::K => "deg/s/sqrt(s)",
                Term::R => "deg/s^2",
            },
            Sensor::Accel => match term {
                Term::Q => "m/s",
                Term::N => "m/s/sqrt(s)",
                Term::B => "m/s^2",
                Term::K => "m/s^2/sqrt(s)",
                Term::R => "m/s^3",
            },
        }
    }

    /// The unit a data sheet prints `term` in and the factor from the base unit to it. A gyro:
    /// Q deg, N deg/sqrt(h), B deg/h, K deg/h/sqrt(h), R deg/h^2. An accelerometer: Q m/s,
    /// N m/s/sqrt(h), B mg, K m/s^2/sqrt(h), R m/s^2/h.
    pub fn display(self, term: Term) -> (&'static str, f64) {
        match self {
            Sensor::Gyro => match term {
                Term::Q => ("deg", 1.0),
                Term::N => ("deg/sqrt(h)", 60.0),
                Term::B => ("deg/h", 3600.0),
                Term::K => ("deg/h/sqrt(h)", 3600.0 * 60.0),
                Term::R => ("deg/h^2", 3600.0 * 3600.0),
            },
            Sensor::Accel => match term {
                Term::Q => ("m/s", 1.0),
                Term::N => ("m/s/sqrt(h)", 60.0),
                Term::B => ("mg", 1000.0 / STANDARD_GRAVITY),
                Term::K => ("m/s^2/sqrt(h)", 60.0),
                Term::R => ("m/s^2/h", 3600.0),
            },
        }
    }

    /// The unit `term` is shown in under `units`, and the factor from the base unit.
    pub fn unit_in(self, term: Term, units: TermUnits) -> (&'static str, f64) {
        match units {
            TermUnits::Datasheet => self.display(term),
            TermUnits::Seconds => (self.base_unit(term), 1.0),
        }
    }

    /// A second unit where one is customary, with its factor from the base unit: Q in arcsec
    /// (a gyro's), N per sqrt(s) (deg/sqrt(s), m/s/sqrt(s)).
    pub fn alternate(self, term: Term) -> Option<(&'static str, f64)> {
        match (self, term) {
            (Sensor::Gyro, Term::Q) => Some(("arcsec", 3600.0)),
            (_, Term::N) => Some((self.base_unit(term), 1.0)),
            _ => None,
        }
    }
}

impl fmt::Display for Sensor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.word())
    }
}

/// The unit of a record's samples: a gyro's or an accelerometer's. It says which sensor the
/// record is of and the factor to that sensor's base unit (deg/s, m/s^2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleUnit {
    /// A gyro's rate.
    Rate(RateUnit),
    /// An accelerometer's specific force.
    Accel(AccelUnit),
}

impl SampleUnit {
    /// The sensor.
    pub fn sensor(self) -> Sensor {
        match self {
            SampleUnit::Rate(_) => Sensor::Gyro,
            SampleUnit::Accel(_) => Sensor::Accel,
        }
    }

    /// Factor that turns a sample into the sensor's base unit (deg/s, m/s^2).
    pub fn to_base(self) -> f64 {
        match self {
            SampleUnit::Rate(u) => u.to_deg_per_s(),
            SampleUnit::Accel(u) => u.to_m_per_s2(),
        }
    }
}

impl fmt::Display for SampleUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SampleUnit::Rate(u) => u.fmt(f),
            SampleUnit::Accel(u) => u.fmt(f),
        }
    }
}

/// The units the noise terms are shown in: data-sheet units (per hour) or the fit's own
/// (per second). Every command that prints terms takes the same choice (`--term-units`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TermUnits {
    /// Q deg, N deg/sqrt(h), B deg/h, K deg/h/sqrt(h), R deg/h^2: what data sheets print.
    #[default]
    Datasheet,
    /// Q deg, N deg/sqrt(s), B deg/s, K deg/s/sqrt(s), R deg/s^2: the fit's base units.
    Seconds,
}

impl FromStr for TermUnits {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "datasheet" => Ok(TermUnits::Datasheet),
            "seconds" => Ok(TermUnits::Seconds),
            _ => Err(format!(
                "unknown term units '{s}' (datasheet: deg/sqrt(h), deg/h; seconds: deg/sqrt(s), deg/s)"
            )),
        }
    }
}

/// One of the five IEEE Std 952 noise terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Term {
    /// Quantisation noise: sigma^2 = 3 Q^2 / tau^2 (slope -1).
    Q,
    /// Angle random walk: sigma^2 = N^2 / tau (slope -1/2).
    N,
    /// Bias instability: sigma^2 = (2 ln 2 / pi) B^2 (slope 0).
    B,
    /// Rate random walk: sigma^2 = K^2 tau / 3 (slope +1/2).
    K,
    /// Rate ramp: sigma^2 = R^2 tau^2 / 2 (slope +1).
    R,
}

impl Term {
    /// All five, in the model's order.
    pub const ALL: [Term; 5] = [Term::Q, Term::N, Term::B, Term::K, Term::R];

    /// The letter.
    pub fn name(self) -> &'static str {
        match self {
            Term::Q => "Q",
            Term::N => "N",
            Term::B => "B",
            Term::K => "K",
            Term::R => "R",
        }
    }

    /// A gyro's base unit of this term ([`Sensor::base_unit`]).
    pub fn base_unit(self) -> &'static str {
        Sensor::Gyro.base_unit(self)
    }

    /// A gyro's data-sheet unit of this term and the factor to it ([`Sensor::display`]).
    pub fn display(self) -> (&'static str, f64) {
        Sensor::Gyro.display(self)
    }

    /// A gyro's unit of this term under `units` ([`Sensor::unit_in`]).
    pub fn unit_in(self, units: TermUnits) -> (&'static str, f64) {
        Sensor::Gyro.unit_in(self, units)
    }

    /// A gyro's second unit of this term ([`Sensor::alternate`]).
    pub fn alternate(self) -> Option<(&'static str, f64)> {
        Sensor::Gyro.alternate(self)
    }

    /// The slope of the deviation (not the variance) on log-log axes.
    pub fn slope(self) -> f64 {
        match self {
            Term::Q => -1.0,
            Term::N => -0.5,
            Term::B => 0.0,
            Term::K => 0.5,
            Term::R => 1.0,
        }
    }

    /// The model's coefficient of this term's square: sigma^2(tau) = sum coefficient(tau) * T^2.
    pub fn coefficient(self, tau: f64) -> f64 {
        match self {
            Term::Q => 3.0 / (tau * tau),
            Term::N => 1.0 / tau,
            Term::B => 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI,
            Term::K => tau / 3.0,
            Term::R => tau * tau / 2.0,
        }
    }
}

impl fmt::Display for Term {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_accelerometer_s_terms_have_their_own_names_and_units() {
        // 0.2 m/s/sqrt(h) is 0.2/60 m/s/sqrt(s); 0.2 mg is 0.2 * 9.80665e-3 m/s^2.
        let (u, f) = Sensor::Accel.display(Term::N);
        assert_eq!((u, f), ("m/s/sqrt(h)", 60.0));
        let (u, f) = Sensor::Accel.display(Term::B);
        assert_eq!(u, "mg");
        assert!((0.2e-3 * STANDARD_GRAVITY * f - 0.2).abs() < 1e-12);
        assert_eq!(Sensor::Accel.display(Term::K), ("m/s^2/sqrt(h)", 60.0));
        assert_eq!(Sensor::Accel.term_name(Term::N), "velocity random walk");
        assert_eq!(Sensor::Accel.term_name(Term::K), "acceleration random walk");
        assert_eq!(Sensor::Gyro.term_name(Term::N), "angle random walk");
        assert_eq!(
            Sensor::Accel.unit_in(Term::B, TermUnits::Seconds),
            ("m/s^2", 1.0)
        );
        // The gyro's units are Term's own, unchanged.
        for t in Term::ALL {
            assert_eq!(Sensor::Gyro.display(t), t.display());
        }
        assert_eq!(Term::N.display(), ("deg/sqrt(h)", 60.0));
        assert_eq!(Sensor::Accel.alternate(Term::N), Some(("m/s/sqrt(s)", 1.0)));
    }

    #[test]
    fn units_parse_and_gravity_says_which_unit_a_still_record_is_in() {
        assert_eq!("g".parse::<AccelUnit>(), Ok(AccelUnit::G));
        assert_eq!("m/s^2".parse::<AccelUnit>(), Ok(AccelUnit::MPerS2));
        assert!("mg"
            .parse::<AccelUnit>()
            .unwrap_err()
            .contains("m/s^2 or g"));
        assert_eq!(AccelUnit::G.to_string(), "g");
        assert_eq!(AccelUnit::implied_by_gravity(1.016), Some(AccelUnit::G));
        assert_eq!(AccelUnit::implied_by_gravity(9.81), Some(AccelUnit::MPerS2));
        assert_eq!(AccelUnit::implied_by_gravity(3.0), None);
        let g = SampleUnit::Accel(AccelUnit::G);
        assert_eq!((g.sensor(), g.to_base()), (Sensor::Accel, STANDARD_GRAVITY));
        let r = SampleUnit::Rate(RateUnit::RadPerS);
        assert_eq!(r.sensor(), Sensor::Gyro);
        assert_eq!(r.to_string(), "rad/s");
    }
}
