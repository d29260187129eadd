//! The daemon's ROS 2 side, on a thread of its own: a driver node's Imu topic into the service
//! an `ingest.iceoryx2` stage reads, chosen services out as Imu topics, and the vehicle's motion
//! into the stop signal `predict.bias` reads. Every hop to the hot thread is an iceoryx2
//! service, as with any driver or subscriber process, so DDS never runs on the hot thread and
//! can never delay it: a slow or absent ROS 2 peer costs this thread, not the pipeline.
//!
//! - **In:** each message becomes a [`RawSample`]: the header stamp as its time (ns since the
//!   epoch), the angular velocity as its rate (rad/s), a non-finite rate flagged invalid, and
//!   a sequence number in arrival order that jumps where the stamps show a gap (more than 1.5
//!   periods at the pipeline's rate), so the guard flags and counts it; nothing is filled.
//!   A stamp that cannot be believed ([`StampCheck`]: 0, back, or over 10 s ahead) is flagged
//!   [`RAW_STAMP_FAULT`] and proves no gap: one wild stamp is one stamp fault, never a loss.
//! - **One publisher per topic:** the first publisher heard is taken. Another one heard while
//!   it publishes (two drivers, or one started twice) is named once, with its GID, and its
//!   messages are refused and counted. When the taken one goes away (discovery loses it, or it
//!   is silent for [`SILENCE`]), the next publisher heard is a restarted driver: a new epoch.
//! - **Out:** [`ImuMapping`] (the bag writer's mapping). The stamp: the input's own ROS stamp
//!   when `imu_in` feeds the pipeline; otherwise the sample's ingest time on the system clock.
//!   The frame: `frame_id` when it is set; else the input's own `header.frame_id` when `imu_in`
//!   feeds the pipeline (a navigator's TF lookup wants the driver's frame); else `imu_link`.
//! - **Motion:** each message becomes a [`StopSignal`]: its speed the norm of the linear
//!   velocity, its yaw rate `angular.z`, their sds from the twist covariance, at its header
//!   stamp on the monotonic clock (the receipt when the stamp is on another clock:
//!   [`super::motion::Motion::stop_signal`]).
//! - A topic nobody matches after [`MATCH_GRACE`] is said on stderr, and again when it matches.

use std::collections::HashSet;
use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::counts::BridgeCounts;
use super::dds::{
    CdrPublisher, DdsReadiness, ImuPublisher, ImuSubscription, MotionSubscription, NodeNames,
    PublisherId, Ros2Node,
};
use super::diagnostics::{
    BiasDiagnosticSettings, BiasWindow, DiagnosticArray, PipelineCounts, Vector3Stamped,
    DIAGNOSTIC_ARRAY_TYPE, VECTOR3_STAMPED_TYPE,
};
use super::imu::{ImuMapping, Time, IMU_TYPE};
use super::mag::{carry, MagJoinRule, MAG_TYPE};
use super::mag_in::MagIn;
use super::motion::MotionKind;
use super::{Ros2Settings, DEFAULT_FRAME_ID, DOMAIN_KEY, NODE_KEY, TOPIC_KEY};
use crate::clock::{monotonic_ns, StampCheck, MAX_STAMP_STEP_NS};
use crate::transport::{
    Announcement, Input, Output, SideStart, Transport, TransportError, WakeSet, Waker,
};
use crate::wire::{
    GyroSample, RawSample, StatsSnapshot, StopSignal, RAW_ACCEL, RAW_INVALID, RAW_STAMP_FAULT,
};

/// How long a topic may go unmatched before stderr says so.
pub const MATCH_GRACE: Duration = Duration::from_secs(3);

/// How long the taken publisher of the Imu input may be silent before another one is taken in
/// its place (a driver killed and restarted, whose old writer discovery still lists until its
/// lease ends).
pub const SILENCE: Duration = Duration::from_secs(1);

/// One line on stderr (a closed stderr is no reason to stop).
fn say(line: std::fmt::Arguments<'_>) {
    let _ = writeln!(std::io::stderr(), "driftless: ros2: {line}");
}

/// The longest sleep: the matching checks' period, and a safety net for a missed wake-up.
const IDLE: Duration = Duration::from_millis(100);

/// How often a service its publisher does not notify is read (epoll's millisecond).
const POLL: Duration = Duration::from_millis(1);

/// The wake-set tag of the DDS readiness descriptor (the outputs' wakers are tagged by index).
const DDS_TAG: usize = usize::MAX;

