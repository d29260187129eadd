//! The flags that qualify a sample: a raw sample's ([`RAW_INVALID`], ...), an output's
//! ([`FLAG_WARMING_UP`], ...) and which sensors an output carries ([`SENSOR_ACCEL`], ...).

/// Raw-sample flag: the sensor driver marks the sample as invalid.
pub const RAW_INVALID: u32 = 1;
/// Raw-sample flag: the vehicle stands at this sample, by a signal logged with it (a replay's
/// stop column): a stop signal judged by sample time, not by wall-clock age.
pub const RAW_VEHICLE_STOPPED: u32 = 1 << 1;
/// Raw-sample flag: the vehicle moves at this sample (as [`RAW_VEHICLE_STOPPED`]). Neither:
/// unknown.
pub const RAW_VEHICLE_MOVING: u32 = 1 << 2;
/// Raw-sample flag: the source does not believe this sample's stamp (a ROS 2 stamp of 0, "not
/// set"; or a stamp its bridge judged as the guard would, [`crate::clock::StampCheck`]). The
/// guard flags it [`FLAG_STAMP_FAULT`] and counts it, never as a loss.
pub const RAW_STAMP_FAULT: u32 = 1 << 3;
/// Raw-sample flag: the sample carries an accelerometer reading (`accel`). Without it the
/// sample is gyro-only: the accelerometer is absent, never zero.
pub const RAW_ACCEL: u32 = 1 << 4;
/// Raw-sample flag: the sample carries a magnetometer reading (`mag`).
pub const RAW_MAG: u32 = 1 << 5;

/// Sensors word: the output carries an accelerometer reading (`accel`).
pub const SENSOR_ACCEL: u32 = 1;
/// Sensors word: the output carries a magnetometer reading (`mag`).
pub const SENSOR_MAG: u32 = 1 << 1;
/// Sensors word: the accelerometer's input was not finite; `accel` holds the last good reading.
pub const SENSOR_ACCEL_INVALID: u32 = 1 << 2;
/// Sensors word: the magnetometer's input was not finite; `mag` holds the last good reading.
pub const SENSOR_MAG_INVALID: u32 = 1 << 3;
/// Sensors word: the sample carries an orientation (`orientation`, `orientation_std`): an
/// attitude stage ran.
pub const SENSOR_ORIENTATION: u32 = 1 << 4;
/// Sensors word: the attitude stage had no valid accelerometer at this sample; the inclination
/// rests on the gyro alone (coasting) and its standard deviation grows.
pub const SENSOR_ORIENTATION_COASTING: u32 = 1 << 5;
/// Sensors word: the accelerometer's norm said free fall or a shock at this sample (outside
/// the attitude stage's `min_g`..`max_g`); the reading was used all the same.
pub const SENSOR_ORIENTATION_NO_GRAVITY: u32 = 1 << 6;
/// Sensors word: the orientation's heading is absolute, from magnetic north (or true north
/// with the attitude stage's `declination_deg`), not relative to where the stage started: the
/// magnetometer fixed it (`use_mag`). Once set it stays so; `orientation_std`'s z is then the
/// magnetometer heading filter's.
pub const SENSOR_HEADING_ABSOLUTE: u32 = 1 << 7;
/// Sensors word: the sample carried a magnetometer reading that the attitude stage rejected
/// as disturbed (its norm, dip or constancy off the learnt field, still settling after that,
/// or its heading at odds with the gyro's): the heading rests on the gyro here.
pub const SENSOR_MAG_REJECTED: u32 = 1 << 8;

/// Output flag: a stage is still filling (denoiser window, predictor warm-up).
pub const FLAG_WARMING_UP: u32 = 1;
/// Output flag: the input was NaN/Inf or marked invalid; the last valid value was held.
pub const FLAG_INPUT_INVALID: u32 = 1 << 1;
/// Output flag: one or more sequence numbers are missing before this sample.
pub const FLAG_GAP_BEFORE: u32 = 1 << 2;
/// Output flag: the sensor timestamp went backwards at this sample.
pub const FLAG_TIME_BACKWARDS: u32 = 1 << 3;
/// Output flag: emitted while draining at shutdown (a lagged stage's held samples).
pub const FLAG_FLUSHED: u32 = 1 << 4;
/// Output flag: a non-finite value was produced by a stage and replaced by 0 before publishing.
pub const FLAG_OUTPUT_REPAIRED: u32 = 1 << 5;
/// Output flag (`predict.rbf`): every axis judged still; the drift model was re-anchored on the
/// measured drift.
pub const FLAG_STILL: u32 = 1 << 6;
/// Output flag (`predict.rbf`): an axis judged moving; its drift model runs on its own
/// predictions, so the rotation is not subtracted.
pub const FLAG_MOVING: u32 = 1 << 7;
/// Output flag (`predict.bias` with a stop signal): the vehicle said it stands while the gyro
/// clearly turned; the signal was not trusted for this sample (it counts as moving).
pub const FLAG_STOP_CONTRADICTED: u32 = 1 << 8;

