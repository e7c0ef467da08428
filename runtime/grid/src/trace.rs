//! The trace of a grid run: the outputs valid at every tick, as text, so two runs (the
//! reference run and a real one) can be compared line by line.
//!
//! # Format (v1)
//! ```text
//! # modbot trace v1 base_period_ns=1000000 components=A,B,C
//! 0 A.y=0 B.y=0.0 C.v=[0.0,0.0]
//! 1 A.y=1 B.y=0.0 C.v=[0.0,0.0]
//! ```
//! - The header line: the format version, the base tick in nanoseconds, and the component
//!   names in component (index) order, separated by commas.
//! - Then one line per tick, in the order the ticks were written: the tick number, then for
//!   every output port of every component, in component order and then port order,
//!   `<component>.<port>=<value>`, separated by single spaces. A value is printed as
//!   [`PortValue`]'s `Display` does it: `true`/`false`, an integer, an f64 as the shortest
//!   text that reads back to the same bits (`0.1`, `1.0`, `-0.0`, `NaN`, `inf`), an array as
//!   `[x,y,...]` without spaces. So equal traces mean bit-identical outputs.
//! - A value the writer was not given for a tick (a line ended early with
//!   [`TraceWriter::end_tick`]) is written `?`.
//! - A component without outputs adds nothing to the lines.
//! - `# state_hash tick=N hash=0x0123456789abcdef` after tick N's line, every
//!   [`STATE_HASH_EVERY`] ticks (or as set: `modbot up --state-hash-every N`) and after the
//!   last tick: the grid's state hash at N (see [`crate::state_hash`]), so two traces compare
//!   in state beyond the outputs they print. Like every `#` line, readers of values skip it.

use std::fmt::Write as _;
use std::io::{self, Write};

use super::component::PortValue;
use super::spec::GridSpec;

/// How often a trace writes the grid's state hash by default: every 1000 ticks (1 s of a
/// 1 kHz grid), and after the last.
pub const STATE_HASH_EVERY: u64 = 1000;

/// The header line of `spec`'s trace, without the newline.
pub fn header(spec: &GridSpec) -> String {
    header_of_first(spec, spec.components.len())
}

/// The header line of a trace of the first `count` components of `spec`.
fn header_of_first(spec: &GridSpec, count: usize) -> String {
    let names: Vec<&str> = spec
        .components
        .iter()
        .take(count)
        .map(|c| c.name.as_str())
        .collect();
    format!(
        "# modbot trace v1 base_period_ns={} components={}",
        spec.base_period.as_nanos(),
        names.join(",")
    )
}

/// Writes a trace: give it the outputs of every component at a tick, in any order; it writes
/// the tick's line once all components are in, or when told to with [`end_tick`] (which after
/// a complete tick does nothing, so calling it after every tick is fine).
///
/// After the first line no allocation happens unless a value's text is longer than any before.
///
/// [`end_tick`]: TraceWriter::end_tick
pub struct TraceWriter<W: Write> {
    out: W,
    /// The header line, written before the first tick line (or by `finish`).
    header: Option<String>,
    /// Per component, per output: `" A.y="`, the text before the value.
    keys: Vec<Vec<String>>,
    /// Per component: the `" A.y=value"` texts of the tick being gathered.
    slots: Vec<String>,
    /// Per component: whether it was given for the tick being gathered.
    given: Vec<bool>,
    /// How many components were given for the tick being gathered.
    count: usize,
    /// The tick being gathered, if any.
    current: Option<u64>,
    /// The tick whose line was written last, so that `end_tick` after a complete tick does
    /// not write it again.
    written: Option<u64>,
    /// Every how many ticks the state hash is written (0: never).
    hash_every: u64,
    /// The last tick's state hash given, and whether it was written.
    last_hash: Option<(u64, u64, bool)>,
}

impl<W: Write> TraceWriter<W> {
    /// A writer of `spec`'s trace to `out`.
    pub fn new(out: W, spec: &GridSpec) -> TraceWriter<W> {
        TraceWriter::of_first(out, spec, spec.components.len())
    }

    /// A writer of the trace of the first `count` components of `spec` (with assemblies: the
    /// system's own).
    pub fn of_first(out: W, spec: &GridSpec, count: usize) -> TraceWriter<W> {
        let keys: Vec<Vec<String>> = spec
            .components
            .iter()
            .take(count)
            .map(|c| {
                c.info
                    .outputs
                    .iter()
                    .map(|p| format!(" {}.{}=", c.name, p.name))
                    .collect()
            })
            .collect();
        let count = keys.len();
        TraceWriter {
            out,
            header: Some(header_of_first(spec, count)),
            keys,
            slots: vec![String::new(); count],
            given: vec![false; count],
            count: 0,
            current: None,
            written: None,
            hash_every: STATE_HASH_EVERY,
            last_hash: None,
        }
    }

