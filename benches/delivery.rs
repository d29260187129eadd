//! Exactly-once at scale: `pipelines/delivery.toml` (the simulator as fast as possible, 10^6
//! samples through every stage) with this process as a separate-process subscriber that checks
//! every `seq`. `tests/exactly_once.rs` runs the same check on 2 x 10^5 samples.
//!
//! ```text
//! cargo bench --bench delivery
//! ```

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use driftless::transport::{Qos, Transport};
use driftless::wire::GyroSample;
use serde_json::Value;

const N: u64 = 1_000_000;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let prefix = format!("dldeliv{}_", std::process::id());
    let report = std::env::temp_dir().join(format!("{prefix}report.json"));
    let qos = Qos {
        buffer_size: 65_536,
        max_subscribers: 2,
    };
    let me = Transport::new(&prefix, "reader", qos).expect("node");
    let input = me
        .input::<GyroSample>("delivery/corrected")
        .expect("subscriber");
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("run")
        .arg(root.join("pipelines/delivery.toml"))
        .args(["--prefix", &prefix, "--quiet", "--report"])
        .arg(&report)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn driftless");
    let (mut received, mut lost, mut dup, mut reordered) = (0u64, 0u64, 0u64, 0u64);
    let mut last: Option<(u32, u64)> = None;
    let mut first_at = None;
    let deadline = Instant::now() + Duration::from_secs(300);
    while received < N && Instant::now() < deadline {
        match input.receive().expect("receive") {
            Some(s) => {
                first_at.get_or_insert_with(Instant::now);
                received += 1;
                if let Some((epoch, seq)) = last {
                    if epoch != s.epoch {
                        reordered += 1; // one run has one epoch
                    } else if s.seq > seq + 1 {
                        lost += s.seq - seq - 1;
                    } else if s.seq == seq {
                        dup += 1;
                    } else if s.seq < seq {
                        reordered += 1;
                    }
                }
                last = Some((s.epoch, s.seq));
            }
            None => std::hint::spin_loop(),
        }
    }
    let secs = first_at.map_or(f64::NAN, |t| t.elapsed().as_secs_f64());
    let _ = daemon.wait();
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&report).expect("report"))
        .expect("report JSON");
    let _ = std::fs::remove_file(&report);
    let daemon_lost = r["lost"].as_u64().unwrap_or(u64::MAX);
    println!(
        "delivery: {received} of {N} samples received by another process in {secs:.2} s ({:.0} samples/s); \
         lost {lost}, duplicated {dup}, reordered {reordered}; the daemon counted {daemon_lost} lost",
        received as f64 / secs
    );
    let goals = [
        (
            "every sample once, in order",
            received == N && lost + dup + reordered == 0,
        ),
        ("the daemon counted no loss", daemon_lost == 0),
    ];
    for (goal, ok) in goals {
        println!("  goal {goal}: {ok}");
    }
}
