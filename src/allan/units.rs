//! Units: the rate unit of the input, and the display units of the IEEE Std 952 terms.
//!
//! Inside [`crate::allan::fit`] every term is in base units built from deg and s:
//! Q deg, N deg/sqrt(s), B deg/s, K deg/s/sqrt(s), R deg/s^2 (the deviation in deg/s, tau in s).

use std::fmt;
use std::str::FromStr;

/// The unit of the rate samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RateUnit {
    /// Degrees per second.
    #[default]
    DegPerS,
    /// Radians per second.
    RadPerS,
}

impl RateUnit {
    /// Factor that turns a rate in this unit into deg/s.
    pub fn to_deg_per_s(self) -> f64 {
        match self {
            RateUnit::DegPerS => 1.0,
            RateUnit::RadPerS => 180.0 / std::f64::consts::PI,
        }
    }
}

impl FromStr for RateUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "deg/s" => Ok(RateUnit::DegPerS),
            "rad/s" => Ok(RateUnit::RadPerS),
            _ => Err(format!("unknown rate unit '{s}' (deg/s or rad/s)")),
        }
    }
}

impl fmt::Display for RateUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RateUnit::DegPerS => "deg/s",
            RateUnit::RadPerS => "rad/s",
        })
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

    /// The base unit the fit works in (deviation in deg/s, tau in s).
    pub fn base_unit(self) -> &'static str {
        match self {
            Term::Q => "deg",
            Term::N => "deg/sqrt(s)",
            Term::B => "deg/s",
            Term::K => "deg/s/sqrt(s)",
            Term::R => "deg/s^2",
        }
    }

    /// The unit a navigation engineer reads (the data-sheet unit) and the factor from the base
    /// unit to it: Q deg, N deg/sqrt(h), B deg/h, K deg/h/sqrt(h), R deg/h^2.
    pub fn display(self) -> (&'static str, f64) {
        match self {
            Term::Q => ("deg", 1.0),
            Term::N => ("deg/sqrt(h)", 60.0),
            Term::B => ("deg/h", 3600.0),
            Term::K => ("deg/h/sqrt(h)", 3600.0 * 60.0),
            Term::R => ("deg/h^2", 3600.0 * 3600.0),
        }
    }

    /// The unit this term is shown in under `units`, and the factor from the base unit.
    pub fn unit_in(self, units: TermUnits) -> (&'static str, f64) {
        match units {
            TermUnits::Datasheet => self.display(),
            TermUnits::Seconds => (self.base_unit(), 1.0),
        }
    }

    /// A second unit where one is customary (Q in arcsec, N in deg/sqrt(s)), with its factor.
    pub fn alternate(self) -> Option<(&'static str, f64)> {
        match self {
            Term::Q => Some(("arcsec", 3600.0)),
            Term::N => Some(("deg/sqrt(s)", 1.0)),
            _ => None,
        }
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
