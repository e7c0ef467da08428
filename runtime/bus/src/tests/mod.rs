//! Tests of the bus: the CiA 402 state machine against the standard's table, the plant's
//! numerics, and the simulated drives in closed loop.

mod backend_params;
mod cia402;
mod joints;
mod plant;
mod sim;
