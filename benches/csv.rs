//! CSV input speed: `read_table` on a 10^6-row log as `driftless simulate -o` writes it (a time
//! column and three rate columns, shortest round-trip floats), plain and gzip-compressed, in MB/s
//! of CSV text; the same through the reference path alone (the csv crate and `str::parse::<f64>`
//! on every row, how every file was read before the fast path); and `write_table` of the same
//! columns.
//!
//! `cargo bench --bench csv`. The goal is >= 500 MB/s of plain CSV input on this 2-core
//! machine; gzip input is bound by decompression.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use driftless::io::{read_table, read_table_reference, write_table};
use std::hint::black_box;
use std::path::Path;

const ROWS: usize = 1_000_000;

/// Columns like a simulated ADIS16405 log at 100 Hz: time, then x, y, z in deg/s.
fn columns() -> Vec<Vec<f64>> {
    let mut rng = driftless::synthetic::SplitMix64(7);
    let t: Vec<f64> = (0..ROWS).map(|i| i as f64 / 100.0).collect();
    let mut axis = |bias: f64| -> Vec<f64> {
        (0..ROWS)
            .map(|_| bias + (rng.next().unwrap_or(0.5) - 0.5) * 0.4)
            .collect()
    };
    let (x, y, z) = (axis(0.1), axis(-0.2), axis(0.05));
    vec![t, x, y, z]
}

fn write(path: &Path, cols: &[Vec<f64>]) {
    let names: Vec<String> = ["t_s", "x", "y", "z"].map(String::from).to_vec();
    let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
    write_table(path, &names, &refs).expect("write");
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("tempdir");
    let cols = columns();
    let plain = dir.path().join("log.csv");
    let gz = dir.path().join("log.csv.gz");
    write(&plain, &cols);
    write(&gz, &cols);
    let bytes = std::fs::metadata(&plain).expect("size").len();
    eprintln!(
        "{ROWS} rows, {:.1} MB of CSV ({:.1} MB gzip)",
        bytes as f64 / 1e6,
        std::fs::metadata(&gz).expect("size").len() as f64 / 1e6
    );
    // Same values back, bit for bit (the time column is left out as `allan` does).
    let t = read_table(&plain, &[]).expect("read");
    assert_eq!(t.columns, cols[1..], "read back exactly");
    assert_eq!(read_table_reference(&plain, &[]).expect("read"), t);

    let mut g = c.benchmark_group("csv");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("read_plain_1e6_rows", |b| {
        b.iter(|| read_table(black_box(&plain), &[]).expect("read"))
    });
    g.bench_function("read_plain_1e6_rows_reference_path", |b| {
        b.iter(|| read_table_reference(black_box(&plain), &[]).expect("read"))
    });
    g.bench_function("read_gzip_1e6_rows", |b| {
        b.iter(|| read_table(black_box(&gz), &[]).expect("read"))
    });
    g.bench_function("read_gzip_1e6_rows_reference_path", |b| {
        b.iter(|| read_table_reference(black_box(&gz), &[]).expect("read"))
    });
    let out = dir.path().join("out.csv");
    g.bench_function("write_plain_1e6_rows", |b| b.iter(|| write(&out, &cols)));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
