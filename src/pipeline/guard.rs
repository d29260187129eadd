//! The input guard between the ingest and the first processing stage: units to rad/s, and the
//! checks on every raw sample (non-finite or driver-invalid values, sequence gaps, stamps that
//! cannot be believed: [`StampCheck`]). A stamp fault is flagged and counted on its own, never
//! as a loss; only the sequence proves a loss. A bad value is replaced by the last good one,
//! flagged and counted: no NaN or Inf ever enters a stage. It also keeps the stream's epoch ([`GyroSample::epoch`]): a
//! source restart starts a new epoch instead of counting as a gap, so that within an epoch
//! `seq` always rises. A driver whose `seq` repeats or steps back (not to 0) also starts a new
//! epoch, and that sample is flagged and counted as a gap: subscribers count on the rise.

use crate::clock::{StampCheck, StampFault};
use crate::units::{AccelUnit, RateUnit};
use crate::wire::{
    GyroSample, RawSample, DRIFT_STD_NOT_PROVIDED, FLAG_GAP_BEFORE, FLAG_INPUT_INVALID,
    FLAG_STAMP_FAULT, FLAG_TIME_BACKWARDS, FLAG_VEHICLE_MOVING, FLAG_VEHICLE_STOPPED, RAW_INVALID,
    RAW_STAMP_FAULT, RAW_VEHICLE_MOVING, RAW_VEHICLE_STOPPED, SENSOR_ACCEL, SENSOR_ACCEL_INVALID,
    SENSOR_MAG, SENSOR_MAG_INVALID,
};

/// Counts of what the guard flagged.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GuardCounts {
    /// Samples with a non-finite or driver-invalid rate.
    pub invalid: u64,
    /// Gaps: a sequence jump, or a sequence number that repeated or stepped back.
    pub gaps: u64,
    /// Sequence numbers missing in total.
    pub missing: u64,
    /// Stamps not believed: back, a leap over 10 s, or unset ([`StampCheck`]).
    pub stamp_faults: u64,
    /// New epochs: source restarts, and sequence numbers that repeated or stepped back.
    pub restarts: u64,
    /// Samples whose accelerometer or magnetometer reading was not finite (the last good one
    /// held, [`SENSOR_ACCEL_INVALID`], [`SENSOR_MAG_INVALID`]); the rate may still be good.
    pub sensors_invalid: u64,
}

/// One sensor beside the gyro: its units' scale and its last good reading, held in place of
/// one that is not finite, as the rate's is.
#[derive(Debug, Clone, Copy)]
struct Beside {
    scale: f64,
    last_good: [f64; 3],
    present: u32,
    invalid: u32,
}

impl Beside {
    /// `reading` (if any) in the published units, and its `sensors` bits.
    fn admit(&mut self, reading: Option<[f64; 3]>) -> ([f64; 3], u32) {
        match reading {
            None => ([0.0; 3], 0),
            Some(v) if v.iter().all(|x| x.is_finite()) => {
                self.last_good = v.map(|x| x * self.scale);
                (self.last_good, self.present)
            }
            Some(_) => (self.last_good, self.present | self.invalid),
        }
    }
}

/// Turns raw samples into [`GyroSample`]s in rad/s.
#[derive(Debug, Clone)]
pub struct Guard {
    scale: f64,
    accel: Beside,
    mag: Beside,
    axes: usize,
    last_good: [f64; 3],
    last_seq: Option<u64>,
    stamps: StampCheck,
    epoch: u32,
    source_epoch: Option<u32>,
    /// Flags [`Guard::stamp`] found for the sample [`Guard::admit`] takes next.
    pending: u32,
    /// What was flagged so far.
    pub counts: GuardCounts,
}

impl Guard {
    /// A guard for `axes` axes in `units` (the accelerometer in `accel_units`), whose stream
    /// starts at `epoch` (0 is taken as 1).
    pub fn new(units: RateUnit, accel_units: AccelUnit, axes: usize, epoch: u32) -> Self {
        Guard {
            scale: units.to_rad_per_s(),
            accel: Beside {
                scale: accel_units.to_m_per_s2(),
                last_good: [0.0; 3],
                present: SENSOR_ACCEL,
                invalid: SENSOR_ACCEL_INVALID,
            },
            mag: Beside {
                scale: 1.0,
                last_good: [0.0; 3],
                present: SENSOR_MAG,
                invalid: SENSOR_MAG_INVALID,
            },
            axes: axes.clamp(1, 3),
            last_good: [0.0; 3],
            last_seq: None,
            // A driver's clock may start at 0; a source whose 0 means "unset" flags it.
            stamps: StampCheck::new(false),
            epoch: epoch.max(1),
            source_epoch: None,
            pending: 0,
            counts: GuardCounts::default(),
        }
    }

