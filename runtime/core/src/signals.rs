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
