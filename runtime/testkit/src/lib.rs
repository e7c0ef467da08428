//! modbot-testkit: what every modbot test that touches shared memory shares.
//!
//! - [`TestDomain`]: a domain of its own for one test, named from the process id, a counter
//!   and the test's name (parallel tests and parallel test runs never meet), whose files in
//!   `/dev/shm` and `/tmp/iceoryx2` are removed when it is dropped, whatever happened;
//!   [`TestDomain::leftover_files`] is what a test asserts empty at its end.
//! - [`watchdog`]: runs a test body on a thread of its own and fails it, with its name, if it
//!   hangs.
//! - [`wait_until`] and [`eventually`]: event-free waiting on a condition with a generous
//!   deadline, saying what was last seen when it does not hold.
//! - [`TempDir`]: a directory of one test's own (programs, assembly data), removed on drop.
//!
//! The suites build their fixtures on these: `runtime/tests/support` (modules on threads,
//! both transport backends) and `tests/common` (the real programs as processes).

mod domain;
mod temp;
mod wait;

pub use domain::TestDomain;
pub use temp::TempDir;
pub use wait::{eventually, wait_until, watchdog};
