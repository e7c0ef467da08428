//! Method ids that every module answers, besides its own methods.
//!
//! A module's own methods take ids `0..=239` in the order it declares them; `240..=255` are
//! reserved for these.

/// The first reserved method id.
pub const FIRST_RESERVED: u8 = 0xF0;

/// `describe()` → `[name: text, pid: i64, mode: text, methods: text, items: text,
/// dropped: i64, rejected: i64, replayed: i64, active: bool]`.
///
/// `methods` lists the method names in id order, comma-separated; `items` lists the blackboard
/// items as `name:kind` (with `:rw` when other modules may write), comma-separated. `dropped`
/// counts frames this module could not deliver (a full inbox); `rejected` counts malformed
/// frames it received and dropped; `replayed` counts retransmitted requests it answered from its
/// record of served requests instead of executing them again; `active` is false while an
/// operator has deactivated the module ([`DEACTIVATE`]).
pub const DESCRIBE: u8 = 0xF0;

/// `bb_get(item: text)` → `[value]`.
pub const BB_GET: u8 = 0xF1;

/// `bb_set(item: text, value)` → ACK, or NAK `unknown item` / `read-only` / `bad arguments`.
pub const BB_SET: u8 = 0xF2;

/// `bb_snapshot()` → `[snapshot: bytes]`, the whole blackboard in the snapshot format.
pub const BB_SNAPSHOT: u8 = 0xF3;

/// `stats()` → `[frames_sent: i64, frames_received: i64, calls: i64, answered: i64,
/// failed: i64, latency: bytes]`.
///
/// Counted since the module started: RVMF* frames sent and received (malformed ones
/// included); calls the module's code made, those answered with a REPLY or an ACK, and those
/// that failed (NAK, malformed answer, timeout, peer died). `latency` is the histogram of the
/// answered calls' latencies (first send to answer, NAKs included) in ns, in the layout of
/// [`crate::latency`] (log-linear buckets, 12.5 % resolution).
pub const STATS: u8 = 0xF4;

/// `activate()` → ACK: the operator (re)activates the module; it serves its own methods and
/// runs its periodic tasks again. Activating an active module changes nothing.
pub const ACTIVATE: u8 = 0xF5;

/// `deactivate()` → ACK: the operator deactivates the module. Until [`ACTIVATE`], it answers
/// its own methods with NAK `not ready` ("module 'x' is deactivated by the operator") and does
/// not run its periodic tasks; the system methods keep answering, and its heartbeats, snapshots
/// and reports go on.
pub const DEACTIVATE: u8 = 0xF6;

/// `upgrade_out(dir: text, methods: text, force: bool)` → ACK, or NAK `failed` naming how the
/// methods differ (or refusing a caller that is not the supervisor, or a `dir` that is no
/// directory): the supervisor asks a module to hand over to the process it started to
/// take it over (`modbot upgrade`). `methods` is the new program's method names in id order,
/// comma-separated; unless `force`, a table other than the module's own is refused and the
/// module serves on. On ACK the module stops serving: it keeps the requests and reports that
/// come, unserved, for the new process, waits for it to subscribe and for its own calls'
/// answers, then writes its state (and what it kept) into `dir` and leaves
/// (`modbot_core::upgrade` describes the handover).
pub const UPGRADE_OUT: u8 = 0xF7;

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
        STATS => "stats",
        ACTIVATE => "activate",
        DEACTIVATE => "deactivate",
        UPGRADE_OUT => "upgrade_out",
        _ => return None,
    })
}

/// The system methods, in id order.
pub const ALL: [u8; 8] = [
    DESCRIBE,
    BB_GET,
    BB_SET,
    BB_SNAPSHOT,
    STATS,
    ACTIVATE,
    DEACTIVATE,
    UPGRADE_OUT,
];

/// The id of a reserved method, by name.
pub fn id(name: &str) -> Option<u8> {
    ALL.into_iter().find(|id| self::name(*id) == Some(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_system_method_has_a_reserved_id_and_a_name_that_maps_back() {
        for sut in ALL {
            assert!(sut >= FIRST_RESERVED && sut != ANNOUNCE_TOPIC);
            let name = name(sut).expect("named");
            assert_eq!(id(name), Some(sut), "{name}");
        }
        assert_eq!(
            ALL.map(|i| name(i).unwrap()),
            [
                "describe",
                "bb_get",
                "bb_set",
                "bb_snapshot",
                "stats",
                "activate",
                "deactivate",
                "upgrade_out"
            ]
        );
        assert_eq!(
            (STATS, ACTIVATE, DEACTIVATE, UPGRADE_OUT),
            (0xF4, 0xF5, 0xF6, 0xF7)
        );
        assert_eq!(id("status"), None);
        assert_eq!(name(0xF8), None);
    }
}
