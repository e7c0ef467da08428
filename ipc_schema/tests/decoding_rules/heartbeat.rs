//! Heartbeats.

use modbot_ipc_schema::heartbeat::{Heartbeat, HeartbeatError};

use crate::support::golden;

#[test]
fn a_heartbeat_reader_ignores_its_reserved_byte() {
    let mut bytes = golden("heartbeat addr=7");
    bytes[7] = 0xaa;
    assert_eq!(Heartbeat::parse(&bytes).unwrap().beat(), 5);
}

#[test]
fn a_heartbeat_of_another_length_is_refused() {
    let mut bytes = golden("heartbeat addr=7");
    bytes.push(0);
    assert_eq!(
        Heartbeat::parse(&bytes).err(),
        Some(HeartbeatError::Size(49))
    );
}

#[test]
fn a_heartbeat_with_an_unknown_state_is_refused() {
    let mut bytes = golden("heartbeat addr=7");
    bytes[6] = 4;
    assert_eq!(
        Heartbeat::parse(&bytes).err(),
        Some(HeartbeatError::State(4))
    );
}
