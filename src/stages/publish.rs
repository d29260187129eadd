//! `publish`: the last guard before the public service: no non-finite value ever leaves (a
//! non-finite `drift_std` leaves as "not provided", -1; an orientation with one, as none).
//!
//! ```toml
//! [[stage]]
//! name = "publish"
//! kind = "publish"
//! input = "demo/predicted"
//! output = "demo/corrected"
//! # notify = true            # notify the event service of the same name after each sample
//! ```

use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Role, Stage};
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type};
use crate::wire::{GyroSample, DRIFT_STD_NOT_PROVIDED, FLAG_OUTPUT_REPAIRED, SENSOR_ORIENTATION};

const NOTIFY: Key = Key {
    name: "notify",
    ty: Type::Bool,
    default: DefaultValue::Bool(true),
    doc: "notify the event service named like `output` after each sample",
};

/// `publish`.
pub const KIND: Kind = Kind {
    name: "publish",
    role: Role::Publish,
    summary:
        "the final guard before the public service: non-finite values replaced by 0 and flagged",
    keys: &[NOTIFY],
    parse,
};

/// `publish` parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PublishParams {
    /// Notify the event service of the same name after each sample.
    pub notify: bool,
}

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    Ok(Box::new(PublishParams {
        notify: t.bool_or_default(&NOTIFY)?,
    }))
}

impl Params for PublishParams {
    fn stage(&self, _cx: &Context) -> Result<Box<dyn Stage>, String> {
        Ok(Box::new(Publish))
    }

    fn notifies(&self) -> bool {
        self.notify
    }
}

/// Passes samples through, replacing any non-finite value by 0 and flagging it.
pub struct Publish;

fn repair(v: &mut [f64]) -> bool {
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
        let mut bad = repair(&mut out.rate)
            | repair(&mut out.drift)
            | repair(&mut out.denoised)
            | repair(&mut out.accel)
            | repair(&mut out.mag);
        // An uncertainty that is not a number is not known: say so, never publish 0 (exact).
        for s in out
            .drift_std
            .iter_mut()
            .chain(out.accel_std.iter_mut())
            .chain(out.orientation_std.iter_mut())
        {
            if !s.is_finite() {
                *s = DRIFT_STD_NOT_PROVIDED;
                bad = true;
            }
        }
        // A quaternion with a NaN in it is no orientation (and 0 in its place no rotation):
        // the sample goes out without one.
        if repair(&mut out.orientation) {
            out.orientation = [0.0; 4];
            out.orientation_std = [DRIFT_STD_NOT_PROVIDED; 3];
            out.sensors &= !SENSOR_ORIENTATION;
            bad = true;
        }
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
        let s = GyroSample {
            drift_std: [f64::NAN, 1e-4, f64::INFINITY],
            ..GyroSample::default()
        };
        let o = Publish.process(&s).unwrap();
        assert_eq!(
            o.drift_std,
            [DRIFT_STD_NOT_PROVIDED, 1e-4, DRIFT_STD_NOT_PROVIDED]
        );
        assert!(o.flags & FLAG_OUTPUT_REPAIRED != 0);
        let s = GyroSample {
            accel: [0.0, f64::NAN, 9.8],
            accel_std: [f64::NAN, 1e-3, 1e-3],
            sensors: crate::wire::SENSOR_ACCEL,
            ..GyroSample::default()
        };
        let o = Publish.process(&s).unwrap();
        assert_eq!(o.accel, [0.0, 0.0, 9.8]);
        assert_eq!(o.accel_std, [DRIFT_STD_NOT_PROVIDED, 1e-3, 1e-3]);
        assert!(o.flags & FLAG_OUTPUT_REPAIRED != 0);
        let s = GyroSample {
            orientation: [0.0, f64::NAN, 0.0, 1.0],
            orientation_std: [1e-3, 1e-3, 0.1],
            sensors: SENSOR_ORIENTATION,
            ..GyroSample::default()
        };
        let o = Publish.process(&s).unwrap();
        assert_eq!(o.orientation_estimate(), None);
        assert_eq!(o.orientation_std, [DRIFT_STD_NOT_PROVIDED; 3]);
        assert!(o.flags & FLAG_OUTPUT_REPAIRED != 0);
        let fine = GyroSample::default();
        assert_eq!(
            Publish.process(&fine).unwrap().flags,
            0,
            "-1 is not a repair"
        );
    }
}
