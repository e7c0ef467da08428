//! Ctrl-C (SIGINT) and SIGTERM while a program runs: a flag the interpreter looks at while it
//! waits for the robot and in the instruction hook, so the program stops at once and the
//! robot is left holding. Unlike a module's termination flag it can be taken back: the REPL
//! goes on after a command it stopped.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Where an interpreter hears of a stop asked for: the signals (a program run from the
/// command line), or a flag of its own (tests, an interpreter embedded in another program).
#[derive(Debug, Clone, Default)]
pub enum Interrupt {
    /// SIGINT and SIGTERM, once [`install`]ed.
    #[default]
    Signals,
    Flag(Arc<AtomicBool>),
}

impl Interrupt {
    /// Whether a stop was asked for since the last [`Interrupt::clear`].
    pub fn is_set(&self) -> bool {
        match self {
            Interrupt::Signals => interrupted(),
            Interrupt::Flag(f) => f.load(Ordering::Relaxed),
        }
    }

    /// Forgets a stop asked for (the REPL, once the command it stopped has been handled).
    pub fn clear(&self) {
        match self {
            Interrupt::Signals => clear(),
            Interrupt::Flag(f) => f.store(false, Ordering::SeqCst),
        }
    }
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: nix::libc::c_int) {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Turns SIGINT and SIGTERM into [`interrupted`] from now on (the process no longer ends on
/// them: its owner looks at the flag).
pub fn install() -> Result<(), nix::Error> {
    use nix::sys::signal::{sigaction, SaFlags, SigAction, SigHandler, SigSet, Signal};
    let action = SigAction::new(
        SigHandler::Handler(on_signal),
        SaFlags::SA_RESTART,
        SigSet::empty(),
    );
    for sig in [Signal::SIGINT, Signal::SIGTERM] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        unsafe { sigaction(sig, &action) }?;
    }
    Ok(())
}

/// Whether a stop was asked for since the last [`clear`].
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

/// Forgets a stop asked for (the REPL, once the command it stopped has been handled).
pub fn clear() {
    INTERRUPTED.store(false, Ordering::SeqCst);
}
