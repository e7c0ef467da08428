//! What a browser sends over the WebSocket, and what it gets back for a command.
//!
//! A message is one JSON object of at most [`MAX_MESSAGE`] bytes:
//! - `{"op": "call", "id": 7, "module": "near_ir", "method": "deactivate", "args": ["1.5"]}`:
//!   calls a method of a module (system methods too: `activate`, `deactivate`, `stats`, a
//!   supervisor's `down`); each argument is text, read as `modbot call` reads it (`1.5` an
//!   f64, `3` an i64, `true` a bool, `[1, 2]` an array, `text:3` text). Answered with
//!   `{"type": "answer", "id": 7, "ok": true, "text": "…"}` or `"ok": false` and the error.
//! - `{"op": "watch", "modules": ["mobility", "arm"]}`: the blackboards this page wants in
//!   the state (besides those the station always watches), for the next few seconds.
//!
//! Anything else — not JSON, an unknown `op`, a missing field, a name that cannot be a module
//! — is a [`MessageError`], and the station closes that connection with its text as the reason.

use modbot_ipc_schema::OwnedValue;
use serde::Deserialize;
use thiserror::Error;

/// The largest message a browser may send, in bytes.
pub const MAX_MESSAGE: usize = 16 * 1024;
/// The most arguments a call may have.
pub const MAX_ARGS: usize = 32;
/// The most modules one watch may name.
pub const MAX_WATCHED: usize = 64;

/// A message from a browser.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    Call(Call),
    Watch(Vec<String>),
}

/// A method call the page asks for.
#[derive(Debug, Clone, PartialEq)]
pub struct Call {
    pub id: u64,
    pub module: String,
    pub method: String,
    pub args: Vec<OwnedValue>,
}

/// Why a message was refused.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MessageError {
    #[error("message of {len} bytes: at most {MAX_MESSAGE}")]
    TooLong { len: usize },
    #[error("malformed message: {0}")]
    Json(String),
    #[error("unknown op '{0}' (call, watch)")]
    UnknownOp(String),
    #[error("'{name}' is not a module name (1 to 48 of a-z A-Z 0-9 _ -)")]
    ModuleName { name: String },
    #[error("'{name}' is not a method name")]
    MethodName { name: String },
    #[error("{count} arguments: at most {MAX_ARGS}")]
    TooManyArgs { count: usize },
    #[error("argument {index}: {why}")]
    Arg { index: usize, why: String },
    #[error("{count} modules to watch: at most {MAX_WATCHED}")]
    TooManyWatched { count: usize },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    op: String,
    #[serde(default)]
    id: u64,
    #[serde(default)]
    module: Option<String>,
    #[serde(default)]
    method: Option<String>,
    #[serde(default)]
    args: Vec<String>,
    #[serde(default)]
    modules: Vec<String>,
}

/// Reads one message from a browser.
pub fn parse(text: &str) -> Result<Message, MessageError> {
    if text.len() > MAX_MESSAGE {
        return Err(MessageError::TooLong { len: text.len() });
    }
    let raw: Raw = serde_json::from_str(text).map_err(|e| MessageError::Json(e.to_string()))?;
    match raw.op.as_str() {
        "call" => {
            let module = module_name(raw.module.unwrap_or_default())?;
            let method = raw.method.unwrap_or_default();
            if method.is_empty()
                || method.len() > 64
                || !method
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(MessageError::MethodName { name: method });
            }
            if raw.args.len() > MAX_ARGS {
                return Err(MessageError::TooManyArgs {
                    count: raw.args.len(),
                });
            }
            let args = raw
                .args
                .iter()
                .enumerate()
                .map(|(index, a)| {
                    OwnedValue::parse(a).map_err(|e| MessageError::Arg {
                        index,
                        why: e.to_string(),
                    })
                })
                .collect::<Result<_, _>>()?;
            Ok(Message::Call(Call {
                id: raw.id,
                module,
                method,
                args,
            }))
        }
        "watch" => {
            if raw.modules.len() > MAX_WATCHED {
                return Err(MessageError::TooManyWatched {
                    count: raw.modules.len(),
                });
            }
            let modules = raw
                .modules
                .into_iter()
                .map(module_name)
                .collect::<Result<_, _>>()?;
            Ok(Message::Watch(modules))
        }
        other => Err(MessageError::UnknownOp(other.chars().take(32).collect())),
    }
}

fn module_name(name: String) -> Result<String, MessageError> {
    if modbot_ipc_schema::names::is_module_name(name.as_bytes()) {
        Ok(name)
    } else {
        Err(MessageError::ModuleName {
            name: name.chars().take(64).collect(),
        })
    }
}

/// The answer to a call, as the page shows it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Answer {
    #[serde(rename = "type")]
    pub kind: &'static str,
    pub id: u64,
    pub ok: bool,
    pub text: String,
}

impl Answer {
    pub fn ok(id: u64, text: String) -> Answer {
        Answer {
            kind: "answer",
            id,
            ok: true,
            text,
        }
    }

    pub fn err(id: u64, text: String) -> Answer {
        Answer {
            kind: "answer",
            id,
            ok: false,
            text,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_call_with_typed_arguments_is_read() {
        let m = parse(
            r#"{"op":"call","id":7,"module":"near_ir","method":"deactivate","args":["1.5","3","true","hi"]}"#,
        )
        .unwrap();
        assert_eq!(
            m,
            Message::Call(Call {
                id: 7,
                module: "near_ir".into(),
                method: "deactivate".into(),
                args: vec![
                    OwnedValue::F64(1.5),
                    OwnedValue::I64(3),
                    OwnedValue::Bool(true),
                    OwnedValue::Text("hi".into())
                ],
            })
        );
    }

    #[test]
    fn a_watch_names_modules() {
        assert_eq!(
            parse(r#"{"op":"watch","modules":["mobility","arm_1"]}"#).unwrap(),
            Message::Watch(vec!["mobility".into(), "arm_1".into()])
        );
    }

    #[test]
    fn malformed_messages_are_refused_with_their_reason() {
        let cases = [
            ("not json", "malformed message"),
            (r#"{"op":"launch"}"#, "unknown op 'launch'"),
            (r#"{"op":"call","method":"x"}"#, "is not a module name"),
            (
                r#"{"op":"call","module":"a b","method":"x"}"#,
                "'a b' is not a module name",
            ),
            (
                r#"{"op":"call","module":"a","method":""}"#,
                "is not a method name",
            ),
            (
                r#"{"op":"call","module":"a","method":"x;y"}"#,
                "'x;y' is not a method name",
            ),
            (
                r#"{"op":"call","module":"a","method":"x","extra":1}"#,
                "unknown field",
            ),
            (
                r#"{"op":"call","module":"a","method":"x","args":["f64:z"]}"#,
                "argument 0",
            ),
            (
                r#"{"op":"call","module":"a","method":"x","args":[1]}"#,
                "malformed message",
            ),
        ];
        for (text, expected) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(expected), "{text}: {e}");
        }
        let long = format!(
            r#"{{"op":"watch","modules":["{}"]}}"#,
            "a".repeat(MAX_MESSAGE)
        );
        assert!(matches!(parse(&long), Err(MessageError::TooLong { .. })));
        let many: Vec<String> = (0..=MAX_ARGS).map(|i| format!("\"{i}\"")).collect();
        let text = format!(
            r#"{{"op":"call","module":"a","method":"x","args":[{}]}}"#,
            many.join(",")
        );
        assert!(matches!(
            parse(&text),
            Err(MessageError::TooManyArgs { .. })
        ));
    }
}
