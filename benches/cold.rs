//! The daemon's denoiser on a cold cache, as at 1 kHz: one push of three axes (db6 / 5 levels /
//! lag 64 / window 1024, `LaneDenoiser<3>` as `denoise.wavelet` runs it) timed back to back
//! (warm), after an 8 MB write that evicts the caches, after a 1 ms sleep, and after a 1 ms
//! sleep followed by `prewarm` (at once, or with another 100 us sleep in between, as
//! `prewarm_us` does; or at once and timed with the push, as a prewarm without a second
//! wake-up would be). The ratios to warm, same run, are the figures docs/performance.md
//! ("Prewarming") quotes. The thread asks for SCHED_FIFO 50 and says whether it got it; pin it
//! with `taskset -c 1 cargo bench --bench cold` to keep the other core's work off it.
//! `DRIFTLESS_COLD_SAMPLES` (default 5000) per sleeping mode.

mod support;

use std::hint::black_box;
use std::time::{Duration, Instant};

use driftless::wavelet::stream::{LaneDenoiser, StreamConfig};

#[derive(Clone, Copy, PartialEq)]
enum Before {
    Nothing,
    Evict,
    Sleep,
    SleepPrewarm,
    SleepPrewarmSleep,
    SleepPrewarmTimed,
}

fn main() {
    println!("thread: {}", support::realtime(50));
    let n: usize = std::env::var("DRIFTLESS_COLD_SAMPLES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000);
    let cfg = StreamConfig {
        lag: 64,
        window: 1024,
        ..StreamConfig::default()
    };
    let mut d = LaneDenoiser::<3>::new(&cfg).expect("valid settings");
    let mut junk = vec![0u8; 8 << 20];
    let mut x = 0.3f64;
    let mut next = move || {
        x = (x * 3.9 * (1.0 - x)).abs();
        [x - 0.5, 0.5 - x, 0.25 * x]
    };
    // Past warm-up, so every push returns a sample.
    for _ in 0..5000 {
        black_box(d.push(next()));
    }
    let modes = [
        ("warm (back to back)", Before::Nothing, 4 * n),
        ("after an 8 MB write", Before::Evict, n),
        ("after a 1 ms sleep", Before::Sleep, n),
        ("after a 1 ms sleep, then prewarm", Before::SleepPrewarm, n),
        (
            "... prewarm, then 100 us sleep",
            Before::SleepPrewarmSleep,
            n,
        ),
        (
            "after a 1 ms sleep, prewarm + push timed",
            Before::SleepPrewarmTimed,
            n,
        ),
    ];
    let mut warm_p50 = 0.0;
    println!("| push of 3 axes | samples | p50 us | p90 us | p50 / warm |");
    println!("|---|---:|---:|---:|---:|");
    // Twice through the modes: the spread between the two rounds is the noise.
    for round in 0..2 {
        for (name, before, count) in modes {
            let mut t = Vec::with_capacity(count);
            for _ in 0..count {
                match before {
                    Before::Nothing => {}
                    Before::Evict => {
                        for b in junk.iter_mut().step_by(64) {
                            *b = b.wrapping_add(1);
                        }
                    }
                    _ => std::thread::sleep(Duration::from_millis(1)),
                }
                if matches!(before, Before::SleepPrewarm | Before::SleepPrewarmSleep) {
                    d.prewarm();
                }
                if before == Before::SleepPrewarmSleep {
                    std::thread::sleep(Duration::from_micros(100));
                }
                let v = next();
                let t0 = Instant::now();
                if before == Before::SleepPrewarmTimed {
                    d.prewarm();
                }
                black_box(d.push(v));
                t.push(t0.elapsed().as_nanos() as f64 / 1e3);
            }
            t.sort_by(f64::total_cmp);
            let (p50, p90) = (t[t.len() / 2], t[t.len() * 9 / 10]);
            if before == Before::Nothing {
                warm_p50 = p50;
            }
            println!(
                "| {name} (round {}) | {count} | {p50:.2} | {p90:.2} | x{:.1} |",
                round + 1,
                p50 / warm_p50
            );
        }
    }
}
