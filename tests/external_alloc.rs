//! No heap allocation per sample in the segments of a pipeline with an `external` stage: the
//! segment after it runs on its own thread, so this test binary counts the allocations of the
//! whole process, and of the hot thread and the in-process reference external stage apart (the
//! rest is the later segment's thread and the reporter), for a short and a long run of the same
//! pipeline. Set-up costs the same in both, so any per-sample allocation shows up as a
//! difference of thousands.
//!
//! iceoryx2 0.10's `Publisher::loan_uninit` allocates a small state per loaned sample: that
//! cost is measured on a bare service and allowed per send to a hop someone reads (a hop
//! nobody reads loans nothing).

#[path = "support/alloc_counter.rs"]
mod alloc_counter;
mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use common::{csv, Dir, Prefix};
use driftless::pipeline::config;
use driftless::pipeline::runtime::{run, RunOptions};
use driftless::stages::external::{relay, RelayOptions};
use driftless::transport::Qos;

const BUFFER: usize = 32_768;

fn pipeline(rows: usize, dir: &Dir, name: &str) -> config::Pipeline {
    dir.write(&format!("{name}.csv"), &csv(rows));
    let text = format!(
        r#"
name = "{name}"
rate_hz = 1000.0
report_interval_s = 600.0
[iceoryx2]
buffer_size = {BUFFER}
[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "{name}/raw"
file = "{name}.csv"
pace = "asap"
[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "{name}/raw"
output = "{name}/denoised"
wavelet = "db6"
level = 5
lag = 64
window = 512
[[stage]]
name = "filter"
kind = "external"
input = "{name}/denoised"
output = "{name}/filtered"
[[stage]]
name = "predict"
kind = "predict.none"
input = "{name}/filtered"
output = "{name}/predicted"
[[stage]]
name = "publish"
kind = "publish"
input = "{name}/predicted"
output = "{name}/corrected"
"#
    );
    let file = dir.write(&format!("{name}.toml"), &text);
    config::load(&file).expect("valid pipeline")
}

fn allocations_for(rows: usize, tag: &str) -> Counts {
    let dir = Dir::new();
    let prefix = Prefix::new(tag);
    let p = pipeline(rows, &dir, tag);
    let relay_opts = RelayOptions {
        prefix: prefix.0.clone(),
        input: format!("{tag}/denoised"),
        output: format!("{tag}/filtered"),
        scale: 2.0,
        offset: 0.0,
        count: Some(rows as u64),
        qos: Qos {
            buffer_size: BUFFER,
            ..Qos::default()
        },
        poll_timeout: Duration::from_millis(10),
        delay: Duration::ZERO,
    };
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let relay_stop = Arc::new(AtomicBool::new(false));
    let stop = Arc::clone(&relay_stop);
    let relay_thread = std::thread::spawn(move || {
        let b = alloc_counter::this_thread();
        let relayed = relay(&relay_opts, &stop, || ready_tx.send(()).expect("ready"));
        (relayed, alloc_counter::this_thread() - b)
    });
    ready_rx.recv().expect("relay started");
    let opts = RunOptions {
        duration: None,
        stop: Arc::new(AtomicBool::new(false)),
        print_summary: false,
    };
    let before = alloc_counter::process();
    let before_hot = alloc_counter::this_thread();
    let report = run(&p, &prefix.0, &opts).expect("run");
    let hot = alloc_counter::this_thread() - before_hot;
    relay_stop.store(true, Ordering::Relaxed);
    let (relayed, relay_allocs) = relay_thread.join().expect("relay thread");
    assert_eq!(relayed.expect("relay"), rows as u64);
    let all = alloc_counter::process() - before;
    assert_eq!(report.samples_out, rows as u64, "{}", report.table());
    Counts {
        hot,
        relay: relay_allocs,
        others: all - hot - relay_allocs,
        samples: report.samples_out,
    }
}

/// Allocations during a run, by thread.
#[derive(Debug, Clone, Copy)]
struct Counts {
    /// The hot thread (segment 1).
    hot: u64,
    /// The reference external stage.
    relay: u64,
    /// The later segment's thread and the reporter.
    others: u64,
    samples: u64,
}

#[test]
fn no_segment_allocates_per_sample_across_an_external_stage() {
    let calibration = Prefix::new("xalloccal");
    let per_send = alloc_counter::iceoryx2_allocations_per_send(&calibration.0);
    let short = allocations_for(1_000, "xallocshort");
    let long = allocations_for(21_000, "xalloclong");
    let extra = long.samples - short.samples;
    eprintln!("allocations: {short:?}, {long:?}; iceoryx2: {per_send} per send");
    // Loaning sends per sample, on the hops someone reads: hot thread 1 (denoised, read by
    // the external stage; raw has no reader), relay 1 (filtered, read by the later segment),
    // later segment 0 (nobody reads predicted or corrected).
    for (what, sends, a, b) in [
        ("hot thread", 1, short.hot, long.hot),
        ("external stage", 1, short.relay, long.relay),
        ("later segment and reporter", 0, short.others, long.others),
    ] {
        let more = b.saturating_sub(a);
        // Slack: a quarter of an allocation per sample. Set-up and idle waits allocate a timing-
        // dependent amount (the short run's count swings by ~1,500 on a loaded machine), while
        // a single allocation of ours per sample adds `extra` (20,000) and still fails.
        let allowed = per_send * sends * extra + extra / 4;
        assert!(
            more <= allowed,
            "{what}: {more} more allocations for {extra} more samples \
             (iceoryx2's own loans account for {})",
            per_send * sends * extra
        );
    }
}
