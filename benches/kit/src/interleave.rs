//! A subject and its baseline measured interleaved, in alternating blocks, so that their ratio
//! does not move with the machine.
//!
//! Two rows measured one after the other on a shared machine compare two different machines:
//! the same raw iceoryx2 round trip measured minutes apart here gave 1.09 µs and 2.66 µs. So
//! both sides stay up (processes started, connections warm) and take turns: block 1 subject
//! then baseline, block 2 baseline then subject, and so on. A side whose server busy-polls would
//! take the CPU from the other side's turn, so each side's server process is stopped (SIGSTOP)
//! while the other side measures and continued (SIGCONT) for its own turn, with a short
//! warm-up thrown away. Each block gives a ratio of the two sides' medians; the report gives the
//! median ratio over the blocks and its spread.

use std::time::Instant;

use hdrhistogram::Histogram;
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;
use serde::Serialize;

use crate::sample::{self, Plan};

/// How many blocks each side measures.
pub const BLOCKS: usize = 10;

/// One side: takes one sample (ns); `server` is its server process, stopped while the other
/// side measures.
pub struct Side<'a> {
    pub one: &'a mut dyn FnMut() -> anyhow::Result<u64>,
    pub server: Option<u32>,
}

impl<'a> Side<'a> {
    /// A side without a server process (both of its ends live in this process).
    pub fn alone(one: &'a mut dyn FnMut() -> anyhow::Result<u64>) -> Side<'a> {
        Side { one, server: None }
    }
}

/// The ratios of the blocks: each block's subject median over its baseline median.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Blocks {
    pub count: usize,
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Blocks {
    /// The summary of `ratios` (at least one).
    pub fn of(ratios: &[f64]) -> Option<Blocks> {
        let mut sorted: Vec<f64> = ratios.iter().copied().filter(|r| r.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = match n {
            0 => return None,
            _ if n % 2 == 1 => sorted[n / 2],
            _ => (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0,
        };
        Some(Blocks {
            count: n,
            median,
            min: sorted[0],
            max: sorted[n - 1],
        })
    }
}

/// What an interleaved measurement gives: every sample of each side, and the block ratios.
pub struct Pair {
    pub subject: Histogram<u64>,
    pub baseline: Histogram<u64>,
    pub blocks: Option<Blocks>,
}

/// Measures `subject` and `baseline` in [`BLOCKS`] alternating blocks of `plan.n / BLOCKS`
/// samples each (after a warm-up of `plan.warm / BLOCKS`, at least 20, per turn). Stops early,
/// after a whole block of both, when `plan.cap` has passed.
pub fn interleave<'a>(plan: &Plan, subject: Side<'a>, baseline: Side<'a>) -> anyhow::Result<Pair> {
    let per_block = (plan.n / BLOCKS as u64).max(1);
    let warm = (plan.warm / BLOCKS as u64).max(20);
    let mut sides = [subject, baseline];
    let mut totals = [sample::histogram(), sample::histogram()];
    let mut ratios = Vec::with_capacity(BLOCKS);
    let start = Instant::now();
    let result = (|| {
        for block in 0..BLOCKS {
            let order = if block % 2 == 0 { [0, 1] } else { [1, 0] };
            let mut medians = [0u64; 2];
            for side in order {
                let other = 1 - side;
                signal(sides[other].server, Signal::SIGSTOP)?;
                signal(sides[side].server, Signal::SIGCONT)?;
                let turn = Plan {
                    warm,
                    n: per_block,
                    cap: plan.cap,
                };
                let h = sample::record(&turn, &mut *sides[side].one)?;
                totals[side].add(&h).map_err(|e| anyhow::anyhow!("{e:?}"))?;
                medians[side] = h.value_at_quantile(0.5);
            }
            if medians[1] > 0 {
                ratios.push(medians[0] as f64 / medians[1] as f64);
            }
            if start.elapsed() > plan.cap {
                break;
            }
        }
        Ok::<(), anyhow::Error>(())
    })();
    // Whatever happened, both servers run again (to be stopped cleanly).
    for side in &sides {
        let _ = signal(side.server, Signal::SIGCONT);
    }
    result?;
    let [subject, baseline] = totals;
    Ok(Pair {
        subject,
        baseline,
        blocks: Blocks::of(&ratios),
    })
}

fn signal(pid: Option<u32>, signal: Signal) -> anyhow::Result<()> {
    if let Some(pid) = pid {
        kill(Pid::from_raw(pid as i32), signal)
            .map_err(|e| anyhow::anyhow!("{signal} to the server process {pid}: {e}"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_summary_is_the_median_and_the_range_of_the_ratios() {
        let b = Blocks::of(&[1.4, 1.2, 1.3, 9.0]).unwrap();
        assert_eq!((b.count, b.median, b.min, b.max), (4, 1.35, 1.2, 9.0));
        let b = Blocks::of(&[2.0, f64::NAN, 1.0, 3.0]).unwrap();
        assert_eq!((b.count, b.median), (3, 2.0));
        assert_eq!(Blocks::of(&[]), None);
    }

    #[test]
    fn two_sides_take_turns_in_alternating_blocks_and_their_ratio_is_per_block() {
        let plan = Plan {
            warm: 0,
            n: 100,
            cap: std::time::Duration::from_secs(60),
        };
        let log = std::cell::RefCell::new(Vec::new());
        let mut a = || {
            log.borrow_mut().push('a');
            Ok(300)
        };
        let mut b = || {
            log.borrow_mut().push('b');
            Ok(100)
        };
        let pair = interleave(&plan, Side::alone(&mut a), Side::alone(&mut b)).unwrap();
        let blocks = pair.blocks.unwrap();
        assert_eq!((blocks.count, blocks.median), (BLOCKS, 3.0));
        assert_eq!((pair.subject.len(), pair.baseline.len()), (100, 100));
        // Warm-up (20) and block (10) per turn; the second block starts with the baseline.
        let log: String = log.into_inner().into_iter().collect();
        assert!(log.starts_with(&("a".repeat(30) + &"b".repeat(60) + &"a".repeat(30))));
    }
}
