//! Sleeping on other processes: [`Waker`] (one event service) and [`WakeSet`] (several, and a
//! due time, on one thread).

use std::os::fd::AsRawFd as _;
use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;

use super::config::Svc;
use super::error::TransportError;

/// Sleeps until a publisher notifies (or a timeout passes).
pub struct Waker {
    pub(super) listener: Listener<Svc>,
}

impl Waker {
    /// Wait up to `timeout` for a notification; consumes all pending ones.
    pub fn wait(&self, timeout: Duration) -> Result<(), TransportError> {
        self.listener
            .timed_wait(|_| {}, timeout)
            .map(|_| ())
            .map_err(|e| TransportError::Io {
                what: "wait",
                reason: format!("{e:?}"),
            })
    }

    /// Consume the pending notifications without waiting (after a [`WakeSet`] reported this
    /// waker: until then its descriptor stays readable).
    pub fn drain(&self) -> Result<(), TransportError> {
        self.listener
            .try_wait(|_| {})
            .map(|_| ())
            .map_err(|e| TransportError::Io {
                what: "wait",
                reason: format!("{e:?}"),
            })
    }

    fn fd(&self) -> std::os::fd::RawFd {
        // SAFETY: only read to register the descriptor with epoll; the listener owns it.
        unsafe { self.listener.file_descriptor().native_handle() }
    }
}

/// One thread sleeping until any of several [`Waker`]s is notified or a due time comes,
/// whichever is first: the hot thread of a daemon whose pipelines read several sensor drivers,
/// or sensor drivers and paced sources.
///
/// Written on epoll and a timerfd rather than iceoryx2 0.10's `WaitSet`, which rounds its
/// timeouts up to whole milliseconds (a 1 kHz source would be served up to a period late) and
/// allocates at every wake-up. A waker's descriptor stays registered until the waker is
/// dropped (closing it removes it from the set).
pub struct WakeSet {
    epoll: std::os::fd::OwnedFd,
    timer: std::os::fd::OwnedFd,
    timer_armed: bool,
}

/// The epoll tag of the timer (wakers are tagged with the caller's index).
const TIMER_TAG: u64 = u64::MAX;

impl WakeSet {
    /// An empty set.
    pub fn new() -> Result<Self, TransportError> {
        use std::os::fd::FromRawFd;
        let os = |what: &'static str| TransportError::Io {
            what,
            reason: std::io::Error::last_os_error().to_string(),
        };
        // SAFETY: plain system calls; each descriptor is owned as soon as it exists.
        let epoll = unsafe { libc::epoll_create1(libc::EPOLL_CLOEXEC) };
        if epoll < 0 {
            return Err(os("epoll_create1"));
        }
        let epoll = unsafe { std::os::fd::OwnedFd::from_raw_fd(epoll) };
        let timer = unsafe {
            libc::timerfd_create(
                libc::CLOCK_MONOTONIC,
                libc::TFD_CLOEXEC | libc::TFD_NONBLOCK,
            )
        };
        if timer < 0 {
            return Err(os("timerfd_create"));
        }
        let mut set = WakeSet {
            epoll,
            timer: unsafe { std::os::fd::OwnedFd::from_raw_fd(timer) },
            timer_armed: false,
        };
        set.register(set.timer.as_raw_fd(), TIMER_TAG)?;
        Ok(set)
    }

    /// Watch `waker`; [`wait`](Self::wait) reports it by `tag`.
    pub fn add(&mut self, waker: &Waker, tag: usize) -> Result<(), TransportError> {
        self.register(waker.fd(), tag as u64)
    }

    /// Watch a descriptor of another kind (one that turns readable when there is work, as a
    /// DDS readiness poll does); [`wait`](Self::wait) reports it by `tag`.
    #[cfg(feature = "ros2")]
    pub(super) fn add_fd(
        &mut self,
        fd: std::os::fd::RawFd,
        tag: usize,
    ) -> Result<(), TransportError> {
        self.register(fd, tag as u64)
    }

    fn register(&mut self, fd: std::os::fd::RawFd, tag: u64) -> Result<(), TransportError> {
        let mut event = libc::epoll_event {
            events: libc::EPOLLIN as u32,
            u64: tag,
        };
        // SAFETY: `event` outlives the call; the kernel copies it.
        let rc =
            unsafe { libc::epoll_ctl(self.epoll.as_raw_fd(), libc::EPOLL_CTL_ADD, fd, &mut event) };
        if rc < 0 {
            return Err(TransportError::Io {
                what: "epoll_ctl",
                reason: std::io::Error::last_os_error().to_string(),
            });
        }
        Ok(())
    }

    /// Sleep until a watched waker has a notification, `due` comes (to the timer's precision,
    /// not epoll's millisecond) or `timeout` passes (rounded up to a millisecond); call
    /// `notified` with the tag of each waker that has one (then [`Waker::drain`] it). A
    /// signal ends the wait early, reporting nothing. Allocation-free.
    pub fn wait(
        &mut self,
        due: Option<std::time::Instant>,
        timeout: Duration,
        mut notified: impl FnMut(usize),
    ) -> Result<(), TransportError> {
        if let Some(due) = due {
            let until = due.saturating_duration_since(std::time::Instant::now());
            if until.is_zero() {
                return Ok(());
            }
            self.arm(until)?;
        } else if self.timer_armed {
            self.arm(Duration::ZERO)?;
        }
        let ms = timeout.as_nanos().div_ceil(1_000_000).min(i32::MAX as u128) as i32;
        let mut events = [libc::epoll_event { events: 0, u64: 0 }; 32];
        // SAFETY: the buffer holds `events.len()` entries.
        let n = unsafe {
            libc::epoll_wait(
                self.epoll.as_raw_fd(),
                events.as_mut_ptr(),
                events.len() as i32,
                ms,
            )
        };
        if n < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == std::io::ErrorKind::Interrupted {
                return Ok(());
            }
            return Err(TransportError::Io {
                what: "epoll_wait",
                reason: e.to_string(),
            });
        }
        for e in &events[..n as usize] {
            let tag = e.u64;
            if tag != TIMER_TAG {
                notified(tag as usize);
            }
        }
        Ok(())
    }

    /// Arm the timer to fire once after `after` (zero disarms it). Setting it also clears an
    /// expiry not yet read, so the timer is readable only when this wait's due time passed.
    fn arm(&mut self, after: Duration) -> Result<(), TransportError> {
        let spec = libc::itimerspec {
            it_interval: libc::timespec {
                tv_sec: 0,
                tv_nsec: 0,
            },
            it_value: libc::timespec {
                tv_sec: after.as_secs() as libc::time_t,
                tv_nsec: after.subsec_nanos() as libc::c_long,
            },
        };
        // SAFETY: `spec` outlives the call; the old value is not asked for.
        let rc = unsafe {
            libc::timerfd_settime(self.timer.as_raw_fd(), 0, &spec, std::ptr::null_mut())
        };
        if rc < 0 {
            return Err(TransportError::Io {
                what: "timerfd_settime",
                reason: std::io::Error::last_os_error().to_string(),
            });
        }
        self.timer_armed = !after.is_zero();
        Ok(())
    }
}
