//! What an FMU says through its logger callback, kept so that a failed call can name it.
//!
//! The fmi crate hands every message an FMU logs to the `log` crate (FMI 2's with the module
//! path `logger`, FMI 3's with `fmu`), and a host's logging turns `log` records into tracing
//! events on the thread that logged them (tracing-subscriber's `LogTracer`). While a call into
//! the FMU runs, [`FmuLog::scope`] puts a subscriber of its own in front of the thread's (a
//! scoped default dispatcher): it keeps the FMU's last [`KEPT`] messages and passes every
//! event on to the subscriber that was there, so the host's log still shows them. Setting the
//! scope allocates nothing; keeping a message does (an FMU that logs is not on its fast path).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use tracing::dispatcher::{self, DefaultGuard, Dispatch};
use tracing::field::{Field, Visit};
use tracing::span;
use tracing::subscriber::{Interest, Subscriber};
use tracing::{Event, Metadata};

/// How many of an FMU's messages are kept (the newest).
pub const KEPT: usize = 4;
/// How much of one message is kept, in bytes.
const LONGEST: usize = 400;
/// The module paths of the `log` records that carry an FMU's messages (fmi-sys for FMI 2, the
/// fmi crate for FMI 3).
const FMU_MODULES: [&str; 2] = ["logger", "fmu"];

/// The messages one FMU instance logged.
pub struct FmuLog {
    kept: Arc<Mutex<VecDeque<String>>>,
    dispatch: Dispatch,
}

impl FmuLog {
    /// A log that passes events on to this thread's subscriber as it is now.
    pub fn new() -> FmuLog {
        let kept = Arc::new(Mutex::new(VecDeque::with_capacity(KEPT)));
        let forward = dispatcher::get_default(|d| d.clone());
        let capture = Capture {
            kept: kept.clone(),
            forward,
            pass_on: AtomicBool::new(false),
        };
        FmuLog {
            kept,
            dispatch: Dispatch::new(capture),
        }
    }

    /// Keeps what the FMU logs on this thread until the guard is dropped.
    pub fn scope(&self) -> DefaultGuard {
        dispatcher::set_default(&self.dispatch)
    }

    /// The messages kept, oldest first.
    pub fn messages(&self) -> Vec<String> {
        let kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        kept.iter().cloned().collect()
    }

    /// `; the FMU logged: "…"; "…"`, or nothing if it logged nothing.
    pub fn said(&self) -> String {
        let messages = self.messages();
        if messages.is_empty() {
            return String::new();
        }
        let quoted: Vec<String> = messages.iter().map(|m| format!("{m:?}")).collect();
        format!("; the FMU logged: {}", quoted.join("; "))
    }
}

/// The subscriber in front of the thread's while an FMU is called.
struct Capture {
    kept: Arc<Mutex<VecDeque<String>>>,
    /// The subscriber that was the thread's.
    forward: Dispatch,
    /// Whether the `log` record just asked about is one `forward` wants (asked in
    /// [`Subscriber::enabled`], used in [`Subscriber::event`], on the same thread).
    pass_on: AtomicBool,
}

/// Whether `meta` is a `log` record's (tracing-log's callsites carry its module path).
fn from_log(meta: &Metadata<'_>) -> bool {
    meta.fields().field("log.module_path").is_some()
}

/// A `log` record's message and module path.
#[derive(Default)]
struct Record {
    message: String,
    module: String,
}

impl Visit for Record {
    fn record_str(&mut self, field: &Field, value: &str) {
        match field.name() {
            "message" => self.message.push_str(value),
            "log.module_path" => self.module.push_str(value),
            _ => {}
        }
    }

    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.message, "{value:?}");
        }
    }
}

impl Subscriber for Capture {
    fn register_callsite(&self, meta: &'static Metadata<'static>) -> Interest {
        if from_log(meta) {
            Interest::sometimes()
        } else {
            self.forward.register_callsite(meta)
        }
    }

    fn max_level_hint(&self) -> Option<tracing::level_filters::LevelFilter> {
        // An FMU's messages come at every level (FMI 2's fmi2Discard as TRACE).
        Some(tracing::level_filters::LevelFilter::TRACE)
    }

    fn enabled(&self, meta: &Metadata<'_>) -> bool {
        if from_log(meta) {
            self.pass_on
                .store(self.forward.enabled(meta), Ordering::Relaxed);
            return true;
        }
        self.forward.enabled(meta)
    }

    fn new_span(&self, span: &span::Attributes<'_>) -> span::Id {
        self.forward.new_span(span)
    }

    fn record(&self, span: &span::Id, values: &span::Record<'_>) {
        self.forward.record(span, values);
    }

    fn record_follows_from(&self, span: &span::Id, follows: &span::Id) {
        self.forward.record_follows_from(span, follows);
    }

    fn event(&self, event: &Event<'_>) {
        if !from_log(event.metadata()) {
            self.forward.event(event);
            return;
        }
        let mut record = Record::default();
        event.record(&mut record);
        if FMU_MODULES.contains(&record.module.as_str()) {
            let mut message = record.message;
            if message.len() > LONGEST {
                let mut end = LONGEST;
                while !message.is_char_boundary(end) {
                    end -= 1;
                }
                message.truncate(end);
                message.push('…');
            }
            let mut kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
            if kept.len() == KEPT {
                kept.pop_front();
            }
            kept.push_back(message);
        }
        if self.pass_on.load(Ordering::Relaxed) {
            self.forward.event(event);
        }
    }

    fn enter(&self, span: &span::Id) {
        self.forward.enter(span);
    }

    fn exit(&self, span: &span::Id) {
        self.forward.exit(span);
    }

    fn clone_span(&self, id: &span::Id) -> span::Id {
        self.forward.clone_span(id)
    }

    fn try_close(&self, id: span::Id) -> bool {
        self.forward.try_close(id)
    }
}
