//! Exactly-once accounting: the calls the soak's driver saw acknowledged against the executions
//! the journal module wrote down.
//!
//! Every call carries its own sequence number (1, 2, 3, ... in the order they were issued);
//! the callee appends each one it executes to the journal, one line per execution, from every
//! process it had (see `modbot_modules::faulty::record`). So:
//! - *lost*: acknowledged (the driver got the reply) but not in the journal;
//! - *duplicated*: in the journal more than once, acknowledged or not (a retransmission
//!   executed a second time is a duplicate even if the caller gave up on it);
//! - *executed, not acknowledged*: in the journal, but the caller saw no reply (it timed out,
//!   or the callee died between the execution and the reply) — allowed: the call failed as
//!   far as the caller knows, and it was executed at most once;
//! - *unknown*: a number the driver never issued (0 expected: a corrupt line or a mix-up).

/// The journal's lines as sequence numbers, and how many lines were not one (a torn write
/// would show here; a write(2) of one short line cannot tear).
pub fn parse(text: &str) -> (Vec<u64>, u64) {
    let mut seqs = Vec::new();
    let mut unreadable = 0;
    for line in text.lines() {
        match line.trim().parse::<u64>() {
            Ok(seq) => seqs.push(seq),
            Err(_) => unreadable += 1,
        }
    }
    (seqs, unreadable)
}

/// What the calls came to.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Tally {
    /// Calls issued (sequence numbers 1 to this).
    pub issued: u64,
    /// Calls whose reply arrived.
    pub acknowledged: u64,
    /// Executions: lines of the journal with a number issued.
    pub executed: u64,
    /// Acknowledged but not executed, ascending.
    pub lost: Vec<u64>,
    /// Executed more than once: (sequence number, executions), ascending.
    pub duplicated: Vec<(u64, u32)>,
    /// Executed (once or more) without a reply to the caller.
    pub executed_unacknowledged: u64,
    /// Numbers in the journal that were never issued.
    pub unknown: Vec<u64>,
}

impl Tally {
    /// Executions beyond the first of every duplicated call.
    pub fn extra_executions(&self) -> u64 {
        self.duplicated.iter().map(|&(_, n)| u64::from(n - 1)).sum()
    }
}

/// Tallies `issued` calls, the sequence numbers `acknowledged` and the journal's `executed`
/// numbers (in any order).
pub fn tally(issued: u64, acknowledged: &[u64], executed: &[u64]) -> Tally {
    let slots = usize::try_from(issued).unwrap_or(usize::MAX - 1) + 1;
    let mut runs = vec![0u32; slots];
    let mut acked = vec![false; slots];
    let mut sut = Tally {
        issued,
        ..Tally::default()
    };
    for &seq in executed {
        match usize::try_from(seq).ok().filter(|&i| i > 0 && i < slots) {
            Some(i) => {
                runs[i] = runs[i].saturating_add(1);
                sut.executed += 1;
            }
            None => sut.unknown.push(seq),
        }
    }
    for &seq in acknowledged {
        if let Some(i) = usize::try_from(seq).ok().filter(|&i| i > 0 && i < slots) {
            acked[i] = true;
        }
    }
    for i in 1..slots {
        let seq = i as u64;
        sut.acknowledged += u64::from(acked[i]);
        if acked[i] && runs[i] == 0 {
            sut.lost.push(seq);
        }
        if runs[i] > 1 {
            sut.duplicated.push((seq, runs[i]));
        }
        if !acked[i] && runs[i] > 0 {
            sut.executed_unacknowledged += 1;
        }
    }
    sut.unknown.sort_unstable();
    sut
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_acknowledged_call_missing_from_the_journal_is_lost() {
        let sut = tally(4, &[1, 2, 3], &[1, 3]);
        assert_eq!(sut.lost, [2]);
        assert_eq!(sut.acknowledged, 3);
        assert!(sut.duplicated.is_empty());
    }

    #[test]
    fn a_call_executed_twice_is_a_duplicate_whether_it_was_acknowledged_or_not() {
        let sut = tally(5, &[1, 2], &[1, 2, 2, 4, 4, 4, 5]);
        assert_eq!(sut.duplicated, [(2, 2), (4, 3)]);
        assert_eq!(sut.extra_executions(), 3);
        assert!(sut.lost.is_empty());
        assert_eq!(sut.executed, 7);
    }

    #[test]
    fn an_execution_without_a_reply_is_counted_but_neither_lost_nor_duplicated() {
        let sut = tally(3, &[1], &[1, 3]);
        assert_eq!(sut.executed_unacknowledged, 1);
        assert!(sut.lost.is_empty() && sut.duplicated.is_empty());
    }

    #[test]
    fn numbers_never_issued_are_unknown() {
        let sut = tally(2, &[1, 2], &[0, 1, 2, 9]);
        assert_eq!(sut.unknown, [0, 9]);
        assert_eq!(sut.executed, 2);
    }

    #[test]
    fn journal_lines_that_are_not_numbers_are_counted_apart() {
        assert_eq!(parse("1\n2\n3x\n\n4\n"), (vec![1, 2, 4], 2));
    }
}
