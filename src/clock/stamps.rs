//! Whether a sensor's stamp can be believed: the one judgment of every source whose stamps come
//! from outside (a driver on iceoryx2, a ROS 2 topic or bag, a CSV time column).
//!
//! A stamp is judged against the last one believed, never against a faulty one, so a single
//! wild stamp costs that sample alone: the next good stamp is judged as if the wild one had not
//! been. A stamp is a fault when it goes back, when it leaps forward by more than
//! [`MAX_STAMP_STEP_NS`], or when it is 0 where 0 means "not set" (ROS 2). A fault is not a
//! loss: a caller that counts missing samples by the stamps counts none across a fault.
//!
//! A clock that really stepped (an NTP correction, a driver that set its clock) gives stamps
//! that agree with each other but not with the old time base: after [`RESYNC`] such stamps in
//! a row, each within the bound of the one before, the last of them is believed and becomes the
//! new time base. The ones before it were faults.

/// The largest forward step between two stamps that is believed, ns (10 s): longer is a
/// stamp fault, never a count of missing samples.
pub const MAX_STAMP_STEP_NS: u64 = 10_000_000_000;

/// Stamps in a row that agree with each other, but not with the believed time base, after
/// which the clock is taken to have stepped (the last of them is believed).
pub const RESYNC: u32 = 3;

/// What is wrong with a stamp.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StampFault {
    /// 0, where the source's 0 means "not set".
    Unset,
    /// Before the last believed stamp.
    Backwards,
    /// More than [`MAX_STAMP_STEP_NS`] after the last believed stamp.
    Leap,
}

/// The judgment of one stream's stamps (the module docs of `clock::stamps`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StampCheck {
    zero_is_unset: bool,
    /// The last stamp believed.
    believed: Option<u64>,
    /// The faulty stamps in a row that agree with each other: the last one and how many.
    candidate: Option<(u64, u32)>,
}

impl StampCheck {
    /// A check for a stream whose stamp 0 means "not set" (`zero_is_unset`, ROS 2's
    /// convention) or is a time like any other (a sensor's clock that starts at 0).
    pub fn new(zero_is_unset: bool) -> Self {
        StampCheck {
            zero_is_unset,
            believed: None,
            candidate: None,
        }
    }

    /// Forget the stream's time (a new epoch: a restarted source starts its clock again).
    pub fn reset(&mut self) {
        self.believed = None;
        self.candidate = None;
    }

    /// The last stamp believed.
    pub fn believed(&self) -> Option<u64> {
        self.believed
    }

    /// Judge the next stamp: `None` when it is believed.
    pub fn judge(&mut self, t_ns: u64) -> Option<StampFault> {
        if self.zero_is_unset && t_ns == 0 {
            return Some(StampFault::Unset);
        }
        let Some(last) = self.believed else {
            self.believed = Some(t_ns);
            return None;
        };
        let fault = if t_ns < last {
            StampFault::Backwards
        } else if t_ns - last > MAX_STAMP_STEP_NS {
            StampFault::Leap
        } else {
            self.believed = Some(t_ns);
            self.candidate = None;
            return None;
        };
        let run = match self.candidate {
            Some((prev, n)) if t_ns > prev && t_ns - prev <= MAX_STAMP_STEP_NS => n + 1,
            _ => 1,
        };
        if run >= RESYNC {
            self.believed = Some(t_ns);
            self.candidate = None;
            return None;
        }
        self.candidate = Some((t_ns, run));
        Some(fault)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;
    const T0: u64 = 1_700_000_000_000_000_000;

    #[test]
    fn a_wild_stamp_costs_its_own_sample_alone() {
        let mut c = StampCheck::new(true);
        let year_2100 = 4_102_444_800_000_000_000;
        let mut faults = Vec::new();
        for k in 0..600u64 {
            let t = match k {
                100 => year_2100,
                200 => 0,
                300 => T0 + k * 10 * MS - 1_000 * MS,
                _ => T0 + k * 10 * MS,
            };
            if let Some(f) = c.judge(t) {
                faults.push((k, f));
            }
        }
        assert_eq!(
            faults,
            [
                (100, StampFault::Leap),
                (200, StampFault::Unset),
                (300, StampFault::Backwards)
            ]
        );
        assert_eq!(c.believed(), Some(T0 + 599 * 10 * MS));
    }

    #[test]
    fn a_clock_that_stepped_is_followed_after_resync_stamps() {
        let mut c = StampCheck::new(false);
        for k in 0..10 {
            assert_eq!(c.judge(T0 + k * MS), None);
        }
        // Stepped back by 5 s: RESYNC - 1 faults, then the new time base.
        let back = T0 - 5_000 * MS;
        assert_eq!(c.judge(back), Some(StampFault::Backwards));
        assert_eq!(c.judge(back + MS), Some(StampFault::Backwards));
        assert_eq!(c.judge(back + 2 * MS), None);
        assert_eq!(c.judge(back + 3 * MS), None);
        // Forward by a minute: the same.
        let ahead = back + 60_000 * MS;
        assert_eq!(c.judge(ahead), Some(StampFault::Leap));
        assert_eq!(c.judge(ahead + MS), Some(StampFault::Leap));
        assert_eq!(c.judge(ahead + 2 * MS), None);
    }

    #[test]
    fn zero_is_a_time_where_the_sensor_clock_starts_there() {
        let mut c = StampCheck::new(false);
        assert_eq!(c.judge(0), None);
        assert_eq!(c.judge(MS), None);
        let mut ros = StampCheck::new(true);
        assert_eq!(ros.judge(0), Some(StampFault::Unset));
        assert_eq!(ros.judge(0), Some(StampFault::Unset));
        assert_eq!(ros.believed(), None);
    }

    #[test]
    fn equal_stamps_and_steps_up_to_the_bound_are_believed() {
        let mut c = StampCheck::new(true);
        assert_eq!(c.judge(T0), None);
        assert_eq!(c.judge(T0), None);
        assert_eq!(c.judge(T0 + MAX_STAMP_STEP_NS), None);
        assert_eq!(
            c.judge(T0 + 2 * MAX_STAMP_STEP_NS + 1),
            Some(StampFault::Leap)
        );
        assert_eq!(c.judge(T0 + MAX_STAMP_STEP_NS + 1), None);
    }
}
