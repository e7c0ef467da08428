//! Traffic statistics and call latency: what the `stats` system method answers.
//!
//! Every module counts the frames it sends and receives and the calls it makes, and records the
//! latency of each of its calls (from just after the request's first send to the answer, by the
//! injected clock) in a
//! [`Histogram`]. Recording is a few integer operations on a fixed array: the hot path never
//! allocates.
//!
//! # Histogram resolution
//!
//! The buckets are those of the wire format, [`modbot_ipc_schema::latency`]: log-linear, as in
//! HdrHistogram, each power of two from 128 ns (2^7) to 2^38 ns (about 275 s) split into
//! [`SUB_BUCKETS`] = 8 equal buckets, so a bucket is at most 12.5 % of its lower bound wide.
//! Values below 128 ns share bucket 0; values of 2^38 ns and more share the last bucket.
//! [`Histogram::percentile`] answers the upper end of the bucket that holds the percentile,
//! capped at the largest value recorded: never below the true value, and at most one bucket
//! width (12.5 %, or 128 ns under 1 µs) above it.
//!
//! # Wire layout
//!
//! [`Histogram::to_bytes`] and [`Histogram::from_bytes`] write and read the layout of
//! [`modbot_ipc_schema::latency`] (magic `MBLH`, the buckets that counted something), written
//! down with a golden vector in `ipc_schema/README.md`.

use core::fmt;

use modbot_ipc_schema::latency::{self, HistogramError, View};
use modbot_ipc_schema::{ArgError, Args, Value};
use thiserror::Error;

pub use modbot_ipc_schema::latency::{
    BUCKETS, FIRST_EXP, OVERFLOW_EXP, SUB_BUCKETS, SUB_BUCKET_BITS,
};

/// Why bytes or an answer are not valid statistics.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum StatsError {
    #[error("{0}")]
    Histogram(#[from] HistogramError),
    #[error("stats answer: {0}")]
    Answer(#[from] ArgError),
    #[error("stats answer: {field} is negative ({value})")]
    Negative { field: &'static str, value: i64 },
}

/// A latency histogram over fixed log-linear buckets (see the [module docs](self)).
#[derive(Clone, PartialEq, Eq)]
pub struct Histogram {
    /// Values recorded per bucket.
    counts: [u64; BUCKETS],
    /// Sum of `counts`, so [`Histogram::count`] needs no scan.
    total: u64,
    /// The largest value recorded: caps percentiles, and tells what the overflow bucket holds.
    max: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram::new()
    }
}

impl Histogram {
    /// An empty histogram.
    pub const fn new() -> Histogram {
        Histogram {
            counts: [0; BUCKETS],
            total: 0,
            max: 0,
        }
    }

    /// The bucket that holds `ns`.
    #[inline]
    pub fn bucket_of(ns: u64) -> usize {
        latency::bucket_of(ns)
    }

    /// The values bucket `index` holds: `lower..upper` in ns (`upper` is `u64::MAX` for the
    /// overflow bucket).
    pub fn bucket_range(index: usize) -> core::ops::Range<u64> {
        latency::bucket_range(index)
    }

    /// Records one value, in ns. Never allocates.
    pub fn record(&mut self, ns: u64) {
        let i = Self::bucket_of(ns);
        self.counts[i] = self.counts[i].saturating_add(1);
        self.total = self.total.saturating_add(1);
        self.max = self.max.max(ns);
    }

    /// Values recorded.
    pub fn count(&self) -> u64 {
        self.total
    }

    pub fn is_empty(&self) -> bool {
        self.total == 0
    }

    /// The largest value recorded (0 when empty).
    pub fn max(&self) -> u64 {
        self.max
    }

    /// Adds the values of `other`.
    pub fn merge(&mut self, other: &Histogram) {
        for (mine, theirs) in self.counts.iter_mut().zip(&other.counts) {
            *mine = mine.saturating_add(*theirs);
        }
        self.total = self.total.saturating_add(other.total);
        self.max = self.max.max(other.max);
    }

    /// The `p`-th percentile (`p` in percent, clamped to 0..=100; NaN counts as 0), in ns: the
    /// upper end of the bucket that holds it, capped at the largest value recorded. 0 when
    /// nothing was recorded.
    pub fn percentile(&self, p: f64) -> u64 {
        if self.total == 0 {
            return 0;
        }
        let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 100.0) };
        // The rank of the percentile among the values, 1-based: at least the first value.
        let rank = ((p / 100.0) * self.total as f64).ceil().max(1.0);
        let rank = if rank >= self.total as f64 {
            self.total
        } else {
            rank as u64
        };
        let mut seen = 0u64;
        for (i, &n) in self.counts.iter().enumerate() {
            seen = seen.saturating_add(n);
            if seen >= rank {
                return Self::bucket_range(i).end.min(self.max);
            }
        }
        self.max
    }

    /// The buckets that counted something: `(bucket index, count)` in index order.
    pub fn buckets(&self) -> impl Iterator<Item = (usize, u64)> + '_ {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(i, n)| (i, *n))
    }

    /// The histogram in its wire layout ([`modbot_ipc_schema::latency`]).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        latency::encode(&self.counts, self.max, &mut out);
        out
    }

    /// Reads a histogram written by [`Histogram::to_bytes`], checking every field.
    pub fn from_bytes(bytes: &[u8]) -> Result<Histogram, StatsError> {
        let view = View::parse(bytes)?;
        Ok(Histogram {
            counts: view.counts(),
            total: view.total(),
            max: view.max(),
        })
    }
}

