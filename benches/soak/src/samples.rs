//! The soak's samples, one a second: the Rss of every process of the system (the supervisor and
//! every module it runs) and the domain's files in /dev/shm; and the growth over the run's last
//! half, read from them.
//!
//! Growth compares two windows of a tenth of the run each ([`windows`]): the one that ends at
//! the middle and the one that ends the run, each value the mean over its samples (single
//! samples swing with every restart: a module that just started is smaller, a flooded one
//! busier). Processes restarted in the second half are fresh at the end, and their Rss says
//! nothing about a leak, so the figure the target is checked on takes only the processes that
//! lived through the whole second half (the same pid at the start of the middle window and in
//! the last sample: the supervisor, the coordinator, and the modules no fault ended in that
//! half); the sum over every process is reported beside it, and the domain's /dev/shm bytes.

use std::collections::BTreeMap;
use std::time::Duration;

use modbot_core::Domain;
use modbot_supervisor::status;

/// One process at one moment.
#[derive(Debug, Clone, PartialEq)]
pub struct Process {
    pub name: String,
    pub pid: u32,
    /// Resident set, bytes.
    pub rss: u64,
    /// Its frame counters since it started: dropped (it could not send), rejected (malformed
    /// frames it received), replayed (RETRYs answered from its record).
    pub dropped: u64,
    pub rejected: u64,
    pub replayed: u64,
}

/// Everything of one moment.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Since the system was up.
    pub at: Duration,
    pub processes: Vec<Process>,
    /// The domain's files in /dev/shm (iceoryx2's node and service files included).
    pub shm_files: usize,
    /// The bytes they occupy (allocated blocks).
    pub shm_bytes: u64,
}

impl Sample {
    /// Takes a sample: the supervisor (`up_pid`), every process of `rows`, the domain's files.
    pub fn take(at: Duration, up_pid: u32, rows: &[status::Row], domain: &Domain) -> Sample {
        let mut processes: Vec<Process> = rows
            .iter()
            .filter(|r| r.pid != 0)
            .map(|r| Process {
                name: r.name.clone(),
                pid: r.pid,
                rss: 0,
                dropped: r.counters.dropped,
                rejected: r.counters.rejected,
                replayed: r.counters.replayed,
            })
            .collect();
        if !processes.iter().any(|p| p.pid == up_pid) {
            processes.push(Process {
                name: "supervisor".into(),
                pid: up_pid,
                rss: 0,
                dropped: 0,
                rejected: 0,
                replayed: 0,
            });
        }
        // A process that ended since the table was read has no Rss: it is left out.
        processes.retain_mut(|p| match modbot_bench_kit::memory::memory_of(p.pid) {
            Some((_, rss)) => {
                p.rss = rss;
                true
            }
            None => false,
        });
        let files = domain.files();
        Sample {
            at,
            processes,
            shm_files: files.iter().filter(|p| p.starts_with("/dev/shm")).count(),
            shm_bytes: modbot_bench_kit::memory::shm_bytes(domain),
        }
    }

    /// The Rss of every process.
    pub fn rss(&self) -> u64 {
        self.processes.iter().map(|p| p.rss).sum()
    }
}

/// A quantity at the middle and at the end of a run: the means over the two windows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Growth {
    pub mid: u64,
    pub end: u64,
    /// How many processes it sums (0 for files).
    pub processes: usize,
}

impl Growth {
    /// End over middle.
    pub fn ratio(&self) -> f64 {
        self.end as f64 / self.mid.max(1) as f64
    }
}

/// The two windows growth is measured over: the tenth of the run that ends at its middle, and
/// the tenth that ends it.
#[derive(Debug, Clone, Copy)]
pub struct Windows<'a> {
    pub mid: &'a [Sample],
    pub end: &'a [Sample],
}

/// The windows of `samples` (in time order), if each holds a sample.
pub fn windows(samples: &[Sample]) -> Option<Windows<'_>> {
    let last = samples.last()?.at;
    let width = (last / 10).max(Duration::from_secs(1));
    let half = last / 2;
    let within = |from: Duration, to: Duration| {
        let a = samples.partition_point(|s| s.at < from);
        let b = samples.partition_point(|s| s.at < to);
        &samples[a..b]
    };
    let mid = within(half.saturating_sub(width), half);
    let end = within(last.saturating_sub(width), last + Duration::from_nanos(1));
    (!mid.is_empty() && !end.is_empty()).then_some(Windows { mid, end })
}

