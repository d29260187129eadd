//! The transform against PyWavelets 1.9.0, on fixtures written by `scripts/gen_pywt_fixtures.py`.
//!
//! Inputs are regenerated here bit for bit (splitmix64, seeded with the signal length), so the
//! fixtures only hold outputs: per band its length, max |value|, a weighted checksum over every
//! value, and some stored values (all of them for short bands). The requirement is 1e-12 relative:
//! max abs error / max abs value of the reference band. Run with `--nocapture` to see the worst
//! errors measured.

use driftless::wavelet::transform::{self, Mode, Plan};
use driftless::wavelet::Wavelet;
use serde_json::Value;
use std::collections::BTreeSet;

const TOL: f64 = 1e-12;

/// Errors are relative to the reference band's max |value|, but never to less than this fraction
/// of the largest band of the case: some bands are pure round-off in PyWavelets itself (db20's cD
/// of one sample is x0 * sum(dec_hi) ~ 1e-17), and any summation order gives other noise there.
const ROUNDOFF_FLOOR: f64 = 1e-3;

/// splitmix64 seeded with `seed`, sample = (u >> 11) * 2^-53 - 0.5: the generator's twin.
fn splitmix(seed: u64, n: usize) -> Vec<f64> {
    driftless::synthetic::SplitMix64(seed)
        .take(n)
        .map(|u| u - 0.5)
        .collect()
}

fn signal(n: usize) -> Vec<f64> {
    splitmix(n as u64, n)
}

/// One stored output array: `[len, max_abs, dot, idx (null = all), val]`.
struct Band {
    len: usize,
    max: f64,
    dot: f64,
    idx: Option<Vec<usize>>,
    val: Vec<f64>,
}

impl Band {
    fn parse(v: &Value) -> Band {
        let a = v.as_array().expect("band is an array");
        let num = |v: &Value| v.as_f64().expect("number");
        let val: Vec<f64> = a[4].as_array().expect("values").iter().map(num).collect();
        let idx = a[3].as_array().map(|ix| {
            ix.iter()
                .map(|i| i.as_u64().expect("index") as usize)
                .collect::<Vec<_>>()
        });
        let band = Band {
            len: a[0].as_u64().expect("len") as usize,
            max: num(&a[1]),
            dot: num(&a[2]),
            idx,
            val,
        };
        match &band.idx {
            Some(ix) => assert_eq!(ix.len(), band.val.len(), "fixture: idx/val mismatch"),
            None => assert_eq!(band.len, band.val.len(), "fixture: full band length"),
        }
        band
    }

    /// The whole reference array, when stored whole.
    fn full(&self) -> Option<Vec<f64>> {
        self.idx.is_none().then(|| self.val.clone())
    }
}

/// Worst errors seen, and every failure (reported together at the end).
struct Checker {
    weights: Vec<f64>,
    worst_value: (f64, String),
    worst_dot: (f64, String),
    /// Worst value error among bands judged against their own max (not the round-off floor).
    worst_unfloored: (f64, String),
    values_checked: usize,
    bands_checked: usize,
    failures: Vec<String>,
}

impl Checker {
    fn new() -> Checker {
        Checker {
            weights: splitmix(0xC0FFEE, 40_000),
            worst_value: (0.0, String::new()),
            worst_dot: (0.0, String::new()),
            worst_unfloored: (0.0, String::new()),
            values_checked: 0,
            bands_checked: 0,
            failures: Vec::new(),
        }
    }

