//! The units a user may give a quantity in, one type per quantity: [`RateUnit`] (a gyro's angular
//! rate), [`AccelUnit`] (an accelerometer's specific force) and [`MagUnit`] (a magnetometer's
//! field). Each has one parser (`FromStr`, from the names users type in pipeline files and on
//! the command line), one printer (`Display`, the same names) and its factors to the SI unit,
//! so that the pipeline file, `allan`, `tap`, `record` and `nav-eval` read and write the same
//! words; a rate unit is stored (serde: a drift model file's `units`) by the same name. Pure: no
//! I/O, no other module of the crate.

use std::fmt;
use std::str::FromStr;

/// Degrees in a radian.
const DEG_PER_RAD: f64 = 180.0 / std::f64::consts::PI;
/// Radians in a degree.
const RAD_PER_DEG: f64 = std::f64::consts::PI / 180.0;

/// Standard gravity, m/s^2 per g (ISO 80000-3): the unit `g` of an accelerometer's reading, in
/// `allan` and `accel_units` (the simulator keeps its own copy: it sits beside `allan`).
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// The unit of angular rate samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RateUnit {
    /// Degrees per second.
    #[default]
    DegPerS,
    /// Radians per second.
    RadPerS,
}

impl RateUnit {
    /// Every rate unit, in the order help texts list them.
    pub const ALL: [RateUnit; 2] = [RateUnit::DegPerS, RateUnit::RadPerS];
    /// Their names, in the same order.
    pub const NAMES: [&'static str; 2] = [RateUnit::DegPerS.name(), RateUnit::RadPerS.name()];

    /// The name users type and files store (`deg/s`, `rad/s`).
    pub const fn name(self) -> &'static str {
        match self {
            RateUnit::DegPerS => "deg/s",
            RateUnit::RadPerS => "rad/s",
        }
    }

    /// Factor that turns a rate in this unit into rad/s (SI).
    pub fn to_rad_per_s(self) -> f64 {
        match self {
            RateUnit::DegPerS => RAD_PER_DEG,
            RateUnit::RadPerS => 1.0,
        }
    }

    /// Factor that turns a rate in rad/s into this unit.
    pub fn from_rad_per_s(self) -> f64 {
        match self {
            RateUnit::DegPerS => DEG_PER_RAD,
            RateUnit::RadPerS => 1.0,
        }
    }

    /// Factor that turns a rate in this unit into deg/s (the Allan analysis' base unit).
    pub fn to_deg_per_s(self) -> f64 {
        match self {
            RateUnit::DegPerS => 1.0,
            RateUnit::RadPerS => DEG_PER_RAD,
        }
    }

    /// The unit in a column name, as `driftless simulate` names its columns (`degps`, `rads`).
    pub fn column_suffix(self) -> &'static str {
        match self {
            RateUnit::DegPerS => "degps",
            RateUnit::RadPerS => "rads",
        }
    }
}

impl FromStr for RateUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        RateUnit::ALL
            .into_iter()
            .find(|u| u.name() == s)
            .ok_or_else(|| format!("unknown rate unit '{s}' (deg/s or rad/s)"))
    }
}

impl fmt::Display for RateUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for RateUnit {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for RateUnit {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// The unit of an accelerometer's samples (specific force).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelUnit {
    /// Metres per second squared (SI, REP 103's, and what every hop after the ingest carries).
    #[default]
    MPerS2,
    /// Standard gravities ([`STANDARD_GRAVITY`]), as many data sheets give them.
    G,
}

impl AccelUnit {
    /// Every accelerometer unit, in the order help texts list them.
    pub const ALL: [AccelUnit; 2] = [AccelUnit::MPerS2, AccelUnit::G];
    /// Their names, in the same order.
    pub const NAMES: [&'static str; 2] = [AccelUnit::MPerS2.name(), AccelUnit::G.name()];

    /// The name users type and files store (`m/s^2`, `g`).
    pub const fn name(self) -> &'static str {
        match self {
            AccelUnit::MPerS2 => "m/s^2",
            AccelUnit::G => "g",
        }
    }

