//! The wire types: what crosses shared memory and the networks, byte for byte, and the flags
//! that qualify it. No transport is named here: `transport` marks these types for iceoryx2
//! (`transport/zero_copy.rs`), `transport::ros2` maps them to ROS 2 messages, and
//! [`WireBytes`] gives the bytes Zenoh carries.
//!
//! All are `#[repr(C)]`, contain only `u64`/`u32`/`f64`/`u8` fields with no implicit padding,
//! and carry a stable type name so that C, C++ or Python subscribers can open the services with
//! iceoryx2's own bindings (docs/wire-types.md). `crate::clock::monotonic_ns` is the clock
//! their `ingest_ns` stamps are read on.
//!
//! | file | concern |
//! |---|---|
//! | `samples.rs` | [`RawSample`], [`GyroSample`], [`StopSignal`] and their type names |
//! | `flags.rs` | the flags of a raw sample, of an output, and the sensors word |
//! | `stats.rs` | [`StatsSnapshot`] |
//! | `fields.rs` | one table of fields per type ([`GYRO_FIELDS`], ...): the one list of them |
//! | `versions.rs` | the layout versions, and the refusal of another one ([`wire_version_mismatch`]) |
//! | `bytes.rs` | [`WireBytes`]: the little-endian bytes of a sample |

mod bytes;
mod fields;
mod flags;
mod samples;
mod stats;
mod versions;

