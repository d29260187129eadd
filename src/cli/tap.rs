//! `driftless tap SERVICE`: print the samples of any of our services, with a rate display
//! (like `ros2 topic echo` and `ros2 topic hz`).

use std::io::Write;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crate::cli::CliError;
use crate::transport::{self, AnyInput, Carried, Transport, WireType};
use crate::units::RateUnit;
use crate::wire::{
    self, Field, FieldTable, FieldUnit, FieldValue, GyroSample, InTap, RawSample, StatsSnapshot,
    WireBytes,
};

/// How samples are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// One readable line per sample, flags by name.
    Text,
    /// A header, then one row per sample (not for a stats service).
    Csv,
    /// One JSON object per line.
    Json,
}

/// The units the processed rates may be printed in, as `--units` lists them (the wire carries
/// rad/s).
fn units_arg() -> impl clap::builder::TypedValueParser<Value = RateUnit> {
    use clap::builder::PossibleValue;
    super::unit_arg([
        PossibleValue::new(RateUnit::RadPerS.name()).help("Radians per second, as on the wire"),
        PossibleValue::new(RateUnit::DegPerS.name()).help("Degrees per second"),
    ])
}

/// Arguments of `driftless tap`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Service name, e.g. demo/corrected (any hop of a pipeline, or a raw sensor service).
    pub service: String,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
    /// Units of the processed rates (rate, drift, denoised). Raw samples are printed in the
    /// pipeline's input_units, as the driver sent them.
    #[arg(long, value_parser = units_arg(), default_value = "rad/s")]
    pub units: RateUnit,
    /// Only the rate line, once a second, on stdout, with the interval between sample
    /// timestamps (min / max / standard deviation), as `ros2 topic hz`; no samples.
    #[arg(long)]
    pub hz: bool,
    /// Exit after this many samples. Should the publisher leave first, or `--timeout` pass,
    /// exit 1 saying how many came.
    #[arg(long)]
    pub count: Option<u64>,
    /// With --count: give up (exit 1) if the samples have not all come within this long.
    #[arg(
        long,
        requires = "count",
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub timeout: Option<Duration>,
    /// Exit after this long ("10s", "500ms", "1.5s", "90min", or seconds).
    #[arg(
        long,
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub duration: Option<Duration>,
}

/// One received item (on the stack, one at a time: its size does not matter).
#[allow(clippy::large_enum_variant)]
enum Item {
    Gyro(GyroSample),
    Raw(RawSample),
    Stats(StatsSnapshot),
}

/// The next item of `input`, if one is there (`tap` opens no stop-signal service).
fn receive(input: &AnyInput) -> Option<Item> {
    match input {
        AnyInput::Gyro(i) => i.receive().ok().flatten().map(Item::Gyro),
        AnyInput::Raw(i) => i.receive().ok().flatten().map(Item::Raw),
        AnyInput::Stats(i) => i.receive().ok().flatten().map(Item::Stats),
        AnyInput::Stop(_) => None,
    }
}

impl Item {
    /// A sample's table and its wire bytes; `None` for a stats snapshot (printed in its JSON
    /// form).
    fn fields(&self) -> Option<(&'static FieldTable, Vec<u8>)> {
        let mut bytes = Vec::new();
        let table = match self {
            Item::Gyro(s) => {
                s.encode(&mut bytes);
                &wire::GYRO_FIELDS
            }
            Item::Raw(s) => {
                s.encode(&mut bytes);
                &wire::RAW_FIELDS
            }
            Item::Stats(_) => return None,
        };
        Some((table, bytes))
    }

    /// (epoch, seq, timestamp ns) of a sample; a stats snapshot has only its uptime.
    fn stamp(&self) -> (Option<(u32, u64)>, u64) {
        match self {
            Item::Gyro(s) => (Some((s.epoch, s.seq)), s.t_ns),
            Item::Raw(s) => (Some((s.epoch, s.seq)), s.t_ns),
            Item::Stats(s) => (None, s.uptime_ns),
        }
    }
}