    /// Compares `ours` with a reference band, errors relative to max(band max, `floor`) (see
    /// [`ROUNDOFF_FLOOR`]).
    fn check(&mut self, what: &str, band: &Band, ours: &[f64], floor: f64) {
        self.bands_checked += 1;
        if ours.len() != band.len {
            self.failures.push(format!(
                "{what}: length {} != PyWavelets' {}",
                ours.len(),
                band.len
            ));
            return;
        }
        let denom = band.max.max(floor).max(f64::MIN_POSITIVE);
        let mut err: f64 = 0.0;
        let positions: Vec<usize> = match &band.idx {
            Some(ix) => ix.clone(),
            None => (0..band.len).collect(),
        };
        for (&i, &r) in positions.iter().zip(&band.val) {
            err = err.max((ours[i] - r).abs() / denom);
            self.values_checked += 1;
        }
        let our_max = ours.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        err = err.max((our_max - band.max).abs() / denom);
        let w = &self.weights[..ours.len()];
        let dot: f64 = w.iter().zip(ours).map(|(w, c)| w * c).sum();
        let wsum: f64 = w.iter().map(|w| w.abs()).sum();
        // If every value were within TOL * denom, the checksum would be within TOL * denom * wsum.
        let dot_err = if wsum > 0.0 {
            (dot - band.dot).abs() / (denom * wsum)
        } else {
            0.0
        };
        if band.max >= floor && err > self.worst_unfloored.0 {
            self.worst_unfloored = (err, what.to_string());
        }
        if err > self.worst_value.0 {
            self.worst_value = (err, what.to_string());
        }
        if dot_err > self.worst_dot.0 {
            self.worst_dot = (dot_err, what.to_string());
        }
        if err > TOL || dot_err > TOL {
            self.failures.push(format!(
                "{what}: value error {err:.3e}, checksum error {dot_err:.3e}"
            ));
        }
    }

    fn finish(self, name: &str) {
        println!(
            "{name}: {} bands, {} stored values; worst value error {:.3e} ({}), worst checksum \
             error {:.3e} ({}); worst value error on bands above the round-off floor {:.3e} ({})",
            self.bands_checked,
            self.values_checked,
            self.worst_value.0,
            self.worst_value.1,
            self.worst_dot.0,
            self.worst_dot.1,
            self.worst_unfloored.0,
            self.worst_unfloored.1
        );
        assert!(
            self.failures.is_empty(),
            "{} mismatches with PyWavelets, first ones:\n{}",
            self.failures.len(),
            self.failures[..self.failures.len().min(20)].join("\n")
        );
    }
}

fn load(file: &str) -> Vec<Value> {
    let path = format!("{}/tests/fixtures/pywt/{file}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let doc: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert_eq!(
        doc["pywavelets"], "1.9.0",
        "{path}: generated by another PyWavelets"
    );
    doc["cases"].as_array().expect("cases").clone()
}

fn head(case: &Value) -> (Wavelet, Mode, usize) {
    let w = Wavelet::by_name(case[0].as_str().expect("wavelet")).expect("known wavelet");
    let mode: Mode = case[1].as_str().expect("mode").parse().expect("known mode");
    let n = case[2].as_u64().expect("n") as usize;
    (w, mode, n)
}

#[test]
fn dwt_and_idwt_match_pywavelets() {
    let cases = load("dwt.json");
    let mut c = Checker::new();
    let mut covered = BTreeSet::new();
    for case in &cases {
        let (w, mode, n) = head(case);
        covered.insert((w.name(), mode.name(), n));
        let what = format!("dwt {} {mode} n={n}", w.name());
        let x = signal(n);
        let bands: Vec<Band> = case[3]
            .as_array()
            .expect("bands")
            .iter()
            .map(Band::parse)
            .collect();
        let floor = ROUNDOFF_FLOOR * bands[0].max.max(bands[1].max);
        let (ca, cd) = transform::dwt(&x, &w, mode);
        c.check(&format!("{what} cA"), &bands[0], &ca, floor);
        c.check(&format!("{what} cD"), &bands[1], &cd, floor);
        // idwt of PyWavelets' own coefficients where they are stored whole, else of ours.
        let (ra, rd) = match (bands[0].full(), bands[1].full()) {
            (Some(a), Some(d)) => (a, d),
            _ => (ca, cd),
        };
        let rec = transform::idwt(&ra, &rd, &w, mode);
        let rec_band = Band::parse(&case[4]);
        c.check(
            &format!("{what} idwt"),
            &rec_band,
            &rec,
            ROUNDOFF_FLOOR * rec_band.max,
        );
    }
    // Every n in 1..=40 in every mode (PyWavelets refuses reflect at n = 1), db20 in all modes.
    for mode in Mode::ALL {
        for n in 1..=40 {
            let present = covered.iter().any(|&(_, m, k)| m == mode.name() && k == n);
            assert!(
                present || (mode == Mode::Reflect && n == 1),
                "{mode} n={n} missing"
            );
        }
        assert!(covered.contains(&("db20", mode.name(), 40)));
    }
    c.finish("dwt.json");
}

