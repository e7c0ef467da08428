//! What the supervisor shows, and whether it is due: the live status table, the status rows
//! its `status` method answers and the directory it publishes each remember the count of
//! changes they last showed, so each is redrawn after a change and not before.

use std::time::{Duration, Instant};

/// The change count, and what each view last showed of it.
#[derive(Debug, Default)]
pub(super) struct Shown {
    /// Counts changes of what the supervisor shows (a module's state, pid, methods).
    changes: u64,
    /// The count the live table last showed.
    table: u64,
    /// The count the status rows were last built at.
    rows: u64,
    /// The count the published directory last showed.
    directory: u64,
    /// When the status rows were last built (their counters are refreshed even without a
    /// change).
    rows_built: Option<Instant>,
}

/// How often the status rows' counters are refreshed without a change.
const ROWS_EVERY: Duration = Duration::from_millis(250);

impl Shown {
    /// Nothing shown yet: every view is due.
    pub(super) fn new() -> Shown {
        Shown {
            changes: 1,
            ..Shown::default()
        }
    }

    /// Something shown changed.
    pub(super) fn changed(&mut self) {
        self.changes += 1;
    }

    /// Whether the live table is due (and, if so, it is taken as shown).
    pub(super) fn table_due(&mut self) -> bool {
        let due = self.changes != self.table;
        self.table = self.changes;
        due
    }

    /// Whether the live table has changes it did not show.
    pub(super) fn table_stale(&self) -> bool {
        self.changes != self.table
    }

    /// Whether the directory is due (`roster_changed`: the modules' own entries changed).
    pub(super) fn directory_due(&mut self, roster_changed: bool) -> bool {
        let due = self.changes != self.directory || roster_changed;
        self.directory = self.changes;
        due
    }

    /// Whether the status rows are due: at once after a change, else every [`ROWS_EVERY`]
    /// (building them for hundreds of modules on every wake-up costs).
    pub(super) fn rows_due(&mut self) -> bool {
        let due =
            self.rows_built.is_none_or(|t| t.elapsed() >= ROWS_EVERY) || self.changes != self.rows;
        if due {
            self.rows = self.changes;
            self.rows_built = Some(Instant::now());
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_view_is_due_once_after_a_change() {
        let mut sut = Shown::new();
        assert!(sut.table_due());
        sut.changed();
        assert!(sut.table_stale());
        assert!(sut.table_due());
        assert!(!sut.table_due());
        assert!(sut.directory_due(false));
        assert!(!sut.directory_due(false));
        assert!(sut.directory_due(true));
        assert!(sut.rows_due());
        assert!(!sut.rows_due());
    }
}