impl Windows<'_> {
    /// The processes that lived through the time from the middle window to the end (the same
    /// pid in its first and in the last sample), each with its Rss.
    pub fn survivors_each(&self) -> Vec<(String, Growth)> {
        let (Some(first), Some(last)) = (self.mid.first(), self.end.last()) else {
            return Vec::new();
        };
        first
            .processes
            .iter()
            .filter(|p| last.processes.iter().any(|q| q.pid == p.pid))
            .map(|p| {
                let of = |s: &Sample| {
                    s.processes
                        .iter()
                        .find(|q| q.pid == p.pid)
                        .map_or(0, |q| q.rss)
                };
                let g = Growth {
                    mid: mean(self.mid, of),
                    end: mean(self.end, of),
                    processes: 1,
                };
                (p.name.clone(), g)
            })
            .collect()
    }

    /// The Rss of the processes of [`Windows::survivors_each`], summed.
    pub fn survivors(&self) -> Growth {
        self.survivors_each().iter().fold(
            Growth {
                mid: 0,
                end: 0,
                processes: 0,
            },
            |a, (_, g)| Growth {
                mid: a.mid + g.mid,
                end: a.end + g.end,
                processes: a.processes + 1,
            },
        )
    }

    /// The Rss of every process.
    pub fn everyone(&self) -> Growth {
        Growth {
            mid: mean(self.mid, Sample::rss),
            end: mean(self.end, Sample::rss),
            processes: self.end.last().map_or(0, |s| s.processes.len()),
        }
    }

    /// The domain's /dev/shm bytes.
    pub fn shm(&self) -> Growth {
        Growth {
            mid: mean(self.mid, |s| s.shm_bytes),
            end: mean(self.end, |s| s.shm_bytes),
            processes: 0,
        }
    }

    /// The domain's /dev/shm files.
    pub fn files(&self) -> (u64, u64) {
        let files = |s: &Sample| s.shm_files as u64;
        (mean(self.mid, files), mean(self.end, files))
    }
}

/// The mean of `f` over `samples` (0 for none).
fn mean(samples: &[Sample], f: impl Fn(&Sample) -> u64) -> u64 {
    let n = samples.len().max(1) as u64;
    samples.iter().map(f).sum::<u64>() / n
}

/// Frame counters over the run: for each process (pid) the last count seen, summed:
/// (dropped, rejected, replayed). A process killed between two samples loses what it counted
/// after the last one.
pub fn counters(samples: &[Sample]) -> (u64, u64, u64) {
    let mut last: BTreeMap<u32, (u64, u64, u64)> = BTreeMap::new();
    for p in samples.iter().flat_map(|s| s.processes.iter()) {
        let e = last.entry(p.pid).or_default();
        *e = (e.0.max(p.dropped), e.1.max(p.rejected), e.2.max(p.replayed));
    }
    last.values()
        .fold((0, 0, 0), |a, c| (a.0 + c.0, a.1 + c.1, a.2 + c.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn process(pid: u32, rss: u64) -> Process {
        Process {
            name: format!("p{pid}"),
            pid,
            rss,
            dropped: 0,
            rejected: pid.into(),
            replayed: 0,
        }
    }

    fn sample(secs: u64, processes: Vec<Process>) -> Sample {
        Sample {
            at: Duration::from_secs(secs),
            processes,
            shm_files: 3,
            shm_bytes: 1000 + secs,
        }
    }

    #[test]
    fn a_process_restarted_in_the_second_half_is_left_out_of_the_survivors_growth() {
        // 0..=20 s; the windows are 8..10 s and 18..20 s. Process 3 was killed at 15 s and
        // came back as 4, smaller.
        let samples: Vec<Sample> = (0..=20)
            .map(|t| {
                let grown = if t >= 18 { 4 } else { 0 };
                let third = if t < 15 {
                    process(3, 50)
                } else {
                    process(4, 10)
                };
                sample(t, vec![process(1, 100 + grown), process(2, 200), third])
            })
            .collect();
        let w = windows(&samples).unwrap();
        assert_eq!(w.mid.first().map(|s| s.at.as_secs()), Some(8));
        assert_eq!(w.end.first().map(|s| s.at.as_secs()), Some(18));
        let sut = w.survivors();
        assert_eq!((sut.mid, sut.end, sut.processes), (300, 304, 2));
        let each = w.survivors_each();
        assert_eq!(each[0].0, "p1");
        assert_eq!((each[0].1.mid, each[0].1.end), (100, 104));
        assert!((sut.ratio() - 304.0 / 300.0).abs() < 1e-12);
        assert_eq!((w.everyone().mid, w.everyone().end), (350, 314));
        assert_eq!((w.shm().mid, w.shm().end), (1008, 1019));
        assert_eq!(w.files(), (3, 3));
    }

    #[test]
    fn growth_is_the_mean_over_each_window_not_one_sample() {
        let samples: Vec<Sample> = (0..100)
            .map(|t| sample(t, vec![process(1, if t % 2 == 0 { 90 } else { 110 })]))
            .collect();
        let sut = windows(&samples).unwrap().survivors();
        assert_eq!((sut.mid, sut.end), (100, 100));
    }

    #[test]
    fn a_run_too_short_for_a_middle_window_has_no_windows() {
        assert!(windows(&[sample(0, vec![])]).is_none());
        assert!(windows(&[]).is_none());
    }

    #[test]
    fn counters_take_each_process_once_at_its_last_count() {
        let a = sample(1, vec![process(1, 1), process(2, 1)]);
        let b = sample(2, vec![process(2, 1), process(5, 1)]);
        assert_eq!(counters(&[a, b]).1, 1 + 2 + 5);
    }
}
