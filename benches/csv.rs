//! CSV input speed: `read_table` on a 10^6-row log as `driftless simulate -o` writes it (a time
//! column and three rate columns, shortest round-trip floats), plain and gzip-compressed, in MB/s
//! of CSV text; the same through the reference path alone (the csv crate and `str::parse::<f64>`
//! on every row, how every file was read before the fast path); and `write_table` of the same
//! columns. Beside it, the same samples as a ROS 2 bag of 10^6 sensor_msgs/msg/Imu messages read
//! as `allan` reads it ([`read_log`]: every message decoded, stamps checked): uncompressed chunks
//! as `ros2 bag record` writes by default, and zstd chunks as `driftless record --format ros2`
//! writes, both in MB/s of the uncompressed bag (what the messages weigh).
//!
//! `cargo bench --bench csv`. The goals are >= 500 MB/s of plain CSV input and >= 200 MB/s of
//! bag input on this 2-core machine; gzip input is bound by decompression.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use driftless::io::{read_table, read_table_reference, write_table};
use driftless::rate_log::read_log;
use driftless::transport::ros2::bag::ImuBagWriter;
use driftless::transport::ros2::{Imu, Time, IMU_DEFINITION, IMU_TYPE};
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

/// The columns as Imu messages at 100 Hz (x, y, z as the angular velocity).
fn messages(cols: &[Vec<f64>]) -> impl Iterator<Item = Imu> + '_ {
    (0..ROWS).map(|i| Imu {
        stamp: Time::from_ns(1_700_000_000_000_000_000 + i as i64 * 10_000_000).expect("stamp"),
        frame_id: "imu_link".into(),
        angular_velocity: [cols[1][i], cols[2][i], cols[3][i]],
        ..Imu::default()
    })
}

/// A bag with uncompressed chunks, as `ros2 bag record` writes by default.
fn write_plain_bag(path: &Path, cols: &[Vec<f64>]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(None)
        .create(file)
        .expect("writer");
    let schema = w
        .add_schema(IMU_TYPE, "ros2msg", IMU_DEFINITION.as_bytes())
        .expect("schema");
    let channel = w
        .add_channel(schema, "/imu", "cdr", &Default::default())
        .expect("channel");
    for m in messages(cols) {
        let t = m.stamp.ns_u64().expect("after 1970");
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: 0,
            log_time: t,
            publish_time: t,
        };
        w.write_to_known_channel(&header, &m.to_cdr().expect("cdr"))
            .expect("write");
    }
    w.finish().expect("finish");
}

fn write_zstd_bag(path: &Path, cols: &[Vec<f64>]) {
    let mut w = ImuBagWriter::create(path, "/imu").expect("writer");
    for m in messages(cols) {
        w.write(&m).expect("write");
    }
    w.finish().expect("finish");
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

    let bag = dir.path().join("log.mcap");
    let bag_zstd = dir.path().join("log-zstd.mcap");
    write_plain_bag(&bag, &cols);
    write_zstd_bag(&bag_zstd, &cols);
    let bag_bytes = std::fs::metadata(&bag).expect("size").len();
    eprintln!(
        "{ROWS} Imu messages, {:.1} MB of bag ({:.1} MB zstd)",
        bag_bytes as f64 / 1e6,
        std::fs::metadata(&bag_zstd).expect("size").len() as f64 / 1e6
    );
    for p in [&bag, &bag_zstd] {
        let log = read_log(p, &[], None, false).expect("read");
        assert_eq!(log.table.columns, cols[1..], "read back exactly");
    }
    let mut g = c.benchmark_group("ros2_bag");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bag_bytes));
    g.bench_function("read_plain_1e6_messages", |b| {
        b.iter(|| read_log(black_box(&bag), &[], None, false).expect("read"))
    });
    g.bench_function("read_zstd_1e6_messages", |b| {
        b.iter(|| read_log(black_box(&bag_zstd), &[], None, false).expect("read"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
