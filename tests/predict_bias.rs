//! `predict.bias` through the daemon's own stage code ([`Offline`]) on the simulator, whose truth
//! is known: it removes the bias (heading far better than raw, on a par with oracle-stop ZARU),
//! never takes real motion for a stop, and its flags say what is true at every sample.

mod common;

use common::Dir;
use driftless::nav::baselines::{BiasEstimator, Zaru};
use driftless::pipeline::config;
use driftless::pipeline::offline::Offline;
use driftless::sim::{Motion, SimConfig, Simulator};
use driftless::transport::{GyroSample, RawSample, FLAG_MOVING, FLAG_STILL, FLAG_WARMING_UP};

const RATE: f64 = 100.0;

/// The detector's latency at the slow start of a motion, s.
const ONSET_S: f64 = 1.0;

fn pipeline(dir: &Dir, denoise: &str) -> config::Pipeline {
    let text = format!(
        r#"
name = "pb"
rate_hz = {RATE}
axes = 3
input_units = "deg/s"

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "pb/raw"

[[stage]]
name = "denoise"
input = "pb/raw"
output = "pb/denoised"
{denoise}

[[stage]]
name = "predict"
kind = "predict.bias"
input = "pb/denoised"
output = "pb/predicted"
profile = "adis16405"

[[stage]]
name = "publish"
kind = "publish"
input = "pb/predicted"
output = "pb/corrected"
"#
    );
    config::load(&dir.write("p.toml", &text)).expect("valid pipeline")
}

/// `n` samples of a simulated ADIS16405 with `motion`, through the pipeline: (raw, published).
fn run(
    p: &config::Pipeline,
    motion: Motion,
    seed: u64,
    n: usize,
) -> (Vec<[f64; 6]>, Vec<GyroSample>) {
    let mut cfg = SimConfig::profile("adis16405").unwrap();
    cfg.rate_hz = RATE;
    cfg.axes = 3;
    cfg.seed = seed;
    cfg.motion = motion;
    let mut sim = Simulator::new(&cfg).unwrap();
    let mut off = Offline::new(p).expect("offline");
    let (mut raw, mut out) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let s = sim.next_sample();
        let r = RawSample {
            t_ns: (i as f64 * 1e9 / RATE).round() as u64,
            seq: i as u64,
            rate: s.measured,
            flags: 0,
            epoch: 0,
        };
        let [m0, m1, m2] = s.measured;
        let [t0, t1, t2] = s.truth;
        raw.push([m0, m1, m2, t0, t1, t2]);
        off.push(&r, &mut |g| out.push(g));
    }
    off.finish(&mut |g| out.push(g));
    assert_eq!(out.len(), n, "every sample published");
    (raw, out)
}

/// RMS over time of the integrated error, deg.
fn rms_heading(err: impl Iterator<Item = f64>) -> f64 {
    let (mut h, mut sum, mut n) = (0.0, 0.0, 0usize);
    for e in err {
        h += e / RATE;
        sum += h * h;
        n += 1;
    }
    (sum / n as f64).sqrt()
}

