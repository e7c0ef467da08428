//! CPU hogs: processes of normal priority that spin, one per core, so a measurement shows what
//! the real-time threads keep when the machine is busy (as a shared controller is).

use crate::opts::Opts;
use crate::procs::{self, Proc};

/// Spinning processes, stopped when dropped.
pub struct Hogs {
    procs: Vec<Proc>,
}

impl Hogs {
    /// Starts `n` hogs (none for 0).
    pub fn start(opts: &Opts, n: usize) -> anyhow::Result<Hogs> {
        let procs = (0..n)
            .map(|_| procs::spawn_role(opts, "hog", &[]))
            .collect::<anyhow::Result<Vec<_>>>()?;
        Ok(Hogs { procs })
    }
}

impl Drop for Hogs {
    fn drop(&mut self) {
        for p in self.procs.drain(..) {
            if let Err(e) = p.stop() {
                eprintln!("warning: a CPU hog did not stop cleanly: {e:#}");
            }
        }
    }
}

/// The child role `hog`: spins at normal priority until told to stop (or its parent dies).
pub fn child(role: &str, _args: &[String]) -> Option<anyhow::Result<()>> {
    if role != "hog" {
        return None;
    }
    let mut x = 0u64;
    while !procs::interrupted() {
        for _ in 0..100_000 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
    }
    Some(Ok(()))
}