/// A topic whose matching we watch.
struct Watched {
    topic: String,
    /// Its ROS 2 type.
    ty: &'static str,
    /// Our publisher (else our subscription).
    ours_publishes: bool,
    matched: bool,
    said_unmatched: bool,
    said_other_type: bool,
}

impl Watched {
    fn new(topic: &str, ty: &'static str, ours_publishes: bool) -> Watched {
        Watched {
            topic: topic.to_string(),
            ty,
            ours_publishes,
            matched: false,
            said_unmatched: false,
            said_other_type: false,
        }
    }

    /// Say on stderr when the topic goes unmatched past the grace, when it matches, and when a
    /// peer of another type is on it (it never matches).
    fn check(&mut self, node: &Ros2Node, since_start: Duration) {
        // Our publishers are reliable and our subscriptions best effort: any peer's reliability
        // matches, so a peer that is missing has another name, domain or type (a peer whose
        // other policies cannot match is found and said by `Ros2Node::qos_mismatches`).
        let peers = node.peer_types(&self.topic, !self.ours_publishes);
        let (peer, side) = if self.ours_publishes {
            ("subscriber", "publishes")
        } else {
            ("publisher", "subscribes")
        };
        if let Some(other) = peers.iter().find(|t| *t != self.ty) {
            if !self.said_other_type {
                say(format_args!(
                    "a {peer} on {} has type {other}, not {}: they never match, and it gets \
                     nothing from us nor we from it",
                    self.topic, self.ty
                ));
                self.said_other_type = true;
            }
        }
        let matched = peers.iter().any(|t| t == self.ty);
        if matched && !self.matched {
            if self.said_unmatched {
                say(format_args!("{} now has a {peer}", self.topic));
            }
        } else if !matched && !self.said_unmatched && since_start >= MATCH_GRACE {
            say(format_args!(
                "no {peer} of {} on {} after {} s (node {} {side} it on domain {}; check the \
                 topic name and ROS_DOMAIN_ID)",
                self.ty,
                self.topic,
                MATCH_GRACE.as_secs(),
                node.name(),
                node.domain()
            ));
            self.said_unmatched = true;
        }
        self.matched = matched;
    }
}

struct ImuIn {
    topic: String,
    sub: ImuSubscription,
    out: Output<RawSample>,
    period_ns: f64,
    epoch: u32,
    /// The publisher taken, when it was last heard, and whether discovery still lists it.
    publisher: Option<(PublisherId, Instant, bool)>,
    /// Other publishers already named on stderr.
    named: Vec<PublisherId>,
    /// Who each publisher's node is (None: discovery could not be read for it).
    names: Option<NodeNames>,
    next_seq: u64,
    stamps: StampCheck,
    /// Messages since the last believed stamp whose stamps were faults.
    faults_since: u64,
    /// The taken publisher's latest `header.frame_id`.
    frame_id: String,
    /// Its latest `linear_acceleration_covariance` (a driver's is usually constant).
    accel_covariance: Option<[f64; 9]>,
    /// The magnetometer joined to its samples (`mag_in`).
    mag: Option<MagIn>,
}

impl ImuIn {
    /// The Imu input: its subscription, and the service it feeds, notified after each send (its
    /// reader sleeps until a sample comes). `period_ns`, the pipeline's, measures its gaps.
    fn open(
        topic: &str,
        service: &str,
        period_ns: f64,
        depth: usize,
        transport: &Transport,
        node: &mut Ros2Node,
    ) -> Result<ImuIn, TransportError> {
        Ok(ImuIn {
            topic: topic.to_string(),
            sub: node.imu_subscription(topic, depth)?,
            out: transport.external_output::<RawSample>(service, true)?,
            period_ns,
            epoch: rand::random::<u32>().max(1),
            publisher: None,
            named: Vec::new(),
            // Naming a node is a courtesy: without it the GID is said alone.
            names: node.node_names().ok(),
            next_seq: 0,
            stamps: StampCheck::new(true),
            faults_since: 0,
            frame_id: String::new(),
            accel_covariance: None,
            mag: None,
        })
    }