/// The refusal of `--format csv` on a stats service (checked at start, and by the printer).
/// ` accel [x y z] units` for a text line, or nothing when the sample has no accelerometer.
fn accel_text(accel: Option<[f64; 3]>, units: &str) -> String {
    accel.map_or(String::new(), |a| {
        format!(" accel [{:+.6} {:+.6} {:+.6}] {units}", a[0], a[1], a[2])
    })
}

/// ` attitude roll r pitch p yaw y deg +- [sx sy sz]` for a text line (the standard
/// deviations about the earth's axes, deg; `?` where not provided), or nothing when the sample
/// has no orientation.
fn attitude_text(s: &GyroSample) -> String {
    s.orientation_estimate().map_or(String::new(), |q| {
        let [r, p, y] = crate::attitude::roll_pitch_yaw(q).map(f64::to_degrees);
        let sd = s.orientation_std.map(|v| {
            if v >= 0.0 {
                format!("{:.3}", v.to_degrees())
            } else {
                "?".into()
            }
        });
        format!(
            " attitude roll {r:+.3} pitch {p:+.3} yaw {y:+.3} deg +- [{} {} {}]",
            sd[0], sd[1], sd[2]
        )
    })
}

/// The sensors word by name (`heading_absolute`, `mag_rejected`, ...); nothing when it is 0.
fn sensors_text(sensors: u32) -> String {
    if sensors == 0 {
        String::new()
    } else {
        format!(" sensors {}", joined(&wire::sensor_names(sensors), ","))
    }
}

fn no_csv_for_stats(service: &str) -> CliError {
    CliError::input(format!(
        "{service} carries statistics snapshots, which have no CSV form: use --format text or json"
    ))
}

fn joined(names: &[String], sep: &str) -> String {
    if names.is_empty() {
        "-".into()
    } else {
        names.join(sep)
    }
}

/// The axes of a field's columns.
const AXES: [&str; 4] = ["x", "y", "z", "w"];

/// The fields that lead every CSV row and JSON line, in this order (the time as `t_s` in a
/// CSV row).
const STAMP: [&str; 3] = ["epoch", "seq", "t_ns"];

/// The fields of `table` that `format` shows after the stamp, in layout order.
fn shown(table: &FieldTable, format: Format) -> impl Iterator<Item = &'static Field> {
    table.fields.iter().filter(move |f| {
        !STAMP.contains(&f.name)
            && match f.tap {
                InTap::Hidden => false,
                InTap::Json => format == Format::Json,
                _ => true,
            }
    })
}

/// The integer field `name` of a sample (0 if the table has none).
fn int(table: &FieldTable, name: &str, bytes: &[u8]) -> u64 {
    match table.field(name).and_then(|f| f.read(bytes)) {
        Some(FieldValue::Ints(v)) => v.first().copied().unwrap_or(0),
        _ => 0,
    }
}

/// A sample's stamp: epoch, seq and time (ns), which lead every row and line.
fn stamp(table: &FieldTable, bytes: &[u8]) -> [u64; 3] {
    STAMP.map(|name| int(table, name, bytes))
}

/// The value of the word `f`.
fn word(table: &FieldTable, f: &Field, bytes: &[u8]) -> u64 {
    int(table, f.name, bytes)
}

/// The names of the bits set in the word `f`.
fn word_names(table: &FieldTable, f: &Field, bytes: &[u8]) -> Vec<String> {
    let bits = u32::try_from(word(table, f, bytes)).unwrap_or(u32::MAX);
    wire::bit_names(bits, f.names.unwrap_or_default())
}

/// Values as CSV cells: Rust's shortest text for each (`NaN` and `inf` as such).
fn texts<T: ToString>(v: &[T]) -> String {
    v.iter().map(T::to_string).collect::<Vec<_>>().join(",")
}

/// Values as JSON: a number for one, an array for several (a non-finite float is `null`).
fn json_of<T: Into<serde_json::Value>>(mut v: Vec<T>) -> serde_json::Value {
    match v.len() {
        1 => v.pop().map_or(serde_json::Value::Null, Into::into),
        _ => v.into_iter().map(Into::into).collect(),
    }
}

/// The printing side: format, units, and the CSV header once.
struct Printer {
    format: Format,
    units: RateUnit,
    service: String,
    header_done: bool,
}

