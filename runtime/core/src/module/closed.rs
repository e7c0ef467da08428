//! What stands in for a module's endpoint once the module has released it.

use core::time::Duration;

use modbot_ipc_schema::Addr;

use crate::transport::{Dest, Directory, PeerInfo, Rx, SendError, Snapshots, TransportError, Tx};

/// Stands in for the endpoint once a module has released it.
pub(super) struct Closed;

impl Rx for Closed {
    fn try_receive(&mut self, _: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        Ok(false)
    }
    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        std::thread::sleep(timeout);
        Ok(())
    }
}

impl Tx for Closed {
    fn send(
        &mut self,
        to: Dest<'_>,
        _: usize,
        _: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), SendError> {
        Err(SendError::NoReceiver(match to {
            Dest::Module(a) => a,
            _ => Addr::BROADCAST,
        }))
    }
    fn connect(&mut self, _: Addr) -> Result<(), SendError> {
        Ok(())
    }
    fn disconnect(&mut self, _: Addr) {}
    fn dropped(&self) -> u64 {
        0
    }
}

impl Snapshots for Closed {
    fn publish(&mut self, _: usize, _: &mut dyn FnMut(&mut [u8])) -> Result<(), TransportError> {
        Ok(())
    }
    fn read_latest(&mut self, _: Addr, _: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        Ok(false)
    }
}

impl Directory for Closed {
    fn list(&self, _: &mut dyn FnMut(PeerInfo)) -> Result<(), TransportError> {
        Ok(())
    }
    fn reap_dead(&self) -> usize {
        0
    }
}
