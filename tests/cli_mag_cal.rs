//! `driftless mag-cal` through the real binary: a rotation with known hard and soft iron gives
//! them back as a table that parses, that `validate` accepts in an `attitude.6d` stage, and
//! that removes the spread of the field's norm; a band is refused naming the missing motion;
//! two bands give the hard iron alone.

mod common;

use common::{driftless, Dir};

/// The hard iron, uT.
const B: [f64; 3] = [12.0, -30.0, 7.5];
/// The distortion `W^-1` (symmetric).
const SOFT_INV: [[f64; 3]; 3] = [[1.08, 0.04, -0.02], [0.04, 0.93, 0.03], [-0.02, 0.03, 1.0]];
/// The earth's field, uT.
const FIELD: f64 = 48.0;

/// Small deterministic noise in -0.3..0.3 uT.
fn jitter(k: usize, axis: usize) -> f64 {
    (((k * 7919 + axis * 104_729) as f64 * 0.618_034).fract() * 2.0 - 1.0) * 0.3
}

/// Readings along the unit directions `dirs` in the body, distorted and offset, as CSV with
/// gyro columns beside (an IMU's log).
fn csv(dirs: &[[f64; 3]], soft_inv: &[[f64; 3]; 3]) -> String {
    let mut s = String::from("t,x,y,z,mx,my,mz\n");
    for (k, u) in dirs.iter().enumerate() {
        let h = u.map(|v| v * FIELD);
        let m: [f64; 3] = [0, 1, 2]
            .map(|i| (0..3).map(|j| soft_inv[i][j] * h[j]).sum::<f64>() + B[i] + jitter(k, i));
        s.push_str(&format!(
            "{},0,0,0,{},{},{}\n",
            k as f64 / 100.0,
            m[0],
            m[1],
            m[2]
        ));
    }
    s
}

/// Directions over the whole sphere (a Fibonacci spiral).
fn sphere(n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
            let a = k as f64 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// The sensor turned about its body `axis` only, the field 60 deg off the turning plane.
fn band(n: usize, axis: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|k| {
            let a = k as f64 * 0.05;
            let mut u = [0.0; 3];
            u[axis] = 60f64.to_radians().sin();
            u[(axis + 1) % 3] = 0.5 * a.cos();
            u[(axis + 2) % 3] = 0.5 * a.sin();
            u
        })
        .collect()
}

/// `driftless mag-cal LOG --mag-columns mx,my,mz`: exit code, stdout, stderr.
fn mag_cal(log: &std::path::Path) -> (Option<i32>, String, String) {
    let o = driftless(&[
        "mag-cal",
        log.to_str().unwrap(),
        "--mag-columns",
        "mx,my,mz",
    ]);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn floats(v: &toml::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_float().unwrap())
        .collect()
}

/// RMS of the readings' norms about their mean, each reading first turned by `f`.
fn norm_spread(text: &str, f: impl Fn([f64; 3]) -> [f64; 3]) -> f64 {
    let norms: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|c| c.parse().unwrap()).collect();
            let m = f([v[4], v[5], v[6]]);
            (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt()
        })
        .collect();
    let mean = norms.iter().sum::<f64>() / norms.len() as f64;
    (norms.iter().map(|n| (n - mean).powi(2)).sum::<f64>() / norms.len() as f64).sqrt()
}

#[test]
fn a_full_rotation_gives_a_table_the_stage_takes() {
    let dir = Dir::new();
    let text = csv(&sphere(2000), &SOFT_INV);
    let log = dir.write("rot.csv", &text);
    let (code, out, err) = mag_cal(&log);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("# fitted: hard and soft iron"), "{out}");
    let table: toml::Table = toml::from_str(&out).expect("the whole output is TOML");
    let stage = &table["stage"].as_array().unwrap()[0];
    assert_eq!(stage["kind"].as_str(), Some("attitude.6d"));
    let b = floats(&stage["mag_hard_iron_ut"]);
    for i in 0..3 {
        assert!((b[i] - B[i]).abs() < 0.2, "{b:?}");
    }
    let rows: Vec<Vec<f64>> = stage["mag_soft_iron"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    let before = norm_spread(&text, |m| m);
    let after = norm_spread(&text, |m| {
        let d = [0, 1, 2].map(|i| m[i] - b[i]);
        [0, 1, 2].map(|i| (0..3).map(|j| rows[i][j] * d[j]).sum())
    });
    assert!(before > 3.0 && after < before / 10.0, "{before} -> {after}");

    // Fed back: the printed table is an attitude.6d stage `validate` accepts.
    let pipeline = format!(
        "name = \"nav\"\nrate_hz = 100.0\ninput_units = \"deg/s\"\n\n[[stage]]\nname = \
         \"sensor\"\nkind = \"ingest.csv\"\noutput = \"nav/raw\"\nfile = \"rot.csv\"\n\
         time_column = \"t\"\nmag_columns = [\"mx\", \"my\", \"mz\"]\n\n[[stage]]\nname = \
         \"predict\"\nkind = \"predict.bias\"\ninput = \"nav/raw\"\noutput = \
         \"nav/predicted\"\nprofile = \"adis16405\"\n\n{out}\n[[stage]]\nname = \
         \"publish\"\nkind = \"publish\"\ninput = \"nav/attitude\"\noutput = \
         \"nav/corrected\"\n"
    );
    let file = dir.write("p.toml", &pipeline);
    let v = driftless(&["validate", file.to_str().unwrap()]);
    let said =
        String::from_utf8_lossy(&v.stdout).into_owned() + &String::from_utf8_lossy(&v.stderr);
    assert_eq!(v.status.code(), Some(0), "{said}");
    assert!(said.contains("magnetometer calibration"), "{said}");

    // A soft iron the stage must refuse, naming its key.
    let bad = pipeline.replace("mag_soft_iron = [[", "mag_soft_iron = [[-");
    let file = dir.write("bad.toml", &bad);
    let v = driftless(&["validate", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&v.stderr).into_owned();
    assert_eq!(v.status.code(), Some(2), "{err}");
    assert!(err.contains("mag_soft_iron"), "{err}");
}

#[test]
fn poor_coverage_is_refused_or_gives_the_hard_iron_alone() {
    let dir = Dir::new();
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let log = dir.write("band.csv", &csv(&band(800, 1), &SOFT_INV));
    let (code, out, err) = mag_cal(&log);
    assert_eq!(code, Some(2), "{err}");
    assert!(out.is_empty(), "nothing printed on a refusal");
    assert!(
        err.contains("only a band") && err.contains("its y axis") && err.contains("rotate it"),
        "{err}"
    );

    let mut dirs = band(800, 2);
    dirs.extend(band(800, 0));
    let log = dir.write("two.csv", &csv(&dirs, &identity));
    let (code, out, err) = mag_cal(&log);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("the hard iron alone"), "{err}");
    let table: toml::Table = toml::from_str(&out).expect("TOML");
    let stage = &table["stage"].as_array().unwrap()[0];
    let b = floats(&stage["mag_hard_iron_ut"]);
    for i in 0..3 {
        assert!((b[i] - B[i]).abs() < 0.3, "{b:?}");
    }
    let w = floats(&stage["mag_soft_iron"][0]);
    assert_eq!(w, [1.0, 0.0, 0.0]);

    // No columns named for a CSV: the option it needs.
    let o = driftless(&["mag-cal", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mag-columns"));
}