    /// Whether a message of `from`, heard `now`, is taken: the first publisher's are; another's
    /// only once the first went away (then it is a restart: a new epoch).
    fn admit(&mut self, from: PublisherId, now: Instant, counts: &mut BridgeCounts) -> bool {
        match self.publisher {
            Some((taken, _, _)) if taken == from => {}
            Some((taken, heard, listed)) if listed && now - heard < SILENCE => {
                counts.imu_in_refused += 1;
                if !self.named.contains(&from) {
                    self.named.push(from);
                    let mut node = |id| {
                        self.names
                            .as_mut()
                            .and_then(|n| n.node_of(id))
                            .map_or(String::new(), |n| format!(", node {n}"))
                    };
                    let (theirs, ours) = (node(from), node(taken));
                    say(format_args!(
                        "{}: a second publisher (GID {from}{theirs}) while GID {taken}{ours} \
                         publishes: its messages are refused and counted (one driver per topic: \
                         two IMUs need two topics and two pipelines)",
                        self.topic
                    ));
                }
                return false;
            }
            Some(_) => {
                // The taken one went away: a restarted driver, as a driver's restart on
                // iceoryx2 is, not a gap.
                self.epoch = self.epoch.wrapping_add(1).max(1);
                self.next_seq = 0;
                self.stamps.reset();
                self.faults_since = 0;
                counts.imu_in_publishers += 1;
                if counts.imu_in_publishers <= 3 {
                    say(format_args!(
                        "{}: a new publisher (GID {from}; the one before went away, a driver \
                         restarted?): a new epoch",
                        self.topic
                    ));
                }
            }
            None => {}
        }
        self.publisher = Some((from, now, true));
        true
    }

    /// Whether discovery still lists the taken publisher (a publisher that said goodbye is
    /// gone at once; one that died, when its lease ends or after [`SILENCE`]).
    fn check_publisher(&mut self, node: &Ros2Node) {
        if let Some((taken, _, listed)) = &mut self.publisher {
            *listed = node.publishers_on(&self.topic).contains(taken);
        }
    }

    /// Take what arrived: the magnetometer's readings first, so that a reading and the Imu
    /// message of its instant that came together join.
    fn pump(&mut self, counts: &mut BridgeCounts) {
        if let Some(m) = &mut self.mag {
            let (unreadable, first) = m.pump();
            counts.unreadable += unreadable;
            if let Some(e) = first.filter(|_| counts.unreadable == unreadable) {
                say(format_args!(
                    "an unreadable message on the magnetometer input: {e}"
                ));
            }
        }
        loop {
            let (imu, from) = match self.sub.take() {
                Ok(Some(m)) => m,
                Ok(None) => break,
                Err(e) => {
                    counts.unreadable += 1;
                    if counts.unreadable == 1 {
                        say(format_args!("an unreadable message on the Imu input: {e}"));
                    }
                    continue;
                }
            };
            if !self.admit(from, Instant::now(), counts) {
                continue;
            }
            if self.frame_id != imu.frame_id {
                self.frame_id.clone_from(&imu.frame_id);
            }
            self.accel_covariance = Some(imu.linear_acceleration_covariance);
            // Before 1970 is no stamp either: 0, which the check refuses.
            let t_ns = u64::try_from(imu.stamp.ns()).unwrap_or(0);
            let believed = self.stamps.believed();
            let fault = self.stamps.judge(t_ns);
            match (fault, believed) {
                (Some(_), _) => {
                    counts.imu_in_stamp_faults += 1;
                    self.faults_since += 1;
                }
                // Only a step the check believed proves a gap (not a resync to a new time
                // base), less the messages of faulty stamps between, which took their places.
                (None, Some(last)) if t_ns >= last && t_ns - last <= MAX_STAMP_STEP_NS => {
                    let periods = ((t_ns - last) as f64 / self.period_ns).round() as u64;
                    let missing = periods.saturating_sub(1 + self.faults_since);
                    if missing > 0 {
                        self.next_seq += missing;
                        counts.imu_in_missing += missing;
                    }
                    self.faults_since = 0;
                }
                (None, _) => self.faults_since = 0,
            }
            if let Some(fault) = fault.filter(|_| counts.imu_in_stamp_faults <= 3) {
                say(format_args!(
                    "{}: a stamp not believed ({fault:?}: {} s {} ns after {}): flagged, not a \
                     loss",
                    self.topic,
                    imu.stamp.sec,
                    imu.stamp.nanosec,
                    believed.map_or("none yet".into(), |b| format!("{:.3} s", b as f64 * 1e-9)),
                ));
            }
            let finite = imu.angular_velocity.iter().all(|v| v.is_finite());
            // The magnetometer's field of this stamp, if a fresh one came (never a reason to
            // hold back or change the sample).
            let mag = self.mag.as_mut().map(|m| {
                let (field, line) = m.field_at(imu.stamp.ns());
                if let Some(line) = line {
                    say(format_args!("{line}"));
                }
                field
            });
            let mut flags = if finite { 0 } else { RAW_INVALID };
            if fault.is_some() {
                flags |= RAW_STAMP_FAULT;
            }
            // The accelerometer, unless the message marks it not provided (a non-finite
            // reading goes in as it came: the guard flags and holds it, as any driver's).
            let accel = imu.accel_reading();
            let mut raw = RawSample {
                t_ns,
                seq: self.next_seq,
                rate: imu.angular_velocity,
                flags: flags | accel.map_or(0, |_| RAW_ACCEL),
                epoch: self.epoch,
                accel: accel.unwrap_or_default(),
                ..RawSample::default()
            };
            carry(&mut raw, mag.flatten());
            self.next_seq += 1;
            counts.imu_in += 1;
            counts.imu_in_invalid += u64::from(!finite);
            if !finite && counts.imu_in_invalid == 1 {
                say(format_args!(
                    "{}: a message with a non-finite rate {:?} (flagged invalid; the daemon \
                     holds the last good rate)",
                    self.topic, imu.angular_velocity
                ));
            }
            // A send error is a lost sample the daemon counts as a gap.
            let _ = self.out.send(&raw);
            self.out.notify();
        }
        if let Some(m) = &self.mag {
            counts.mag = m.counts;
        }
    }
}

