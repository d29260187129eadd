//! The window loop: every motion, every window, every axis; each method corrects the noise
//! plus the motion, and is judged by the heading error of the integrated rate.

use super::{Chain, NavEvalError, Source};
use crate::drift::bias::OdometryAidConfig;
use crate::drift::bias::{stillness_from_terms, AccelTerms, BiasModel, BiasTerms};
use crate::io::truth::Truth;
use crate::nav::{
    body_acceleration, evaluate, evaluate_odometry, fusion, generate, heading_error, odometry,
    summarize_methods, BiasEstimator, HeadingAccumulator, HeadingMetrics, Method, MethodSummary,
    MotionTrace, OdometryModel, Profile, Setup, Zaru,
};
use crate::pipeline::offline::Offline;

/// The column of x-io Fusion's gyroscope bias algorithm ([`fusion`]).
pub const FUSION_LABEL: &str = "x-io Fusion bias (imufusion defaults)";

/// Points per heading error trace at most (keeps an SVG small).
const TRACE_POINTS: usize = 4000;

/// The motion added to the windows: a built-in profile, drawn anew for each window and axis
/// (seed `3 w + axis`), or a truth file's motion, the same for every window.
#[derive(Debug, Clone)]
pub enum Motion {
    /// A built-in profile.
    Profile(Profile),
    /// A truth file's motion.
    Truth {
        /// `truth FILE`.
        label: String,
        /// One per axis.
        traces: Vec<MotionTrace>,
    },
}

impl Motion {
    /// A truth file's motion for `axes` axes at `rate` Hz, labelled by its file name.
    pub fn truth(t: &Truth, axes: usize, rate: f64) -> Result<Motion, NavEvalError> {
        Ok(Motion::Truth {
            label: format!(
                "truth {}",
                t.path.file_name().map_or_else(
                    || t.path.display().to_string(),
                    |f| f.to_string_lossy().into_owned()
                )
            ),
            traces: t.traces(axes, rate)?,
        })
    }

    /// Its name in the tables: the profile's, or `truth FILE`.
    pub fn label(&self) -> String {
        match self {
            Motion::Profile(p) => p.to_string(),
            Motion::Truth { label, .. } => label.clone(),
        }
    }

    /// The motion of each of `axes` axes in window `w`.
    fn traces(
        &self,
        rate: f64,
        window_s: f64,
        w: usize,
        axes: usize,
    ) -> Result<Vec<MotionTrace>, NavEvalError> {
        match self {
            Motion::Profile(p) => (0..axes)
                .map(|a| generate(*p, rate, window_s, (w * 3 + a) as u64))
                .collect::<Result<_, _>>()
                .map_err(|e| NavEvalError::Internal(e.to_string())),
            Motion::Truth { traces, .. } => Ok(traces.clone()),
        }
    }

    /// The body acceleration (m/s², gravity not included) of `trace`: a profile's vehicle
    /// moving at its stated speed ([`crate::nav::force`]); a truth file's motion turns in place
    /// (no translation), so none.
    fn body_acceleration(&self, trace: &MotionTrace) -> Vec<[f64; 3]> {
        match self {
            Motion::Profile(p) => body_acceleration(trace, p.speed()),
            Motion::Truth { .. } => vec![[0.0; 3]; trace.truth.len()],
        }
    }
}

/// What the benchmark judges, and on what.
#[derive(Debug)]
pub struct Bench {
    /// The static noise.
    pub source: Source,
    /// The estimators' noise terms, one set per axis.
    pub terms: Vec<BiasTerms>,
    /// The accelerometer's terms the gyro+accel chain was given (None: the stage's defaults).
    pub accel_terms: Option<AccelTerms>,
    /// Samples per window.
    pub window: usize,
    /// The motions added, each a section of the tables.
    pub motions: Vec<Motion>,
    /// The methods that run a pipeline's stages, after the built-in ones.
    pub chains: Vec<Chain>,
    /// Samples of each window every method runs before its heading is judged (0: from the
    /// first sample, start-up included).
    pub judge_from: usize,
    /// The bias filter with the true stops and a wheel odometry, one column per variant
    /// (after x-io Fusion's): on the vehicle profiles only (the others' cases are NaN there).
    pub odometry: Vec<OdometryVariant>,
}

