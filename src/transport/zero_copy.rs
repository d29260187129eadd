//! Our wire types ([`crate::wire`]) marked for iceoryx2's shared memory, each under its stable
//! type name: the one place that tells iceoryx2 what the types are.

use iceoryx2::prelude::ZeroCopySend;

use crate::wire::{
    GyroSample, Percentiles, RawSample, StageStats, StatsSnapshot, StopSignal, GYRO_TYPE_NAME,
    RAW_TYPE_NAME, STATS_TYPE_NAME, STOP_TYPE_NAME,
};

/// Marks `$ty` as shareable under `$name`.
macro_rules! zero_copy {
    ($ty:ty, $name:expr) => {
        // SAFETY: every wire type is `repr(C)` of plain numbers and arrays of them, with no
        // padding, pointer or handle (`crate::wire` checks the layouts in its tests), so its bytes
        // mean the same in any process that maps them.
        unsafe impl ZeroCopySend for $ty {
            unsafe fn type_name() -> &'static str {
                $name
            }
        }
    };
}

zero_copy!(RawSample, RAW_TYPE_NAME);
zero_copy!(GyroSample, GYRO_TYPE_NAME);
zero_copy!(StopSignal, STOP_TYPE_NAME);
zero_copy!(StatsSnapshot, STATS_TYPE_NAME);
zero_copy!(StageStats, "driftless::StageStats");
zero_copy!(Percentiles, "driftless::Percentiles");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn type_names_are_stable() {
        // SAFETY: type_name only returns a static string.
        unsafe {
            assert_eq!(RawSample::type_name(), "driftless::RawSample.v2");
            assert_eq!(GyroSample::type_name(), "driftless::GyroSample.v4");
            assert_eq!(StatsSnapshot::type_name(), "driftless::StatsSnapshot.v4");
            assert_eq!(StopSignal::type_name(), "driftless::StopSignal.v2");
        }
        assert_eq!(std::mem::size_of::<StopSignal>(), 56);
        assert_eq!(std::mem::offset_of!(StopSignal, stopped), 16);
    }
}
