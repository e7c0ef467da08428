//! `modbot rvmf encode|decode`.

use std::process::ExitCode;

use clap::{Subcommand, ValueEnum};
use modbot_ipc_schema::hex::{self, HexError};
use modbot_ipc_schema::{Addr, Frame, FrameError, FrameKind, FrameSpec, NakCode, Seq, ValueError};

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum KindArg {
    Ack,
    Nak,
    Exec,
    /// A retransmitted EXEC.
    Retry,
    Reply,
    Report,
}

#[derive(Debug, Subcommand)]
pub enum RvmfCommand {
    /// Print a frame as one line of lowercase hex.
    Encode {
        kind: KindArg,
        #[arg(long)]
        dst: u8,
        #[arg(long)]
        src: u8,
        /// Sequence number, 0..=31.
        #[arg(long, default_value_t = 0)]
        seq: u8,
        /// Method id (exec), error code (nak) or topic (report).
        #[arg(long)]
        method: Option<u8>,
        /// The payload, already encoded, as hex.
        #[arg(long)]
        payload: Option<String>,
    },
    /// Print a frame's fields, one `field: value` per line. Exits 2 on a malformed frame.
    Decode {
        /// The frame as hex, or `-` to read it from standard input: hex text (whitespace
        /// ignored) or, if that is not hex, the raw bytes.
        hex: String,
    },
}

pub fn run(command: RvmfCommand) -> ExitCode {
    match command {
        RvmfCommand::Encode {
            kind,
            dst,
            src,
            seq,
            method,
            payload,
        } => match encode(kind, dst, src, seq, method, payload) {
            Ok(line) => {
                println!("{line}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("modbot rvmf encode: {e}");
                ExitCode::from(2)
            }
        },
        RvmfCommand::Decode { hex: text } => match frame_bytes(&text).and_then(|b| decode(&b)) {
            Ok(lines) => {
                print!("{lines}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("malformed frame: {e}");
                ExitCode::from(2)
            }
        },
    }
}

/// Why a frame is not encoded or decoded; one line for stderr.
#[derive(Debug, thiserror::Error)]
enum RvmfError {
    #[error("sequence number {0} does not fit in 5 bits (0..=31)")]
    Seq(u8),
    /// `--method` is missing for a kind with an operand, named here.
    #[error("--method is required for {0} (the {0} operand)")]
    NoOperand(&'static str),
    /// `--method` is given for a kind without an operand (`n ack`, ` reply`: the article's end).
    #[error("a{0} frame carries no method, code or topic: leave out --method")]
    NoMethod(&'static str),
    #[error("an ack frame carries no payload: leave out --payload")]
    AckPayload,
    #[error("--payload: {0}")]
    PayloadHex(#[source] HexError),
    #[error("--payload is not a sequence of values a receiver accepts: {0}")]
    Rejected(#[source] FrameError),
    #[error(transparent)]
    Hex(#[from] HexError),
    #[error("reading standard input: {0}")]
    Stdin(#[source] std::io::Error),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error(transparent)]
    Value(#[from] ValueError),
}

fn encode(
    kind: KindArg,
    dst: u8,
    src: u8,
    seq: u8,
    op: Option<u8>,
    payload: Option<String>,
) -> Result<String, RvmfError> {
    let seq = Seq::new(seq).ok_or(RvmfError::Seq(seq))?;
    let need_op = |what| op.ok_or(RvmfError::NoOperand(what));
    let no_op = |what| match op {
        Some(_) => Err(RvmfError::NoMethod(what)),
        None => Ok(()),
    };
    let kind = match kind {
        KindArg::Ack => {
            no_op("n ack")?;
            if payload.is_some() {
                return Err(RvmfError::AckPayload);
            }
            FrameKind::Ack
        }
        KindArg::Reply => {
            no_op(" reply")?;
            FrameKind::Reply
        }
        KindArg::Retry => FrameKind::Retry {
            method: need_op("retry")?,
        },
        KindArg::Exec => FrameKind::Exec {
            method: need_op("exec")?,
        },
        KindArg::Nak => FrameKind::Nak {
            code: NakCode(need_op("nak")?),
        },
        KindArg::Report => FrameKind::Report {
            topic: need_op("report")?,
        },
    };
    let payload = match payload {
        Some(p) => hex::decode(&p).map_err(RvmfError::PayloadHex)?,
        None => Vec::new(),
    };
    let spec = FrameSpec {
        dst: Addr(dst),
        src: Addr(src),
        seq,
        kind,
    };
    let mut out = vec![0; spec.encoded_len(payload.len())];
    spec.encode(&payload, &mut out)?;
    // What a receiver would refuse is not printed as a frame.
    Frame::decode_strict(&out).map_err(RvmfError::Rejected)?;
    Ok(hex::encode(&out))
}

/// The frame's bytes: `text` as hex, or for `-` standard input, as hex text or raw bytes.
fn frame_bytes(text: &str) -> Result<Vec<u8>, RvmfError> {
    if text != "-" {
        return Ok(hex::decode(text)?);
    }
    let mut input = Vec::new();
    std::io::Read::read_to_end(&mut std::io::stdin().lock(), &mut input)
        .map_err(RvmfError::Stdin)?;
    let as_hex = std::str::from_utf8(&input).ok().and_then(|t| {
        let digits: String = t.chars().filter(|c| !c.is_ascii_whitespace()).collect();
        hex::decode(&digits).ok().filter(|_| !digits.is_empty())
    });
    Ok(as_hex.unwrap_or(input))
}

fn decode(bytes: &[u8]) -> Result<String, RvmfError> {
    let frame = Frame::decode_strict(bytes)?;
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("{k}: {v}\n"));
    line("kind", frame.kind().kind().to_string());
    line("dst", frame.dst().to_string());
    line("src", frame.src().to_string());
    line("seq", frame.seq().to_string());
    line(
        "length",
        format!(
            "{} bytes{}",
            frame.len(),
            if frame.is_extended() {
                " (extended form)"
            } else {
                ""
            }
        ),
    );
    match frame.kind() {
        FrameKind::Exec { method } | FrameKind::Retry { method } => {
            line("method", method.to_string())
        }
        FrameKind::Nak { code } => line("code", code.to_string()),
        FrameKind::Report { topic } => line("topic", topic.to_string()),
        FrameKind::Ack | FrameKind::Reply => {}
    }
    if frame.kind() != FrameKind::Ack {
        line("payload", hex::encode(frame.payload()));
    }
    for (i, v) in frame.values().enumerate() {
        let v = v?;
        line(&format!("value[{i}]"), format!("{} {v}", v.kind()));
    }
    Ok(out)
}