    /// The current epoch.
    pub fn epoch(&self) -> u32 {
        self.epoch
    }

    /// `raw` with the stream's epoch in place of the source's; call it before [`Guard::admit`]
    /// (the daemon republishes the stamped sample on the ingest's output). A source restart (its
    /// own non-zero epoch changed, or its `seq` went back to 0) starts the next epoch and
    /// forgets the old run's sequence and time, so neither counts as a gap or a step back.
    pub fn stamp(&mut self, raw: &RawSample) -> RawSample {
        let new_source_run = raw.epoch != 0 && self.source_epoch.is_some_and(|e| e != raw.epoch);
        let seq_restarted = raw.seq == 0 && self.last_seq.is_some();
        // A repeat or a step back within a run: a driver's fault, flagged, and a new epoch so
        // that no subscriber sees seq fall within one.
        let seq_fell =
            !new_source_run && !seq_restarted && self.last_seq.is_some_and(|last| raw.seq <= last);
        if seq_fell {
            self.pending |= FLAG_GAP_BEFORE;
            self.counts.gaps += 1;
        }
        if new_source_run || seq_restarted || seq_fell {
            self.epoch = self.epoch.checked_add(1).unwrap_or(1);
            self.counts.restarts += 1;
            self.last_seq = None;
            self.stamps.reset();
        }
        if raw.epoch != 0 {
            self.source_epoch = Some(raw.epoch);
        }
        RawSample {
            epoch: self.epoch,
            ..*raw
        }
    }

