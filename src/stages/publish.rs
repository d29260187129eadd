//! `publish`: the last guard before the public service: no non-finite value ever leaves.

use crate::pipeline::stage::Stage;
use crate::transport::{GyroSample, FLAG_OUTPUT_REPAIRED};

/// Passes samples through, replacing any non-finite value by 0 and flagging it.
pub struct Publish;

fn repair(v: &mut [f64; 3]) -> bool {
    let mut bad = false;
    for x in v.iter_mut() {
        if !x.is_finite() {
            *x = 0.0;
            bad = true;
        }
    }
    bad
}

impl Stage for Publish {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        let bad = repair(&mut out.rate) | repair(&mut out.drift) | repair(&mut out.denoised);
        if bad {
            out.flags |= FLAG_OUTPUT_REPAIRED;
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_lets_a_nan_out() {
        let s = GyroSample {
            rate: [f64::NAN, 1.0, f64::NEG_INFINITY],
            ..GyroSample::default()
        };
        let o = Publish.process(&s).unwrap();
        assert_eq!(o.rate, [0.0, 1.0, 0.0]);
        assert!(o.flags & FLAG_OUTPUT_REPAIRED != 0);
    }
}