#[test]
fn it_removes_the_bias_and_never_the_motion() {
    let dir = Dir::new();
    let p = pipeline(&dir, "kind = \"denoise.none\"");
    let motion = Motion::StopAndGo;
    let n = (20.0 * 60.0 * RATE) as usize;
    let mut ratios = Vec::new();
    for seed in [1, 2] {
        let (raw, out) = run(&p, motion, seed, n);
        for axis in 0..3 {
            let raw_rms = rms_heading(raw.iter().map(|r| r[axis] - r[3 + axis]));
            let ours = rms_heading(
                out.iter()
                    .zip(&raw)
                    .map(|(g, r)| g.rate[axis].to_degrees() - r[3 + axis]),
            );
            // The reference a navigator already has: the mean of each true stop, held.
            let mut zaru = Zaru::oracle(RATE as usize);
            let zaru_rms = rms_heading(raw.iter().enumerate().map(|(k, r)| {
                let still = motion.is_still(k as f64 / RATE);
                r[axis] - zaru.push(r[axis], still) - r[3 + axis]
            }));
            assert!(
                ours < raw_rms / 20.0,
                "seed {seed} axis {axis}: {ours} deg against raw {raw_rms}"
            );
            ratios.push(ours / zaru_rms);
        }
        let mut still_when_moving = 0;
        let (mut settled_still, mut settled_still_flagged) = (0, 0);
        for (k, g) in out.iter().enumerate() {
            let t = k as f64 / RATE;
            let truly_still = motion.is_still(t);
            // A detector sees an onset some samples late (the ramp starts from 0): those are
            // flagged still but never enter the filter (the delay window). Later is an error.
            if !truly_still && g.flags & FLAG_STILL != 0 && !motion.is_still(t - ONSET_S) {
                still_when_moving += 1;
            }
            // Well inside a stop (3 s after it began, before it ends).
            if (0..=3).all(|d| motion.is_still(t - d as f64)) && motion.is_still(t + 0.1) {
                settled_still += 1;
                settled_still_flagged += usize::from(g.flags & FLAG_STILL != 0);
            }
            assert!(
                g.flags & (FLAG_STILL | FLAG_MOVING) != FLAG_STILL | FLAG_MOVING,
                "sample {k}: still and moving at once"
            );
        }
        assert_eq!(still_when_moving, 0, "seed {seed}: motion taken for a stop");
        assert!(
            settled_still_flagged as f64 > 0.95 * settled_still as f64,
            "seed {seed}: {settled_still_flagged} of {settled_still} still samples flagged still"
        );
        // After the first stop there is always something to go on.
        assert!(out[(70.0 * RATE) as usize..]
            .iter()
            .all(|g| g.flags & FLAG_WARMING_UP == 0));
    }
    // One 20-minute heading is a lottery of a few stops: judge the median of six, and bound the
    // worst (measured: 0.70 to 0.88, and 2.04 on one axis).
    ratios.sort_by(f64::total_cmp);
    let median = (ratios[2] + ratios[3]) / 2.0;
    assert!(median < 1.0, "RMS heading / oracle ZARU: {ratios:?}");
    assert!(ratios[5] < 3.0, "RMS heading / oracle ZARU: {ratios:?}");
}

#[test]
fn moving_before_the_first_stop_is_moving_and_nothing_is_subtracted() {
    let dir = Dir::new();
    let p = pipeline(&dir, "kind = \"denoise.none\"");
    let (_, out) = run(&p, Motion::Sines, 3, (30.0 * RATE) as usize);
    // The detector's first window (1 s) cannot tell: warming only.
    assert_eq!(
        out[0].flags & (FLAG_WARMING_UP | FLAG_MOVING),
        FLAG_WARMING_UP
    );
    for g in &out[(1.5 * RATE) as usize..] {
        assert_eq!(
            g.flags & (FLAG_WARMING_UP | FLAG_MOVING | FLAG_STILL),
            FLAG_WARMING_UP | FLAG_MOVING,
            "sample {}",
            g.seq
        );
        assert_eq!(g.drift, [0.0; 3]);
        assert_eq!(g.rate, g.denoised);
    }
}

#[test]
fn after_the_wavelet_denoiser_it_still_wins() {
    let dir = Dir::new();
    let p = pipeline(&dir, "kind = \"denoise.wavelet\"\nlag = 32");
    let motion = Motion::StopAndGo;
    let (raw, out) = run(&p, motion, 4, (10.0 * 60.0 * RATE) as usize);
    for axis in 0..3 {
        let raw_rms = rms_heading(raw.iter().map(|r| r[axis] - r[3 + axis]));
        // Published samples carry their own seq: compare each with its own truth.
        let ours = rms_heading(
            out.iter()
                .map(|g| g.rate[axis].to_degrees() - raw[g.seq as usize][3 + axis]),
        );
        assert!(
            ours < raw_rms / 20.0,
            "axis {axis}: {ours} vs raw {raw_rms}"
        );
    }
    assert!(out.iter().all(|g| {
        let t = g.seq as f64 / RATE;
        g.flags & FLAG_STILL == 0 || motion.is_still(t) || motion.is_still(t - ONSET_S)
    }));
}