    /// Check and convert one raw sample ingested at `ingest_ns`.
    pub fn admit(&mut self, raw: &RawSample, ingest_ns: u64) -> GyroSample {
        let mut flags = std::mem::take(&mut self.pending);
        let mut rate = [0.0; 3];
        let driver_invalid = raw.flags & RAW_INVALID != 0;
        let finite = raw.rate[..self.axes].iter().all(|v| v.is_finite());
        if driver_invalid || !finite {
            flags |= FLAG_INPUT_INVALID;
            self.counts.invalid += 1;
            rate = self.last_good;
        } else {
            for (r, v) in rate.iter_mut().zip(&raw.rate).take(self.axes) {
                *r = v * self.scale;
            }
            self.last_good = rate;
        }
        if let Some(prev) = self.last_seq {
            let expected = prev.wrapping_add(1);
            if raw.seq != expected {
                flags |= FLAG_GAP_BEFORE;
                self.counts.gaps += 1;
                if raw.seq > expected {
                    self.counts.missing += raw.seq - expected;
                }
            }
        }
        self.last_seq = Some(raw.seq);
        // A stamp its source did not believe is a fault whatever the check says. It is still
        // judged, so that the check keeps the history the source's own check keeps (a ROS 2
        // bridge judges as we do), but for a 0, the "not set" of a ROS 2 stamp, which must never
        // become the time base.
        let flagged = raw.flags & RAW_STAMP_FAULT != 0;
        let judged = if flagged && raw.t_ns == 0 {
            None
        } else {
            self.stamps.judge(raw.t_ns)
        };
        let fault = judged.or(flagged.then_some(StampFault::Unset));
        if let Some(fault) = fault {
            flags |= FLAG_STAMP_FAULT;
            if fault == StampFault::Backwards {
                flags |= FLAG_TIME_BACKWARDS;
            }
            self.counts.stamp_faults += 1;
        }
        // A stop signal logged with the sample travels with it.
        if raw.flags & RAW_VEHICLE_STOPPED != 0 {
            flags |= FLAG_VEHICLE_STOPPED;
        } else if raw.flags & RAW_VEHICLE_MOVING != 0 {
            flags |= FLAG_VEHICLE_MOVING;
        }
        let (accel, accel_bits) = self.accel.admit(raw.accel_reading());
        let (mag, mag_bits) = self.mag.admit(raw.mag_reading());
        let sensors = accel_bits | mag_bits;
        if sensors & (SENSOR_ACCEL_INVALID | SENSOR_MAG_INVALID) != 0 {
            self.counts.sensors_invalid += 1;
        }
        GyroSample {
            t_ns: raw.t_ns,
            seq: raw.seq,
            ingest_ns,
            rate,
            drift: [0.0; 3],
            denoised: rate,
            flags,
            epoch: raw.epoch,
            // Nothing estimated the drift yet, nor knows the accelerometer's noise.
            drift_std: [DRIFT_STD_NOT_PROVIDED; 3],
            accel,
            accel_std: [DRIFT_STD_NOT_PROVIDED; 3],
            mag,
            sensors,
            ..GyroSample::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(seq: u64, t_ns: u64, x: f64) -> RawSample {
        RawSample {
            t_ns,
            seq,
            rate: [x, 1.0, 2.0],
            ..RawSample::default()
        }
    }

    #[test]
    fn flags_and_counts_bad_samples() {
        let mut g = Guard::new(RateUnit::RadPerS, AccelUnit::MPerS2, 3, 7);
        assert_eq!(g.admit(&raw(0, 10, 1.0), 0).flags, 0);
        let s = g.admit(&raw(1, 20, f64::NAN), 0);
        assert_eq!(s.flags, FLAG_INPUT_INVALID);
        assert_eq!(s.rate, [1.0, 1.0, 2.0]);
        let s = g.admit(&raw(2, 30, f64::INFINITY), 0);
        assert!(s.rate.iter().all(|v| v.is_finite()));
        assert_eq!(g.admit(&raw(5, 40, 1.0), 0).flags, FLAG_GAP_BEFORE);
        assert_eq!(
            g.admit(&raw(6, 35, 1.0), 0).flags,
            FLAG_STAMP_FAULT | FLAG_TIME_BACKWARDS
        );
        assert_eq!(
            g.counts,
            GuardCounts {
                invalid: 2,
                gaps: 1,
                missing: 2,
                stamp_faults: 1,
                restarts: 0,
                sensors_invalid: 0,
            }
        );
    }

    #[test]
    fn a_stamp_fault_is_flagged_and_counted_never_a_loss() {
        const S: u64 = 1_000_000_000;
        let t0 = 1_700_000_000 * S;
        let mut g = Guard::new(RateUnit::RadPerS, AccelUnit::MPerS2, 3, 7);
        let mut faults = Vec::new();
        for k in 0..1_000u64 {
            let mut r = raw(k, t0 + k * S / 100, 1.0);
            match k {
                100 => r.t_ns = 4_102_444_800 * S,               // the year 2100
                200 => (r.t_ns, r.flags) = (0, RAW_STAMP_FAULT), // a ROS 2 stamp of 0, flagged
                300 => r.t_ns -= S,                              // 1 s back
                _ => {}
            }
            let stamped = g.stamp(&r);
            let s = g.admit(&stamped, 0);
            if s.flags != 0 {
                faults.push((k, s.flags));
            }
        }
        assert_eq!(
            faults,
            [
                (100, FLAG_STAMP_FAULT),
                (200, FLAG_STAMP_FAULT),
                (300, FLAG_STAMP_FAULT | FLAG_TIME_BACKWARDS)
            ]
        );
        assert_eq!(
            g.counts,
            GuardCounts {
                stamp_faults: 3,
                ..GuardCounts::default()
            }
        );
    }

    #[test]
    fn carries_the_accelerometer_in_m_s2_and_holds_a_bad_one() {
        let mut g = Guard::new(RateUnit::RadPerS, AccelUnit::G, 3, 7);
        let with = |seq, accel: [f64; 3]| RawSample {
            accel,
            flags: crate::wire::RAW_ACCEL,
            ..raw(seq, seq * 10, 1.0)
        };
        // Absent stays absent (never a zero reading).
        let s = g.admit(&raw(0, 0, 1.0), 0);
        assert_eq!((s.accel_reading(), s.sensors), (None, 0));
        let s = g.admit(&with(1, [0.0, 0.5, -1.0]), 0);
        assert_eq!(s.sensors, SENSOR_ACCEL);
        assert_eq!(s.accel_reading(), Some([0.0, 0.5 * 9.80665, -9.80665]));
        // A non-finite reading: the last good one held and flagged; the rate is untouched.
        let s = g.admit(&with(2, [f64::NAN, 0.0, 0.0]), 0);
        assert_eq!(s.sensors, SENSOR_ACCEL | SENSOR_ACCEL_INVALID);
        assert_eq!(s.accel, [0.0, 0.5 * 9.80665, -9.80665]);
        assert_eq!((s.accel_reading(), s.flags, s.rate[0]), (None, 0, 1.0));
        assert_eq!(g.counts.sensors_invalid, 1);
        assert_eq!(g.counts.invalid, 0);
    }

    #[test]
    fn carries_the_magnetometer_in_tesla_and_holds_a_bad_one() {
        let mut g = Guard::new(RateUnit::RadPerS, AccelUnit::MPerS2, 3, 7);
        let with = |seq, mag: [f64; 3]| RawSample {
            mag,
            flags: crate::wire::RAW_MAG,
            ..raw(seq, seq * 10, 1.0)
        };
        // A raw sample carries tesla already (its sources convert): passed as it is.
        let field = [21e-6, -3.5e-6, -40.25e-6];
        let s = g.admit(&with(0, field), 0);
        assert_eq!((s.sensors, s.mag_reading()), (SENSOR_MAG, Some(field)));
        // Not finite (an empty cell read as NaN): the last good field held and flagged, the
        // sample and its rate kept.
        let s = g.admit(&with(1, [f64::NAN; 3]), 0);
        assert_eq!(s.sensors, SENSOR_MAG | SENSOR_MAG_INVALID);
        assert_eq!(
            (s.mag, s.mag_reading(), s.flags, s.rate[0]),
            (field, None, 0, 1.0)
        );
        assert_eq!((g.counts.sensors_invalid, g.counts.invalid), (1, 0));
    }

    #[test]
    fn converts_degrees() {
        let mut g = Guard::new(RateUnit::DegPerS, AccelUnit::MPerS2, 1, 7);
        let s = g.admit(&raw(0, 0, 180.0), 0);
        assert!((s.rate[0] - std::f64::consts::PI).abs() < 1e-15);
        assert_eq!(s.rate[1], 0.0);
    }

    #[test]
    fn a_source_restart_starts_a_new_epoch_instead_of_a_gap() {
        let mut g = Guard::new(RateUnit::RadPerS, AccelUnit::MPerS2, 3, 7);
        let mut admit = |r: RawSample| {
            let stamped = g.stamp(&r);
            g.admit(&stamped, 0)
        };
        assert_eq!(admit(raw(0, 10, 1.0)).epoch, 7);
        assert_eq!(admit(raw(1, 20, 1.0)).epoch, 7);
        // The driver restarts: seq and time begin again.
        let s = admit(raw(0, 5, 1.0));
        assert_eq!((s.epoch, s.flags), (8, 0));
        // A driver that stamps its own run id: a change is a restart even without seq 0.
        let run = |seq, id| RawSample {
            epoch: id,
            ..raw(seq, 100 + seq, 1.0)
        };
        assert_eq!(admit(run(1, 42)).epoch, 8);
        assert_eq!(admit(run(2, 42)).epoch, 8);
        let s = admit(run(1, 43));
        assert_eq!((s.epoch, s.flags), (9, 0));
        // A jump within a run is still a gap.
        assert_eq!(admit(run(5, 43)).flags, FLAG_GAP_BEFORE);
        // A repeat (and a step back) within a run: flagged, counted, and a new epoch, so seq
        // never falls within one; the next sample is clean.
        let s = admit(run(5, 43));
        assert_eq!((s.epoch, s.flags), (10, FLAG_GAP_BEFORE));
        assert_eq!(admit(run(6, 43)).flags, 0);
        let s = admit(run(3, 43));
        assert_eq!((s.epoch, s.flags), (11, FLAG_GAP_BEFORE));
        assert_eq!(g.counts.gaps, 3);
        assert_eq!(g.counts.missing, 3);
        assert_eq!(g.counts.restarts, 4);
    }
}
