//! The default application controller: the main loop of a module that needs no special one.

use crate::error::ModuleError;
use crate::module::Module;
use crate::transport::ReceiveMode;

/// Serves frames and runs periodic work until SIGTERM/SIGINT or [`crate::Ctx::stop`].
pub(crate) fn run_loop<S>(module: &mut Module<S>) -> Result<(), ModuleError> {
    if let Err(e) = crate::signals::install_termination_handler() {
        tracing::warn!("cannot handle SIGTERM/SIGINT: {e}");
    }
    crate::transport::launch::apply_mlockall();
    while !module.should_stop() {
        let mut served = 0;
        while served < 64 && module.poll_once()? {
            served += 1;
        }
        module.housekeeping();
        if served == 0 {
            match module.mode() {
                ReceiveMode::Blocking => {
                    let budget = module.idle_budget();
                    module.wait(budget)?;
                }
                ReceiveMode::BusyPoll => core::hint::spin_loop(),
            }
        }
    }
    tracing::info!("module {} stops", module.ctx().name());
    Ok(())
}

/// Runs `module` with the default application controller: serve, tick, stop cleanly.
pub fn run<S>(module: Module<S>) -> Result<(), ModuleError> {
    module.run()
}