impl fmt::Debug for Histogram {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Histogram")
            .field("count", &self.total)
            .field("max", &self.max)
            .field("buckets", &self.buckets().collect::<Vec<_>>())
            .finish()
    }
}

/// A module's traffic and call counters, as the `stats` system method answers them.
///
/// Frames are RVMF* frames on the message transport (heartbeats and snapshots have services of
/// their own and are not counted). Calls are the application's calls ([`crate::Ctx::call`] and
/// the blocking calls), not the `describe` lookups the runtime makes on its own.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Stats {
    /// Frames handed to the transport (requests, retransmissions, answers, reports).
    pub frames_sent: u64,
    /// Frames received, malformed ones included (those are also counted as rejected).
    pub frames_received: u64,
    /// Calls started (each got a handle).
    pub calls: u64,
    /// Calls answered with a REPLY or an ACK.
    pub answered: u64,
    /// Calls that ended otherwise: NAK, malformed answer, timeout, peer died or unreachable.
    pub failed: u64,
    /// First send to answer (REPLY, ACK or NAK), per answered call, in ns.
    pub latency: Histogram,
}

impl Stats {
    /// Reads a `stats` answer: `[frames_sent, frames_received, calls, answered, failed: i64,
    /// latency: bytes]`.
    pub fn from_answer(args: &Args<'_>) -> Result<Stats, StatsError> {
        let count = |index: usize, field: &'static str| -> Result<u64, StatsError> {
            let value = args.i64(index)?;
            u64::try_from(value).map_err(|_| StatsError::Negative { field, value })
        };
        Ok(Stats {
            frames_sent: count(0, "frames_sent")?,
            frames_received: count(1, "frames_received")?,
            calls: count(2, "calls")?,
            answered: count(3, "answered")?,
            failed: count(4, "failed")?,
            latency: Histogram::from_bytes(args.bytes(5)?)?,
        })
    }

    /// Writes the `stats` answer (see [`Stats::from_answer`]), value by value, into `push`.
    pub(crate) fn write_answer(&self, push: &mut dyn FnMut(Value<'_>)) {
        for n in [
            self.frames_sent,
            self.frames_received,
            self.calls,
            self.answered,
            self.failed,
        ] {
            push(Value::I64(i64::try_from(n).unwrap_or(i64::MAX)));
        }
        push(Value::Bytes(&self.latency.to_bytes()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_known_values_are_the_upper_ends_of_their_buckets() {
        let mut sut = Histogram::new();
        // 1..=100 µs, one value each.
        for us in 1..=100u64 {
            sut.record(us * 1000);
        }
        assert_eq!(sut.count(), 100);
        assert_eq!(sut.max(), 100_000);
        // 50 µs = 50_000 ns lies in 2^15 + 4 * 4096 .. + 4096 = 49_152..53_248.
        assert_eq!(sut.percentile(50.0), 53_248);
        // 90 µs lies in 2^16 + 2 * 8192 .. + 8192 = 81_920..90_112.
        assert_eq!(sut.percentile(90.0), 90_112);
        // 99 µs: 98_304..106_496, capped at the largest value, 100 µs.
        assert_eq!(sut.percentile(99.0), 100_000);
        assert_eq!(sut.percentile(100.0), 100_000);
        // 1 µs: 960..1024.
        assert_eq!(sut.percentile(0.0), 1024);
        assert_eq!(sut.percentile(f64::NAN), 1024);
        assert_eq!(sut.percentile(-5.0), 1024);
        assert_eq!(sut.percentile(500.0), 100_000);
        for p in [1.0, 10.0, 25.0, 50.0, 75.0, 90.0, 99.0] {
            let exact = (p as u64) * 1000;
            let got = sut.percentile(p);
            assert!(
                got >= exact && got <= exact + exact / 8,
                "p{p}: {got} vs {exact}"
            );
        }
    }

    #[test]
    fn an_empty_histogram_answers_zero_and_tiny_or_huge_values_are_kept() {
        let mut sut = Histogram::new();
        assert_eq!((sut.count(), sut.percentile(50.0), sut.max()), (0, 0, 0));
        sut.record(0);
        sut.record(5);
        assert_eq!(
            sut.percentile(100.0),
            5,
            "bucket 0, capped at the largest value"
        );
        sut.record(u64::MAX);
        assert_eq!(sut.percentile(100.0), u64::MAX);
        assert_eq!(sut.count(), 3);
    }

    #[test]
    fn merging_adds_counts_and_keeps_the_larger_maximum() {
        let (mut a, mut b, mut both) = (Histogram::new(), Histogram::new(), Histogram::new());
        for v in [200, 3_000, 3_100, 70_000] {
            a.record(v);
            both.record(v);
        }
        for v in [150, 9_000_000] {
            b.record(v);
            both.record(v);
        }
        a.merge(&b);
        assert_eq!(a, both);
        assert_eq!(a.count(), 6);
        assert_eq!(a.max(), 9_000_000);
        a.merge(&Histogram::new());
        assert_eq!(a, both, "merging an empty histogram changes nothing");
    }

    fn golden() -> Histogram {
        let mut h = Histogram::new();
        for v in [100, 1_000, 1_000, 300_000_000_000] {
            h.record(v);
        }
        h
    }

    #[test]
    fn a_recorded_histogram_survives_its_bytes_and_bad_bytes_say_why() {
        let sut = golden();
        let bytes = sut.to_bytes();
        // The README's golden vector of the latency histogram holds these four values.
        assert_eq!(bytes.len(), latency::HEADER_LEN + 3 * latency::ENTRY_LEN);
        assert_eq!(Histogram::from_bytes(&bytes), Ok(sut));
        let empty = Histogram::new();
        assert_eq!(empty.to_bytes().len(), latency::HEADER_LEN);
        assert_eq!(Histogram::from_bytes(&empty.to_bytes()), Ok(empty));
        assert!(matches!(
            Histogram::from_bytes(&bytes[..bytes.len() - 1]),
            Err(StatsError::Histogram(HistogramError::Length { .. }))
        ));
    }

    #[test]
    fn a_stats_answer_reads_back_and_refuses_negative_counts() {
        let sut = Stats {
            frames_sent: 7,
            frames_received: 9,
            calls: 3,
            answered: 2,
            failed: 1,
            latency: golden(),
        };
        let mut reply = crate::hooks::Reply::default();
        sut.write_answer(&mut |v| reply.push(v));
        let values = modbot_ipc_schema::value::Values::new(&reply.buf, 0);
        let args = Args::decode(values).unwrap();
        assert_eq!(Stats::from_answer(&args), Ok(sut));

        let bytes = Histogram::new().to_bytes();
        let bad = [
            Value::I64(1),
            Value::I64(-1),
            Value::I64(0),
            Value::I64(0),
            Value::I64(0),
            Value::Bytes(&bytes),
        ];
        assert_eq!(
            Stats::from_answer(&Args::from_values(&bad).unwrap()),
            Err(StatsError::Negative {
                field: "frames_received",
                value: -1
            })
        );
        let no_histogram = [Value::I64(0); 5];
        assert!(matches!(
            Stats::from_answer(&Args::from_values(&no_histogram).unwrap()),
            Err(StatsError::Answer(ArgError::Missing { index: 5, .. }))
        ));
    }
}

#[cfg(test)]
mod props {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        /// What is recorded survives the wire, and percentiles never decrease with `p` nor fall
        /// below the exact value.
        #[test]
        fn recorded_values_round_trip_and_percentiles_bound_the_exact_ones(
            values in proptest::collection::vec(any::<u64>().prop_map(|v| v >> (v % 64)), 1..200),
            p in 0.0f64..=100.0,
        ) {
            let mut sut = Histogram::new();
            for v in &values {
                sut.record(*v);
            }
            prop_assert_eq!(Histogram::from_bytes(&sut.to_bytes()), Ok(sut.clone()));
            let mut sorted = values.clone();
            sorted.sort_unstable();
            let rank = ((p / 100.0) * sorted.len() as f64).ceil().max(1.0) as usize;
            let exact = sorted[rank.min(sorted.len()) - 1];
            let got = sut.percentile(p);
            prop_assert!(got >= exact, "p{} = {} below the exact {}", p, got, exact);
            prop_assert!(got <= sut.percentile((p + 1.0).min(100.0)));
        }
    }
}
