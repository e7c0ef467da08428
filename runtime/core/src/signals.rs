//! SIGTERM and SIGINT as a flag the main loop checks, and [`Shutdown`]: what a loop is handed
//! to know when to stop (the signals, or a flag its owner sets).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// When a loop should stop: handed to it by whoever runs it. [`Shutdown::on_signals`] follows
/// SIGINT/SIGTERM (what a program's `main` passes); [`Shutdown::new`] only its own
/// [`Shutdown::request`] (tests, a supervisor embedded in another program). Clones share the
/// request.
#[derive(Debug, Clone, Default)]
pub struct Shutdown {
    requested: Arc<AtomicBool>,
    signals: bool,
}

impl Shutdown {
    /// A shutdown that only [`Shutdown::request`] asks for.
    pub fn new() -> Shutdown {
        Shutdown::default()
    }

    /// A shutdown that SIGINT and SIGTERM ask for too (installs their handler, see
    /// [`install_termination_handler`]).
    pub fn on_signals() -> Result<Shutdown, nix::Error> {
        install_termination_handler()?;
        Ok(Shutdown {
            requested: Arc::default(),
            signals: true,
        })
    }

    /// Asks every holder of this shutdown (and its clones) to stop.
    pub fn request(&self) {
        self.requested.store(true, Ordering::SeqCst);
    }

    /// Whether stopping was asked for.
    pub fn requested(&self) -> bool {
        self.requested.load(Ordering::Relaxed) || (self.signals && termination_requested())
    }
}

static TERMINATE: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    TERMINATE.store(true, Ordering::SeqCst);
}

/// Installs handlers that turn SIGTERM and SIGINT into [`termination_requested`].
///
/// Without `SA_RESTART`, so that a blocking wait returns early and the loop sees the flag.
pub fn install_termination_handler() -> Result<(), nix::Error> {
    use nix::sys::signal::{sigaction, SaFlags, SigAction, SigHandler, SigSet, Signal};
    let action = SigAction::new(
        SigHandler::Handler(on_signal),
        SaFlags::empty(),
        SigSet::empty(),
    );
    for sig in [Signal::SIGTERM, Signal::SIGINT] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        unsafe { sigaction(sig, &action) }?;
    }
    Ok(())
}

static CHILD_ENDED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_child(_: libc::c_int) {
    CHILD_ENDED.store(true, Ordering::SeqCst);
}

/// Whether SIGCHLD arrived since the last call (the handler of [`install_child_handler`] must
/// be installed). Several ends may come as one signal: look at every child.
pub fn take_child_ended() -> bool {
    CHILD_ENDED.swap(false, Ordering::SeqCst)
}

/// Makes SIGCHLD interrupt this thread's blocking waits (a supervisor sleeps until something
/// happens; a child's end is something). Other threads of the process should block SIGCHLD
/// ([`block_child_signal`]), so that it is this thread the kernel interrupts.
pub fn install_child_handler() -> Result<(), nix::Error> {
    use nix::sys::signal::{sigaction, SaFlags, SigAction, SigHandler, SigSet, Signal};
    let action = SigAction::new(
        SigHandler::Handler(on_child),
        SaFlags::SA_NOCLDSTOP,
        SigSet::empty(),
    );
    // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
    unsafe { sigaction(Signal::SIGCHLD, &action) }?;
    Ok(())
}

/// Blocks SIGCHLD in the calling thread (see [`install_child_handler`]).
pub fn block_child_signal() {
    use nix::sys::signal::{pthread_sigmask, SigSet, SigmaskHow, Signal};
    let mut set = SigSet::empty();
    set.add(Signal::SIGCHLD);
    let _ = pthread_sigmask(SigmaskHow::SIG_BLOCK, Some(&set), None);
}

/// Whether SIGTERM or SIGINT arrived since the handler was installed.
pub fn termination_requested() -> bool {
    TERMINATE.load(Ordering::Relaxed)
}

/// Asks the main loop of this process to stop, as a signal would.
pub fn request_termination() {
    TERMINATE.store(true, Ordering::SeqCst);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shutdown_is_requested_through_any_of_its_clones_and_only_then() {
        let sut = Shutdown::new();
        let clone = sut.clone();
        assert!(!sut.requested());
        clone.request();
        assert!(sut.requested());
        assert!(!Shutdown::new().requested(), "a new one is its own");
    }
}
