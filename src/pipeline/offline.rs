//! The daemon's stage code without the daemon: the same [`Guard`] and the same stages, built
//! from the same pipeline file, in chain order, each output handed to the next stage in
//! memory instead of through an iceoryx2 hop. The daemon's in-thread hops deliver every sample
//! once and in order, so for the same raw samples this gives the same published samples as a
//! live run (a test checks it, sample for sample); offline tools (`driftless nav-eval`) judge
//! exactly what the daemon publishes.

use crate::pipeline::config::Pipeline;
use crate::pipeline::guard::Guard;
use crate::stages::contract::{Role, SideInput, SideValue, Stage};
use crate::wire::{GyroSample, RawSample, StopSignal, RAW_ACCEL, RAW_MAG};

/// The epoch of an offline run's samples (a daemon picks a random one per start).
pub const OFFLINE_EPOCH: u32 = 1;

/// A pipeline's guard and stages (everything after the ingest), run in the caller's thread.
pub struct Offline {
    guard: Guard,
    stages: Vec<Box<dyn Stage>>,
    /// Per stage, what its side inputs carry, by slot.
    sides: Vec<Vec<SideInput>>,
}

impl Offline {
    /// Build the stages of a validated pipeline. A pipeline with an `external` stage cannot run
    /// offline (that stage is another process).
    pub fn new(p: &Pipeline) -> Result<Self, String> {
        let cx = p.context();
        let mut stages = Vec::with_capacity(p.stages.len());
        let mut sides = Vec::with_capacity(p.stages.len());
        for spec in p.stages.iter().skip(1) {
            sides.push(
                spec.params
                    .side_inputs()
                    .into_iter()
                    .map(|(_, k)| k)
                    .collect(),
            );
            if spec.kind.role == Role::External {
                return Err(format!(
                    "stage {:?} is external (another process): the pipeline cannot run offline",
                    spec.name
                ));
            }
            stages.push(
                spec.params
                    .stage(&cx)
                    .map_err(|e| format!("stage {:?}: {e}", spec.name))?,
            );
        }
        Ok(Offline {
            guard: Guard::new(p.input_units, p.accel_units, p.axes, OFFLINE_EPOCH),
            stages,
            sides,
        })
    }

    /// Hand `value` to every side input that carries its kind, as the daemon does when a new
    /// value arrives on the service: offline, the caller publishes the side inputs.
    pub fn side(&mut self, value: &SideValue) {
        let kind = match value {
            SideValue::Stop(_) => SideInput::Stop { by_speed: false },
        };
        for (stage, kinds) in self.stages.iter_mut().zip(&self.sides) {
            for (slot, k) in kinds.iter().enumerate() {
                if *k == kind {
                    stage.side(slot, value);
                }
            }
        }
    }

    /// One raw sample through the guard and every stage; `out` receives what the last stage
    /// publishes (nothing while a lagged stage fills up). Offline, the sample's own time
    /// stands for its ingest time (`ingest_ns`, what a side input's age is judged against).
    pub fn push(&mut self, raw: &RawSample, out: &mut impl FnMut(GyroSample)) {
        let raw = self.guard.stamp(raw);
        let s = self.guard.admit(&raw, raw.t_ns);
        self.run_from(0, s, out);
    }

    /// At the end of the input: drain the lagged stages, oldest first, as the daemon does.
    pub fn finish(&mut self, out: &mut impl FnMut(GyroSample)) {
        for k in 0..self.stages.len() {
            while let Some(s) = self.stages[k].flush() {
                self.run_from(k + 1, s, out);
            }
        }
    }

    /// Total algorithmic delay of the stages, samples.
    pub fn lag(&self) -> usize {
        self.stages.iter().map(|s| s.lag()).sum()
    }

    /// Rates (deg/s) through `p`'s stages: `inputs` holds one measured series per axis (deg/s,
    /// equal lengths, sample k at time k / `rate_hz`); the result has one corrected series per
    /// input, aligned with it (the stages' lag undone by the flush at the end). Lanes beyond the
    /// pipeline's `axes` run in further passes. `stops`, when given, is the vehicle's stop
    /// signal at each sample, handed to every stop side input before the sample (stamped with
    /// its time). What `driftless nav-eval` judges a chain by.
    pub fn run_series(
        p: &Pipeline,
        inputs: &[&[f64]],
        stops: Option<&[bool]>,
    ) -> Result<Vec<Vec<f64>>, String> {
        Offline::run_imu_series(p, inputs, None, stops)
    }

    /// [`Offline::run_series`] with the accelerometer: `accel`, when given, is the specific
    /// force (m/s²) at each sample, carried in every raw sample beside its rates (in the
    /// pipeline's `accel_units`); without it the samples carry none, as a gyro-only source's.
    pub fn run_imu_series(
        p: &Pipeline,
        inputs: &[&[f64]],
        accel: Option<&[[f64; 3]]>,
        stops: Option<&[bool]>,
    ) -> Result<Vec<Vec<f64>>, String> {
        let mut out = Vec::with_capacity(inputs.len());
        for chunk in inputs.chunks(p.axes) {
            let samples = Offline::run_imu_samples(p, chunk, accel, stops)?;
            for lane in 0..chunk.len() {
                out.push(
                    samples
                        .iter()
                        .map(|s| s.map_or(f64::NAN, |g| g.rate[lane].to_degrees()))
                        .collect(),
                );
            }
        }
        Ok(out)
    }