    /// Factor that turns a reading in this unit into m/s^2 (SI).
    pub fn to_m_per_s2(self) -> f64 {
        match self {
            AccelUnit::MPerS2 => 1.0,
            AccelUnit::G => STANDARD_GRAVITY,
        }
    }

    /// The unit in which a still accelerometer's three axes reading a gravity of `norm` (the
    /// length of their mean vector, as the numbers read) would read 1 g: `G` for 0.5 to 1.5,
    /// `MPerS2` for 5 to 15 (half to one and a half g either way); None for anything else.
    pub fn implied_by_gravity(norm: f64) -> Option<AccelUnit> {
        if (0.5..=1.5).contains(&norm) {
            Some(AccelUnit::G)
        } else if (5.0..=15.0).contains(&norm) {
            Some(AccelUnit::MPerS2)
        } else {
            None
        }
    }
}

impl FromStr for AccelUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        AccelUnit::ALL
            .into_iter()
            .find(|u| u.name() == s)
            .ok_or_else(|| format!("unknown accelerometer unit '{s}' (m/s^2 or g)"))
    }
}

impl fmt::Display for AccelUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The unit of a magnetometer's samples (magnetic flux density): `ingest.csv`'s `mag_units`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MagUnit {
    /// Tesla (SI).
    T,
    /// Gauss (1e-4 T).
    Gauss,
    /// Microtesla, as most magnetometers and REP 145's field strengths are quoted.
    #[default]
    MicroT,
}

impl MagUnit {
    /// Every magnetometer unit, in the order help texts list them.
    pub const ALL: [MagUnit; 3] = [MagUnit::T, MagUnit::Gauss, MagUnit::MicroT];
    /// Their names, in the same order.
    pub const NAMES: [&'static str; 3] = [
        MagUnit::T.name(),
        MagUnit::Gauss.name(),
        MagUnit::MicroT.name(),
    ];

    /// The name users type and files store (`T`, `gauss`, `uT`).
    pub const fn name(self) -> &'static str {
        match self {
            MagUnit::T => "T",
            MagUnit::Gauss => "gauss",
            MagUnit::MicroT => "uT",
        }
    }

    /// Factor that turns a reading in this unit into tesla (SI).
    pub fn to_tesla(self) -> f64 {
        match self {
            MagUnit::T => 1.0,
            MagUnit::Gauss => 1e-4,
            MagUnit::MicroT => 1e-6,
        }
    }
}

impl FromStr for MagUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        MagUnit::ALL
            .into_iter()
            .find(|u| u.name() == s)
            .ok_or_else(|| format!("unknown magnetometer unit '{s}' (T, gauss or uT)"))
    }
}

impl fmt::Display for MagUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_unit_parses_its_own_name_and_nothing_else() {
        for u in RateUnit::ALL {
            assert_eq!(u.to_string().parse::<RateUnit>(), Ok(u));
        }
        for u in AccelUnit::ALL {
            assert_eq!(u.to_string().parse::<AccelUnit>(), Ok(u));
        }
        for u in MagUnit::ALL {
            assert_eq!(u.to_string().parse::<MagUnit>(), Ok(u));
        }
        assert_eq!(RateUnit::NAMES, ["deg/s", "rad/s"]);
        assert_eq!(AccelUnit::NAMES, ["m/s^2", "g"]);
        assert_eq!(MagUnit::NAMES, ["T", "gauss", "uT"]);
        assert!("deg"
            .parse::<RateUnit>()
            .unwrap_err()
            .contains("deg/s or rad/s"));
        assert!("mg"
            .parse::<AccelUnit>()
            .unwrap_err()
            .contains("m/s^2 or g"));
        assert!("mT".parse::<MagUnit>().is_err());
    }

    #[test]
    fn factors_go_both_ways() {
        for u in RateUnit::ALL {
            assert!((u.to_rad_per_s() * u.from_rad_per_s() - 1.0).abs() < 1e-15);
            assert!((u.to_rad_per_s() * DEG_PER_RAD - u.to_deg_per_s()).abs() < 1e-12);
        }
        assert_eq!(AccelUnit::G.to_m_per_s2(), STANDARD_GRAVITY);
        assert!((MagUnit::Gauss.to_tesla() / MagUnit::MicroT.to_tesla() - 100.0).abs() < 1e-9);
    }
}
