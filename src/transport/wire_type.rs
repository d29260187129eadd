//! Which of our wire types a service carries: the one lookup of the commands that open any of
//! our services by name (`tap`, `record`, `bridge`) and of the listing (`list`), and a
//! subscriber of whichever type it is.

use super::node::Transport;
use super::ports::Input;
use super::TransportError;
use crate::wire::{
    wire_version_mismatch, GyroSample, RawSample, StatsSnapshot, StopSignal, GYRO_TYPE_NAME,
    RAW_TYPE_NAME, STATS_TYPE_NAME, STOP_TYPE_NAME,
};

/// Which of our wire types a publish-subscribe service carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireType {
    /// [`RawSample`].
    Raw,
    /// [`GyroSample`].
    Gyro,
    /// [`StatsSnapshot`].
    Stats,
    /// [`StopSignal`].
    Stop,
}

impl WireType {
    /// Every wire type.
    pub const ALL: [WireType; 4] = [
        WireType::Raw,
        WireType::Gyro,
        WireType::Stats,
        WireType::Stop,
    ];

    /// The type's name without the crate: `RawSample`, `GyroSample`, `StatsSnapshot`,
    /// `StopSignal`.
    pub fn short_name(self) -> &'static str {
        match self {
            WireType::Raw => "RawSample",
            WireType::Gyro => "GyroSample",
            WireType::Stats => "StatsSnapshot",
            WireType::Stop => "StopSignal",
        }
    }

    /// Its iceoryx2 type name in this release's layout (e.g. `driftless::GyroSample.v2`).
    pub fn type_name(self) -> &'static str {
        match self {
            WireType::Raw => RAW_TYPE_NAME,
            WireType::Gyro => GYRO_TYPE_NAME,
            WireType::Stats => STATS_TYPE_NAME,
            WireType::Stop => STOP_TYPE_NAME,
        }
    }

    /// Its size in bytes.
    pub fn size(self) -> usize {
        match self {
            WireType::Raw => std::mem::size_of::<RawSample>(),
            WireType::Gyro => std::mem::size_of::<GyroSample>(),
            WireType::Stats => std::mem::size_of::<StatsSnapshot>(),
            WireType::Stop => std::mem::size_of::<StopSignal>(),
        }
    }

    /// Ours when `type_name` is one of our types' names in this release's layout.
    pub fn named(type_name: &str) -> Option<WireType> {
        WireType::ALL
            .into_iter()
            .find(|w| w.type_name() == type_name)
    }

    /// Ours if both the type name and the size are those of one of our types.
    pub(super) fn of(type_name: &str, size: usize) -> Option<WireType> {
        WireType::named(type_name).filter(|w| w.size() == size)
    }
}

/// What a publish-subscribe service carries, found before opening it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Carried {
    /// One of our wire types, in this release's layout.
    Ours(WireType),
    /// Another layout version of one of ours (a driftless of another release publishes it):
    /// the refusal, worded by [`wire_version_mismatch`].
    OtherVersion(String),
    /// Another program's type: its name.
    Foreign(String),
    /// No such service under the prefix.
    Missing,
}

/// A subscriber of whichever of our wire types a service carries.
pub enum AnyInput {
    /// Of a [`RawSample`] service.
    Raw(Input<RawSample>),
    /// Of a [`GyroSample`] service.
    Gyro(Input<GyroSample>),
    /// Of a [`StatsSnapshot`] service.
    Stats(Input<StatsSnapshot>),
    /// Of a [`StopSignal`] service.
    Stop(Input<StopSignal>),
}

impl AnyInput {
    /// The wire type it reads.
    pub fn wire_type(&self) -> WireType {
        match self {
            AnyInput::Raw(_) => WireType::Raw,
            AnyInput::Gyro(_) => WireType::Gyro,
            AnyInput::Stats(_) => WireType::Stats,
            AnyInput::Stop(_) => WireType::Stop,
        }
    }

    /// Samples it holds unread before it loses new ones.
    pub fn buffer_size(&self) -> usize {
        match self {
            AnyInput::Raw(i) => i.buffer_size(),
            AnyInput::Gyro(i) => i.buffer_size(),
            AnyInput::Stats(i) => i.buffer_size(),
            AnyInput::Stop(i) => i.buffer_size(),
        }
    }

    /// How many publishers the service has now.
    pub fn publishers(&self) -> usize {
        match self {
            AnyInput::Raw(i) => i.publishers(),
            AnyInput::Gyro(i) => i.publishers(),
            AnyInput::Stats(i) => i.publishers(),
            AnyInput::Stop(i) => i.publishers(),
        }
    }
}

impl Transport {
    /// What the publish-subscribe service `name` carries (by its payload's type name).
    pub fn carried(&self, name: &str) -> Result<Carried, TransportError> {
        let Some(found) = self.payload_type_name(name)? else {
            return Ok(Carried::Missing);
        };
        Ok(match WireType::named(&found) {
            Some(w) => Carried::Ours(w),
            None => match wire_version_mismatch(&format!("service {name:?}"), &found) {
                Some(m) => Carried::OtherVersion(m),
                None => Carried::Foreign(found),
            },
        })
    }

    /// A subscriber of the existing service `name` of type `wire` ([`Transport::open_input`]:
    /// whatever its creator's QoS, with the largest buffer the service allows).
    pub fn open_any(&self, name: &str, wire: WireType) -> Result<AnyInput, TransportError> {
        Ok(match wire {
            WireType::Raw => AnyInput::Raw(self.open_input(name)?),
            WireType::Gyro => AnyInput::Gyro(self.open_input(name)?),
            WireType::Stats => AnyInput::Stats(self.open_input(name)?),
            WireType::Stop => AnyInput::Stop(self.open_input(name)?),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wire_type_is_known_by_its_name_and_size() {
        for w in WireType::ALL {
            assert_eq!(WireType::named(w.type_name()), Some(w));
            assert_eq!(WireType::of(w.type_name(), w.size()), Some(w));
            assert_eq!(WireType::of(w.type_name(), w.size() + 8), None);
        }
        assert_eq!(WireType::named(crate::wire::GYRO_V1_TYPE_NAME), None);
        assert_eq!(WireType::named("driftless::Percentiles"), None);
    }
}
