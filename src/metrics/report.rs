//! The final report of a run: its types (`--report FILE` writes them as JSON) and the table
//! printed at exit.

use super::*;

/// Percentiles in a report, ns.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Pct {
    /// Values recorded.
    pub count: u64,
    /// Minimum.
    pub min: u64,
    /// Median.
    pub p50: u64,
    /// 90th percentile.
    pub p90: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Maximum.
    pub max: u64,
    /// Mean.
    pub mean: f64,
}

impl Pct {
    pub(super) fn of(h: &Histogram<u64>) -> Self {
        if h.is_empty() {
            return Pct::default();
        }
        Pct {
            count: h.len(),
            min: h.min(),
            p50: h.value_at_quantile(0.5),
            p90: h.value_at_quantile(0.9),
            p99: h.value_at_quantile(0.99),
            p999: h.value_at_quantile(0.999),
            max: h.max(),
            mean: h.mean(),
        }
    }

    pub(super) fn wire(&self) -> Percentiles {
        Percentiles {
            count: self.count,
            p50: self.p50,
            p99: self.p99,
            p999: self.p999,
            max: self.max,
        }
    }
}

/// One stage in the final report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageReport {
    /// Stage name.
    pub name: String,
    /// Kind.
    pub kind: String,
    /// Samples in.
    pub samples_in: u64,
    /// Samples out.
    pub samples_out: u64,
    /// Samples subscribers of its output lost (full buffers).
    pub lost: u64,
    /// Time per sample (compute and publish of the output), ns.
    pub compute_ns: Pct,
}

/// Flagged input.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Flagged {
    /// Non-finite or driver-invalid samples (value held, flagged).
    pub invalid: u64,
    /// Sequence gaps.
    pub gaps: u64,
    /// Sequence numbers missing in the gaps.
    pub missing: u64,
    /// Stamps not believed: back, a leap over 10 s, or unset ([`crate::clock::StampCheck`]);
    /// never counted as lost.
    pub stamp_faults: u64,
    /// Samples whose accelerometer or magnetometer reading was not finite (the last good one
    /// held and flagged; the rate may be good).
    pub sensors_invalid: u64,
    /// Outputs with a non-finite value replaced by 0.
    pub repaired_outputs: u64,
}

/// What the published outputs were, by their flags (one output may be both moving and warming
/// up: a drift stage flags motion while it waits for its first stop).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Outputs {
    /// Flagged still ([`crate::wire::FLAG_STILL`]): the drift estimate was re-measured.
    pub still: u64,
    /// Flagged moving ([`crate::wire::FLAG_MOVING`]): the estimate was held.
    pub moving: u64,
    /// Flagged warming up ([`crate::wire::FLAG_WARMING_UP`]).
    pub warming_up: u64,
    /// Flushed at shutdown ([`crate::wire::FLAG_FLUSHED`]): held in the chain's delay when
    /// the input ended; published but not timed end to end.
    pub flushed: u64,
}

impl Outputs {
    /// The flags counted, in the order of [`Counters::outputs`].
    pub const FLAGS: [u32; 4] = [
        crate::wire::FLAG_STILL,
        crate::wire::FLAG_MOVING,
        crate::wire::FLAG_WARMING_UP,
        crate::wire::FLAG_FLUSHED,
    ];

    pub(super) fn from_counts([still, moving, warming_up, flushed]: [u64; 4]) -> Self {
        Outputs {
            still,
            moving,
            warming_up,
            flushed,
        }
    }
}

/// Misses the report keeps with their time and stage times (the count goes on beyond).
pub const MISSES_KEPT: usize = 100;

/// One output over the deadline, as the reporter saw it: when, and where the time went.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Miss {
    /// When the reporter took the output's record, s since the reporter started (records reach
    /// it in batches, drained every 50 ms: up to about 100 ms after the output).
    pub at_s: f64,
    /// Ingest of the completing sample to publish, ns.
    pub e2e_ns: u64,
    /// Time of each stage (its compute and the publish of its output), chain order, ns; 0 for a
    /// stage that did not run for it (or ran in another segment, after an `external` stage).
    pub stage_ns: Vec<u64>,
    /// How long of `e2e_ns` the hot thread was off a CPU, ns (None: not measured).
    pub off_cpu_ns: Option<u64>,
}

pub use crate::clock::miss_explained;