/// A service the side reads, and what it publishes of each sample.
struct ServiceOut {
    service: String,
    input: Input<GyroSample>,
    /// Its event service, when the daemon notifies one (the public service).
    waker: Option<Waker>,
    /// Imu topics.
    imu: Vec<(ImuPublisher, ImuMapping)>,
    /// The bias topic: the message reused for every sample, and its bytes.
    bias: Option<(CdrPublisher, Vector3Stamped, Vec<u8>)>,
    /// The samples of the diagnostics' period.
    window: Option<BiasWindow>,
}

impl ServiceOut {
    fn new(transport: &Transport, service: &str) -> Result<ServiceOut, TransportError> {
        Ok(ServiceOut {
            service: service.to_string(),
            input: transport.open_input::<GyroSample>(service)?,
            waker: transport.existing_waker(service)?,
            imu: Vec::new(),
            bias: None,
            window: None,
        })
    }

    /// Publish its samples on `topic` too, as a message of `ty`: an Imu topic, the bias, or
    /// (the diagnostics, published by [`Diagnostics`]) a window of the samples. Every topic is
    /// written in the configured frame until an input's frame is heard.
    fn publish_on(
        &mut self,
        settings: &Ros2Settings,
        node: &mut Ros2Node,
        topic: &str,
        ty: &'static str,
    ) -> Result<(), TransportError> {
        let frame_id = settings.frame_id.as_deref().unwrap_or(DEFAULT_FRAME_ID);
        match ty {
            IMU_TYPE => self.imu.push((
                node.imu_publisher(topic, settings.depth)?,
                ImuMapping::new(frame_id, 1.0, settings.rate_noise)
                    .with_accel_noise(settings.accel_noise),
            )),
            VECTOR3_STAMPED_TYPE => {
                let msg = Vector3Stamped {
                    frame_id: frame_id.to_string(),
                    ..Vector3Stamped::default()
                };
                self.bias = Some((
                    node.cdr_publisher(topic, ty, settings.depth)?,
                    msg,
                    Vec::new(),
                ));
            }
            _ => self.window = Some(BiasWindow::default()),
        }
        Ok(())
    }

    /// Publish what came, each sample on each topic; `t_ns` from the ingest time on the system
    /// clock (`realtime` offset) when no ROS stamps come in.
    fn serve(
        &mut self,
        frame: Option<&str>,
        accel_covariance: Option<&[f64; 9]>,
        realtime: Option<i128>,
        counts: &mut BridgeCounts,
    ) {
        for (_, mapping) in &mut self.imu {
            if let Some(f) = frame {
                mapping.set_frame_id(f);
            }
            if let Some(c) = accel_covariance {
                mapping.set_input_accel_covariance(c);
            }
        }
        if let (Some(f), Some((_, msg, _))) = (frame, &mut self.bias) {
            if msg.frame_id != f {
                msg.frame_id.clear();
                msg.frame_id.push_str(f);
            }
        }
        while let Ok(Some(mut s)) = self.input.receive() {
            if let Some(offset) = realtime {
                s.t_ns = u64::try_from(i128::from(s.ingest_ns) + offset).unwrap_or(0);
            }
            for (publisher, mapping) in &mut self.imu {
                let sent = mapping.gyro(&s).and_then(|imu| publisher.publish(imu));
                match sent {
                    Ok(()) => counts.imu_out += 1,
                    Err(e) => {
                        counts.imu_out_failed += 1;
                        if counts.imu_out_failed == 1 {
                            say(format_args!("an Imu message was not sent: {e}"));
                        }
                    }
                }
            }
            if let Some((publisher, msg, buf)) = &mut self.bias {
                let sent = i64::try_from(s.t_ns)
                    .ok()
                    .and_then(Time::from_ns)
                    .ok_or_else(|| format!("sample time {} ns is past 2038", s.t_ns))
                    .and_then(|stamp| {
                        msg.stamp = stamp;
                        msg.vector = s.drift;
                        msg.write_cdr(buf).map_err(|e| e.to_string())
                    })
                    .and_then(|()| publisher.publish(buf));
                other_sent(sent, "bias", counts, |c| c.bias_out += 1);
            }
            if let Some(w) = &mut self.window {
                w.observe(s.drift, s.drift_std, s.flags);
            }
        }
    }
}

