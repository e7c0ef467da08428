//! The device behind the process data.

use std::any::Any;

use crate::dictionary::{ObjectDictionary, ObjectEntry};

/// What a slave does: the objects it adds to the dictionary and one process-data cycle.
///
/// # When `step` runs
/// Once per frame whose process-data datagram (LWR/LRW) wrote this slave's outputs (the last
/// byte of its output sync manager), in SAFE-OP and OP, within the slave's pass over that
/// datagram: the written outputs are copied into the dictionary (in OP only; SAFE-OP keeps
/// outputs safe), `step` runs, then the inputs it produced are copied into the input buffer,
/// so the same LRW reads them back. This is a slave whose sync point falls between the write
/// and the read of one frame, so a test sees the reaction of a cycle in the same cycle. A
/// slave without outputs steps on the read of its inputs instead.
///
/// `dt_s` is the SYNC0 cycle time (0x09A0) while DC SYNC0 is active, else the chain's
/// default period.
pub trait Application: Send {
    /// Objects it adds to the dictionary (e.g. CiA 402's 0x6040, 0x6041, 0x6060, ...).
    fn objects(&self) -> Vec<ObjectEntry>;
    /// One process-data cycle of dt_s seconds: the RxPDO objects have just been written
    /// into `od`; update the TxPDO objects in `od`.
    fn step(&mut self, od: &mut ObjectDictionary, dt_s: f64);
    /// The slave left OP (the master asked, or the sync manager watchdog expired): its outputs
    /// no longer come from the master. A device puts them in their safe state here (a CiA 402
    /// drive: the reaction its abort connection option code 0x6007 gives). Does nothing by
    /// default.
    fn outputs_invalid(&mut self, od: &mut ObjectDictionary) {
        let _ = od;
    }
}

/// An application that can also be downcast to its concrete type.
pub(crate) trait AnyApplication: Application {
    fn as_any_mut(&mut self) -> &mut dyn Any;
    fn as_application_mut(&mut self) -> &mut dyn Application;
}

impl<T: Application + Any> AnyApplication for T {
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }

    fn as_application_mut(&mut self) -> &mut dyn Application {
        self
    }
}

/// An application with no objects that does nothing: a slave of mailbox only.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoApplication;

impl Application for NoApplication {
    fn objects(&self) -> Vec<ObjectEntry> {
        Vec::new()
    }

    fn step(&mut self, _od: &mut ObjectDictionary, _dt_s: f64) {}
}
