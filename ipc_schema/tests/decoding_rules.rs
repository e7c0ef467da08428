//! The decoding rules `ipc_schema/README.md` states ("What decoders accept"), one test and one
//! assertion each, so that the text, the code and these tests agree: each test takes a golden
//! vector of the README, breaks the one thing its rule is about, and shows that the decoder
//! refuses it with the error that names the problem — or, for bytes written 0 and ignored,
//! that it reads the same as before. A test fails if its rule is not implemented.
//!
//! One file per format, under `decoding_rules/`.

mod support;

#[path = "decoding_rules/bus.rs"]
mod bus;
#[path = "decoding_rules/directory.rs"]
mod directory;
#[path = "decoding_rules/frames.rs"]
mod frames;
#[path = "decoding_rules/grid.rs"]
mod grid;
#[path = "decoding_rules/grid_spec.rs"]
mod grid_spec;
#[path = "decoding_rules/heartbeat.rs"]
mod heartbeat;
#[path = "decoding_rules/latency.rs"]
mod latency;
#[path = "decoding_rules/ledger.rs"]
mod ledger;
#[path = "decoding_rules/relay.rs"]
mod relay;
#[path = "decoding_rules/snapshot.rs"]
mod snapshot;
#[path = "decoding_rules/status.rs"]
mod status;
#[path = "decoding_rules/switch.rs"]
mod switch;

use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{OwnedValue, Value};

/// The values of a run in the payload encoding (a ledger, status rows, an `assembly()` answer,
/// a checked grid).
pub fn run_values(bytes: &[u8]) -> Vec<OwnedValue> {
    Values::new(bytes, 0)
        .map(|v| v.unwrap().to_owned_value())
        .collect()
}

/// `values` encoded back to back.
pub fn run_bytes(values: &[OwnedValue]) -> Vec<u8> {
    let mut out = Vec::new();
    for v in values {
        v.as_value().encode_to_vec(&mut out).unwrap();
    }
    out
}

/// The run of the golden vector `description` with value `index` replaced by `value`.
pub fn run_with(description: &str, index: usize, value: Value<'_>) -> Vec<u8> {
    let mut values = run_values(&support::golden(description));
    values[index] = value.to_owned_value();
    run_bytes(&values)
}