/// Count a bias or diagnostics message sent, or say the first one not sent.
fn other_sent(
    sent: Result<(), String>,
    what: &str,
    counts: &mut BridgeCounts,
    ok: impl FnOnce(&mut BridgeCounts),
) {
    match sent {
        Ok(()) => ok(counts),
        Err(e) => {
            counts.other_out_failed += 1;
            if counts.other_out_failed == 1 {
                say(format_args!("a {what} message was not sent: {e}"));
            }
        }
    }
}

/// The diagnostics: their publisher, what names their status, the pipeline's stats.
struct Diagnostics {
    publisher: CdrPublisher,
    /// Which of the outputs holds the window.
    out: usize,
    settings: BiasDiagnosticSettings,
    period: Duration,
    next: Instant,
    stats_service: String,
    /// Opened when first needed (the stats service appears with the pipeline's reporting).
    stats: Option<Input<StatsSnapshot>>,
    last_stats: Option<PipelineCounts>,
    buf: Vec<u8>,
}

impl Diagnostics {
    /// The diagnostics on `topic`, of the window of output `out`: the status named after the
    /// node (as `gyro_bias_estimator` names its own), and the first one due at once.
    fn new(
        settings: &Ros2Settings,
        node: &mut Ros2Node,
        topic: &str,
        out: usize,
    ) -> Result<Diagnostics, TransportError> {
        let ns = settings.namespace.trim_end_matches('/');
        let full = format!("{ns}/{}", settings.node);
        let name = full.trim_start_matches('/');
        Ok(Diagnostics {
            publisher: node.cdr_publisher(topic, DIAGNOSTIC_ARRAY_TYPE, settings.depth)?,
            out,
            settings: BiasDiagnosticSettings {
                name: format!("{name}: gyro_bias"),
                hardware_id: name.to_string(),
                threshold: settings.bias_threshold,
            },
            period: Duration::from_secs_f64(settings.diagnostics_period_s),
            next: Instant::now(),
            stats_service: settings.stats_service.clone(),
            stats: None,
            last_stats: None,
            buf: Vec::new(),
        })
    }

    /// Publish a period's status when it is due.
    fn tick(
        &mut self,
        now: Instant,
        transport: &Transport,
        outs: &mut [ServiceOut],
        counts: &mut BridgeCounts,
    ) {
        if now < self.next {
            return;
        }
        self.next = now + self.period;
        if self.stats.is_none() {
            self.stats = transport.open_input(&self.stats_service).ok();
        }
        if let Some(stats) = &self.stats {
            while let Ok(Some(s)) = stats.receive() {
                self.last_stats = Some(PipelineCounts {
                    deadline_misses: s.deadline_misses,
                    lost: s.lost,
                    missing_in_input: s.gap_samples,
                    odometry: s.odometry,
                });
            }
        }
        let Some(window) = outs[self.out].window.as_mut() else {
            return;
        };
        let status = window.report(&self.settings, self.period.as_secs_f64(), self.last_stats);
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64);
        let array = DiagnosticArray {
            stamp: Time::from_ns(now_ns).unwrap_or_default(),
            frame_id: String::new(),
            status: vec![status],
        };
        let sent = array
            .write_cdr(&mut self.buf)
            .map_err(|e| e.to_string())
            .and_then(|()| self.publisher.publish(&self.buf));
        other_sent(sent, "diagnostics", counts, |c| c.diagnostics_out += 1);
    }
}

struct MotionIn {
    sub: MotionSubscription,
    out: Output<StopSignal>,
    /// Whether a stamp not on this host's clock has been said (once).
    said_receipt: bool,
}

impl MotionIn {
    /// The motion input: its subscription as a message of `kind`, and the service it feeds,
    /// not notified (the bias filter keeps the newest signal and reads it at its next sample).
    fn open(
        topic: &str,
        kind: MotionKind,
        service: &str,
        depth: usize,
        transport: &Transport,
        node: &mut Ros2Node,
    ) -> Result<MotionIn, TransportError> {
        Ok(MotionIn {
            sub: node.motion_subscription(topic, kind, depth)?,
            out: transport.external_output::<StopSignal>(service, false)?,
            said_receipt: false,
        })
    }

