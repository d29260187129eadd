//! `predict.bias` with a vehicle's stop signal, between real processes: this test is the
//! sensor driver and the vehicle (it publishes raw rates and `StopSignal`s on iceoryx2), the
//! daemon reads the newest signal at each sample. A fresh "stands" is used from its first
//! sample, "stands" while the gyro turns is flagged and not trusted, a stale signal leaves it
//! to our own detector, and the stops given teach the filter its walk (`run`'s report).

mod common;

use std::time::{Duration, Instant};

use common::{collect, finish, qos, raw, report, signal, start, wait_ready, Dir, Prefix};
use driftless::transport::{monotonic_ns, Transport};
use driftless::wire::{
    GyroSample, RawSample, StopSignal, FLAG_MOVING, FLAG_STILL, FLAG_STOP_CONTRADICTED,
};
use libc::SIGTERM;

const BIAS_DEG_S: f64 = 0.5;

/// Phases at 1 kHz: what the gyro does and what the vehicle says.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Phase {
    /// Still, the vehicle says it stands.
    Stands,
    /// Turning at 20 deg/s, the vehicle (wrongly) says it stands.
    Lies,
    /// Turning at 20 deg/s, the vehicle says it moves.
    Moves,
    /// Still, the vehicle says nothing (its last word goes stale).
    Silent,
}

fn phase(i: usize) -> Phase {
    match i {
        0..3000 => Phase::Stands,
        3000..4000 => Phase::Lies,
        4000..6000 => Phase::Stands,
        6000..6500 => Phase::Moves,
        _ => Phase::Silent,
    }
}

const N: usize = 11_000;