impl Printer {
    /// `drift_std` for the text line: the value in the display units, or `-` where not
    /// provided.
    fn std_text(&self, sd: [f64; 3]) -> [String; 3] {
        let f = wire::GYRO_FIELDS.field("drift_std");
        sd.map(|v| match f.map_or(v, |f| self.scaled(f, v)) {
            v if v < 0.0 => "-".to_string(),
            v => format!("{v:.6}"),
        })
    }

    /// The CSV header of `item`'s type: the stamp, then each field the table shows
    /// ([`wire::InTap`]), its axes' columns named with the units they are printed in.
    fn header(&self, item: &Item) -> Option<String> {
        if self.format != Format::Csv {
            return None;
        }
        let (table, _) = item.fields()?;
        let mut columns = vec!["epoch".to_string(), "seq".into(), "t_s".into()];
        for f in shown(table, Format::Csv) {
            match f.tap {
                InTap::ValueAndNames(names) => columns.extend([f.name.into(), names.into()]),
                InTap::Names => columns.push(f.name.into()),
                _ if f.len == 1 => columns.push(f.name.into()),
                _ => {
                    let suffix = self.suffix(f.unit);
                    columns.extend(AXES[..f.len].iter().map(|a| match suffix {
                        "" => format!("{}_{a}", f.name),
                        _ => format!("{}_{a}_{suffix}", f.name),
                    }));
                }
            }
        }
        Some(columns.join(","))
    }