/// Output flag: the raw sample said the vehicle stood ([`RAW_VEHICLE_STOPPED`], carried on
/// with the sample through every stage; `predict.bias` takes it as its stop signal).
pub const FLAG_VEHICLE_STOPPED: u32 = 1 << 9;
/// Output flag: the raw sample said the vehicle moved ([`RAW_VEHICLE_MOVING`]).
pub const FLAG_VEHICLE_MOVING: u32 = 1 << 10;
/// Output flag: the sensor's stamp was not believed (it went back, leapt more than 10 s ahead,
/// or was unset: [`crate::clock::StampCheck`]); `t_ns` is the source's as it came. A stamp that
/// went back also sets [`FLAG_TIME_BACKWARDS`].
pub const FLAG_STAMP_FAULT: u32 = 1 << 11;

/// The output flags by name, in bit order (`tap`, `record` and reports decode them with it).
pub const FLAG_NAMES: [(u32, &str); 12] = [
    (FLAG_WARMING_UP, "warming_up"),
    (FLAG_INPUT_INVALID, "input_invalid"),
    (FLAG_GAP_BEFORE, "gap_before"),
    (FLAG_TIME_BACKWARDS, "time_backwards"),
    (FLAG_FLUSHED, "flushed"),
    (FLAG_OUTPUT_REPAIRED, "output_repaired"),
    (FLAG_STILL, "still"),
    (FLAG_MOVING, "moving"),
    (FLAG_STOP_CONTRADICTED, "stop_contradicted"),
    (FLAG_VEHICLE_STOPPED, "vehicle_stopped"),
    (FLAG_VEHICLE_MOVING, "vehicle_moving"),
    (FLAG_STAMP_FAULT, "stamp_fault"),
];

/// The raw-sample flags by name, in bit order.
pub const RAW_FLAG_NAMES: [(u32, &str); 6] = [
    (RAW_INVALID, "invalid"),
    (RAW_VEHICLE_STOPPED, "vehicle_stopped"),
    (RAW_VEHICLE_MOVING, "vehicle_moving"),
    (RAW_STAMP_FAULT, "stamp_fault"),
    (RAW_ACCEL, "accel"),
    (RAW_MAG, "mag"),
];

/// The sensors word's bits by name, in bit order.
pub const SENSOR_NAMES: [(u32, &str); 9] = [
    (SENSOR_ACCEL, "accel"),
    (SENSOR_MAG, "mag"),
    (SENSOR_ACCEL_INVALID, "accel_invalid"),
    (SENSOR_MAG_INVALID, "mag_invalid"),
    (SENSOR_ORIENTATION, "orientation"),
    (SENSOR_ORIENTATION_COASTING, "orientation_coasting"),
    (SENSOR_ORIENTATION_NO_GRAVITY, "orientation_no_gravity"),
    (SENSOR_HEADING_ABSOLUTE, "heading_absolute"),
    (SENSOR_MAG_REJECTED, "mag_rejected"),
];

/// Names of the output flags set in `flags` ([`FLAG_NAMES`]); a bit without a name reads as
/// its hex value, so nothing is hidden.
pub fn flag_names(flags: u32) -> Vec<String> {
    bit_names(flags, &FLAG_NAMES)
}

/// Names of the raw-sample flags set in `flags` ([`RAW_FLAG_NAMES`]), as [`flag_names`].
pub fn raw_flag_names(flags: u32) -> Vec<String> {
    bit_names(flags, &RAW_FLAG_NAMES)
}

/// Names of the sensors word's bits set in `sensors` ([`SENSOR_NAMES`]), as [`flag_names`].
pub fn sensor_names(sensors: u32) -> Vec<String> {
    bit_names(sensors, &SENSOR_NAMES)
}

/// Names of the bits set in `flags`, by `table` (one of the tables above); a bit without a
/// name reads as its hex value.
pub fn bit_names(flags: u32, table: &[(u32, &str)]) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = flags;
    for &(bit, name) in table {
        if flags & bit != 0 {
            names.push(name.to_string());
            rest &= !bit;
        }
    }
    for i in 0..32 {
        if rest & (1 << i) != 0 {
            names.push(format!("{:#x}", 1u32 << i));
        }
    }
    names
}
