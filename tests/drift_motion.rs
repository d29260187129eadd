//! The live compensator on synthetic motion plus drift, scored against the simulator's truth:
//! it must beat the raw and the denoised-only rate in RMS error and in mean bias, and must not
//! eat a 60 s constant-rate turn.

use driftless::drift::compensator::{Compensator, Mode};
use driftless::drift::model::{DenoiseSettings, LowbandSettings};
use driftless::drift::separation::{separate_causal, stream_config};
use driftless::drift::stillness::StillnessConfig;
use driftless::drift::training::{train, TrainConfig};
use driftless::drift::LowBand;
use driftless::sim::{Motion, NoiseTerms, SimConfig, Simulator};
use driftless::wavelet::stream::StreamingDenoiser;

const RATE: f64 = 100.0;

/// A MEMS gyro with a large turn-on bias (what compensation is for) and realistic noise.
fn sensor(seed: u64) -> SimConfig {
    SimConfig {
        terms: NoiseTerms {
            q: 0.0,
            n: 0.005,
            b: 0.005,
            k: 2e-4,
            r: 0.0,
            bias: 0.5,
        },
        rate_hz: RATE,
        axes: 1,
        seed,
        motion: Motion::None,
        lsb: None,
    }
}

fn record(seed: u64, n: usize, truth: impl Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>) {
    let mut sim = Simulator::new(&sensor(seed)).unwrap();
    (0..n)
        .map(|_| {
            let s = sim.next_sample();
            let t = truth(s.t);
            (s.measured[0] + t, t)
        })
        .unzip()
}

fn denoise() -> DenoiseSettings {
    DenoiseSettings {
        wavelet: "db6".into(),
        level: 5,
        threshold: "improved".into(),
        window: 1024,
        lag: 33,
    }
}

fn lowband() -> LowbandSettings {
    LowbandSettings {
        wavelet: "db6".into(),
        level: 5,
    }
}

/// The scenario: still 60 s, the simulator's turn profile (90 deg turns, raised-cosine rate)
/// for 240 s, still 30 s, a constant 10 deg/s turn for 60 s, still 30 s.
fn truth(t: f64) -> f64 {
    if (60.0..300.0).contains(&t) {
        Motion::Turn.rate(0, 1, t - 60.0)
    } else if (330.0..390.0).contains(&t) {
        10.0
    } else {
        0.0
    }
}

fn rms_and_bias(e: &[f64]) -> (f64, f64) {
    let n = e.len() as f64;
    (
        (e.iter().map(|v| v * v).sum::<f64>() / n).sqrt(),
        e.iter().sum::<f64>() / n,
    )
}

struct Run {
    raw: Vec<f64>,
    truth: Vec<f64>,
    denoised: Vec<f64>,
    steps: Vec<driftless::drift::compensator::Step>,
}

/// Train on a static log, then run the denoiser and compensator live over the scenario;
/// `loosen` multiplies the stillness thresholds (a huge value: a detector that never sees motion).
fn run(loosen: f64) -> Run {
    // Train on a static log of the same sensor model (another seed: another turn-on state).
    let (still, _) = record(1, 60_000, |_| 0.0);
    let sep = separate_causal(&still, &denoise(), &lowband()).unwrap();
    let w = sep.warm_up;
    let model = train(&sep.drift[w..], &TrainConfig::default(), &mut |_| {}).unwrap();
    let lb = LowBand::new("db6", 5).unwrap();
    let mut stillness = StillnessConfig::calibrate(&sep.denoised, &sep.drift, 50, lb.span(), 1.5);
    stillness.var_enter *= loosen;
    stillness.var_exit *= loosen;
    stillness.mean_enter *= loosen;
    stillness.mean_exit *= loosen;
    let max_step = 2.0
        * sep.drift[w..]
            .windows(2)
            .map(|d| (d[1] - d[0]).abs())
            .fold(0.0, f64::max);

    // Live: streaming denoiser, then the compensator, sample by sample.
    let n = (420.0 * RATE) as usize;
    let (raw, truth) = record(2, n, truth);
    let mut den = StreamingDenoiser::new(&stream_config(&denoise()).unwrap()).unwrap();
    let mut comp = Compensator::new(&model, lb, stillness, max_step).unwrap();
    let mut denoised = Vec::with_capacity(n);
    for &x in &raw {
        if let Some(y) = den.push(x) {
            denoised.push(y);
        }
    }
    while let Some(y) = den.flush() {
        denoised.push(y);
    }
    let steps: Vec<_> = denoised.iter().map(|&x| comp.push(x)).collect();
    Run {
        raw,
        truth,
        denoised,
        steps,
    }
}

