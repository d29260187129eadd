//! The side contract through the runtime, with a side of the test's own: what adding a side
//! takes (its own code, one registration, its test). The side reads the pipeline's public
//! output through a real iceoryx2 service on the thread the runtime gave it, says it is set up
//! before the first sample, and is stopped after the pipeline; a side that cannot set up stops
//! the run before it starts, naming its table, and leaves nothing behind.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use common::Prefix;
use driftless::pipeline::config::{parse, Pipeline};
use driftless::pipeline::runtime::{run_group, RunError, RunOptions};
use driftless::sides::{Kind, Ready, Side, SideSpec, Start};
use driftless::transport::Transport;
use driftless::wire::GyroSample;

/// What the test side saw.
#[derive(Debug, Default)]
struct Seen {
    samples: AtomicU64,
    thread: Mutex<Option<String>>,
}

/// A side that counts the samples of one service (or fails to set up).
#[derive(Debug)]
struct Counter {
    service: String,
    fail: bool,
    seen: Arc<Seen>,
}

static COUNTER: Kind = Kind {
    table: "counter",
    summary: "counts a service's samples (a test's own side)",
    keys: &[],
    read: |t, _| Err(t.error("the test builds its side by hand")),
};

impl Side for Counter {
    fn describe(&self) -> Vec<String> {
        vec![format!("counts {}", self.service)]
    }

    fn run(&self, start: &Start<'_>, ready: Ready<'_>) -> Result<String, String> {
        *self.seen.thread.lock().unwrap() = std::thread::current().name().map(str::to_string);
        if self.fail {
            ready(Err("no such device".into()));
            return Err("no such device".into());
        }
        let set_up = Transport::new(start.prefix, start.node, start.qos)
            .and_then(|t| Ok((t.input::<GyroSample>(&self.service)?, t)));
        let (input, _transport) = match set_up {
            Ok(ok) => ok,
            Err(e) => {
                ready(Err(e.to_string()));
                return Err(e.to_string());
            }
        };
        ready(Ok(()));
        let mut last_round = false;
        loop {
            // After the stop, one more round takes what is still queued.
            let stopping = start.stop.load(Ordering::Relaxed);
            while let Some(_sample) = input.receive().map_err(|e| e.to_string())? {
                self.seen.samples.fetch_add(1, Ordering::Relaxed);
            }
            if last_round {
                break;
            }
            last_round = stopping;
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(format!(
            "{} samples",
            self.seen.samples.load(Ordering::Relaxed)
        ))
    }
}

const SAMPLES: u64 = 600;

fn pipeline(name: &str) -> Pipeline {
    let text = format!(
        "name = \"{name}\"\nrate_hz = 1000.0\n[iceoryx2]\nbuffer_size = 4096\n\
         [[stage]]\nname = \"in\"\nkind = \"ingest.sim\"\noutput = \"{name}/raw\"\n\
         samples = {SAMPLES}\n\
         [[stage]]\nname = \"pub\"\nkind = \"publish\"\ninput = \"{name}/raw\"\n\
         output = \"{name}/corrected\"\n"
    );
    parse(std::path::Path::new("sides.toml"), &text).expect("a valid pipeline")
}

fn with_counter(name: &str, fail: bool) -> (Pipeline, Arc<Seen>) {
    let mut p = pipeline(name);
    let seen = Arc::new(Seen::default());
    p.sides.push(SideSpec {
        kind: &COUNTER,
        side: Arc::new(Counter {
            service: format!("{name}/corrected"),
            fail,
            seen: Arc::clone(&seen),
        }),
    });
    (p, seen)
}

fn options() -> RunOptions {
    RunOptions {
        duration: Some(Duration::from_secs(30)),
        stop: Arc::default(),
        print_summary: false,
    }
}

#[test]
fn a_side_runs_on_its_own_thread_and_sees_every_sample_through_the_service() {
    let prefix = Prefix::new("sidecount");
    let (p, seen) = with_counter("sidecount", false);
    let reports = run_group(&[(&p, prefix.0.clone())], &options()).expect("the group ran");
    let report = reports
        .into_iter()
        .next()
        .unwrap()
        .expect("the pipeline ran");
    assert_eq!(report.samples_out, SAMPLES, "{report:?}");
    assert_eq!(
        seen.samples.load(Ordering::Relaxed),
        SAMPLES,
        "the side read every sample the pipeline published"
    );
    assert_eq!(
        seen.thread.lock().unwrap().as_deref(),
        Some("driftless-counter"),
        "a side runs on a thread of its own, named after its table"
    );
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

#[test]
fn a_side_that_cannot_set_up_stops_the_run_before_it_starts() {
    let prefix = Prefix::new("sidefail");
    let (p, seen) = with_counter("sidefail", true);
    let e = run_group(&[(&p, prefix.0.clone())], &options()).expect_err("the run must fail");
    match &e {
        RunError::Stage { stage, message } => {
            assert_eq!(stage, "counter", "{e}");
            assert!(message.contains("no such device"), "{e}");
        }
        other => panic!("not a side's failure: {other}"),
    }
    assert!(
        seen.thread.lock().unwrap().is_some(),
        "the side was started"
    );
    assert_eq!(Transport::node_count(&prefix.0).unwrap_or(0), 0);
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}