    /// What [`Offline::run_imu_series`] runs for one pass: the published sample at each input
    /// sample (None where the stages published none for it), `inputs` holding at most the
    /// pipeline's `axes` series (deg/s). An attitude stage's orientation is read from here.
    pub fn run_imu_samples(
        p: &Pipeline,
        inputs: &[&[f64]],
        accel: Option<&[[f64; 3]]>,
        stops: Option<&[bool]>,
    ) -> Result<Vec<Option<GyroSample>>, String> {
        Offline::run_imu_mag_samples(p, inputs, accel, None, stops)
    }

    /// [`Offline::run_imu_samples`] with the magnetometer: `mag`, when given, is the field
    /// (tesla) at each sample, carried in every raw sample beside its rates; without it the
    /// samples carry none.
    pub fn run_imu_mag_samples(
        p: &Pipeline,
        inputs: &[&[f64]],
        accel: Option<&[[f64; 3]]>,
        mag: Option<&[[f64; 3]]>,
        stops: Option<&[bool]>,
    ) -> Result<Vec<Option<GyroSample>>, String> {
        if inputs.is_empty() || inputs.len() > p.axes {
            return Err(format!(
                "{} series for a pipeline of {} axes",
                inputs.len(),
                p.axes
            ));
        }
        let to_units = 1.0f64.to_radians() / p.input_units.to_rad_per_s();
        let n = inputs[0].len();
        let mut off = Offline::new(p)?;
        let mut got: Vec<Option<GyroSample>> = vec![None; n];
        let mut put = |g: GyroSample| {
            if let Some(slot) = got.get_mut(g.seq as usize) {
                *slot = Some(g);
            }
        };
        for k in 0..n {
            let mut rate = [0.0; 3];
            for (lane, r) in rate.iter_mut().enumerate().take(p.axes) {
                // Unused lanes repeat the first axis (their output is not read).
                *r = inputs.get(lane).unwrap_or(&inputs[0])[k] * to_units;
            }
            let mut raw = raw_sample(p, k, rate, accel.and_then(|a| a.get(k)));
            if let Some(m) = mag.and_then(|m| m.get(k)) {
                raw.mag = *m;
                raw.flags |= RAW_MAG;
            }
            if let Some(stopped) = stops.and_then(|s| s.get(k)) {
                off.side(&SideValue::Stop(StopSignal::new(
                    raw.t_ns.max(1),
                    f64::NAN,
                    u32::from(*stopped),
                )));
            }
            off.push(&raw, &mut put);
        }
        off.finish(&mut put);
        Ok(got)
    }

    fn run_from(&mut self, first: usize, mut s: GyroSample, out: &mut impl FnMut(GyroSample)) {
        for stage in &mut self.stages[first..] {
            match stage.process(&s) {
                Some(next) => s = next,
                None => return,
            }
        }
        out(s);
    }
}

/// Sample `k` of an offline run of `p`: its time `k / rate_hz`, its rates in `input_units`,
/// and the specific force `accel` (m/s²), when given, in `accel_units` and flagged present.
fn raw_sample(p: &Pipeline, k: usize, rate: [f64; 3], accel: Option<&[f64; 3]>) -> RawSample {
    let mut raw = RawSample {
        t_ns: (k as f64 * 1e9 / p.rate_hz).round() as u64,
        seq: k as u64,
        rate,
        ..RawSample::default()
    };
    if let Some(f) = accel {
        let to_units = 1.0 / p.accel_units.to_m_per_s2();
        raw.accel = f.map(|v| v * to_units);
        raw.flags |= RAW_ACCEL;
    }
    raw
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::config;
    use crate::units::AccelUnit;
    use std::path::Path;

    fn pipeline(accel_units: AccelUnit) -> Pipeline {
        let text = format!(
            r#"name = "t"
rate_hz = 100.0
axes = 3
input_units = "deg/s"
accel_units = "{accel_units}"

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "t/raw"

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "t/raw"
output = "t/denoised"

[[stage]]
name = "publish"
kind = "publish"
input = "t/denoised"
output = "t/corrected"
"#
        );
        config::parse(Path::new("t.toml"), &text).unwrap()
    }

    /// The force given in m/s² enters in the pipeline's units and is published in m/s², present;
    /// without it the sample carries none.
    #[test]
    fn an_offline_sample_carries_the_accelerometer_in_the_pipelines_units() {
        let force = [0.5, -1.25, -9.80665];
        for units in AccelUnit::ALL {
            let p = pipeline(units);
            let raw = raw_sample(&p, 3, [1.0; 3], Some(&force));
            let scale = units.to_m_per_s2();
            assert_eq!(
                raw.accel_reading().map(|a| a.map(|v| v * scale)),
                Some(force)
            );
            let mut off = Offline::new(&p).unwrap();
            let mut got = Vec::new();
            off.push(&raw, &mut |g| got.push(g));
            let a = got[0].accel_reading().expect("published present");
            for i in 0..3 {
                assert!((a[i] - force[i]).abs() < 1e-12, "{units}: {a:?}");
            }
            let none = raw_sample(&p, 4, [1.0; 3], None);
            assert_eq!(none.accel_reading(), None);
            got.clear();
            off.push(&none, &mut |g| got.push(g));
            assert_eq!(got[0].accel_reading(), None);
        }
    }
}