/// Mean error of the compensated rate over the last 50 s of the constant turn.
fn constant_turn_error(r: &Run) -> f64 {
    let c: Vec<f64> = ((340.0 * RATE) as usize..(390.0 * RATE) as usize)
        .map(|t| r.steps[t].rate - r.truth[t])
        .collect();
    rms_and_bias(&c).1
}

#[test]
fn compensation_beats_raw_and_denoised_and_keeps_a_constant_turn() {
    let r = run(1.0);
    let (raw, truth, denoised, steps) = (&r.raw, &r.truth, &r.denoised, &r.steps);
    let n = raw.len();

    // Scored after the first 30 s (warm-up).
    let s0 = (30.0 * RATE) as usize;
    let err = |y: &dyn Fn(usize) -> f64| -> Vec<f64> { (s0..n).map(|t| y(t) - truth[t]).collect() };
    let (raw_rms, raw_bias) = rms_and_bias(&err(&|t| raw[t]));
    let (den_rms, den_bias) = rms_and_bias(&err(&|t| denoised[t]));
    let (comp_rms, comp_bias) = rms_and_bias(&err(&|t| steps[t].rate));
    println!("error vs truth, RMS / mean bias (deg/s):");
    println!("  raw          {raw_rms:.4} / {raw_bias:+.4}");
    println!("  denoised     {den_rms:.4} / {den_bias:+.4}");
    println!("  compensated  {comp_rms:.4} / {comp_bias:+.4}");
    assert!(comp_rms < raw_rms && comp_rms < den_rms, "RMS not lower");
    assert!(
        comp_bias.abs() < raw_bias.abs() && comp_bias.abs() < den_bias.abs(),
        "bias not lower"
    );
    assert!(
        comp_bias.abs() < 0.1 * raw_bias.abs(),
        "bias barely reduced"
    );

    // Every turn sample is flagged moving; none of the still stretch after warm-up is a turn.
    let moving_in_turns = (0..n)
        .filter(|&t| truth[t].abs() > 1.0)
        .all(|t| steps[t].mode == Mode::Moving);
    assert!(moving_in_turns, "a turn sample was judged still");
    assert!(steps[(55.0 * RATE) as usize].mode == Mode::Still);
    assert!(
        steps[(325.0 * RATE) as usize].mode == Mode::Still,
        "never re-anchored"
    );

    // The 60 s constant-rate turn is kept: over its last 50 s the compensated rate stays within
    // 0.05 deg/s of the truth on average (eating it would pull it towards 0).
    let turn_bias = constant_turn_error(&r);
    println!("constant turn: mean error {turn_bias:+.4} deg/s over its last 50 s");
    assert!(turn_bias.abs() < 0.05, "constant turn eaten: {turn_bias}");
}

/// The control: the same chain with a detector that never sees motion anchors on the turn and
/// eats it, so the test above can fail.
#[test]
fn a_compensator_that_always_anchors_eats_the_constant_turn() {
    let r = run(1e9);
    let e = constant_turn_error(&r);
    println!("always anchored: constant-turn mean error {e:+.3} deg/s");
    assert!(e < -5.0, "the control did not eat the turn: {e}");
}
