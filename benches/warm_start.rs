//! The warm start (`predict.bias`'s `state_file`) on the real ADIS16405 log with motion added:
//! the heading error over the first minute after a restart, warm and cold, against a run that
//! never stopped. Library code only (the filter's `snapshot` and `resume`, what the stage saves
//! and reads); the file and the daemon are tested in tests/warm_start.rs.
//!
//! ```text
//! DRIFTLESS_ADIS16405=../shared/data/adis16405-imu1-static-100hz.csv.gz cargo bench --bench warm_start
//! ```
//!
//! Each case: 10 minutes of one axis of the static log plus a motion profile
//! (`nav::profiles`, all four, seeds by case) as the truth. The daemon stops at 6 minutes and
//! starts again 30 s later, on the data that follows:
//! - **uninterrupted**: one tracker over all of it;
//! - **warm**: a tracker to the stop, its snapshot resumed 30 s later;
//! - **cold**: a new tracker from the restart.
//!
//! Each is scored over the minute after the restart: the RMS of its heading error (integrated
//! from the restart) and the share of the first second it corrected (a bias removed). Goals
//! (issue 40): warm's first second corrected; its heading error within 10% of uninterrupted's.
//! The datasheet's terms (`profile = "adis16405"`), the gyro-only path (its own detector).

use driftless::drift::bias::{BiasTerms, BiasTracker, TrackerConfig};
use driftless::nav::{generate, heading_metrics, Profile};
use driftless::rate_log::read_log;

const RATE: f64 = 100.0;
const WINDOW_S: f64 = 600.0;
const STOP_S: f64 = 360.0;
const GAP_S: f64 = 30.0;
const SCORED_S: f64 = 60.0;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let Some(path) = std::env::var_os("DRIFTLESS_ADIS16405") else {
        println!("warm_start bench: skipped: DRIFTLESS_ADIS16405 unset (the real log's path)");
        return;
    };
    let log = read_log(std::path::Path::new(&path), &[], None, false).expect("the real log");
    let columns = log.table.columns;
    let n = (WINDOW_S * RATE) as usize;
    let (stop, gap, scored) = (
        (STOP_S * RATE) as usize,
        (GAP_S * RATE) as usize,
        (SCORED_S * RATE) as usize,
    );
    let restart = stop + gap;
    let terms = BiasTerms::profile("adis16405").unwrap();
    let cfg = TrackerConfig::default();
    let windows = columns[0].len() / n;
    let cases = windows.min(16);
    println!(
        "warm_start bench: {cases} cases of {WINDOW_S} s at {RATE} Hz; stop at {STOP_S} s, restart {GAP_S} s later, scored over {SCORED_S} s"
    );
    let (mut ratio_warm, mut ratio_cold) = (Vec::new(), Vec::new());
    let mut first_second = [0usize; 2];
    for case in 0..cases {
        let axis = &columns[case % columns.len()][case * n..(case + 1) * n];
        let profile = Profile::ALL[case % Profile::ALL.len()];
        let motion = generate(profile, RATE, WINDOW_S, case as u64).unwrap();
        let measured: Vec<f64> = axis.iter().zip(&motion.truth).map(|(s, t)| s + t).collect();
        let tracker = || BiasTracker::new(&terms, RATE, &cfg).unwrap();
        let run = |t: &mut BiasTracker, from: usize, to: usize| -> Vec<f64> {
            measured[from..to].iter().map(|&x| t.push(x).bias).collect()
        };

        let mut whole = tracker();
        let biases = run(&mut whole, 0, restart + scored);
        let uninterrupted = &biases[restart..];

        let mut before = tracker();
        run(&mut before, 0, stop);
        let mut warm_t = tracker();
        warm_t.resume(&before.snapshot(), gap as u64).unwrap();
        let warm = run(&mut warm_t, restart, restart + scored);
        let cold = run(&mut tracker(), restart, restart + scored);

        let truth = &motion.truth[restart..restart + scored];
        let x = &measured[restart..restart + scored];
        let rms = |b: &[f64]| {
            let corrected: Vec<f64> = x.iter().zip(b).map(|(x, b)| x - b).collect();
            heading_metrics(&corrected, truth, 1.0 / RATE).rms_deg
        };
        let (u, w, c) = (rms(uninterrupted), rms(&warm), rms(&cold));
        let second = RATE as usize;
        first_second[0] += warm[..second].iter().filter(|b| **b != 0.0).count();
        first_second[1] += cold[..second].iter().filter(|b| **b != 0.0).count();
        println!(
            "  case {case:>2} ({:<13}) RMS heading over the minute: uninterrupted {u:.4} deg, warm {w:.4} deg ({:.2}x), cold {c:.4} deg ({:.2}x)",
            profile.name(),
            w / u,
            c / u
        );
        ratio_warm.push(w / u);
        ratio_cold.push(c / u);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let total = cases * RATE as usize;
    println!(
        "median over {cases} cases: warm {:.3}x uninterrupted (goal <= 1.10x), cold {:.3}x; first second corrected: warm {} of {total} samples, cold {} of {total}",
        median(&mut ratio_warm),
        median(&mut ratio_cold),
        first_second[0],
        first_second[1]
    );
}
