//! The golden block of `ipc_schema/README.md` and its notation, for the tests that read it.
//!
//! A line is a description, two or more spaces, then the bytes. In the bytes, `|` separates
//! the parts of a message (a header, its records, its names, its values) and is skipped;
//! `XX*N` is N bytes `XX`; anything else is hex, spaces and `_` grouping the digits. A `bytes=`
//! value in a description is written the same way.

#![allow(dead_code)] // each test crate uses part of it

use modbot_ipc_schema::{hex, OwnedValue};

/// Every line of the README's golden block: its description and its bytes.
pub fn lines() -> Vec<(String, Vec<u8>)> {
    let readme = include_str!("../../README.md");
    let block = readme
        .split("```golden")
        .nth(1)
        .expect("README has a golden block")
        .split("```")
        .next()
        .unwrap_or_default();
    block
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let (desc, notation) = l
                .split_once("  ")
                .unwrap_or_else(|| panic!("a description, two spaces, then bytes: {l}"));
            (desc.trim().to_owned(), bytes(notation))
        })
        .collect()
}

/// The bytes of the golden line whose description starts with `description`.
pub fn golden(description: &str) -> Vec<u8> {
    lines()
        .into_iter()
        .find(|(desc, _)| desc.starts_with(description))
        .unwrap_or_else(|| panic!("the golden vector '{description}'"))
        .1
}

/// The bytes `notation` writes (see the module doc).
pub fn bytes(notation: &str) -> Vec<u8> {
    let mut out = Vec::new();
    for word in notation.split_whitespace().filter(|w| *w != "|") {
        match word.split_once('*') {
            Some((byte, count)) => {
                let byte = hex::decode(byte).unwrap_or_else(|e| panic!("{word}: {e}"));
                let count: usize = count.parse().unwrap_or_else(|e| panic!("{word}: {e}"));
                assert_eq!(byte.len(), 1, "{word}: a run is of one byte");
                out.extend(std::iter::repeat_n(byte[0], count));
            }
            None => out.extend(hex::decode(word).unwrap_or_else(|e| panic!("{word}: {e}"))),
        }
    }
    out
}

/// The value of kind `kind` (`f64`, `i64`, `bool`, `text`, `bytes`, `f64s`) written `text`;
/// `None` for a word that is not a kind.
pub fn value(kind: &str, text: &str) -> Option<OwnedValue> {
    Some(match kind {
        "f64" => OwnedValue::F64(text.parse().unwrap()),
        "i64" => OwnedValue::I64(text.parse().unwrap()),
        "bool" => OwnedValue::Bool(text.parse().unwrap()),
        "text" => OwnedValue::Text(text.to_owned()),
        "bytes" => OwnedValue::Bytes(bytes(text)),
        "f64s" => OwnedValue::F64s(text.split(',').map(|x| x.parse().unwrap()).collect()),
        _ => return None,
    })
}

/// The values a description lists as `KIND=VALUE`, in order.
pub fn values(desc: &str) -> Vec<OwnedValue> {
    desc.split_whitespace()
        .filter_map(|w| w.split_once('='))
        .filter_map(|(kind, text)| value(kind, text))
        .collect()
}

/// The field `key=VALUE` of a description.
pub fn field<'a>(desc: &'a str, key: &str) -> &'a str {
    desc.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .unwrap_or_else(|| panic!("{key} in {desc}"))
}

/// A snapshot item a description lists as `NAME:KIND=VALUE`, with `:writable` and `:bulk`
/// after the kind when its flags say so.
pub struct SnapshotItem {
    pub name: String,
    pub writable: bool,
    pub bulk: bool,
    pub value: OwnedValue,
}

/// The snapshot items of a description, in its order.
pub fn snapshot_items(desc: &str) -> Vec<SnapshotItem> {
    desc.split_whitespace()
        .filter_map(|w| w.split_once('='))
        .filter(|(key, _)| key.contains(':'))
        .map(|(key, text)| {
            let mut parts = key.split(':');
            let name = parts.next().unwrap_or_default().to_owned();
            let kind = parts.next().unwrap_or_default();
            let flags: Vec<&str> = parts.collect();
            assert!(
                flags.iter().all(|f| matches!(*f, "writable" | "bulk")),
                "{key}: flags are writable and bulk"
            );
            SnapshotItem {
                name,
                writable: flags.contains(&"writable"),
                bulk: flags.contains(&"bulk"),
                value: value(kind, text).unwrap_or_else(|| panic!("{key}: unknown kind")),
            }
        })
        .collect()
}