/// The final report (`--report FILE` writes it as JSON).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Pipeline name.
    pub pipeline: String,
    /// Wall time run, s.
    pub duration_s: f64,
    /// Samples ingested.
    pub samples_in: u64,
    /// Samples published by the last stage.
    pub samples_out: u64,
    /// Mean ingest rate, Hz.
    pub rate_hz: f64,
    /// Deadline, ns.
    pub deadline_ns: u64,
    /// Algorithmic delay of the chain, ns (reported beside the end-to-end latency).
    pub algorithmic_delay_ns: u64,
    /// Outputs over the deadline.
    pub deadline_misses: u64,
    /// Of them, those the kernel explains: the hot thread was off a CPU for longer than the
    /// output was late, so on a CPU it would have made the deadline.
    pub deadline_misses_explained: u64,
    /// The first [`MISSES_KEPT`] of them with their time and stage times (fewer than
    /// `deadline_misses` if the reporter could not take some records: `metric_drops`).
    pub misses: Vec<Miss>,
    /// Records the reporter could not take (histograms then miss those samples).
    pub metric_drops: u64,
    /// Samples lost anywhere: by subscribers of every service (full buffers) and before the
    /// ingest (sequence numbers missing from the source, `flagged.missing`).
    pub lost: u64,
    /// Samples subscribers that went away had stopped taking before they left (a `tap
    /// --count` that had its count): not lost, nobody wanted them ([`crate::transport::Losses`]).
    pub left_unread: u64,
    /// The stream's epoch at start ([`crate::wire::GyroSample::epoch`]).
    pub epoch: u32,
    /// New epochs after the first: source restarts, and sequence numbers that repeated or
    /// stepped back (each started the next epoch).
    pub source_restarts: u64,
    /// Flagged input.
    pub flagged: Flagged,
    /// How the state-keeping stages started, the worst of them
    /// ([`crate::wire::warm_start_name`] of the stats' code; `warm_start` has each line).
    #[serde(serialize_with = "warm_start_words")]
    pub warm_start_outcome: u64,
    /// The published outputs by their flags.
    pub outputs: Outputs,
    /// End to end: ingest of the completing sample to publish, ns.
    pub end_to_end_ns: Pct,
    /// How long after it was due each sample of a paced source (`ingest.sim` or a replay, at
    /// a `pace` other than `"asap"`) was taken, ns: the hot thread's wake-up lateness, which
    /// `end_to_end_ns` does not include. None when the source is not paced.
    pub woken_late_ns: Option<Pct>,
    /// Paced samples taken more than the deadline after they were due.
    pub woken_late_over_deadline: u64,
    /// For a paced source, from when the completing sample was due to publish, ns
    /// (`woken_late_ns` + `end_to_end_ns` of the same output): what a reader waiting on the
    /// sensor's clock sees, and what grows when pipelines share a hot thread (those served
    /// later in a round are taken later). None when the source is not paced.
    pub due_to_published_ns: Option<Pct>,
    /// Outputs published more than the deadline after their sample was due.
    pub due_to_published_over_deadline: u64,
    /// Shared memory this process could not have: writes to segments that `/dev/shm` could not
    /// back (they reached no other process) and bytes of segments created while running that
    /// could not be reserved. Zero on a healthy machine.
    pub shared_memory: crate::transport::ShmTrouble,
    /// Per stage.
    pub stages: Vec<StageReport>,
    /// Heading error of the raw, denoised and corrected rates against the truth (a simulated
    /// ingest only).
    pub heading: Option<HeadingSummary>,
    /// How the stages that keep state across runs started, one line each after the stage's
    /// name: `predict.bias` warm from its `state_file`, or cold and why (e.g. `predict: cold:
    /// state_file s: it was saved with other noise terms ...; kept as s.unusable-...`).
    pub warm_start: Vec<String>,
    /// What the stages learnt while running, one line each after the stage's name (e.g. the
    /// bias filter's walk per axis against the configured one).
    pub learnt: Vec<String>,
}

fn warm_start_words<S: serde::Serializer>(code: &u64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(crate::wire::warm_start_name(*code))
}

