//! SIGINT and SIGTERM, handled from the first instruction of `main`: the commands that hold
//! iceoryx2 ports (`run`, `tap`, `stats`, `record`, `list`, `relay`, `bridge`) turn them into a
//! stop flag they all read, so a stop at any moment of their start is a clean exit that
//! leaves nothing behind (before, the first millisecond of `run` died by the signal's default
//! action). Every other command keeps the default action: an offline filter stops at once.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};

/// The commands that hold iceoryx2 ports and read the stop flag.
const STOPPABLE: &[&str] = &["run", "tap", "stats", "record", "list", "relay", "bridge"];

static STOP: OnceLock<Arc<AtomicBool>> = OnceLock::new();

/// The signal that set the stop flag first (0: none yet).
static FIRST: AtomicI32 = AtomicI32::new(0);

/// Install the handlers for the command named by `argv[1]`. Call it first thing in `main`.
pub fn install() {
    let command = std::env::args_os().nth(1);
    let stoppable = command.is_some_and(|c| STOPPABLE.iter().any(|s| c == **s));
    if !stoppable {
        return;
    }
    let stop = stop_flag();
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let stop = Arc::clone(&stop);
        // SAFETY: the action only stores to atomics (async-signal-safe). Registering cannot
        // fail for these two signals; if it ever did, the default action would stay.
        let _ = unsafe {
            signal_hook::low_level::register(sig, move || {
                let _ = FIRST.compare_exchange(0, sig, Ordering::Relaxed, Ordering::Relaxed);
                stop.store(true, Ordering::SeqCst);
            })
        };
    }
}

/// The process's stop flag: set once SIGINT or SIGTERM came.
pub fn stop_flag() -> Arc<AtomicBool> {
    Arc::clone(STOP.get_or_init(Arc::default))
}

/// The name of the signal that stopped us, if one did.
pub fn stopped_by() -> Option<&'static str> {
    match FIRST.load(Ordering::Relaxed) {
        signal_hook::consts::SIGINT => Some("SIGINT"),
        signal_hook::consts::SIGTERM => Some("SIGTERM"),
        _ => None,
    }
}
