//! `modbot record export FILE.h5 --mcap OUT.mcap`: a recording as an MCAP file, which Foxglove
//! opens: one channel per signal (`/modbot/<comp>.<port>`), JSON messages with a JSON schema
//! (`{"tick": N, "value": x}` or an array of values), each stamped with its tick's time
//! (tick × base period, from the recording's `time`).

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use anyhow::Context;
use mcap::records::MessageHeader;
use mcap::{WriteOptions, Writer};
use modbot_record::read::{read_signal, signals, Series};

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exported {
    pub channels: usize,
    pub messages: u64,
}

/// The JSON schema of a signal's messages: `width` values per row (1: a number).
fn schema(width: usize) -> String {
    let value = match width {
        1 => r#"{"type":"number"}"#.to_owned(),
        n => format!(
            r#"{{"type":"array","items":{{"type":"number"}},"minItems":{n},"maxItems":{n}}}"#
        ),
    };
    format!(
        r#"{{"type":"object","properties":{{"tick":{{"type":"integer"}},"value":{value}}},"required":["tick","value"]}}"#
    )
}

/// A number as JSON (which has no NaN or infinity: those are null).
fn number(x: f64, out: &mut String) {
    use std::fmt::Write;
    if x.is_finite() {
        let _ = write!(out, "{x:?}");
    } else {
        out.push_str("null");
    }
}

/// One row of `series` as a message.
fn message(tick: i64, values: &[f64]) -> String {
    let mut out = format!(r#"{{"tick":{tick},"value":"#);
    if let [x] = values {
        number(*x, &mut out);
    } else {
        out.push('[');
        for (i, x) in values.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            number(*x, &mut out);
        }
        out.push(']');
    }
    out.push('}');
    out
}

/// Writes the recording `h5` as the MCAP file `out`.
pub fn export(h5: &Path, out: &Path) -> anyhow::Result<Exported> {
    let all = |signal: &str| read_signal(h5, signal, i64::MIN, i64::MAX);
    let names = signals(h5)?;
    let time = all("time")?;
    let series: Vec<(String, Series)> = names
        .into_iter()
        .map(|n| Ok((n.clone(), all(&n)?)))
        .collect::<anyhow::Result<_>>()?;
    let file = std::fs::File::create(out).with_context(|| format!("{}", out.display()))?;
    let options = WriteOptions::new().compression(None).profile("");
    let mut writer = Writer::with_options(BufWriter::new(file), options)?;
    let mut channels = Vec::with_capacity(series.len());
    for (name, s) in &series {
        let schema = writer.add_schema(
            &format!("modbot.{name}"),
            "jsonschema",
            schema(s.width).as_bytes(),
        )?;
        let topic = format!("/modbot/{name}");
        channels.push(writer.add_channel(schema, &topic, "json", &BTreeMap::new())?);
    }
    let mut messages = 0u64;
    for (row, &tick) in time.ticks.iter().enumerate() {
        let t = time.row(row)[0];
        let ns = if t.is_finite() && t >= 0.0 {
            (t * 1e9).round() as u64
        } else {
            0
        };
        for ((_, s), &channel_id) in series.iter().zip(&channels) {
            let Some(at) = s.ticks.get(row).filter(|&&t| t == tick) else {
                continue;
            };
            let header = MessageHeader {
                channel_id,
                sequence: u32::try_from(row).unwrap_or(u32::MAX),
                log_time: ns,
                publish_time: ns,
            };
            writer.write_to_known_channel(&header, message(*at, s.row(row)).as_bytes())?;
            messages += 1;
        }
    }
    writer.finish()?;
    Ok(Exported {
        channels: channels.len(),
        messages,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_is_a_json_message_and_its_schema_says_its_width() {
        assert_eq!(message(7, &[1.5]), r#"{"tick":7,"value":1.5}"#);
        assert_eq!(
            message(8, &[1.0, f64::NAN]),
            r#"{"tick":8,"value":[1.0,null]}"#
        );
        assert!(schema(6).contains(r#""minItems":6"#));
        assert!(schema(1).contains(r#""value":{"type":"number"}"#));
    }
}