    /// Take what arrived, each message a stop signal at its header stamp
    /// ([`super::motion::Motion::stop_signal`]).
    fn pump(&mut self, counts: &mut BridgeCounts) {
        let offset = realtime_offset_ns();
        loop {
            match self.sub.take() {
                Ok(Some(m)) => {
                    counts.motion_in += 1;
                    let received = monotonic_ns();
                    let (signal, believed) = m.stop_signal(received, offset);
                    if !believed && !self.said_receipt {
                        self.said_receipt = true;
                        let off = (i128::from(m.stamp.ns()) - offset - i128::from(received)) as f64;
                        say(format_args!(
                            "the motion's header.stamp is {:+.3} s off this host's clock (a \
                             simulation's clock, or a driver's own): its messages are timed at \
                             receipt, so the odometry's latency is taken for motion",
                            off * 1e-9
                        ));
                    }
                    let _ = self.out.send(&signal);
                }
                Ok(None) => break,
                Err(e) => {
                    counts.unreadable += 1;
                    if counts.unreadable == 1 {
                        say(format_args!("an unreadable motion message: {e}"));
                    }
                }
            }
        }
    }
}

/// The system clock's ns since the epoch minus the monotonic clock's: maps an `ingest_ns` to
/// the system clock.
fn realtime_offset_ns() -> i128 {
    let real = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i128);
    real - i128::from(monotonic_ns())
}

/// What the ROS 2 side of a pipeline says of itself on its iceoryx2 node, for `driftless
/// list`: the node, its domain and each topic with its direction, type and service.
fn announcement(settings: &Ros2Settings, node: &Ros2Node) -> Vec<(&'static str, String)> {
    let ns = settings.namespace.trim_end_matches('/');
    let mut topics: Vec<String> = settings
        .topics()
        .iter()
        .map(|t| format!("{} {} {} {}", t.direction.name(), t.topic, t.ty, t.service))
        .collect();
    let room = crate::transport::MAX_ATTRIBUTES - 2;
    if topics.len() > room {
        let more = topics.len() - (room - 1);
        topics.truncate(room - 1);
        topics.push(format!("+{more} more"));
    }
    let mut out = vec![
        (NODE_KEY, format!("{ns}/{}", node.name())),
        (DOMAIN_KEY, node.domain().to_string()),
    ];
    out.extend(topics.into_iter().map(|t| (TOPIC_KEY, t)));
    out
}

/// Pin the calling thread to `cpu`, the hot thread's, before it starts the DDS threads (they
/// inherit it): each hand-over between them and the hot thread then wakes a thread on the CPU
/// that is running, never an idle one (on a VM, waking an idle vCPU costs tens of us). A
/// failure is said and costs only that.
fn beside_the_hot_thread(cpu: usize) {
    // SAFETY: a zeroed cpu_set_t is valid; CPU_SET stays in bounds (cpu < 1024 = CPU_SETSIZE).
    let rc = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
    };
    if rc != 0 {
        say(format_args!(
            "cannot run beside the hot thread on CPU {cpu}: {}",
            std::io::Error::last_os_error()
        ));
    }
}

/// Run the ROS 2 side of a pipeline, `settings`, as `start` says (its iceoryx2 node, where it
/// announces itself, the pipeline's rate, beside the hot thread on its CPU when the pipeline
/// pins it) until `start.stop`. `started` hears once whether it set up (so the daemon can
/// refuse to run without it); then it runs, and returns what it carried.
pub fn run_bridge(
    settings: &Ros2Settings,
    start: &SideStart<'_>,
    started: impl FnOnce(Result<(), String>),
) -> Result<BridgeCounts, TransportError> {
    let bridge = match Bridge::set_up(settings, start) {
        Ok(bridge) => {
            started(Ok(()));
            bridge
        }
        Err(e) => {
            started(Err(e.to_string()));
            return Err(e);
        }
    };
    Ok(bridge.serve(start.stop))
}

