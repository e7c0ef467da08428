//! A grid process's module, served on a thread of its own at normal scheduling: its method
//! calls, heartbeats and directory reads (milliseconds, now and then) never hold up the thread
//! that serves the grid, which may run under SCHED_FIFO (started before that thread raises
//! its priority, this one keeps the normal one).

use std::time::Duration;

use modbot_core::{signals, Module};

/// Starts the thread: it opens the module with `open` (so the module announces itself only
/// after the caller opened its grid channels), then serves it until a termination signal,
/// calling `between` between rounds of serving (at least every 2 ms: the host's blackboard).
/// Returns once the module is open, or with the error that kept it from opening — at once for
/// the new process of a live upgrade, whose module opens only when the running one hands it
/// over (after the grid's components: the caller's thread takes those over meanwhile; a module
/// that fails to open ends the thread, which the caller sees).
pub fn serve_module<S: 'static>(
    open: impl FnOnce() -> anyhow::Result<Module<S>> + Send + 'static,
    mut between: impl FnMut(&mut Module<S>) + Send + 'static,
) -> anyhow::Result<std::thread::JoinHandle<anyhow::Result<()>>> {
    let (opened_tx, opened) = std::sync::mpsc::channel();
    let handle = std::thread::Builder::new().name("service".into()).spawn(
        move || -> anyhow::Result<()> {
            let mut module = match open() {
                Ok(m) => {
                    let _ = opened_tx.send(Ok(()));
                    m
                }
                Err(e) => {
                    let text = e.to_string();
                    let _ = opened_tx.send(Err(e));
                    anyhow::bail!("{text}");
                }
            };
            // A module that handed over to a new process (a live upgrade) stops here.
            while !signals::termination_requested() && !module.should_stop() {
                let mut served = 0;
                while served < 16 && module.poll_once()? {
                    served += 1;
                }
                between(&mut module);
                module.housekeeping();
                if served == 0 {
                    std::thread::sleep(Duration::from_millis(2));
                }
            }
            Ok(())
        },
    )?;
    if std::env::var_os(modbot_core::transport::launch::UPGRADE_DIR).is_some() {
        return Ok(handle);
    }
    match opened.recv() {
        Ok(Ok(())) => Ok(handle),
        Ok(Err(e)) => Err(e),
        Err(_) => match handle.join() {
            Ok(Err(e)) => Err(e),
            _ => anyhow::bail!("the service thread ended before the module was open"),
        },
    }
}