/// One odometry column: the odometry's errors and how the filter weighs it.
#[derive(Debug, Clone)]
pub struct OdometryVariant {
    /// Its column's label.
    pub label: String,
    /// The odometry's errors ([`mod@crate::nav::odometry`]).
    pub model: OdometryModel,
    /// How the filter weighs and tests it.
    pub aid: OdometryAidConfig,
}

impl OdometryVariant {
    /// The default odometry and filter, then the robustness variants: scale error 3%, ten
    /// slip bursts per window, 100 ms latency, an odometry that stops at mid-window, white
    /// noise of 0.5 deg/s per message, and the default without the innovation tests (what
    /// they are worth). `window_s` places the mid-window stop.
    pub fn all(window_s: f64) -> Vec<OdometryVariant> {
        let m = OdometryModel::default();
        let a = OdometryAidConfig::default();
        let v = |label: &str, model: OdometryModel, aid: OdometryAidConfig| OdometryVariant {
            label: format!("KF true stops + odometry{label}"),
            model,
            aid,
        };
        vec![
            v("", m, a),
            v(
                ", scale 3%",
                OdometryModel {
                    scale_error: 0.03,
                    ..m
                },
                a,
            ),
            v(", 10 slips", OdometryModel { slips: 10, ..m }, a),
            v(
                ", latency 100 ms",
                OdometryModel {
                    latency_s: (0.1, 0.1),
                    ..m
                },
                a,
            ),
            v(
                ", stops at mid-window",
                OdometryModel {
                    ends_at_s: Some(window_s / 2.0),
                    ..m
                },
                a,
            ),
            v(
                ", white 0.5 deg/s",
                OdometryModel { white_sd: 0.5, ..m },
                OdometryAidConfig { white_sd: 0.5, ..a },
            ),
            v(", no slip test", m, OdometryAidConfig { test: false, ..a }),
        ]
    }
}

/// One evaluated case: a window of one axis under one motion.
#[derive(Debug, Clone)]
pub struct Case {
    /// Index into [`Bench::motions`].
    pub motion: usize,
    /// Window number, from 0.
    pub window: usize,
    /// Index into the source's axes.
    pub axis: usize,
    /// One per column ([`Outcome::labels`]).
    pub metrics: Vec<HeadingMetrics>,
}

/// One table: every method summarised over a set of cases, against ZARU with the true stops.
#[derive(Debug, Clone)]
pub struct Section {
    /// The motion's label, or `all profiles`.
    pub title: String,
    /// One per column ([`Outcome::labels`]).
    pub rows: Vec<MethodSummary>,
}

/// Heading error over time of one case, thinned to a few thousand points.
#[derive(Debug, Clone)]
pub struct HeadingTraces {
    /// Time, s.
    pub t: Vec<f64>,
    /// Per method: its name and its heading error, deg, at `t`.
    pub series: Vec<(String, Vec<f64>)>,
}

/// What the benchmark found.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The columns: the built-in methods, x-io Fusion's, then each chain's.
    pub labels: Vec<String>,
    /// Windows per axis and motion.
    pub windows: usize,
    /// Every case, by motion, window and axis.
    pub cases: Vec<Case>,
    /// One section per motion, and one of all cases when there are several motions.
    pub sections: Vec<Section>,
    /// When asked for: the heading error traces of the first case (power-on, ZARU oracle,
    /// ZARU detected, then each chain).
    pub traces: Option<HeadingTraces>,
}

impl Bench {
    /// The built-in methods, in column order: [`Method::ALL`] but heading hold and the filter on
    /// the denoised rate, which nav-eval does not run, and the floor only where the true noise
    /// model is known (the simulator).
    pub fn methods(&self) -> Vec<Method> {
        Method::ALL
            .into_iter()
            .filter(|m| match m {
                Method::KfHold | Method::KfDenoised => false,
                Method::Floor => self.source.floor.is_some(),
                _ => true,
            })
            .collect()
    }

    /// Window length, s (whole samples).
    pub fn window_s(&self) -> f64 {
        self.window as f64 / self.source.rate
    }

    /// The first sample of window `w`.
    pub fn window_start(&self, w: usize) -> usize {
        self.source.first_window + w * self.window
    }

