//! `nav::fusion::FusionBias` against x-io Fusion's own `imufusion.Bias` (1.3.3, default
//! settings) on the same rates: the corrected rates and the offset equal bit for bit at every
//! 50th sample, and the in-order sum of every corrected rate equals imufusion's to the last
//! bit, so a wrong value anywhere shows. Fixtures and the inputs' recipe:
//! `scripts/gen_fusion_fixture.py`.

use driftless::nav::fusion::FusionBias;
use driftless::synthetic::SplitMix64;

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/fusion");

/// The script's `signal`, operation for operation.
fn signal(rate: f64, seconds: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut u = SplitMix64(seed);
    let bias = [0.4, -0.3, 0.2];
    let n = (rate * seconds) as usize;
    (0..n)
        .map(|k| {
            let t = k as f64 / rate;
            let mut row = [0.0; 3];
            for (a, r) in row.iter_mut().enumerate() {
                *r = bias[a] + 0.6 * (u.next().unwrap() - 0.5);
            }
            if (20.0..25.0).contains(&t) {
                row[2] += 20.0;
            }
            if (27.0..30.0).contains(&t) {
                row[0] += 10.0;
            }
            if (60.0..75.0).contains(&t) {
                let mut phase = (t - 60.0) * 0.2;
                phase -= phase.trunc();
                row[1] += 4.0 * (phase - 0.5).abs() - 1.0;
            }
            row
        })
        .collect()
}

fn check(rate: u32, seed: u64) {
    let path = format!("{FIXTURES}/bias_{rate}hz.csv");
    let text = std::fs::read_to_string(&path).expect("fixture (scripts/gen_fusion_fixture.py)");
    let mut rows = text.lines().skip(1);
    let input = signal(rate as f64, 90.0, seed);
    let mut f = FusionBias::new(rate as f64);
    let mut sums = [0.0f64; 3];
    let mut checked = 0;
    let mut next = rows.next().expect("a row");
    for (k, x) in input.iter().enumerate() {
        let out = f.update(*x);
        for a in 0..3 {
            sums[a] += out[a];
        }
        let cols: Vec<&str> = next.split(',').collect();
        if cols[0] == k.to_string() {
            let want: Vec<f64> = cols[1..7].iter().map(|v| v.parse().unwrap()).collect();
            let off = f.offset();
            let got = [out[0], out[1], out[2], off[0], off[1], off[2]];
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                assert_eq!(
                    g.to_bits(),
                    w.to_bits(),
                    "{path}: sample {k}, column {}: {g} against imufusion's {w}",
                    i + 1
                );
            }
            checked += 1;
            next = rows.next().expect("more rows");
        }
    }
    let cols: Vec<&str> = next.split(',').collect();
    assert_eq!(cols[0], "sum", "{path}: every stored sample checked");
    for a in 0..3 {
        let want: f64 = cols[a + 1].parse().unwrap();
        assert_eq!(
            sums[a].to_bits(),
            want.to_bits(),
            "{path}: sum of axis {a}: {} against imufusion's {want}",
            sums[a]
        );
    }
    assert!(checked > 150, "{checked} samples compared");
    // The signal reaches every branch: the offset learnt the bias, the sway moved it.
    let off = f.offset();
    assert!((off[0] - 0.4).abs() < 0.25 && off[0] > 0.05, "{off:?}");
}

#[test]
fn equals_imufusion_at_100_hz() {
    check(100, 100);
}

#[test]
fn equals_imufusion_at_1_khz() {
    check(1000, 1000);
}