impl Report {
    /// The human-readable table printed at exit.
    pub fn table(&self) -> String {
        let us = |ns: u64| format!("{:.1}", ns as f64 / 1e3);
        let mut s = String::new();
        s.push_str(&format!(
            "pipeline {}: {} in, {} out in {:.2} s ({:.0} Hz); deadline {} us, {} missed; \
             algorithmic delay {} us; epoch {}{}\n",
            self.pipeline,
            self.samples_in,
            self.samples_out,
            self.duration_s,
            self.rate_hz,
            us(self.deadline_ns),
            self.deadline_misses,
            us(self.algorithmic_delay_ns),
            self.epoch,
            match self.source_restarts {
                0 => String::new(),
                n => format!(" then {n} more (source restarts, or its seq falling back)"),
            }
        ));
        s.push_str(&format!(
            "{:<14} {:<16} {:>10} {:>10} {:>8} {:>9} {:>9} {:>9} {:>9}\n",
            "stage", "kind", "in", "out", "lost", "p50 us", "p99 us", "p99.9 us", "max us"
        ));
        for st in &self.stages {
            s.push_str(&format!(
                "{:<14} {:<16} {:>10} {:>10} {:>8} {:>9} {:>9} {:>9} {:>9}\n",
                st.name,
                st.kind,
                st.samples_in,
                st.samples_out,
                st.lost,
                us(st.compute_ns.p50),
                us(st.compute_ns.p99),
                us(st.compute_ns.p999),
                us(st.compute_ns.max)
            ));
        }
        let e = &self.end_to_end_ns;
        s.push_str(&format!(
            "{:<14} {:<16} {:>10} {:>10} {:>8} {:>9} {:>9} {:>9} {:>9}\n",
            "end-to-end",
            "",
            e.count,
            "",
            self.lost,
            us(e.p50),
            us(e.p99),
            us(e.p999),
            us(e.max)
        ));
        for (name, note, w) in [
            ("woken late", "(not in e2e)", &self.woken_late_ns),
            ("due to publish", "(late + e2e)", &self.due_to_published_ns),
        ] {
            let Some(w) = w else { continue };
            s.push_str(&format!(
                "{:<14} {:<16} {:>10} {:>10} {:>8} {:>9} {:>9} {:>9} {:>9}\n",
                name,
                note,
                w.count,
                "",
                "",
                us(w.p50),
                us(w.p99),
                us(w.p999),
                us(w.max)
            ));
        }
        let f = &self.flagged;
        s.push_str(&format!(
            "flagged: {} invalid, {} gaps ({} missing from the source, counted as lost), {} stamp faults (not lost), {} accelerometer or magnetometer readings held, {} repaired; metric drops {}\n",
            f.invalid, f.gaps, f.missing, f.stamp_faults, f.sensors_invalid, f.repaired_outputs, self.metric_drops
        ));
        s.push_str(&self.outputs_line());
        s.push_str(&self.misses_lines());
        for l in &self.warm_start {
            s.push_str(&format!("warm start: {l}\n"));
        }
        for l in &self.learnt {
            s.push_str(&format!("learnt: {l}\n"));
        }
        if let Some(h) = &self.heading {
            s.push_str(
                "heading error vs the simulator's truth, deg (final / rms / max per axis):\n",
            );
            for (name, part) in [
                ("raw", &h.raw),
                ("denoised", &h.denoised),
                ("corrected", &h.corrected),
            ] {
                let Some(axes) = part else { continue };
                let cells: Vec<String> = axes
                    .iter()
                    .map(|e| format!("{:>7.3} {:>6.3} {:>6.3}", e.final_deg, e.rms_deg, e.max_deg))
                    .collect();
                s.push_str(&format!("  {:<10} {}\n", name, cells.join("  |  ")));
            }
        }
        s.push_str(&self.verdict());
        s.push('\n');
        s
    }

    /// What the outputs were (still, moving, warming up) and why fewer were timed end to end
    /// than published.
    fn outputs_line(&self) -> String {
        let o = &self.outputs;
        let n = self.samples_out;
        let pct = |k: u64| 100.0 * k as f64 / n.max(1) as f64;
        // A sample is judged still or moving, or neither (no drift stage, or nothing to judge
        // on yet); warming up overlaps them.
        let neither = n.saturating_sub(o.still + o.moving);
        let mut s = format!(
            "outputs: {n} published: {} still ({:.1}%), {} moving ({:.1}%), {neither} neither \
             ({:.1}%); {} warming up ({:.1}%)\n",
            o.still,
            pct(o.still),
            o.moving,
            pct(o.moving),
            pct(neither),
            o.warming_up,
            pct(o.warming_up),
        );
        let timed = self.end_to_end_ns.count;
        if timed != n {
            s.push_str(&format!(
                "end-to-end timed {timed} of {n}: {} flushed at shutdown are not timed (the \
                 chain's delay held them when the input ended){}\n",
                o.flushed,
                match self.metric_drops {
                    0 => String::new(),
                    d => format!(", {d} records the reporter could not take"),
                }
            ));
        }
        s
    }