#[test]
fn a_stop_signal_is_trusted_fresh_checked_against_the_gyro_and_dropped_stale() {
    let prefix = Prefix::new("stopsig");
    let dir = Dir::new();
    let text = r#"
name = "v"
rate_hz = 1000.0
axes = 3
input_units = "deg/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = 16384

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "v/sensor"
output = "v/raw"

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "v/raw"
output = "v/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
input = "v/denoised"
output = "v/predicted"
profile = "adis16405"
stop_input = "v/stop"
# A signal's age is judged at the daemon's ingest, so a stall of both processes ages it: at
# the default 0.5 s, one long VM stall under load made a fresh "stands" stale for a sample
# (the detector, still seeing the lie in its window, then said moving). 2 s rides out any
# stall this machine shows; the silent phase is long enough for it to go stale.
stop_max_age_s = 2.0

[[stage]]
name = "publish"
kind = "publish"
input = "v/predicted"
output = "v/corrected"
"#;
    let file = dir.write("p.toml", text);
    let me = Transport::new(&prefix.0, "vehicle", qos(16384)).expect("node");
    let corrected = me.input::<GyroSample>("v/corrected").expect("subscriber");
    let sensor = me.output::<RawSample>("v/sensor", true).expect("sensor");
    let stop = me
        .output::<StopSignal>("v/stop", false)
        .expect("stop signal");
    let mut child = start(
        &file,
        &prefix,
        &["--report", dir.path("report.json").to_str().unwrap()],
    );
    wait_ready(&prefix, "v/stats", &mut child);

    // Deterministic noise of about the ADIS16405's, paced at 1 kHz in real time (staleness is
    // judged on the clock).
    let noise = |i: usize| 0.3 * (((i * 7919) % 101) as f64 / 101.0 - 0.5);
    let started = Instant::now();
    let mut got = Vec::with_capacity(N);
    for i in 0..N {
        let p = phase(i);
        // The daemon pairs a sample with the newest signal; one lagging behind this loop under
        // load would pair the last samples of a phase with the next phase's word. The vehicle
        // changes its word only once the phase's last sample is corrected, so that each
        // phase's edges are exact (the pacing catches up after).
        if i > 0 && p != phase(i - 1) {
            got.extend(collect(&corrected, i - got.len(), Duration::from_secs(10)));
            assert_eq!(got.len(), i, "samples before {p:?} corrected");
        }
        if p != Phase::Silent {
            stop.send(&StopSignal::new(
                monotonic_ns(),
                f64::NAN,
                u32::from(p != Phase::Moves),
            ))
            .expect("send stop signal");
        }
        let turn = if matches!(p, Phase::Lies | Phase::Moves) {
            20.0
        } else {
            0.0
        };
        let r = BIAS_DEG_S + turn + noise(i);
        assert_eq!(
            sensor
                .send(&raw(i as u64, i as u64 * 1_000_000, [r; 3]))
                .unwrap(),
            1
        );
        let due = started + Duration::from_micros(1000 * (i as u64 + 1));
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
    got.extend(collect(&corrected, N - got.len(), Duration::from_secs(10)));
    signal(&child, SIGTERM);
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(got.len(), N, "every sample once");

    let drift_deg = |s: &GyroSample| s.drift[0].to_degrees();
    // Fresh "stands": still from the first samples (no detector window to fill), the bias
    // measured from them.
    all_still(&got, 50..3000);
    assert!(
        (drift_deg(&got[2999]) - BIAS_DEG_S).abs() < 0.01,
        "{}",
        drift_deg(&got[2999])
    );
    // "Stands" while turning at 20 deg/s: flagged, moving, and the turn not taken as bias.
    let lied = &got[3000..4000];
    let flagged = lied
        .iter()
        .filter(|s| s.flags & FLAG_STOP_CONTRADICTED != 0 && s.flags & FLAG_MOVING != 0)
        .count();
    assert!(flagged > 950, "{flagged} of 1000 flagged");
    assert!(
        (drift_deg(&got[3999]) - BIAS_DEG_S).abs() < 0.01,
        "{}",
        drift_deg(&got[3999])
    );
    assert!(got[..3000]
        .iter()
        .all(|s| s.flags & FLAG_STOP_CONTRADICTED == 0));
    // Back to a true stop: still from its first samples again, nothing flagged.
    all_still(&got, 4100..6000);
    // "Moves" is trusted: moving, not flagged.
    assert!(got[6000..6500]
        .iter()
        .all(|s| s.flags & FLAG_MOVING != 0 && s.flags & FLAG_STOP_CONTRADICTED == 0));
    // Silent: the last signal ("moves") goes stale after 2 s; from then on our detector
    // decides (a window and settling, then still).
    assert!(got[4100..]
        .iter()
        .all(|s| s.flags & FLAG_STOP_CONTRADICTED == 0));
    let first = got[6500..]
        .iter()
        .position(|s| s.flags & FLAG_STILL != 0)
        .map(|k| k + 6500);
    assert!(
        got[6500..7000].iter().all(|s| s.flags & FLAG_STILL == 0),
        "still from {first:?}, while \"moves\" was fresh"
    );
    assert!(
        got[10_000..].iter().all(|s| s.flags & FLAG_STILL != 0),
        "still from {first:?}"
    );
    assert!((drift_deg(&got[N - 1]) - BIAS_DEG_S).abs() < 0.01);

    // The second given stop (its end said by the signal) taught the walk: its mean against
    // the first's; the report says so per axis.
    let r = report(&dir);
    let learnt: Vec<&str> = r["learnt"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap())
        .collect();
    assert_eq!(learnt.len(), 3, "{learnt:?}");
    for l in &learnt {
        assert!(
            l.contains("from 1 stops") && l.contains("learn_walk = given-stops"),
            "{l}"
        );
    }
}

/// Every sample of `range` flagged still; else the first that is not and how many, with the
/// report's flag names, so that a failure says where the stop was lost.
fn all_still(got: &[GyroSample], range: std::ops::Range<usize>) {
    let not: Vec<usize> = range
        .clone()
        .filter(|&i| got[i].flags & FLAG_STILL == 0)
        .collect();
    assert!(
        not.is_empty(),
        "{} of samples {range:?} not still, the first {} with flags {:?}",
        not.len(),
        not[0],
        driftless::wire::flag_names(got[not[0]].flags)
    );
}
