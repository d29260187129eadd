//! `driftless simulate`: a gyro log with known IEEE Std 952 noise terms (and optional true motion).

use super::duration::parse_duration;
use super::CliError;
use crate::io::atomic::write_text_atomically;
use crate::io::progress;
use crate::sim::{Motion, NoiseTerms, SimConfig, Simulator};
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `driftless simulate`. Terms are in the units `driftless allan` prints.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A named sensor: adxrs450 (50 Hz, 1 axis) or adis16405 (100 Hz, 3 axes).
    #[arg(long, conflicts_with_all = ["n", "b", "k", "q", "r"])]
    pub profile: Option<String>,
    /// Angle random walk N, deg/sqrt(h).
    #[arg(
        long = "N",
        id = "n",
        value_name = "DEG/SQRT(H)",
        allow_hyphen_values = true
    )]
    pub n: Option<String>,
    /// Bias instability B, deg/h.
    #[arg(long = "B", id = "b", value_name = "DEG/H", allow_hyphen_values = true)]
    pub b: Option<String>,
    /// Rate random walk K, deg/h/sqrt(h).
    #[arg(
        long = "K",
        id = "k",
        value_name = "DEG/H/SQRT(H)",
        allow_hyphen_values = true
    )]
    pub k: Option<String>,
    /// Quantisation noise Q, deg.
    #[arg(long = "Q", id = "q", value_name = "DEG", allow_hyphen_values = true)]
    pub q: Option<String>,
    /// Rate ramp R, deg/h^2.
    #[arg(
        long = "R",
        id = "r",
        value_name = "DEG/H^2",
        allow_hyphen_values = true
    )]
    pub r: Option<String>,
    /// Sample rate in Hz (default: the profile's, else 100).
    #[arg(long, allow_hyphen_values = true)]
    pub rate: Option<String>,
    /// Length: "3h", "90min", "500ms", "1.5s", or seconds.
    #[arg(
        long,
        default_value = "3h",
        value_parser = parse_duration,
        allow_hyphen_values = true
    )]
    pub duration: Duration,
    /// Axes, 1 to 3 (default: the profile's, else 1).
    #[arg(long)]
    pub axes: Option<usize>,
    /// Seed of the random stream.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// True motion: none, sines, steps, turn, stop-and-go.
    #[arg(long, default_value = "none")]
    pub motion: String,
    /// Output CSV (gzip-compressed if the name ends in .gz).
    #[arg(short = 'o', long = "output", value_name = "OUT.csv")]
    pub output: PathBuf,
}

/// A number given for `flag`, or a one-line input error.
pub fn parse_number(flag: &str, s: &str) -> Result<f64, CliError> {
    s.trim()
        .parse::<f64>()
        .map_err(|_| CliError::input(format!("{flag} '{s}' is not a number")))
}

fn parse_opt(flag: &str, s: &Option<String>) -> Result<Option<f64>, CliError> {
    s.as_deref().map(|v| parse_number(flag, v)).transpose()
}

const AXIS: [&str; 3] = ["x", "y", "z"];

/// Run `driftless simulate`.
pub fn run(args: Args) -> Result<(), CliError> {
    let (n, b, k, q, r) = (
        parse_opt("--N", &args.n)?,
        parse_opt("--B", &args.b)?,
        parse_opt("--K", &args.k)?,
        parse_opt("--Q", &args.q)?,
        parse_opt("--R", &args.r)?,
    );
    for (flag, v) in [("--N", n), ("--B", b), ("--K", k), ("--Q", q), ("--R", r)] {
        if let Some(v) = v {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CliError::input(format!(
                    "{flag} must be a finite number >= 0, not {v}"
                )));
            }
        }
    }
    let mut cfg = match &args.profile {
        Some(p) => SimConfig::profile(p).map_err(|e| CliError::input(e.to_string()))?,
        None => {
            if [args.n, args.b, args.k, args.q, args.r]
                .iter()
                .all(Option::is_none)
            {
                return Err(CliError::input(
                    "give --profile NAME or at least one of --N --B --K --Q --R",
                ));
            }
            let g = |v: Option<f64>| v.unwrap_or(0.0);
            SimConfig {
                terms: NoiseTerms {
                    n: g(n) / 60.0,
                    b: g(b) / 3600.0,
                    k: g(k) / 216_000.0,
                    q: g(q),
                    r: g(r) / (3600.0 * 3600.0),
                    bias: 0.0,
                },
                rate_hz: 100.0,
                axes: 1,
                seed: 0,
                motion: Motion::None,
                lsb: None,
            }
        }
    };
    if let Some(rate) = parse_opt("--rate", &args.rate)? {
        cfg.rate_hz = rate;
    }
    if let Some(a) = args.axes {
        cfg.axes = a;
    }
    cfg.seed = args.seed;
    cfg.motion = args
        .motion
        .parse()
        .map_err(|e: crate::sim::SimError| CliError::input(e.to_string()))?;
    let duration = args.duration.as_secs_f64();
    let mut sim = Simulator::new(&cfg).map_err(|e| CliError::input(e.to_string()))?;
    let samples = (duration * cfg.rate_hz).round().max(1.0) as u64;

    let out = &args.output;
    let io_err = |e: std::io::Error| CliError::input(format!("{}: {e}", out.display()));
    // A name ending in .gz is written gzip-compressed, as `allan` and the others read it.
    write_text_atomically(out, |w| {
        let truth = cfg.motion != Motion::None;
        let mut header = vec!["t_s".to_string()];
        header.extend((0..cfg.axes).map(|a| format!("gyro_{}_degps", AXIS[a])));
        if truth {
            header.extend((0..cfg.axes).map(|a| format!("truth_{}_degps", AXIS[a])));
        }
        writeln!(w, "{}", header.join(","))?;
        let bar = progress::bar(samples, 2_000_000, "simulating");
        let mut line = String::new();
        for k in 0..samples {
            let s = sim.next_sample();
            line.clear();
            use std::fmt::Write as _;
            let _ = write!(line, "{}", s.t);
            for v in &s.measured[..cfg.axes] {
                let _ = write!(line, ",{v}");
            }
            if truth {
                for v in &s.truth[..cfg.axes] {
                    let _ = write!(line, ",{v}");
                }
            }
            line.push('\n');
            w.write_all(line.as_bytes())?;
            if k % 65_536 == 0 {
                bar.set_position(k);
            }
        }
        bar.finish_and_clear();
        Ok(())
    })
    .map_err(io_err)?;
    eprintln!(
        "driftless: wrote {} samples x {} axes at {} Hz ({} s) to {}",
        samples,
        cfg.axes,
        cfg.rate_hz,
        samples as f64 / cfg.rate_hz,
        out.display()
    );
    Ok(())
}
