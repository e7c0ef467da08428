//! The default application controller: the main loop of a module that needs no special one.

use crate::error::ModuleError;
use crate::module::Module;

/// Runs `module` with the default application controller: serve, tick, stop cleanly.
pub fn run<S>(module: Module<S>) -> Result<(), ModuleError> {
    module.run()
}