#[test]
fn wavedec_and_waverec_match_pywavelets() {
    let cases = load("wavedec.json");
    let mut c = Checker::new();
    let (mut wavelets, mut modes, mut longest) = (BTreeSet::new(), BTreeSet::new(), 0);
    for case in &cases {
        let (w, mode, n) = head(case);
        wavelets.insert(w.name());
        modes.insert(mode.name());
        longest = longest.max(n);
        let what = format!("wavedec {} {mode} n={n}", w.name());
        let x = signal(n);
        let bands: Vec<Band> = case[3]
            .as_array()
            .expect("bands")
            .iter()
            .map(Band::parse)
            .collect();
        let top = bands.len() - 1;
        assert_eq!(transform::dwt_max_level(n, w.filter_len()), top, "{what}");
        let floor = ROUNDOFF_FLOOR * bands.iter().fold(0.0f64, |m, b| m.max(b.max));
        let coeffs = transform::wavedec(&x, &w, mode, top).expect("valid level");
        for (k, (band, ours)) in bands.iter().zip(&coeffs).enumerate() {
            c.check(&format!("{what} L{top} band {k}"), band, ours, floor);
        }

        // Lower levels: PyWavelets' approximation; the details are the deepest ones' tail.
        let approx: Vec<Band> = case[4]
            .as_array()
            .expect("approx")
            .iter()
            .map(Band::parse)
            .collect();
        assert_eq!(approx.len(), top - 1, "{what}");
        for (lev, band) in (1..top).zip(&approx) {
            let cl = transform::wavedec(&x, &w, mode, lev).expect("valid level");
            c.check(&format!("{what} L{lev} cA"), band, &cl[0], floor);
            assert_eq!(cl[1..], coeffs[top - lev + 1..], "{what} L{lev} details");
        }

        // waverec of PyWavelets' coefficients where all are stored whole, else of ours.
        let input: Vec<Vec<f64>> = match bands.iter().map(Band::full).collect::<Option<Vec<_>>>() {
            Some(reference) => reference,
            None => coeffs.clone(),
        };
        let rec = transform::waverec(&input, &w, mode).expect("consistent coefficients");
        let rec_band = Band::parse(&case[5]);
        c.check(
            &format!("{what} waverec"),
            &rec_band,
            &rec,
            ROUNDOFF_FLOOR * rec_band.max,
        );

        // The plan must give exactly the free functions' results.
        let mut plan = Plan::new(&w, mode, n, top).expect("valid plan");
        let mut flat = vec![0.0; plan.coeffs_len()];
        plan.wavedec(&x, &mut flat);
        let planned: Vec<Vec<f64>> = plan
            .ranges()
            .iter()
            .map(|r| flat[r.clone()].to_vec())
            .collect();
        assert_eq!(
            planned, coeffs,
            "{what}: Plan::wavedec differs from wavedec"
        );
        let mut out = vec![0.0; n];
        plan.waverec(&flat, &mut out);
        let free = transform::waverec(&coeffs, &w, mode).expect("consistent coefficients");
        assert_eq!(
            out[..],
            free[..n],
            "{what}: Plan::waverec differs from waverec"
        );
    }
    assert_eq!(wavelets.len(), 16, "wavelets covered: {wavelets:?}");
    assert_eq!(modes.len(), 7, "modes covered: {modes:?}");
    assert!(longest >= 20_000, "longest signal {longest}");
    c.finish("wavedec.json");
}

#[test]
fn input_generator_matches_python() {
    // Printed by the Python generator: signal(3) and the first checksum weight, bit for bit.
    assert_eq!(
        signal(3),
        [
            -0.38654965794284546,
            0.20029351359290237,
            0.11297468254662435
        ]
    );
    assert_eq!(splitmix(0xC0FFEE, 1)[0], 0.29104751221925373);
}
