//! No heap allocation per sample when the hot thread sleeps on a sensor driver
//! (`ingest.iceoryx2`: epoll over the driver's listener, the notification drained): a short
//! and a long run of the same pipeline, fed by a driver thread of this test, as in
//! `tests/no_alloc.rs` (a binary of its own, so that no other test's iceoryx2 files change
//! what the runs' set-up and clean-up allocate).

mod common;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use common::{external_pipeline, raw, test_rates, Dir, Prefix};
use driftless::pipeline::config;
use driftless::pipeline::runtime::{run, RunOptions};

#[path = "support/alloc_counter.rs"]
mod alloc_counter;

/// `rows` samples from a sensor driver (a thread of this test, which waits until the daemon
/// subscribes, sends each with a notification and stops the daemon after the last) through
/// `ingest.iceoryx2`: the hot thread sleeps on the driver's listener between samples.
fn driver_allocations_for(rows: usize, tag: &str) -> (u64, u64) {
    use driftless::transport::Transport;
    use driftless::wire::RawSample;
    let dir = Dir::new();
    let prefix = Prefix::new(tag);
    let denoise =
        "kind = \"denoise.wavelet\"\nwavelet = \"db6\"\nlevel = 5\nlag = 64\nwindow = 512";
    let file = dir.write("p.toml", &external_pipeline(tag, denoise, 256));
    let p = config::load(&file).expect("valid pipeline");
    let stop = Arc::new(AtomicBool::new(false));
    let opts = RunOptions {
        duration: None,
        stop: stop.clone(),
        print_summary: false,
    };
    let (driver_prefix, service) = (prefix.0.clone(), format!("{tag}/sensor"));
    let driver = std::thread::spawn(move || {
        let t = Transport::new(&driver_prefix, "driver", common::qos(256)).expect("node");
        let out = t.output::<RawSample>(&service, true).expect("publisher");
        let rates = test_rates(rows);
        let mut i = 0;
        while i < rows {
            // Until the daemon subscribes, nobody takes a sample: send the first again.
            if out
                .send(&raw(i as u64, i as u64 * 1_000_000, rates[i]))
                .expect("send")
                == 1
            {
                out.notify();
                i += 1;
            }
            std::thread::sleep(std::time::Duration::from_micros(50));
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    });
    let (allocations, report) = alloc_counter::allocations_during(|| run(&p, &prefix.0, &opts));
    driver.join().expect("driver");
    let report = report.expect("run");
    assert_eq!(report.samples_out, rows as u64);
    (allocations as u64, report.samples_out)
}

#[test]
fn waiting_on_a_sensor_driver_does_not_allocate_per_sample() {
    const HOPS: u64 = 4;
    let calibration = Prefix::new("alloccaldrv");
    let per_send = alloc_counter::iceoryx2_allocations_per_send(&calibration.0);
    alloc_counter::assert_only_iceoryx2_allocates_per_sample(
        HOPS,
        per_send,
        driver_allocations_for(1_000, "allocdrvshort"),
        driver_allocations_for(31_000, "allocdrvlong"),
        // The set-up allocates 48,400-52,900 times from one run to the next here (the driver
        // and the daemon connect in varying order); one allocation of ours per sample would
        // be 30,000 more.
        8_000,
    );
}
