use driftless::synthetic::{record, Regime, SAMPLES};
use driftless::wavelet::stream::*;
use driftless::wavelet::threshold::ThresholdFn;
fn main() {
    let r = record(Regime::Dynamic, SAMPLES, 1);
    println!("raw {:.2}", driftless::quality::snr_db(&r.truth, &r.measured));
    for f in ["hard","soft","garrote","firm","improved"] {
    for window in [256usize, 1024, 4096, 18000] {
        let mut line = format!("{f:9} w{window:6}");
        for lag in [0usize, 12, 34, 64, 78, 128, 166, 341] {
            let mut d = StreamingDenoiser::new(&StreamConfig { lag, window, threshold: f.parse::<ThresholdFn>().unwrap(), ..Default::default() }).unwrap();
            let mut out: Vec<f64> = r.measured.iter().filter_map(|v| d.push(*v)).collect();
            while let Some(v) = d.flush() { out.push(v); }
            line += &format!(" {lag}:{:.2}", driftless::quality::snr_db(&r.truth, &out));
        }
        println!("{line}");
    }}
}