    /// The same writer writing the state hash every `every` ticks and after the last (0:
    /// never).
    pub fn with_state_hash_every(mut self, every: u64) -> TraceWriter<W> {
        self.hash_every = every;
        self
    }

    /// Gives the grid's state hash at tick `n` (after its values): written when `n` is a
    /// multiple of the writer's period, and for the last tick given, by [`finish`].
    ///
    /// [`finish`]: TraceWriter::finish
    pub fn state_hash(&mut self, n: u64, hash: u64) -> io::Result<()> {
        if self.hash_every == 0 {
            return Ok(());
        }
        self.end_tick(n)?;
        let due = n > 0 && n.is_multiple_of(self.hash_every);
        if due {
            writeln!(self.out, "# state_hash tick={n} hash={hash:#018x}")?;
        }
        self.last_hash = Some((n, hash, due));
        Ok(())
    }

    /// Records the outputs of `component` valid at tick `n`. A tick other than the one being
    /// gathered ends that one first. Fails on an unknown component or the wrong number of
    /// outputs (`InvalidInput`), or when writing fails.
    pub fn tick(&mut self, n: u64, component: usize, outputs: &[PortValue]) -> io::Result<()> {
        let Some(expected) = self.keys.get(component).map(Vec::len) else {
            return Err(invalid(format!(
                "component {component} is not in the trace"
            )));
        };
        if expected != outputs.len() {
            return Err(invalid(format!(
                "component {component} has {expected} outputs, not {}",
                outputs.len()
            )));
        }
        if let Some(m) = self.current.filter(|&m| m != n) {
            self.end_tick(m)?;
        }
        self.current = Some(n);
        let (keys, slot) = (&self.keys[component], &mut self.slots[component]);
        slot.clear();
        for (key, value) in keys.iter().zip(outputs) {
            slot.push_str(key);
            // Writing to a String cannot fail.
            let _ = write!(slot, "{value}");
        }
        if !self.given[component] {
            self.given[component] = true;
            self.count += 1;
        }
        if self.count == self.slots.len() {
            self.end_tick(n)?;
        }
        Ok(())
    }

    /// Writes the line of tick `n` with what was given for it (`?` for the rest), unless it
    /// was written already (every component was in). If another tick was being gathered, its
    /// line is written first.
    pub fn end_tick(&mut self, n: u64) -> io::Result<()> {
        if let Some(m) = self.current.filter(|&m| m != n) {
            self.end_tick(m)?;
        }
        if self.current.is_none() && self.written == Some(n) {
            return Ok(());
        }
        if let Some(header) = self.header.take() {
            writeln!(self.out, "{header}")?;
        }
        write!(self.out, "{n}")?;
        for (c, keys) in self.keys.iter().enumerate() {
            if self.given[c] {
                self.out.write_all(self.slots[c].as_bytes())?;
            } else {
                for key in keys {
                    write!(self.out, "{key}?")?;
                }
            }
        }
        self.out.write_all(b"\n")?;
        self.given.iter_mut().for_each(|g| *g = false);
        self.count = 0;
        self.current = None;
        self.written = Some(n);
        Ok(())
    }

    /// Ends a tick still being gathered, writes the header if no line was written, flushes,
    /// and returns the output.
    pub fn finish(mut self) -> io::Result<W> {
        if let Some(n) = self.current {
            self.end_tick(n)?;
        }
        if let Some(header) = self.header.take() {
            writeln!(self.out, "{header}")?;
        }
        if let Some((n, hash, false)) = self.last_hash {
            writeln!(self.out, "# state_hash tick={n} hash={hash:#018x}")?;
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Where two traces first differ: `None` if they are equal, else the 1-based line number and
/// both lines (empty past the end of a trace), for a test's failure message.
pub fn first_difference(expected: &str, actual: &str) -> Option<(usize, String, String)> {
    let (mut a, mut b) = (expected.lines(), actual.lines());
    let mut line = 0;
    loop {
        line += 1;
        match (a.next(), b.next()) {
            (None, None) => return None,
            (x, y) if x == y => continue,
            (x, y) => {
                let text = |l: Option<&str>| l.unwrap_or("").to_owned();
                return Some((line, text(x), text(y)));
            }
        }
    }
}