    /// What a column of values in `unit` is suffixed with: the units `tap` prints them in.
    fn suffix(&self, unit: FieldUnit) -> &'static str {
        match unit {
            FieldUnit::RadPerS => self.units.column_suffix(),
            FieldUnit::InputUnits | FieldUnit::AccelUnits => "input",
            FieldUnit::MPerS2 => "ms2",
            FieldUnit::Rad => "rad",
            FieldUnit::Ns => "ns",
            FieldUnit::Tesla => "t",
            FieldUnit::MPerS => "ms",
            FieldUnit::Hz => "hz",
            FieldUnit::Unitless => "",
        }
    }

    /// A value of `f` as printed: a rate in the display units, where "not provided" stays the
    /// wire's sentinel whatever the units (it is not a rate); any other value as it came.
    fn scaled(&self, f: &Field, v: f64) -> f64 {
        match (f.unit, f.not_provided) {
            (FieldUnit::RadPerS, Some(sentinel)) if v < 0.0 => sentinel,
            (FieldUnit::RadPerS, _) => v * self.units.from_rad_per_s(),
            _ => v,
        }
    }

    /// The values of `f` in `bytes` as printed (rates scaled); `None` when the sample does not
    /// carry it.
    fn values(&self, table: &FieldTable, f: &Field, bytes: &[u8]) -> Option<FieldValue> {
        if !table.present(f, bytes) {
            return None;
        }
        match f.read(bytes)? {
            FieldValue::Floats(v) => Some(FieldValue::Floats(
                v.into_iter().map(|x| self.scaled(f, x)).collect(),
            )),
            other => Some(other),
        }
    }

    /// A sample as one CSV row: its stamp, then the cells of [`Printer::header`]'s columns
    /// (a value the sample does not carry: empty cells, never 0).
    fn csv_row(&self, table: &FieldTable, bytes: &[u8]) -> String {
        let [epoch, seq, t_ns] = stamp(table, bytes);
        let mut cells = vec![
            epoch.to_string(),
            seq.to_string(),
            (t_ns as f64 * 1e-9).to_string(),
        ];
        for f in shown(table, Format::Csv) {
            let names = || joined(&word_names(table, f, bytes), "|");
            match f.tap {
                InTap::ValueAndNames(_) => {
                    cells.extend([word(table, f, bytes).to_string(), names()])
                }
                InTap::Names => cells.push(names()),
                _ => cells.push(match self.values(table, f, bytes) {
                    Some(FieldValue::Ints(v)) => texts(&v),
                    Some(FieldValue::Floats(v)) => texts(&v),
                    _ => ",".repeat(f.len - 1),
                }),
            }
        }
        cells.join(",")
    }

    /// A sample as one JSON object: its stamp, the units of its rates, then each field the
    /// table shows (a value the sample does not carry: null).
    fn json_line(&self, table: &FieldTable, bytes: &[u8]) -> String {
        let [epoch, seq, t_ns] = stamp(table, bytes);
        let mut out = serde_json::Map::new();
        out.insert("epoch".into(), epoch.into());
        out.insert("seq".into(), seq.into());
        out.insert("t_ns".into(), t_ns.into());
        let units = match table.field("rate").map(|f| f.unit) {
            Some(FieldUnit::RadPerS) => self.units.name(),
            _ => "input",
        };
        out.insert("units".into(), units.into());
        for f in shown(table, Format::Json) {
            match f.tap {
                InTap::ValueAndNames(names) => {
                    out.insert(f.name.into(), word(table, f, bytes).into());
                    out.insert(names.into(), word_names(table, f, bytes).into());
                }
                InTap::Names => {
                    out.insert(f.name.into(), word_names(table, f, bytes).into());
                }
                _ => {
                    let v = match self.values(table, f, bytes) {
                        Some(FieldValue::Ints(v)) => json_of(v),
                        Some(FieldValue::Floats(v)) => json_of(v),
                        _ => serde_json::Value::Null,
                    };
                    out.insert(f.name.into(), v);
                }
            }
        }
        serde_json::Value::Object(out).to_string()
    }

    /// Print `item` (after the header, the first time); false when the reader went away.
    fn print(&mut self, out: &mut impl Write, item: &Item) -> Result<bool, CliError> {
        if !self.header_done {
            self.header_done = true;
            if let Some(h) = self.header(item) {
                if writeln!(out, "{h}").is_err() {
                    return Ok(false);
                }
            }
        }
        let line = self.line(item)?;
        Ok(writeln!(out, "{line}").is_ok())
    }

    fn line(&self, item: &Item) -> Result<String, CliError> {
        let k = self.units.from_rad_per_s();
        let scaled = |v: [f64; 3]| v.map(|x| x * k);
        Ok(match (self.format, item) {
            (Format::Text, Item::Gyro(s)) => {
                let [r, d, n] = [s.rate, s.drift, s.denoised].map(scaled);
                let sd = self.std_text(s.drift_std);
                format!(
                    "epoch {} seq {} t {:.6} s rate [{:+.6} {:+.6} {:+.6}] drift [{:+.6} {:+.6} {:+.6}] \
                     +- [{} {} {}] denoised [{:+.6} {:+.6} {:+.6}] {}{}{}{} flags {}",
                    s.epoch,
                    s.seq,
                    s.t_ns as f64 * 1e-9,
                    r[0], r[1], r[2], d[0], d[1], d[2], sd[0], sd[1], sd[2], n[0], n[1], n[2],
                    self.units.name(),
                    accel_text((s.sensors & wire::SENSOR_ACCEL != 0).then_some(s.accel), "m/s²"),
                    attitude_text(s),
                    sensors_text(s.sensors),
                    joined(&wire::flag_names(s.flags), ",")
                )
            }
            (Format::Text, Item::Raw(s)) => format!(
                "epoch {} seq {} t {:.6} s rate [{:+.6} {:+.6} {:+.6}] (input units){} flags {}",
                s.epoch,
                s.seq,
                s.t_ns as f64 * 1e-9,
                s.rate[0],
                s.rate[1],
                s.rate[2],
                accel_text(s.accel_reading(), "(input units)"),
                joined(&wire::raw_flag_names(s.flags), ",")
            ),
            (Format::Text, Item::Stats(s)) => crate::metrics::format_snapshot(&self.service, s),
            (Format::Csv, Item::Stats(_)) => return Err(no_csv_for_stats(&self.service)),
            (Format::Json, Item::Stats(s)) => {
                crate::io::recording::StatsMessage::json(s).to_string()
            }
            (format, Item::Gyro(_) | Item::Raw(_)) => {
                let (table, bytes) = item.fields().expect("a sample has a table");
                match format {
                    Format::Csv => self.csv_row(table, &bytes),
                    _ => self.json_line(table, &bytes),
                }
            }
        })
    }
}