pub use bytes::WireBytes;
pub use fields::*;
pub use flags::*;
pub use samples::*;
pub use stats::*;
pub use versions::{other_layout_of, wire_version_mismatch};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_layouts_are_the_documented_ones() {
        assert_eq!(std::mem::size_of::<RawSample>(), 96);
        assert_eq!(std::mem::align_of::<RawSample>(), 8);
        assert_eq!(std::mem::offset_of!(RawSample, rate), 16);
        assert_eq!(std::mem::offset_of!(RawSample, flags), 40);
        // Version 1 was this layout up to `epoch`.
        assert_eq!(std::mem::offset_of!(RawSample, accel), RAW_V1_SIZE);
        assert_eq!(std::mem::offset_of!(RawSample, mag), 72);
        assert_eq!(std::mem::size_of::<GyroSample>(), 264);
        assert_eq!(std::mem::align_of::<GyroSample>(), 8);
        assert_eq!(std::mem::offset_of!(GyroSample, ingest_ns), 16);
        assert_eq!(std::mem::offset_of!(GyroSample, rate), 24);
        assert_eq!(std::mem::offset_of!(GyroSample, drift), 48);
        assert_eq!(std::mem::offset_of!(GyroSample, denoised), 72);
        assert_eq!(std::mem::offset_of!(GyroSample, flags), 96);
        assert_eq!(std::mem::offset_of!(GyroSample, epoch), 100);
        assert_eq!(std::mem::offset_of!(GyroSample, drift_std), 104);
        // Version 1 was this layout up to `epoch`.
        assert_eq!(std::mem::offset_of!(GyroSample, drift_std), GYRO_V1_SIZE);
        // Version 2 was this layout up to `drift_std`.
        assert_eq!(std::mem::offset_of!(GyroSample, accel), GYRO_V2_SIZE);
        assert_eq!(std::mem::offset_of!(GyroSample, accel_std), 152);
        assert_eq!(std::mem::offset_of!(GyroSample, mag), 176);
        assert_eq!(std::mem::offset_of!(GyroSample, sensors), 200);
        // Version 3 was this layout up to `reserved`.
        assert_eq!(std::mem::offset_of!(GyroSample, orientation), GYRO_V3_SIZE);
        assert_eq!(std::mem::offset_of!(GyroSample, orientation_std), 240);
        let d = GyroSample::default();
        assert_eq!(d.drift_std, [DRIFT_STD_NOT_PROVIDED; 3]);
        assert_eq!(d.accel_std, [DRIFT_STD_NOT_PROVIDED; 3]);
        assert_eq!((d.accel_reading(), d.mag_reading()), (None, None));
        assert_eq!(d.orientation_estimate(), None);
        assert_eq!(d.orientation_std, [DRIFT_STD_NOT_PROVIDED; 3]);
        assert_eq!(RawSample::default().accel_reading(), None);
    }

    #[test]
    fn a_reading_is_present_only_when_flagged_and_valid() {
        let mut g = GyroSample {
            accel: [0.0, 0.0, 9.8],
            sensors: SENSOR_ACCEL,
            ..GyroSample::default()
        };
        assert_eq!(g.accel_reading(), Some([0.0, 0.0, 9.8]));
        g.sensors |= SENSOR_ACCEL_INVALID;
        assert_eq!(g.accel_reading(), None);
        let r = RawSample {
            mag: [1e-5, 0.0, 0.0],
            flags: RAW_MAG,
            ..RawSample::default()
        };
        assert_eq!(
            (r.mag_reading(), r.accel_reading()),
            (Some([1e-5, 0.0, 0.0]), None)
        );
    }

    #[test]
    fn another_layout_version_is_named_and_ours_is_not() {
        let old = wire_version_mismatch("service \"d/corrected\"", GYRO_V1_TYPE_NAME).unwrap();
        assert_eq!(
            old,
            "service \"d/corrected\" carries driftless::GyroSample (layout v1, 104 bytes, from \
             an older driftless); this driftless reads driftless::GyroSample.v4 (layout v4, 264 \
             bytes, with the orientation): run the daemon and its subscribers from one release \
             (docs/wire-types.md#versions)"
        );
        let stats = wire_version_mismatch("service \"d/stats\"", STATS_V1_TYPE_NAME).unwrap();
        assert_eq!(
            stats,
            "service \"d/stats\" carries driftless::StatsSnapshot (layout v1, 904 bytes, from \
             an older driftless); this driftless reads driftless::StatsSnapshot.v4 (layout v4, \
             1024 bytes, with the odometry): run the daemon and its subscribers from one \
             release (docs/wire-types.md#versions)"
        );
        assert_eq!(other_layout_of(STATS_V1_TYPE_NAME), Some("StatsSnapshot"));
        assert_eq!(other_layout_of(GYRO_V1_TYPE_NAME), Some("GyroSample"));
        assert_eq!(other_layout_of(GYRO_TYPE_NAME), None);
        let v2 = wire_version_mismatch("s", "driftless::GyroSample.v2").unwrap();
        assert!(
            v2.contains("(layout v2, 128 bytes, from an older driftless)"),
            "{v2}"
        );
        let raw = wire_version_mismatch("service \"sensor/raw\"", RAW_V1_TYPE_NAME).unwrap();
        assert!(raw.contains("(layout v1, 48 bytes, from an older driftless); this driftless reads driftless::RawSample.v2 (layout v2, 96 bytes"), "{raw}");
        assert_eq!(other_layout_of(RAW_V1_TYPE_NAME), Some("RawSample"));
        let v3 = wire_version_mismatch("s", "driftless::GyroSample.v3").unwrap();
        assert!(
            v3.contains("(layout v3, 208 bytes, from an older driftless)"),
            "{v3}"
        );
        let newer = wire_version_mismatch("key k", "driftless::GyroSample.v5").unwrap();
        assert!(
            newer.contains("(layout v5, from a newer driftless)"),
            "{newer}"
        );
        assert!(wire_version_mismatch("s", "driftless::GyroSample.v0").is_some());
        for not_a_version in [
            GYRO_TYPE_NAME,
            RAW_TYPE_NAME,
            STATS_TYPE_NAME,
            "driftless::GyroSample.vx",
            "driftless::GyroSampleX",
            "driftless::StatsSnapshotX",
            "other::GyroSample",
        ] {
            assert_eq!(
                wire_version_mismatch("s", not_a_version),
                None,
                "{not_a_version}"
            );
        }
    }

    /// The bytes a bridge sends are the bytes in shared memory (on this little-endian host),
    /// and they decode back to the identical sample.
    #[test]
    fn wire_bytes_are_the_memory_layout_and_round_trip() {
        fn memory<T>(v: &T) -> Vec<u8> {
            // SAFETY: the wire types are repr(C) with no padding: every byte is initialised.
            unsafe {
                std::slice::from_raw_parts(v as *const T as *const u8, std::mem::size_of::<T>())
            }
            .to_vec()
        }
        let g = GyroSample {
            t_ns: 1,
            seq: u64::MAX - 3,
            ingest_ns: 0x0102_0304_0506_0708,
            rate: [1.5, -0.0, f64::MIN_POSITIVE],
            drift: [f64::MAX, 2e-300, -7.25],
            denoised: [0.1, 0.2, 0.3],
            flags: FLAG_STILL | FLAG_GAP_BEFORE,
            epoch: 0xdead_beef,
            drift_std: [1e-5, DRIFT_STD_NOT_PROVIDED, 3.5e-7],
            accel: [0.5, -9.81, 1e-3],
            accel_std: [DRIFT_STD_NOT_PROVIDED, 2e-3, 4.0],
            mag: [2e-5, -3e-5, 4.5e-5],
            sensors: SENSOR_ACCEL | SENSOR_MAG | SENSOR_MAG_INVALID | SENSOR_ORIENTATION,
            reserved: 0,
            orientation: [0.5, -0.5, 0.5, 0.5],
            orientation_std: [1e-3, 2e-3, DRIFT_STD_NOT_PROVIDED],
        };
        let r = RawSample {
            t_ns: 9,
            seq: 10,
            rate: [-1.0, 1e-9, 3.0],
            flags: RAW_INVALID | RAW_ACCEL,
            epoch: 77,
            accel: [0.01, 0.02, -1.0],
            mag: [0.0; 3],
        };
        let mut out = Vec::new();
        g.encode(&mut out);
        assert_eq!(out.len(), GyroSample::SIZE);
        if cfg!(target_endian = "little") {
            assert_eq!(out, memory(&g));
        }
        assert_eq!(&out[8..16], &g.seq.to_le_bytes());
        assert_eq!(&out[96..100], &g.flags.to_le_bytes());
        assert_eq!(&out[104..112], &1e-5f64.to_le_bytes());
        assert_eq!(GyroSample::decode(&out), Some(g));
        assert_eq!(&out[200..204], &g.sensors.to_le_bytes());
        assert_eq!(GyroSample::decode(&out), Some(g));
        assert_eq!(&out[208..216], &0.5f64.to_le_bytes());
        assert_eq!(GyroSample::decode(&out[..263]), None);
        // An older version's payload is refused, not read as a short current one.
        assert_eq!(GyroSample::decode(&out[..GYRO_V1_SIZE]), None);
        assert_eq!(GyroSample::decode(&out[..GYRO_V2_SIZE]), None);
        assert_eq!(GyroSample::decode(&out[..GYRO_V3_SIZE]), None);
        r.encode(&mut out);
        assert_eq!(out.len(), RawSample::SIZE);
        if cfg!(target_endian = "little") {
            assert_eq!(out, memory(&r));
        }
        assert_eq!(&out[44..48], &77u32.to_le_bytes());
        assert_eq!(RawSample::decode(&out), Some(r));
        assert_eq!(RawSample::decode(&out[..RAW_V1_SIZE]), None);
    }

    #[test]
    fn stats_layout_is_the_documented_one() {
        assert_eq!(std::mem::size_of::<Percentiles>(), 40);
        assert_eq!(std::mem::size_of::<StageStats>(), 96);
        assert_eq!(std::mem::offset_of!(StageStats, compute), 56);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, rate_hz), 24);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, end_to_end), 88);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, stage_count), 128);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, stages), 136);
        assert_eq!(
            std::mem::offset_of!(StatsSnapshot, deadline_misses_explained),
            STATS_V1_SIZE
        );
        assert_eq!(
            std::mem::offset_of!(StatsSnapshot, last_miss_off_cpu_ns),
            928
        );
        // Version 3 appended two counts to version 2's 936 bytes.
        assert_eq!(
            std::mem::offset_of!(StatsSnapshot, stamp_faults),
            STATS_V2_SIZE
        );
        // Version 4 appended the odometry's 72 bytes.
        assert_eq!(std::mem::offset_of!(StatsSnapshot, odometry), STATS_V3_SIZE);
        assert_eq!(std::mem::size_of::<OdometryStats>(), 72);
        assert_eq!(std::mem::size_of::<StatsSnapshot>(), 1024);
    }
}