    /// Run every method on every case; with `traces`, keep the first case's heading error
    /// over time.
    pub fn run(&self, traces: bool) -> Result<Outcome, NavEvalError> {
        let methods = self.methods();
        let mut labels: Vec<String> = methods.iter().map(|m| m.label().to_string()).collect();
        labels.push(FUSION_LABEL.into());
        labels.extend(self.odometry.iter().map(|v| v.label.clone()));
        labels.extend(self.chains.iter().map(|c| c.label.clone()));
        let src = &self.source;
        let windows = src.windows(self.window);
        let mut cases: Vec<Case> = Vec::new();
        let mut first: Option<HeadingTraces> = None;
        for (mi, motion) in self.motions.iter().enumerate() {
            for w in 0..windows {
                let motion_traces = motion.traces(src.rate, self.window_s(), w, src.axes.len())?;
                let measured = self.measured(w, &motion_traces);
                let accel = self.accel(w, motion, &motion_traces);
                // Each axis alone, the others still: nav-eval gives every axis its own motion,
                // so a case is one axis of a vehicle whose stops are that axis's (Fusion waits
                // for all three axes to be still; other axes' unrelated motion would only
                // handicap it).
                let fusion_out: Vec<Vec<f64>> = measured
                    .iter()
                    .map(|y| fusion::correct(&[y], src.rate).remove(0))
                    .collect();
                let chain_out = self.run_chains(&measured, &motion_traces, accel.as_deref())?;
                for (a, m) in motion_traces.iter().enumerate() {
                    let setup = self.setup(a)?;
                    let mut metrics = evaluate(&measured[a], &m.truth, &m.still, &setup, &methods)
                        .map_err(|e| NavEvalError::Input(format!("{}: {e}", src.name)))?;
                    let dt = 1.0 / src.rate;
                    metrics.push(metrics_of(&fusion_out[a], &m.truth, dt, self.judge_from));
                    metrics.extend(self.odometry_metrics(
                        motion,
                        &measured[a],
                        m,
                        &setup,
                        (w * 3 + a) as u64,
                    )?);
                    for out in &chain_out {
                        metrics.push(metrics_of(&out[a], &m.truth, dt, self.judge_from));
                    }
                    if first.is_none() && traces {
                        first = Some(self.traces(&measured[a], m, &chain_out, a, &setup)?);
                    }
                    cases.push(Case {
                        motion: mi,
                        window: w,
                        axis: a,
                        metrics,
                    });
                }
            }
        }
        let sections = self.sections(&cases, &methods, labels.len());
        Ok(Outcome {
            labels,
            windows,
            cases,
            sections,
            traces: first,
        })
    }

    /// Each odometry variant's figures on one case: a vehicle profile's (the odometry seeded
    /// by the case), NaN for the others (a walker, a truth file: no wheels).
    fn odometry_metrics(
        &self,
        motion: &Motion,
        measured: &[f64],
        m: &MotionTrace,
        setup: &Setup,
        seed: u64,
    ) -> Result<Vec<HeadingMetrics>, NavEvalError> {
        let wheels = matches!(
            motion,
            Motion::Profile(Profile::Vehicle | Profile::Continuous | Profile::StopAndGo)
        );
        self.odometry
            .iter()
            .map(|v| {
                if !wheels {
                    let nan = f64::NAN;
                    return Ok(HeadingMetrics {
                        final_deg: nan,
                        rms_deg: nan,
                        max_deg: nan,
                        rms_rate: nan,
                    });
                }
                let odo = odometry(m, &v.model, seed)
                    .map_err(|e| NavEvalError::Internal(e.to_string()))?;
                evaluate_odometry(measured, &m.truth, &m.still, setup, &odo, &v.aid)
                    .map(|r| r.0)
                    .map_err(|e| NavEvalError::Input(format!("{}: {e}", self.source.name)))
            })
            .collect()
    }

    /// Window `w` of each axis' noise plus its motion.
    fn measured(&self, w: usize, motion: &[MotionTrace]) -> Vec<Vec<f64>> {
        let start = self.window_start(w);
        self.source
            .axes
            .iter()
            .zip(motion)
            .map(|((_, y), m)| {
                y[start..start + self.window]
                    .iter()
                    .zip(&m.truth)
                    .map(|(x, t)| x + t)
                    .collect()
            })
            .collect()
    }

    /// Window `w`'s specific force for each axis's case, when the source has an accelerometer:
    /// the source's static force (time-aligned with the rates) plus that axis's motion's body
    /// acceleration. Each case is a vehicle whose yaw axis is that gyro axis.
    fn accel(
        &self,
        w: usize,
        motion: &Motion,
        traces: &[MotionTrace],
    ) -> Option<Vec<Vec<[f64; 3]>>> {
        let start = self.window_start(w);
        let still = &self.source.accel.as_ref()?[start..start + self.window];
        Some(
            traces
                .iter()
                .map(|m| {
                    still
                        .iter()
                        .zip(motion.body_acceleration(m))
                        .map(|(s, a)| std::array::from_fn(|i| s[i] + a[i]))
                        .collect()
                })
                .collect(),
        )
    }