    /// The first misses, one line each: when, how late, and each stage's time (its compute and
    /// publish; the rest of the end-to-end time went between stages: waiting for the CPU).
    fn misses_lines(&self) -> String {
        const SHOWN: usize = 5;
        let us = |ns: u64| format!("{:.1}", ns as f64 / 1e3);
        let shown = self.misses.len().min(SHOWN);
        let mut s = String::new();
        for m in &self.misses[..shown] {
            let stages: Vec<String> = m.stage_ns.iter().map(|&ns| us(ns)).collect();
            let why = match m.off_cpu_ns {
                Some(off) if miss_explained(m.e2e_ns, Some(off), self.deadline_ns) => {
                    format!("; off the CPU {} us: the kernel's", us(off))
                }
                Some(off) => format!("; off the CPU {} us: UNEXPLAINED, ours", us(off)),
                None => "; off-CPU time not measured (after an external stage)".into(),
            };
            s.push_str(&format!(
                "missed at {:.3} s: {} us end to end; stages {} us{why}\n",
                m.at_s,
                us(m.e2e_ns),
                stages.join(" / ")
            ));
        }
        if shown > 0 && self.deadline_misses > shown as u64 {
            s.push_str(&format!(
                "({} misses in all; the report's JSON keeps the first {})\n",
                self.deadline_misses,
                self.misses.len()
            ));
        }
        s
    }

    /// One line: whether the deadline held and nothing was lost.
    pub fn verdict(&self) -> String {
        let e = &self.end_to_end_ns;
        let deadline = format!("{:.1} us", self.deadline_ns as f64 / 1e3);
        let max = format!("max {:.1} us", e.max as f64 / 1e3);
        let timing = if e.count == 0 {
            "deadline not measured (nothing published end to end)".to_string()
        } else if self.deadline_misses == 0 {
            format!(
                "deadline held: 0 of {} outputs over {deadline} ({max})",
                e.count
            )
        } else {
            let unexplained = self.deadline_misses - self.deadline_misses_explained;
            let why = match (self.deadline_misses_explained, unexplained) {
                (_, 0) => "all the kernel's: the hot thread was held off a CPU".to_string(),
                (0, n) => format!("{n} UNEXPLAINED"),
                (k, n) => format!("{k} the kernel's, {n} UNEXPLAINED"),
            };
            format!(
                "deadline MISSED: {} of {} outputs over {deadline} ({max}; {why})",
                self.deadline_misses, e.count
            )
        };
        let loss = match self.lost {
            0 => "nothing lost".to_string(),
            n => format!("{n} samples LOST"),
        };
        let loss = match self.left_unread {
            0 => loss,
            n => format!("{loss} ({n} left unread by subscribers that went away)"),
        };
        let woken = match self.woken_late_over_deadline {
            0 => String::new(),
            n => format!("; {n} samples taken LATE (over {deadline} after they were due)"),
        };
        let due = match self.due_to_published_over_deadline {
            0 => String::new(),
            n => format!("; {n} outputs published over {deadline} after their sample was due"),
        };
        let shm = &self.shared_memory;
        let shm = if *shm == Default::default() {
            String::new()
        } else {
            format!(
                "; shared memory FULL: {} writes reached no other process, {} bytes of new \
                 segments unreserved (free /dev/shm)",
                shm.unbacked_writes, shm.unreserved_bytes
            )
        };
        let stamps = match self.flagged.stamp_faults {
            0 => String::new(),
            1 => "; 1 stamp fault (flagged, not lost)".to_string(),
            n => format!("; {n} stamp faults (flagged, not lost)"),
        };
        let warm = if self.warm_start_outcome == crate::wire::WARM_START_UNUSABLE {
            "; started COLD: the saved state was unusable (moved aside)"
        } else {
            ""
        };
        format!("verdict: {timing}; {loss}{stamps}{woken}{due}{shm}{warm}")
    }
}
