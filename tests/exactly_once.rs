//! Exactly-once delivery to another process at full speed: the daemon runs the simulator as fast
//! as possible through every stage, and this test process, subscribed before the first sample,
//! checks every `seq` (none lost, duplicated or reordered) and the daemon's own count of losses.
//! `cargo bench --bench delivery` runs the same check on 10^6 samples.

mod common;

use std::time::Duration;

use common::{collect, finish, qos, report, start, Dir, Prefix};
use driftless::transport::Transport;
use driftless::wire::GyroSample;

const N: usize = 200_000;
const BUFFER: usize = 65_536;

#[test]
fn a_flat_out_run_reaches_another_process_exactly_once_in_order() {
    let prefix = Prefix::new("once");
    let dir = Dir::new();
    let pipeline = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/delivery.toml"),
    )
    .expect("pipelines/delivery.toml")
    .replace("samples = 1000000", &format!("samples = {N}"));
    assert!(pipeline.contains(&format!("samples = {N}")));
    assert!(pipeline.contains(&format!("buffer_size = {BUFFER}")));
    let file = dir.write("p.toml", &pipeline);
    let report_path = dir.path("report.json");

    let me = Transport::new(&prefix.0, "reader", qos(BUFFER)).expect("node");
    let corrected = me
        .input::<GyroSample>("delivery/corrected")
        .expect("subscriber");
    let child = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    let got = collect(&corrected, N, Duration::from_secs(120));
    let (code, err) = finish(child, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");

    let epoch = got.first().map(|s| s.epoch).expect("samples");
    let (mut lost, mut dup, mut reordered) = (0u64, 0u64, 0u64);
    for w in got.windows(2) {
        assert_eq!(w[1].epoch, epoch, "one run, one epoch");
        match w[1].seq.cmp(&(w[0].seq + 1)) {
            std::cmp::Ordering::Greater => lost += w[1].seq - w[0].seq - 1,
            std::cmp::Ordering::Less if w[1].seq == w[0].seq => dup += 1,
            std::cmp::Ordering::Less => reordered += 1,
            std::cmp::Ordering::Equal => {}
        }
    }
    assert_eq!((lost, dup, reordered), (0, 0, 0));
    assert_eq!(got.len(), N, "every sample");
    assert_eq!(got[0].seq, 0);
    assert_eq!(got[N - 1].seq, N as u64 - 1);
    let r = report(&dir);
    assert_eq!(r["samples_out"], N as u64);
    assert_eq!(r["lost"], 0, "the daemon counted no loss either");
}
