//! Prints docs/denoise.md's table: SNR of the streaming denoiser against its lag, on the
//! dynamic and static synthetic benchmarks, beside the batch denoiser of the whole record.
//!
//! `cargo run --release --example lag_table`

use driftless::quality::snr_db;
use driftless::synthetic::{record, Regime, SAMPLES};
use driftless::wavelet::denoise::{denoise, DenoiseConfig};
use driftless::wavelet::stream::{StreamConfig, StreamingDenoiser};
use driftless::wavelet::threshold::ThresholdFn;

const LAGS: [usize; 11] = [0, 5, 11, 22, 33, 50, 77, 110, 165, 240, 341];

fn main() {
    let seed = 1;
    for regime in [Regime::Dynamic, Regime::Static] {
        let r = record(regime, SAMPLES, seed);
        println!(
            "\n{} regime (seed {seed}, {SAMPLES} samples at 50 Hz; raw SNR {:.2} dB)\n",
            regime.name(),
            snr_db(&r.truth, &r.measured)
        );
        let mut header = String::from("| function | batch |");
        let mut rule = String::from("|---|---:|");
        for lag in LAGS {
            header += &format!(" lag {lag} |");
            rule += "---:|";
        }
        println!("{header}\n{rule}");
        for name in ThresholdFn::NAMES {
            let threshold: ThresholdFn = name.parse().expect("a known name");
            let batch = denoise(
                &r.measured,
                &DenoiseConfig {
                    threshold,
                    ..DenoiseConfig::paper()
                },
            )
            .expect("valid settings");
            let mut line = format!("| {name} | {:.2} |", snr_db(&r.truth, &batch.signal));
            for lag in LAGS {
                let mut d = StreamingDenoiser::new(&StreamConfig {
                    lag,
                    threshold,
                    ..StreamConfig::default()
                })
                .expect("valid settings");
                let mut out: Vec<f64> = r.measured.iter().filter_map(|v| d.push(*v)).collect();
                out.extend(std::iter::from_fn(|| d.flush()));
                line += &format!(" {:.2} |", snr_db(&r.truth, &out));
            }
            println!("{line}");
        }
    }
}