    /// Each chain's output, per axis: per-axis pipelines one axis at a time, a file's all axes
    /// at once. A chain reading a stop signal gets each axis's true stops, and a chain fed the
    /// accelerometer each axis's specific force, so it runs each axis alone (the axes'
    /// motions, and so their stops and forces, differ).
    fn run_chains(
        &self,
        measured: &[Vec<f64>],
        motion: &[MotionTrace],
        accel: Option<&[Vec<[f64; 3]>]>,
    ) -> Result<Vec<Vec<Vec<f64>>>, NavEvalError> {
        let mut chain_out: Vec<Vec<Vec<f64>>> = Vec::with_capacity(self.chains.len());
        for c in &self.chains {
            let reads_stops = c.reads_stops();
            let fed = accel.filter(|_| c.accel);
            if c.pipelines.len() > 1 || reads_stops || fed.is_some() {
                let mut per_axis = Vec::with_capacity(measured.len());
                for (a, y) in measured.iter().enumerate() {
                    let p = &c.pipelines[a.min(c.pipelines.len() - 1)];
                    let stops = reads_stops.then_some(motion[a].still.as_slice());
                    let force = fed.map(|f| f[a].as_slice());
                    per_axis.extend(
                        Offline::run_imu_series(p, &[y], force, stops)
                            .map_err(NavEvalError::Input)?,
                    );
                }
                chain_out.push(per_axis);
            } else {
                let inputs: Vec<&[f64]> = measured.iter().map(Vec::as_slice).collect();
                chain_out.push(
                    Offline::run_series(&c.pipelines[0], &inputs, None)
                        .map_err(NavEvalError::Input)?,
                );
            }
        }
        Ok(chain_out)
    }

    /// The built-in methods' setup for axis `a`: its terms, and on the simulator its true
    /// noise model.
    fn setup(&self, a: usize) -> Result<Setup, NavEvalError> {
        let mut setup = Setup::new(self.terms[a], self.source.rate);
        setup.judge_from = self.judge_from;
        if let Some(cfg) = &self.source.floor {
            setup.floor = Some(
                BiasModel::simulator_truth(cfg, setup.terms.initial_sd)
                    .map_err(|e| NavEvalError::Internal(e.to_string()))?,
            );
        }
        Ok(setup)
    }

    /// One section per motion, and one of all cases when there are several.
    fn sections(&self, cases: &[Case], methods: &[Method], columns: usize) -> Vec<Section> {
        let table = |title: String, sel: &dyn Fn(&Case) -> bool| -> Section {
            let res: Vec<Vec<HeadingMetrics>> = cases
                .iter()
                .filter(|c| sel(c))
                .map(|c| c.metrics.clone())
                .collect();
            // Chain columns have no `Method`: a placeholder that is never the reference,
            // relabelled on output.
            let all: Vec<Method> = (0..columns)
                .map(|i| methods.get(i).copied().unwrap_or(Method::KfDenoised))
                .collect();
            Section {
                title,
                rows: summarize_methods(&all, &res, Method::ZaruOracle),
            }
        };
        let mut sections: Vec<Section> = self
            .motions
            .iter()
            .enumerate()
            .map(|(i, m)| table(m.label(), &|c: &Case| c.motion == i))
            .collect();
        if self.motions.len() > 1 {
            sections.push(table("all profiles".into(), &|_| true));
        }
        sections
    }

