//! The accelerometer's noise terms in a stage's table: `accel_vrw` and
//! `accel_bias_instability`, in the units `driftless allan --accel-column` prints and
//! `allan --stage` writes them. One definition, keys and reading, for every stage that reads
//! them (`predict.bias`'s stillness test that uses both sensors). Their defaults are the
//! ADIS16405 data sheet's ([`AccelTerms::ADIS16405`]).

use crate::drift::bias::{AccelTerms, ADIS16405_BIAS_INSTABILITY_MG, ADIS16405_VRW_PER_HOUR};
use crate::io::InputError;
use crate::stages::schema::{DefaultValue, Key, Table, Type};

/// `accel_vrw`.
pub const ACCEL_VRW: Key = Key {
    name: "accel_vrw",
    ty: Type::Positive(100.0),
    default: DefaultValue::Noted(
        &DefaultValue::Float(ADIS16405_VRW_PER_HOUR),
        " m/s/sqrt(h): the ADIS16405 data sheet's",
    ),
    doc: "the accelerometer's velocity random walk N, m/s/sqrt(h) (as `driftless allan --accel-column` prints it): its white noise, N / 60 x sqrt(rate_hz) m/s^2 per sample",
};

/// `accel_bias_instability`.
pub const ACCEL_BIAS_INSTABILITY: Key = Key {
    name: "accel_bias_instability",
    ty: Type::NonNegative,
    default: DefaultValue::Noted(
        &DefaultValue::Float(ADIS16405_BIAS_INSTABILITY_MG),
        " mg: the ADIS16405 data sheet's (its in-run stability, 0.2 mg, is the Allan floor 0.664 B)",
    ),
    doc: "the accelerometer's bias instability B, mg (1 mg = 0.00980665 m/s^2)",
};

/// The accelerometer's terms of a stage's table, each key's default where it is absent.
pub fn read(t: &mut Table<'_, '_>) -> Result<AccelTerms, InputError> {
    let vrw = t.float_or_default(&ACCEL_VRW)?;
    let b = t.float_or_default(&ACCEL_BIAS_INSTABILITY)?;
    Ok(AccelTerms::from_stage_units(vrw, b))
}