/// The side, set up. Its fields drop in the order they are declared, the order the side has
/// always closed in: the announcement and the iceoryx2 node first; then the wake set before the
/// readiness whose descriptor it watches, the readiness before the subscriptions registered on
/// it; the ROS 2 node after every port it made.
struct Bridge<'a> {
    /// Held, never read: the side is listed while it lives.
    _announced: Announcement,
    transport: Transport,
    wake: WakeSet,
    readiness: DdsReadiness,
    motion: Option<MotionIn>,
    diagnostics: Option<Diagnostics>,
    outs: Vec<ServiceOut>,
    imu_in: Option<ImuIn>,
    watched: Vec<Watched>,
    node: Ros2Node,
    /// Read on each round: a configured `frame_id` overrides the driver's.
    settings: &'a Ros2Settings,
    counts: BridgeCounts,
    /// QoS mismatches already said: each is said once.
    said_qos: HashSet<String>,
}

impl<'a> Bridge<'a> {
    /// Make everything, each step after what it needs: the iceoryx2 node; the CPU, before the
    /// ROS 2 node starts the DDS threads (they inherit it); the announcement, which names the
    /// ROS 2 node; each direction's topics and services (Imu in, the outputs, motion); the
    /// wake-ups, which watch their ports. A setup that fails says the first error in this order.
    fn set_up(
        settings: &'a Ros2Settings,
        start: &SideStart<'_>,
    ) -> Result<Bridge<'a>, TransportError> {
        let transport = Transport::new(start.prefix, start.node, start.qos)?;
        if let Some(cpu) = start.cpu {
            beside_the_hot_thread(cpu);
        }
        let mut node = Ros2Node::new(&settings.namespace, &settings.node)?;
        let announced = transport.announce(start.announce_as, &announcement(settings, &node))?;
        let mut watched = Vec::new();
        let mut imu_in = match &settings.imu_in {
            Some((topic, service)) => {
                watched.push(Watched::new(topic, IMU_TYPE, false));
                let period_ns = 1e9 / start.rate_hz;
                let mut imu = ImuIn::open(
                    topic,
                    service,
                    period_ns,
                    settings.depth,
                    &transport,
                    &mut node,
                )?;
                if let Some(mag) = &settings.mag_in {
                    watched.push(Watched::new(mag, MAG_TYPE, false));
                    let rule = MagJoinRule::new(start.rate_hz, settings.mag_max_age_s);
                    imu.mag = Some(MagIn::open(mag, rule, settings.depth, &mut node)?);
                }
                Some(imu)
            }
            None => None,
        };
        let (outs, diagnostics) = open_outs(settings, &transport, &mut node, &mut watched)?;
        let mut motion = match &settings.motion_in {
            Some((topic, ty, service)) => {
                let (name, kind) = MotionKind::ALL
                    .iter()
                    .find(|(name, _)| name == ty)
                    .copied()
                    .unwrap_or(MotionKind::ALL[0]);
                watched.push(Watched::new(topic, name, false));
                Some(MotionIn::open(
                    topic,
                    kind,
                    service,
                    settings.depth,
                    &transport,
                    &mut node,
                )?)
            }
            None => None,
        };
        let (readiness, wake) = wake_ups(&mut imu_in, &mut motion, &outs)?;
        transport.reserve_shared_memory()?;
        Ok(Bridge {
            _announced: announced,
            transport,
            wake,
            readiness,
            motion,
            diagnostics,
            outs,
            imu_in,
            watched,
            node,
            settings,
            counts: BridgeCounts::default(),
            said_qos: HashSet::new(),
        })
    }

    /// Forward both ways until `stop`; between rounds, sleep until something arrives or the
    /// diagnostics fall due. Discovery changes slowly: it is read every half second, not every
    /// round. Returns what it carried.
    fn serve(mut self, stop: &AtomicBool) -> BridgeCounts {
        // Without ROS stamps coming in, a sample's stamp is its ingest on the system clock.
        let realtime = self.imu_in.is_none().then(realtime_offset_ns);
        let t0 = Instant::now();
        let mut next_check = t0;
        // Every output notified: sleep until woken; else read the others every millisecond.
        let sleep = if self.outs.iter().all(|o| o.waker.is_some()) {
            IDLE
        } else {
            POLL
        };
        while !stop.load(Ordering::Relaxed) {
            self.take_wake_ups();
            if let Some(i) = &mut self.imu_in {
                i.pump(&mut self.counts);
            }
            self.forward_out(realtime);
            if let Some(m) = &mut self.motion {
                m.pump(&mut self.counts);
            }
            let now = Instant::now();
            if let Some(d) = &mut self.diagnostics {
                d.tick(now, &self.transport, &mut self.outs, &mut self.counts);
            }
            if now >= next_check {
                self.check_graph(now - t0);
                next_check = now + Duration::from_millis(500);
            }
            // A signal or a failed wait only shortens the sleep.
            let sleep = self.diagnostics.as_ref().map_or(sleep, |d| {
                sleep.min(d.next.saturating_duration_since(Instant::now()))
            });
            let _ = self.wake.wait(None, sleep, |_| {});
        }
        self.counts
    }

    /// Edge-triggered: the wake-ups are taken before everything there is, so that what comes
    /// while it is taken wakes the next sleep rather than being slept through.
    fn take_wake_ups(&mut self) {
        self.readiness.clear();
        for o in &self.outs {
            if let Some(w) = &o.waker {
                let _ = w.drain();
            }
        }
    }

    /// The pipeline's samples out to their topics: in the driver's frame unless a frame is
    /// configured (a navigator's TF lookup wants the driver's), with the driver's accelerometer
    /// covariance at hand where neither a sample nor `accel_noise` gives one.
    fn forward_out(&mut self, realtime: Option<i128>) {
        let frame = match (&self.settings.frame_id, &self.imu_in) {
            (None, Some(i)) if !i.frame_id.is_empty() => Some(i.frame_id.as_str()),
            _ => None,
        };
        let accel_covariance = self
            .imu_in
            .as_ref()
            .and_then(|i| i.accel_covariance.as_ref());
        for o in &mut self.outs {
            o.serve(frame, accel_covariance, realtime, &mut self.counts);
        }
    }

    /// What discovery shows: topics unmatched or of another type, whether the taken Imu
    /// publisher is still listed, and peers whose QoS can never match (each said once).
    fn check_graph(&mut self, since_start: Duration) {
        for w in &mut self.watched {
            w.check(&self.node, since_start);
        }
        if let Some(i) = &mut self.imu_in {
            i.check_publisher(&self.node);
        }
        for line in self.node.qos_mismatches() {
            if self.said_qos.insert(line.clone()) {
                say(format_args!("{line}"));
            }
        }
    }
}