    /// Heading error traces of one case: power-on, ZARU oracle, ZARU detected, then each
    /// chain.
    fn traces(
        &self,
        measured: &[f64],
        m: &MotionTrace,
        chains: &[Vec<Vec<f64>>],
        axis: usize,
        setup: &Setup,
    ) -> Result<HeadingTraces, NavEvalError> {
        let dt = 1.0 / setup.rate_hz;
        let min = (setup.zaru_min_s * setup.rate_hz).round().max(1.0) as usize;
        let step = (measured.len() / TRACE_POINTS).max(1);
        let thin = |c: &[f64]| -> Vec<f64> {
            heading_error(c, &m.truth, dt)
                .into_iter()
                .step_by(step)
                .collect()
        };
        let t: Vec<f64> = (0..measured.len())
            .step_by(step)
            .map(|k| k as f64 * dt)
            .collect();
        let correct = |mut est: Zaru| -> Vec<f64> {
            measured
                .iter()
                .zip(&m.still)
                .map(|(&x, &s)| x - est.push(x, s))
                .collect()
        };
        let detector = stillness_from_terms(&setup.terms, setup.rate_hz, &setup.tracker)
            .map_err(|e| NavEvalError::Input(e.to_string()))?;
        let mut series = vec![
            ("power-on".to_string(), thin(&correct(Zaru::power_on(min)))),
            ("ZARU oracle".into(), thin(&correct(Zaru::oracle(min)))),
            (
                "ZARU detected".into(),
                thin(&correct(Zaru::detected(min, detector))),
            ),
        ];
        series.extend(
            self.chains
                .iter()
                .zip(chains)
                .map(|(c, out)| (c.label.clone(), thin(&out[axis]))),
        );
        Ok(HeadingTraces { t, series })
    }
}

/// One odometry column against the same filter without it ("KF oracle": the true stops
/// alone), over one motion's cases.
#[derive(Debug, Clone)]
pub struct OdometryComparison {
    /// The motion's label.
    pub motion: String,
    /// The odometry column's label.
    pub label: String,
    /// Median RMS heading error of the true stops alone, deg.
    pub stops_rms: f64,
    /// Median RMS heading error with the odometry, deg.
    pub odometry_rms: f64,
    /// Per case, RMS with the odometry over RMS with the stops alone.
    pub ratio: crate::nav::Summary,
    /// The same over the stops alone's RMS or [`crate::nav::eval::RATIO_FLOOR_DEG`], whichever
    /// is larger (below it a window's error is noise, as for the ratios to ZARU).
    pub ratio_floored: crate::nav::Summary,
    /// Cases where the odometry's RMS is more than 2% above the stops alone's (floored).
    pub worse: usize,
    /// Cases.
    pub cases: usize,
}

impl Outcome {
    /// Each odometry column against the true stops alone, per motion that has its cases
    /// (the vehicle profiles).
    pub fn odometry_against_stops(&self, bench: &Bench) -> Vec<OdometryComparison> {
        let Some(stops) = self
            .labels
            .iter()
            .position(|l| l == Method::KfOracle.label())
        else {
            return Vec::new();
        };
        let median = |v: &[f64]| crate::nav::summarize(v).median;
        let mut out = Vec::new();
        for (mi, motion) in bench.motions.iter().enumerate() {
            for v in &bench.odometry {
                let Some(col) = self.labels.iter().position(|l| *l == v.label) else {
                    continue;
                };
                let pairs: Vec<(f64, f64)> = self
                    .cases
                    .iter()
                    .filter(|c| c.motion == mi)
                    .map(|c| (c.metrics[stops].rms_deg, c.metrics[col].rms_deg))
                    .filter(|(_, o)| o.is_finite())
                    .collect();
                if pairs.is_empty() {
                    continue;
                }
                let a: Vec<f64> = pairs.iter().map(|p| p.0).collect();
                let b: Vec<f64> = pairs.iter().map(|p| p.1).collect();
                let r: Vec<f64> = pairs.iter().map(|p| p.1 / p.0).collect();
                let floor = crate::nav::eval::RATIO_FLOOR_DEG;
                let rf: Vec<f64> = pairs.iter().map(|p| p.1 / p.0.max(floor)).collect();
                out.push(OdometryComparison {
                    motion: motion.label(),
                    label: v.label.clone(),
                    stops_rms: median(&a),
                    odometry_rms: median(&b),
                    ratio: crate::nav::summarize(&r),
                    ratio_floored: crate::nav::summarize(&rf),
                    worse: rf.iter().filter(|&&x| x > 1.02).count(),
                    cases: pairs.len(),
                });
            }
        }
        out
    }
}

/// The heading figures of a corrected rate against the truth, judged from sample `from`.
fn metrics_of(corrected: &[f64], truth: &[f64], dt: f64, from: usize) -> HeadingMetrics {
    let mut acc = HeadingAccumulator::new(dt);
    for (&c, &t) in corrected.iter().zip(truth).skip(from) {
        // A sample a stage never published (it cannot happen with the shipped stages) counts
        // as uncorrected zero rate, not as silently skipped.
        acc.push(if c.is_finite() { c } else { 0.0 }, t);
    }
    acc.metrics()
}
