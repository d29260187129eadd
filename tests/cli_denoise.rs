//! `driftless denoise` as a user runs it: the real binary on real files.

mod common;

use common::{driftless, text};

use driftless::io::read_table;
use driftless::wavelet::denoise::{denoise, DenoiseConfig};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn write(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

fn noisy_csv(dir: &Path, rows: usize) -> PathBuf {
    let mut body = String::from("time,gyro_x,gyro_y\n");
    for i in 0..rows {
        let t = i as f64 / 50.0;
        let n = ((i * 7919) % 997) as f64 / 997.0 - 0.5;
        body += &format!("{t},{},{}\n", (t * 0.7).sin() + 0.3 * n, 0.1 - 0.2 * n);
    }
    write(dir, "in.csv", &body)
}

/// Assert a one-line error, exit code 2, and that `needle` is in it.
fn assert_input_error(o: &Output, needle: &str) {
    let (out, err) = text(o);
    assert_eq!(o.status.code(), Some(2), "stdout: {out}\nstderr: {err}");
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn output_round_trips_and_equals_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let input = noisy_csv(dir.path(), 2000);
    let out = dir.path().join("out.csv");
    let o = driftless(&[
        "denoise",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    let written = read_table(&out, &[]).unwrap();
    let original = read_table(&input, &[]).unwrap();
    // The time column is not a signal: left out unless named.
    assert_eq!(written.names, ["gyro_x", "gyro_y"]);
    assert_eq!(original.names, written.names);
    for (k, x) in original.columns.iter().enumerate() {
        let want = denoise(x, &DenoiseConfig::paper()).unwrap().signal;
        assert_eq!(written.columns[k], want, "column {}", written.names[k]);
    }
}

#[test]
fn output_keeps_the_time_column_and_header_and_a_gz_name_is_gzip() {
    let dir = tempfile::tempdir().unwrap();
    let input = noisy_csv(dir.path(), 1000);
    let input_text = std::fs::read_to_string(&input).unwrap();
    let time_in: Vec<&str> = input_text
        .lines()
        .map(|l| l.split(',').next().unwrap())
        .collect();
    for (name, column) in [
        ("out.csv", None),
        ("out.csv.gz", None),
        ("y.csv", Some("gyro_y")),
    ] {
        let out = dir.path().join(name);
        let mut args = vec![
            "denoise",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        if let Some(c) = column {
            args.extend(["--column", c]);
        }
        let o = driftless(&args);
        assert!(o.status.success(), "{name}: {:?}", text(&o));
        let bytes = std::fs::read(&out).unwrap();
        let written = if name.ends_with(".gz") {
            assert_eq!(&bytes[..2], &[0x1f, 0x8b], "{name}: gzip");
            let mut s = String::new();
            std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut s)
                .unwrap();
            s
        } else {
            String::from_utf8(bytes).unwrap()
        };
        let header = written.lines().next().unwrap();
        let want = if column.is_some() {
            "time,gyro_y"
        } else {
            "time,gyro_x,gyro_y"
        };
        assert_eq!(header, want, "{name}");
        let time_out: Vec<&str> = written
            .lines()
            .map(|l| l.split(',').next().unwrap())
            .collect();
        assert_eq!(time_out, time_in, "{name}: the time column unchanged");
        // And it reads back as the denoised signals.
        let back = read_table(&out, &[]).unwrap();
        let want = denoise(
            read_table(&input, &["gyro_y".into()])
                .unwrap()
                .column("gyro_y")
                .unwrap(),
            &DenoiseConfig::paper(),
        )
        .unwrap()
        .signal;
        assert_eq!(back.column("gyro_y").unwrap(), &want[..], "{name}");
    }
}

#[test]
fn selected_columns_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let input = noisy_csv(dir.path(), 1000);
    let o = driftless(&[
        "denoise",
        input.to_str().unwrap(),
        "--column",
        "gyro_y",
        "--units",
        "rad/s",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("sigma (rad/s)"), "{out}");
    assert!(
        out.contains("column gyro_y: 1000 samples, db6 level 5 symmetric"),
        "{out}"
    );
    assert!(!out.contains("gyro_x"), "{out}");
    // One line per level and an RMS line.
    assert_eq!(
        out.lines()
            .filter(|l| l.trim_start().starts_with(char::is_numeric))
            .count(),
        5
    );
    assert!(out.contains("RMS removed"), "{out}");
}

#[test]
fn headerless_input_names_columns_c0_c1() {
    let dir = tempfile::tempdir().unwrap();
    let body: String = (0..800)
        .map(|i| format!("{},{}\n", i % 7, (i % 5) as f64 * 0.5))
        .collect();
    let input = write(dir.path(), "raw.csv", &body);
    let out = dir.path().join("o.csv");
    let o = driftless(&[
        "denoise",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_eq!(read_table(&out, &[]).unwrap().names, ["c0", "c1"]);
}

#[test]
fn compare_on_the_synthetic_benchmark_prints_table_two() {
    let o = driftless(&["denoise", "--synthetic", "dynamic", "--compare"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let snr_of = |f: &str| -> f64 {
        let row = out.lines().find(|l| l.trim_start().starts_with(f)).unwrap();
        row.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    // The synthetic record's input SNR, then every function; every column says its unit.
    assert!((snr_of("raw") - 22.93).abs() < 0.01, "{out}");
    assert!(
        out.contains("MSE ((deg/s)^2)") && out.contains("RMS removed (deg/s)"),
        "{out}"
    );
    assert!(snr_of("improved") > snr_of("soft"), "{out}");
    for f in ["hard", "soft", "garrote", "firm", "improved"] {
        let row = out
            .lines()
            .find(|l| l.trim_start().starts_with(f))
            .unwrap_or_else(|| panic!("no {f} row in {out}"));
        let snr: f64 = row.split_whitespace().nth(1).unwrap().parse().unwrap();
        assert!(snr > 15.0 && snr < 40.0, "{row}");
    }
}

#[test]
fn truth_file_scores_snr() {
    let dir = tempfile::tempdir().unwrap();
    let mut noisy = String::from("x\n");
    let mut truth = String::from("x\n");
    for i in 0..4000 {
        let s = (i as f64 * 0.01).sin();
        let n = ((i * 7919) % 997) as f64 / 997.0 - 0.5;
        noisy += &format!("{}\n", s + 0.2 * n);
        truth += &format!("{s}\n");
    }
    let input = write(dir.path(), "n.csv", &noisy);
    let t = write(dir.path(), "t.csv", &truth);
    let o = driftless(&[
        "denoise",
        input.to_str().unwrap(),
        "--truth",
        t.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("SNR") && out.contains("MSE"), "{out}");
    // A truth of another length is refused.
    let short = write(dir.path(), "s.csv", "x\n1\n2\n");
    let o = driftless(&[
        "denoise",
        input.to_str().unwrap(),
        "--truth",
        short.to_str().unwrap(),
    ]);
    assert_input_error(&o, "2 rows");
}

/// The SVG's texts (`<text ...>CONTENT</text>`) with their anchor (`middle` for titles, axis
/// names and x ticks; `end` for y ticks; `start` for the legend).
fn svg_texts(svg: &str) -> Vec<(String, String)> {
    svg.split("<text ")
        .skip(1)
        .filter_map(|t| {
            let (attrs, rest) = t.split_once('>')?;
            let content = rest.split("</text>").next()?.trim().to_string();
            let anchor = attrs
                .split("text-anchor=\"")
                .nth(1)
                .and_then(|a| a.split('"').next())
                .unwrap_or("start")
                .to_string();
            Some((anchor, content))
        })
        .collect()
}

/// Points of each polyline with more than two (the data; axes and legend marks have two).
fn data_lines(svg: &str) -> Vec<usize> {
    svg.split("<polyline ")
        .skip(1)
        .filter_map(|p| {
            let pts = p.split("points=\"").nth(1)?.split('"').next()?;
            Some(pts.split_whitespace().count())
        })
        .filter(|&n| n > 2)
        .collect()
}

/// The numbers on the x axis (middle-anchored numeric texts).
fn x_ticks(texts: &[(String, String)]) -> Vec<f64> {
    texts
        .iter()
        .filter(|(a, _)| a == "middle")
        .filter_map(|(_, c)| c.parse::<f64>().ok())
        .collect()
}

fn plot(args: &[&str]) -> (Output, String) {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("fig6.svg");
    let mut all = vec!["denoise"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--plot", svg.to_str().unwrap()]);
    let o = driftless(&all);
    let body = std::fs::read_to_string(&svg).unwrap_or_default();
    (o, body)
}

#[test]
fn the_figure_shows_a_window_of_each_function_its_error_units_and_legend() {
    let (o, svg) = plot(&[
        "--synthetic",
        "dynamic",
        "--compare",
        "--plot-from",
        "10s",
        "--plot-window",
        "2s",
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert!(svg.starts_with("<svg"), "{}", &svg[..200.min(svg.len())]);
    let texts = svg_texts(&svg);
    let has = |s: &str| texts.iter().any(|(_, c)| c == s);
    for want in [
        "rate (deg/s)",
        "error (deg/s)",
        "time (s)",
        "raw",
        "truth",
        "raw - truth",
    ] {
        assert!(has(want), "no {want:?} in {texts:?}");
    }
    for f in ["hard", "soft", "garrote", "firm", "improved"] {
        assert!(has(f), "no legend entry {f}");
        assert!(has(&format!("{f} - truth")), "no error legend for {f}");
        assert!(
            texts
                .iter()
                .any(|(_, c)| c.starts_with(&format!("rate: {f} threshold, SNR "))),
            "no title for {f}"
        );
    }
    // 2 s at 50 Hz: 100 samples in each of the 5 x (3 signal + 2 error) lines, nothing else.
    assert_eq!(data_lines(&svg), vec![100; 25]);
    let ticks = x_ticks(&texts);
    assert!(!ticks.is_empty());
    assert!(
        ticks.iter().all(|t| (10.0..=12.0).contains(t)),
        "x ticks outside the window: {ticks:?}"
    );

    // The default window: the first 5 s.
    let (o, svg) = plot(&["--synthetic", "static"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_eq!(data_lines(&svg), vec![250; 5]);
    let ticks = x_ticks(&svg_texts(&svg));
    assert!(ticks.iter().all(|t| (0.0..=5.0).contains(t)), "{ticks:?}");
}

#[test]
fn a_log_is_plotted_on_its_time_column_in_its_units_and_bad_windows_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = noisy_csv(dir.path(), 1000); // `time` at 50 Hz: 20 s
    let input = input.to_str().unwrap();
    let (o, svg) = plot(&[
        input,
        "--column",
        "gyro_x",
        "--units",
        "rad/s",
        "--plot-from",
        "3s",
        "--plot-window",
        "1s",
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    let texts = svg_texts(&svg);
    assert!(
        texts.iter().any(|(_, c)| c == "gyro_x (rad/s)"),
        "{texts:?}"
    );
    assert!(
        !texts.iter().any(|(_, c)| c.contains("error")),
        "no truth, no error panel"
    );
    assert_eq!(data_lines(&svg), vec![50, 50]);
    assert!(x_ticks(&texts).iter().all(|t| (3.0..=4.0).contains(t)));

    let (o, svg) = plot(&[input, "--plot-from", "30s"]);
    assert_input_error(&o, "the record spans 0 to 19.98 s, no sample to plot");
    assert!(svg.is_empty(), "no figure written");
    let (o, _) = plot(&[input, "--units", "furlongs"]);
    assert_input_error(&o, "--units: unknown rate unit 'furlongs'");
    // Without a time column the window needs --rate.
    let bare = write(
        dir.path(),
        "bare.csv",
        &format!("x\n{}", "1\n2\n3\n".repeat(40)),
    );
    let bare = bare.to_str().unwrap();
    let (o, _) = plot(&[bare, "--level", "2", "--plot-window", "1s"]);
    assert_input_error(&o, "need a time axis: give --rate HZ");
    let (o, svg) = plot(&[bare, "--level", "2", "--rate", "10", "--plot-window", "1s"]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert_eq!(data_lines(&svg), vec![10, 10]);
    // A window without a plot is a usage error.
    let o = driftless(&["denoise", input, "--plot-window", "1s"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn bad_input_is_refused_with_position_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("never.csv");
    let o_arg = out.to_str().unwrap();
    let good = noisy_csv(d, 1000);
    let good = good.to_str().unwrap();
    let cases: Vec<(Vec<String>, String)> = vec![
        (
            vec![d.join("missing.csv").display().to_string()],
            "missing.csv".into(),
        ),
        (
            vec![write(d, "empty.csv", "").display().to_string()],
            "the file is empty".into(),
        ),
        (
            vec![good.into(), "--column".into(), "gyro_q".into()],
            "no column named 'gyro_q' (columns: time, gyro_x, gyro_y)".into(),
        ),
        (
            vec![write(d, "cell.csv", "a,b\n1,2\n3,x2\n")
                .display()
                .to_string()],
            "cell.csv:3:3: column 'b': 'x2' is not a number".into(),
        ),
        (
            vec![write(d, "nan.csv", "a\n1\nNaN\n").display().to_string()],
            "nan.csv:3:1: column 'a': NaN is not a finite sample".into(),
        ),
        (
            vec![write(d, "short.csv", "a\n1\n2\n3\n").display().to_string()],
            "level 5 with db6 needs at least 352 samples, got 3".into(),
        ),
        (
            vec![good.into(), "--wavelet".into(), "db42".into()],
            "db1..db20".into(),
        ),
        (
            vec![good.into(), "--mode".into(), "mirror".into()],
            "symmetric, reflect".into(),
        ),
        (
            vec![good.into(), "--threshold".into(), "medium".into()],
            "hard, soft, garrote, firm, improved".into(),
        ),
        (
            vec![good.into(), "--rule".into(), "minimax".into()],
            "universal, level-universal, sure, bayes".into(),
        ),
        (
            vec![good.into(), "--sigma=-1".into()],
            "mad, mad-per-level".into(),
        ),
        (
            vec![good.into(), "--beta".into(), "0".into()],
            "beta".into(),
        ),
        (
            vec![good.into(), "--level".into(), "0".into()],
            "level".into(),
        ),
    ];
    for (mut args, needle) in cases {
        args.insert(0, "denoise".into());
        args.extend(["-o".to_string(), o_arg.to_string()]);
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = driftless(&refs);
        assert_input_error(&o, &needle);
        assert_eq!(text(&o).1.lines().count(), 1, "one line: {}", text(&o).1);
        assert!(!out.exists(), "partial output after {args:?}");
    }
    // An unwritable destination: an error, and nothing left behind.
    let nowhere = d.join("no/such/dir/out.csv");
    let o = driftless(&["denoise", good, "-o", nowhere.to_str().unwrap()]);
    assert_ne!(o.status.code(), Some(0));
    assert!(!nowhere.exists());
    assert_eq!(
        std::fs::read_dir(d)
            .unwrap()
            .filter(|e| e
                .as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x != "csv"))
            .count(),
        0
    );
}

#[test]
fn a_closed_stdout_is_not_a_panic() {
    use std::io::Read;
    let mut child = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .args([
            "denoise",
            "--synthetic",
            "dynamic",
            "--compare",
            "--samples",
            "400000",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    child.wait().unwrap();
    assert!(!err.contains("panicked"), "{err}");
}