/// The services the outputs read, each opened once however many topics it feeds (one input
/// port per service), and the diagnostics; then each topic's publisher, in the table's order
/// (Imu, bias, diagnostics).
fn open_outs(
    settings: &Ros2Settings,
    transport: &Transport,
    node: &mut Ros2Node,
    watched: &mut Vec<Watched>,
) -> Result<(Vec<ServiceOut>, Option<Diagnostics>), TransportError> {
    let mut outs: Vec<ServiceOut> = Vec::new();
    let mut out_of = |service: &str| -> Result<usize, TransportError> {
        match outs.iter().position(|o| o.service == service) {
            Some(k) => Ok(k),
            None => {
                outs.push(ServiceOut::new(transport, service)?);
                Ok(outs.len() - 1)
            }
        }
    };
    let mut wants = Vec::new();
    for (service, topic) in &settings.imu_out {
        wants.push((out_of(service)?, topic, IMU_TYPE));
    }
    if let Some((service, topic)) = &settings.bias_out {
        wants.push((out_of(service)?, topic, VECTOR3_STAMPED_TYPE));
    }
    let mut diagnostics = None;
    if let Some((service, topic)) = &settings.diagnostics {
        let out = out_of(service)?;
        wants.push((out, topic, DIAGNOSTIC_ARRAY_TYPE));
        diagnostics = Some(Diagnostics::new(settings, node, topic, out)?);
    }
    for (out, topic, ty) in wants {
        watched.push(Watched::new(topic, ty, true));
        outs[out].publish_on(settings, node, topic, ty)?;
    }
    Ok((outs, diagnostics))
}

/// One descriptor for everything that can wake the side: the DDS subscriptions' readiness
/// and the notifying outputs' event services, so that it sleeps until either has something.
fn wake_ups(
    imu_in: &mut Option<ImuIn>,
    motion: &mut Option<MotionIn>,
    outs: &[ServiceOut],
) -> Result<(DdsReadiness, WakeSet), TransportError> {
    let io = |e: std::io::Error| TransportError::Io {
        what: "ROS 2 readiness",
        reason: e.to_string(),
    };
    let readiness = DdsReadiness::new().map_err(io)?;
    if let Some(i) = imu_in {
        readiness.watch_imu(&mut i.sub, 0).map_err(io)?;
        if let Some(m) = &mut i.mag {
            readiness.watch_mag(&mut m.sub, 2).map_err(io)?;
        }
    }
    if let Some(m) = motion {
        readiness.watch_motion(&mut m.sub, 1).map_err(io)?;
    }
    let mut wake = WakeSet::new()?;
    wake.add_fd(readiness.fd(), DDS_TAG)?;
    for (k, o) in outs.iter().enumerate() {
        if let Some(w) = &o.waker {
            wake.add(w, k)?;
        }
    }
    Ok((readiness, wake))
}