/// Intervals between consecutive sample timestamps within one epoch, over one display window
/// (Welford's running mean and variance).
#[derive(Default)]
struct Intervals {
    n: u64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
}

impl Intervals {
    fn add(&mut self, dt: f64) {
        self.n += 1;
        if self.n == 1 {
            (self.min, self.max) = (dt, dt);
        } else {
            self.min = self.min.min(dt);
            self.max = self.max.max(dt);
        }
        let d = dt - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (dt - self.mean);
    }

    fn describe(&self) -> String {
        if self.n == 0 {
            return "no interval".into();
        }
        let std = if self.n > 1 {
            (self.m2 / (self.n - 1) as f64).sqrt()
        } else {
            0.0
        };
        format!(
            "interval min {:.3} ms max {:.3} ms std {:.3} ms over {}",
            self.min * 1e3,
            self.max * 1e3,
            std * 1e3,
            self.n
        )
    }
}

/// Subscribe to SERVICE (whichever of our wire types it carries) and print what comes.
pub fn run(args: Args) -> Result<(), CliError> {
    transport::quiet_logging();
    transport::check_service_name(&args.service)
        .map_err(|e| CliError::input(format!("invalid service name {:?}: {e}", args.service)))?;
    let prefix = args.iceoryx2.resolve(None)?;
    let result = tap(&args, &prefix);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    result
}

/// Subscribe to the service, whichever of our sample types it carries.
fn open(args: &Args, node: &Transport, prefix: &str) -> Result<AnyInput, CliError> {
    // Nothing to read is a run-time failure (exit 1), as for `stats`: the name may be right.
    let missing = || {
        CliError::internal(format!(
            "no service {:?} of a driftless type under prefix {prefix:?} (is the pipeline running?)",
            args.service
        ))
    };
    let wire = match node.carried(&args.service) {
        Ok(Carried::Ours(w)) if w != WireType::Stop => w,
        Ok(Carried::OtherVersion(m)) => return Err(CliError::input(m)),
        _ => return Err(missing()),
    };
    let input = node.open_any(&args.service, wire).map_err(|_| missing())?;
    if wire == WireType::Stats && args.format == Format::Csv && !args.hz {
        return Err(no_csv_for_stats(&args.service));
    }
    Ok(input)
}

/// What came so far: the totals, and the display window's rate and intervals.
#[derive(Default)]
struct Seen {
    total: u64,
    window: u64,
    gaps: u64,
    intervals: Intervals,
    /// (epoch, seq, timestamp ns) of the last sample; epoch and seq are None for stats.
    last: Option<(Option<(u32, u64)>, u64)>,
}

impl Seen {
    fn add(&mut self, item: &Item) {
        self.total += 1;
        self.window += 1;
        let (seq, t_ns) = item.stamp();
        // Sequence numbers and timestamps count within one epoch (a daemon or source restart
        // starts another).
        if let Some((prev_seq, prev_t)) = self.last {
            let same_epoch = match (seq, prev_seq) {
                (Some((e, _)), Some((pe, _))) => e == pe,
                _ => true,
            };
            if same_epoch {
                if let (Some((_, s)), Some((_, p))) = (seq, prev_seq) {
                    if s > p + 1 {
                        self.gaps += s - p - 1;
                    }
                }
                self.intervals
                    .add(t_ns.wrapping_sub(prev_t) as i64 as f64 * 1e-9);
            }
        }
        self.last = Some((seq, t_ns));
    }

    /// The rate line over the window of `dt`, and a new window.
    fn rate_line(&mut self, service: &str, dt: Duration) -> String {
        let line = format!(
            "{service}: {:.1} Hz ({}), {} samples, {} missing (sequence gaps)",
            self.window as f64 / dt.as_secs_f64(),
            self.intervals.describe(),
            self.total,
            self.gaps
        );
        self.window = 0;
        self.intervals = Intervals::default();
        line
    }
}

