//! A replay at a chosen speed (`pace = 10.0`) publishes exactly what the same log publishes as
//! fast as possible, bit for bit, only slower: the same CSV log, with the vehicle's stops in a
//! column, through the real daemon (wavelet denoiser, bias filter) at each pace, every corrected
//! sample read by this process. The 10x run's samples are judged on their own ingest times
//! against their sensor times: never ahead of ten times real time (a firm bound), and well
//! ahead of real time (a loose one: a loaded machine makes a replay late, never early).

mod common;

use std::time::{Duration, Instant};

use common::{finish, qos, report, start, Dir, Prefix};
use driftless::transport::Transport;
use driftless::wire::{GyroSample, FLAG_STILL, FLAG_VEHICLE_STOPPED};

const RATE_HZ: f64 = 200.0;
/// Larger than any log here: no subscriber loses a sample, however fast the replay.
const BUFFER: usize = 4096;

/// `n` rows at 200 Hz of a gyro at rest with a bias: the vehicle moves for the first third,
/// stands for the second, and moves again.
fn log(n: usize) -> String {
    let mut csv = String::from("t,x,y,z,stopped\n");
    for i in 0..n {
        let stop = ["0", "1", "0"][i * 3 / n];
        let wobble = 0.02 * ((i * 7919 % 17) as f64 / 17.0 - 0.5);
        csv.push_str(&format!(
            "{:.3},{},{},{},{stop}\n",
            i as f64 / RATE_HZ,
            0.4 + wobble,
            -0.2 - wobble,
            0.1 + wobble
        ));
    }
    csv
}

/// What one run published: each sample as it was taken, the corrected samples, the report.
struct Run {
    taken: Vec<GyroSample>,
    corrected: Vec<GyroSample>,
    report: serde_json::Value,
}

