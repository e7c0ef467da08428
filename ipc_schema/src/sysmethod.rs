//! Method ids that every module answers, besides its own methods.
//!
//! A module's own methods take ids `0..=239` in the order it declares them; `240..=255` are
//! reserved for these.

/// The first reserved method id.
pub const FIRST_RESERVED: u8 = 0xF0;

/// `describe()` → `[name: text, pid: i64, mode: text, methods: text, items: text,
/// dropped: i64, rejected: i64, replayed: i64]`.
///
/// `methods` lists the method names in id order, comma-separated; `items` lists the blackboard
/// items as `name:kind` (with `:rw` when other modules may write), comma-separated. `dropped`
/// counts frames this module could not deliver (a full inbox); `rejected` counts malformed
/// frames it received and dropped; `replayed` counts retransmitted requests it answered from its
/// record of served requests instead of executing them again.
pub const DESCRIBE: u8 = 0xF0;

/// `bb_get(item: text)` → `[value]`.
pub const BB_GET: u8 = 0xF1;

/// `bb_set(item: text, value)` → ACK, or NAK `unknown item` / `read-only` / `bad arguments`.
pub const BB_SET: u8 = 0xF2;

/// `bb_snapshot()` → `[snapshot: bytes]`, the whole blackboard in the snapshot format.
pub const BB_SNAPSHOT: u8 = 0xF3;

/// REPORT topic of the announcement a module broadcasts when it comes up:
/// `[name: text, pid: i64]`.
pub const ANNOUNCE_TOPIC: u8 = 0xFF;

/// The name of a reserved method, if `id` is one.
pub fn name(id: u8) -> Option<&'static str> {
    Some(match id {
        DESCRIBE => "describe",
        BB_GET => "bb_get",
        BB_SET => "bb_set",
        BB_SNAPSHOT => "bb_snapshot",
        _ => return None,
    })
}

/// The id of a reserved method, by name.
pub fn id(name: &str) -> Option<u8> {
    [DESCRIBE, BB_GET, BB_SET, BB_SNAPSHOT]
        .into_iter()
        .find(|id| self::name(*id) == Some(name))
}
