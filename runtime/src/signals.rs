//! SIGTERM and SIGINT as a flag the main loop checks.

use std::sync::atomic::{AtomicBool, Ordering};

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

/// Whether SIGTERM or SIGINT arrived since the handler was installed.
pub fn termination_requested() -> bool {
    TERMINATE.load(Ordering::Relaxed)
}

/// Asks the main loop of this process to stop, as a signal would.
pub fn request_termination() {
    TERMINATE.store(true, Ordering::SeqCst);
}