/// Replay `n` rows of [`log`] at `pace` (as written in the file) through a real daemon; this
/// process subscribes before the daemon starts, so it misses nothing.
fn replay(test: &str, n: usize, pace: &str) -> Run {
    let dir = Dir::new();
    dir.write("log.csv", &log(n));
    let file = dir.write(
        "p.toml",
        &format!(
            r#"
name = "p"
rate_hz = {RATE_HZ}
input_units = "deg/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = {BUFFER}

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "p/raw"
file = "log.csv"
time_column = "t"
stop_column = "stopped"
pace = {pace}

# Each sample as the guard took it (its own ingest_ns), for the timing.
[[stage]]
name = "taken"
kind = "denoise.none"
input = "p/raw"
output = "p/taken"

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "p/taken"
output = "p/denoised"
wavelet = "db4"
level = 4
lag = 16

[[stage]]
name = "predict"
kind = "predict.bias"
input = "p/denoised"
output = "p/predicted"
profile = "adis16405"
lsb = 0.0

[[stage]]
name = "publish"
kind = "publish"
input = "p/predicted"
output = "p/corrected"
"#
        ),
    );
    let prefix = Prefix::new(test);
    let me = Transport::new(&prefix.0, "pace-reader", qos(BUFFER)).expect("node");
    let taken_in = me.input::<GyroSample>("p/taken").expect("subscriber");
    let out_in = me.input::<GyroSample>("p/corrected").expect("subscriber");
    let report_path = dir.path("report.json");
    let daemon = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    // Both read as they come, while the daemon runs; a loaded machine only makes it longer.
    let (mut taken, mut corrected) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let end = Instant::now() + Duration::from_secs(120);
    while (taken.len() < n || corrected.len() < n) && Instant::now() < end {
        let mut idle = true;
        while let Some(s) = taken_in.receive().expect("receive") {
            taken.push(s);
            idle = false;
        }
        while let Some(s) = out_in.receive().expect("receive") {
            corrected.push(s);
            idle = false;
        }
        if idle {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    let (code, err) = finish(daemon, Duration::from_secs(60));
    assert_eq!(code, Some(0), "pace {pace}: {err}");
    assert_eq!(taken.len(), n, "pace {pace}: every sample taken: {err}");
    assert_eq!(corrected.len(), n, "pace {pace}: every output: {err}");
    Run {
        taken,
        corrected,
        report: report(&dir),
    }
}

/// Every field of the outputs but the run's own (`ingest_ns`, `epoch`), bit for bit.
fn assert_same_outputs(a: &[GyroSample], b: &[GyroSample], what: &str) {
    let bits = |v: &[f64; 3]| v.map(f64::to_bits);
    assert_eq!(a.len(), b.len(), "{what}");
    for (x, y) in a.iter().zip(b) {
        let at = format!("{what}: seq {}", x.seq);
        assert_eq!((x.seq, x.t_ns, x.flags), (y.seq, y.t_ns, y.flags), "{at}");
        assert_eq!(bits(&x.rate), bits(&y.rate), "{at}: rate");
        assert_eq!(bits(&x.denoised), bits(&y.denoised), "{at}: denoised");
        assert_eq!(bits(&x.drift), bits(&y.drift), "{at}: drift");
        assert_eq!(bits(&x.drift_std), bits(&y.drift_std), "{at}: drift_std");
    }
}

#[test]
fn a_replay_at_10x_publishes_what_asap_does_bit_for_bit_at_ten_times_real_time() {
    const N: usize = 3000; // 15 s of log: 1.5 s at 10x
    let asap = replay("asap", N, "\"asap\"");
    let fast = replay("fast", N, "10.0");
    assert_same_outputs(&asap.corrected, &fast.corrected, "10x against asap");

    // The stops rode with the samples at both speeds: the bias filter stood on them.
    let stood = |r: &Run| {
        r.corrected
            .iter()
            .filter(|s| s.flags & FLAG_VEHICLE_STOPPED != 0 && s.flags & FLAG_STILL != 0)
            .count()
    };
    assert!(stood(&fast) >= N / 3 - 20, "{} of {}", stood(&fast), N / 3);
    let learnt = fast.corrected[2 * N / 3 - 1].drift.map(f64::to_degrees);
    for (d, b) in learnt.iter().zip([0.4, -0.2, 0.1]) {
        assert!((d - b).abs() < 0.01, "{learnt:?}");
    }

    // Never ahead of 10x: each sample is taken no earlier than a tenth of its log time after
    // the first (firm: the pace clock starts after the first sample is taken).
    let (t0, i0) = (fast.taken[0].t_ns, fast.taken[0].ingest_ns);
    for s in &fast.taken[1..] {
        assert!(
            s.ingest_ns - i0 >= (s.t_ns - t0) / 10,
            "seq {} taken {} ns after the first, due {} ns after it",
            s.seq,
            s.ingest_ns - i0,
            (s.t_ns - t0) / 10
        );
    }
    // Well ahead of real time (loose: a loaded machine wakes the replay late, and a late
    // sample is taken at once; at 10x exactly this is 0.1).
    let last = fast.taken.last().unwrap();
    let ratio = (last.ingest_ns - i0) as f64 / (last.t_ns - t0) as f64;
    eprintln!(
        "10x: the log's {:.2} s taken in {:.3} s of wall time, {ratio:.4} of real time ({:.2}x)",
        (last.t_ns - t0) as f64 * 1e-9,
        (last.ingest_ns - i0) as f64 * 1e-9,
        1.0 / ratio
    );
    assert!(ratio < 0.5, "10x took {ratio:.3} of real time");

    // The default deadline is one period of the samples as they come: a tenth at 10x.
    assert_eq!(asap.report["deadline_ns"], 5_000_000);
    assert_eq!(fast.report["deadline_ns"], 500_000);
}

#[test]
fn a_replay_at_pace_1_publishes_what_asap_does_bit_for_bit_in_real_time() {
    const N: usize = 300; // 1.5 s of log
    let asap = replay("asap1", N, "\"asap\"");
    let real = replay("real", N, "1.0");
    assert_same_outputs(&asap.corrected, &real.corrected, "1.0 against asap");
    let (first, last) = (&real.taken[0], real.taken.last().unwrap());
    // Firm, as at 10x: never ahead of real time.
    assert!(last.ingest_ns - first.ingest_ns >= last.t_ns - first.t_ns);
    assert_eq!(real.report["deadline_ns"], 5_000_000);
}