fn tap(args: &Args, prefix: &str) -> Result<(), CliError> {
    let node = Transport::new(
        prefix,
        &format!("driftless-tap-{}", std::process::id()),
        Default::default(),
    )?;
    let input = open(args, &node, prefix)?;
    let stop = crate::cli::signals::stop_flag();
    let mut printer = Printer {
        format: args.format,
        units: args.units,
        service: args.service.clone(),
        header_done: false,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let end = args.duration.map(|d| Instant::now() + d);
    let give_up = args.timeout.map(|d| Instant::now() + d);
    // With --count, a publisher seen and then gone ends the tap (once its samples are read).
    let mut had_publisher = false;
    let mut seen = Seen::default();
    let mut tick = Instant::now();
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        match receive(&input) {
            Some(item) => {
                seen.add(&item);
                if !args.hz && !printer.print(&mut out, &item)? {
                    return Ok(()); // the reader went away (e.g. `| head`)
                }
                if args.count.is_some_and(|c| seen.total >= c) {
                    break;
                }
            }
            None => {
                if let Some(count) = args.count {
                    let publishers = input.publishers();
                    had_publisher |= publishers > 0;
                    let why = if had_publisher && publishers == 0 {
                        Some("its publisher left".to_string())
                    } else if give_up.is_some_and(|g| Instant::now() >= g) {
                        let t = args.timeout.unwrap_or_default();
                        Some(format!("--timeout {t:?} passed"))
                    } else {
                        None
                    };
                    if let Some(why) = why {
                        let _ = out.flush();
                        return Err(CliError::internal(format!(
                            "{}: {} of {count} samples: {why}",
                            args.service, seen.total
                        )));
                    }
                }
                std::thread::sleep(Duration::from_micros(500));
            }
        }
        let dt = tick.elapsed();
        if dt >= Duration::from_secs(1) {
            let rate = seen.rate_line(&args.service, dt);
            // With --hz the rate is the data asked for (stdout); beside samples, a message.
            if args.hz {
                if writeln!(out, "{rate}").and_then(|()| out.flush()).is_err() {
                    return Ok(());
                }
            } else {
                eprintln!("{rate}");
            }
            tick = Instant::now();
        }
    }
    let _ = out.flush();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_give_min_max_and_sample_standard_deviation() {
        let mut i = Intervals::default();
        for dt in [0.001, 0.002, 0.003] {
            i.add(dt);
        }
        assert_eq!(
            i.describe(),
            "interval min 1.000 ms max 3.000 ms std 1.000 ms over 3"
        );
        assert_eq!(Intervals::default().describe(), "no interval");
    }

    fn printer(format: Format, units: RateUnit) -> Printer {
        Printer {
            format,
            units,
            service: "t/corrected".into(),
            header_done: false,
        }
    }

    #[test]
    fn deg_s_is_rad_s_times_180_over_pi_in_every_format() {
        let s = GyroSample {
            seq: 7,
            t_ns: 1_500_000,
            rate: [std::f64::consts::PI, 0.0, -1.0],
            drift: [0.5, 0.0, 0.0],
            denoised: [1.0, 0.0, 0.0],
            flags: crate::wire::FLAG_STILL,
            epoch: 3,
            drift_std: [0.25, crate::wire::DRIFT_STD_NOT_PROVIDED, 0.0],
            ..GyroSample::default()
        };
        let item = Item::Gyro(s);
        let json: serde_json::Value = serde_json::from_str(
            &printer(Format::Json, RateUnit::DegPerS)
                .line(&item)
                .unwrap(),
        )
        .unwrap();
        assert_eq!(json["rate"][0], 180.0);
        assert_eq!(json["rate"][2], -180.0 / std::f64::consts::PI);
        assert_eq!(json["flag_names"], serde_json::json!(["still"]));
        // The std scales with the units; "not provided" stays -1.
        assert_eq!(
            json["drift_std"],
            serde_json::json!([0.25 * (180.0 / std::f64::consts::PI), -1.0, 0.0])
        );
        let rad = printer(Format::Csv, RateUnit::RadPerS);
        assert_eq!(
            rad.header(&item).unwrap(),
            "epoch,seq,t_s,rate_x_rads,rate_y_rads,rate_z_rads,drift_x_rads,drift_y_rads,\
             drift_z_rads,denoised_x_rads,denoised_y_rads,denoised_z_rads,flags,flag_names,\
             drift_std_x_rads,drift_std_y_rads,drift_std_z_rads,accel_x_ms2,accel_y_ms2,\
             accel_z_ms2,accel_std_x_ms2,accel_std_y_ms2,accel_std_z_ms2,sensors,\
             orientation_x,orientation_y,orientation_z,orientation_w,orientation_std_x_rad,\
             orientation_std_y_rad,orientation_std_z_rad"
        );
        // No accelerometer: empty cells, never zeros.
        assert_eq!(
            rad.line(&item).unwrap(),
            format!(
                "3,7,0.0015,{},0,-1,0.5,0,0,1,0,0,64,still,0.25,-1,0,,,,,,,-,,,,,,,",
                std::f64::consts::PI
            )
        );
        assert_eq!(json["accel"], serde_json::Value::Null);
        let with = Item::Gyro(GyroSample {
            accel: [0.5, -0.25, 9.75],
            sensors: crate::wire::SENSOR_ACCEL,
            ..s
        });
        assert!(rad
            .line(&with)
            .unwrap()
            .ends_with(",0.5,-0.25,9.75,-1,-1,-1,accel,,,,,,,"));
        let text = printer(Format::Text, RateUnit::DegPerS)
            .line(&with)
            .unwrap();
        assert!(
            text.contains("accel [+0.500000 -0.250000 +9.750000] m/s² sensors accel flags still"),
            "{text}"
        );
        // An orientation: 90 deg of yaw, its heading's sd not provided, absolute (9D).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let turned = Item::Gyro(GyroSample {
            orientation: [0.0, 0.0, h, h],
            orientation_std: [0.01, 0.01, -1.0],
            sensors: crate::wire::SENSOR_ORIENTATION | crate::wire::SENSOR_HEADING_ABSOLUTE,
            ..s
        });
        let text = printer(Format::Text, RateUnit::DegPerS)
            .line(&turned)
            .unwrap();
        assert!(
            text.contains(
                "attitude roll +0.000 pitch +0.000 yaw +90.000 deg +- [0.573 0.573 ?] \
                 sensors orientation,heading_absolute flags still"
            ),
            "{text}"
        );
        assert!(rad.line(&turned).unwrap().ends_with(&format!(
            ",,orientation|heading_absolute,0,0,{h},{h},0.01,0.01,-1"
        )));
        let json: serde_json::Value = serde_json::from_str(
            &printer(Format::Json, RateUnit::DegPerS)
                .line(&turned)
                .unwrap(),
        )
        .unwrap();
        assert_eq!(json["orientation"], serde_json::json!([0.0, 0.0, h, h]));
        assert_eq!(
            json["orientation_std"],
            serde_json::json!([0.01, 0.01, -1.0])
        );
        let text = printer(Format::Text, RateUnit::DegPerS)
            .line(&item)
            .unwrap();
        assert!(
            text.contains("rate [+180.000000 +0.000000 -57.295780] drift"),
            "{text}"
        );
        assert!(
            text.contains("denoised [+57.295780 +0.000000 +0.000000] deg/s"),
            "{text}"
        );
        assert!(
            text.contains("drift [+28.647890 +0.000000 +0.000000] +- [14.323945 - 0.000000]"),
            "{text}"
        );
        assert!(text.ends_with("flags still"), "{text}");
        let stats = Item::Stats(StatsSnapshot::default());
        assert!(printer(Format::Csv, RateUnit::RadPerS)
            .line(&stats)
            .is_err());
    }

    #[test]
    fn flags_read_by_name_and_unknown_bits_stay_visible() {
        use crate::wire::{flag_names, FLAG_GAP_BEFORE, FLAG_STILL};
        assert_eq!(
            flag_names(FLAG_STILL | FLAG_GAP_BEFORE | 1 << 20),
            ["gap_before", "still", "0x100000"]
        );
        assert_eq!(
            wire::raw_flag_names(wire::RAW_INVALID | 4 | 1 << 9),
            ["invalid", "vehicle_moving", "0x200"]
        );
        assert_eq!(joined(&[], ","), "-");
    }
}
