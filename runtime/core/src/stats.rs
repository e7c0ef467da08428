//! Traffic statistics and call latency: what the `stats` system method answers.
//!
//! Every module counts the frames it sends and receives and the calls it makes, and records the
//! latency of each of its calls (first send to answer, by the injected clock) in a
//! [`Histogram`]. Recording is a few integer operations on a fixed array: the hot path never
//! allocates.
//!
//! # Histogram resolution
//!
//! The buckets are log-linear, as in HdrHistogram: each power of two from 128 ns (2^7) to
//! 2^38 ns (about 275 s) is split into [`SUB_BUCKETS`] = 8 equal buckets, so a bucket is at
//! most 12.5 % of its lower bound wide. Values below 128 ns share bucket 0; values of 2^38 ns
//! and more share the last bucket. [`Histogram::percentile`] answers the upper end of the
//! bucket that holds the percentile, capped at the largest value recorded: never below the
//! true value, and at most one bucket width (12.5 %, or 128 ns under 1 µs) above it.
//!
//! # Wire layout ([`Histogram::to_bytes`])
//!
//! ```text
//! offset size  field
//! 0      4     magic "MBLH"
//! 4      1     format version = 1
//! 5      1     sub-bucket bits = 3 (8 buckets per power of two)
//! 6      1     first exponent = 7 (bucket 0 holds 0..128 ns)
//! 7      1     overflow exponent = 38 (the last bucket holds 2^38 ns and more)
//! 8      8     largest value recorded, ns (u64 LE; 0 when nothing was recorded)
//! 16     2     n, the number of buckets that follow (u16 LE)
//! 18     10*n  bucket index (u16 LE), count (u64 LE, > 0); indexes strictly increasing
//! ```
//!
//! Only buckets that counted something are sent: a typical latency histogram is a few hundred
//! bytes. [`Histogram::from_bytes`] checks everything (it reads untrusted bytes from another
//! process) and never panics.

use core::fmt;

use modbot_ipc_schema::{ArgError, Args, Value};
use thiserror::Error;

use crate::module::Reply;

/// Buckets per power of two, as a number of bits.
pub const SUB_BUCKET_BITS: u32 = 3;
/// Buckets per power of two.
pub const SUB_BUCKETS: usize = 1 << SUB_BUCKET_BITS;
/// Values below `2^FIRST_EXP` ns share bucket 0.
pub const FIRST_EXP: u32 = 7;
/// Values of `2^OVERFLOW_EXP` ns and more share the last bucket.
pub const OVERFLOW_EXP: u32 = 38;
/// Number of buckets: one below, [`SUB_BUCKETS`] per power of two, one overflow.
pub const BUCKETS: usize = 1 + (OVERFLOW_EXP - FIRST_EXP) as usize * SUB_BUCKETS + 1;

/// The magic at the start of a serialized histogram.
pub const MAGIC: [u8; 4] = *b"MBLH";
/// The format version of [`Histogram::to_bytes`].
pub const VERSION: u8 = 1;
/// Bytes before the bucket entries.
pub const HEADER_LEN: usize = 18;
/// Bytes per bucket entry.
pub const ENTRY_LEN: usize = 10;

/// Why bytes or an answer are not valid statistics.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum StatsError {
    #[error("histogram truncated: {got} bytes, expected {expected}")]
    Length { expected: usize, got: usize },
    #[error("not a latency histogram (magic {0:02x?}, expected \"MBLH\")")]
    Magic([u8; 4]),
    #[error(
        "unsupported histogram layout: version {version}, {sub_bits} sub-bucket bits, \
         exponents {first_exp}..{overflow_exp} (this build reads version {VERSION}, \
         {SUB_BUCKET_BITS} bits, exponents {FIRST_EXP}..{OVERFLOW_EXP})"
    )]
    Layout {
        version: u8,
        sub_bits: u8,
        first_exp: u8,
        overflow_exp: u8,
    },
    #[error("histogram bucket {index} is out of range or out of order (after {after:?}; {BUCKETS} buckets)")]
    Bucket { index: u16, after: Option<u16> },
    #[error("histogram bucket {0} is listed with a count of 0")]
    EmptyBucket(u16),
    #[error("histogram counts overflow u64")]
    Overflow,
    #[error("largest value {max} ns does not lie in the histogram's highest bucket ({bucket})")]
    Max { max: u64, bucket: usize },
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
    pub fn bucket_of(ns: u64) -> usize {
        if ns < 1 << FIRST_EXP {
            return 0;
        }
        let exp = 63 - ns.leading_zeros();
        if exp >= OVERFLOW_EXP {
            return BUCKETS - 1;
        }
        let sub = (ns >> (exp - SUB_BUCKET_BITS)) as usize & (SUB_BUCKETS - 1);
        1 + (exp - FIRST_EXP) as usize * SUB_BUCKETS + sub
    }

    /// The values bucket `index` holds: `lower..upper` in ns (`upper` is `u64::MAX` for the
    /// overflow bucket).
    pub fn bucket_range(index: usize) -> core::ops::Range<u64> {
        match index {
            0 => 0..1 << FIRST_EXP,
            i if i >= BUCKETS - 1 => 1 << OVERFLOW_EXP..u64::MAX,
            i => {
                let exp = FIRST_EXP + ((i - 1) / SUB_BUCKETS) as u32;
                let width = 1u64 << (exp - SUB_BUCKET_BITS);
                let lower = (1u64 << exp) + ((i - 1) % SUB_BUCKETS) as u64 * width;
                lower..lower + width
            }
        }
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

    /// The histogram in its wire layout (see the [module docs](self)).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.buckets().count();
        let mut out = Vec::with_capacity(HEADER_LEN + ENTRY_LEN * n);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&[
            VERSION,
            SUB_BUCKET_BITS as u8,
            FIRST_EXP as u8,
            OVERFLOW_EXP as u8,
        ]);
        out.extend_from_slice(&self.max.to_le_bytes());
        // BUCKETS < u16::MAX, so n fits.
        out.extend_from_slice(&(n as u16).to_le_bytes());
        for (i, count) in self.buckets() {
            out.extend_from_slice(&(i as u16).to_le_bytes());
            out.extend_from_slice(&count.to_le_bytes());
        }
        out
    }

    /// Reads a histogram written by [`Histogram::to_bytes`], checking every field.
    pub fn from_bytes(bytes: &[u8]) -> Result<Histogram, StatsError> {
        let header = bytes.get(..HEADER_LEN).ok_or(StatsError::Length {
            expected: HEADER_LEN,
            got: bytes.len(),
        })?;
        let magic = [header[0], header[1], header[2], header[3]];
        if magic != MAGIC {
            return Err(StatsError::Magic(magic));
        }
        let layout = [header[4], header[5], header[6], header[7]];
        let expected = [
            VERSION,
            SUB_BUCKET_BITS as u8,
            FIRST_EXP as u8,
            OVERFLOW_EXP as u8,
        ];
        if layout != expected {
            return Err(StatsError::Layout {
                version: layout[0],
                sub_bits: layout[1],
                first_exp: layout[2],
                overflow_exp: layout[3],
            });
        }
        let max = u64_at(bytes, 8);
        let n = usize::from(u16::from_le_bytes([header[16], header[17]]));
        let expected = HEADER_LEN + ENTRY_LEN * n;
        if bytes.len() != expected {
            return Err(StatsError::Length {
                expected,
                got: bytes.len(),
            });
        }
        let mut h = Histogram::new();
        let mut after: Option<u16> = None;
        for entry in bytes[HEADER_LEN..].chunks_exact(ENTRY_LEN) {
            let index = u16::from_le_bytes([entry[0], entry[1]]);
            let count = u64_at(entry, 2);
            if usize::from(index) >= BUCKETS || after.is_some_and(|a| index <= a) {
                return Err(StatsError::Bucket { index, after });
            }
            if count == 0 {
                return Err(StatsError::EmptyBucket(index));
            }
            after = Some(index);
            h.counts[usize::from(index)] = count;
            h.total = h.total.checked_add(count).ok_or(StatsError::Overflow)?;
        }
        // The largest value lies in the highest bucket that counted something (0 when none).
        let highest = after.map_or(0, usize::from);
        let range = Self::bucket_range(highest);
        let fits = match after {
            None => max == 0,
            Some(_) => range.contains(&max) || (highest == BUCKETS - 1 && max == u64::MAX),
        };
        if !fits {
            return Err(StatsError::Max {
                max,
                bucket: highest,
            });
        }
        h.max = max;
        Ok(h)
    }
}

/// The u64 (LE) at `at`; the caller checked the length.
fn u64_at(bytes: &[u8], at: usize) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[at..at + 8]);
    u64::from_le_bytes(b)
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

    /// Writes the `stats` answer (see [`Stats::from_answer`]).
    pub(crate) fn write_answer(&self, reply: &mut Reply) {
        for n in [
            self.frames_sent,
            self.frames_received,
            self.calls,
            self.answered,
            self.failed,
        ] {
            reply.push(Value::I64(i64::try_from(n).unwrap_or(i64::MAX)));
        }
        reply.push(Value::Bytes(&self.latency.to_bytes()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_are_contiguous_and_each_value_lands_in_the_bucket_whose_range_holds_it() {
        let mut end = 0;
        for i in 0..BUCKETS {
            let r = Histogram::bucket_range(i);
            assert_eq!(
                r.start,
                end,
                "bucket {i} starts where {} ends",
                i.wrapping_sub(1)
            );
            assert!(r.end > r.start);
            assert_eq!(Histogram::bucket_of(r.start), i);
            assert_eq!(Histogram::bucket_of(r.end - 1), i);
            if i > 0 && i < BUCKETS - 1 {
                // 12.5 % resolution: a bucket is at most an eighth of its lower bound wide.
                assert!((r.end - r.start) * 8 <= r.start, "bucket {i}: {r:?}");
            }
            end = r.end;
        }
        assert_eq!(end, u64::MAX);
        assert_eq!(Histogram::bucket_of(u64::MAX), BUCKETS - 1);
        assert_eq!(BUCKETS, 250);
    }

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

    /// The wire layout documented above, byte for byte.
    const GOLDEN: &[u8] = &[
        b'M', b'B', b'L', b'H', // magic
        1, 3, 7, 38, // version, sub-bucket bits, first and overflow exponent
        0x00, 0xb8, 0x64, 0xd9, 0x45, 0, 0, 0, // max = 300_000_000_000 ns
        3, 0, // 3 buckets
        0, 0, 1, 0, 0, 0, 0, 0, 0, 0, // bucket 0 (100 ns): 1
        24, 0, 2, 0, 0, 0, 0, 0, 0, 0, // bucket 24 (960..1024 ns): 2
        249, 0, 1, 0, 0, 0, 0, 0, 0, 0, // bucket 249 (overflow): 1
    ];

    #[test]
    fn bytes_match_the_golden_vector_and_round_trip() {
        let sut = golden();
        assert_eq!(Histogram::bucket_of(1_000), 24);
        assert_eq!(sut.to_bytes(), GOLDEN);
        assert_eq!(Histogram::from_bytes(GOLDEN), Ok(sut));
        let empty = Histogram::new();
        assert_eq!(empty.to_bytes().len(), HEADER_LEN);
        assert_eq!(Histogram::from_bytes(&empty.to_bytes()), Ok(empty));
    }

    #[test]
    fn inconsistent_bytes_are_refused_with_what_is_wrong() {
        let with = |at: usize, b: u8| {
            let mut v = GOLDEN.to_vec();
            v[at] = b;
            Histogram::from_bytes(&v)
        };
        assert!(matches!(with(0, b'X'), Err(StatsError::Magic(_))));
        assert!(matches!(
            with(4, 2),
            Err(StatsError::Layout { version: 2, .. })
        ));
        assert!(matches!(with(16, 4), Err(StatsError::Length { .. })));
        assert!(matches!(
            with(28, 0),
            Err(StatsError::Bucket { index: 0, .. })
        ));
        assert!(matches!(
            with(38, 250),
            Err(StatsError::Bucket { index: 250, .. })
        ));
        assert!(matches!(with(30, 0), Err(StatsError::EmptyBucket(24))));
        assert!(matches!(with(12, 0), Err(StatsError::Max { .. })));
        let mut overflow = GOLDEN.to_vec();
        overflow[20..28].copy_from_slice(&u64::MAX.to_le_bytes());
        assert_eq!(Histogram::from_bytes(&overflow), Err(StatsError::Overflow));
        assert!(matches!(
            Histogram::from_bytes(&GOLDEN[..GOLDEN.len() - 1]),
            Err(StatsError::Length { .. })
        ));
    }

    #[test]
    fn garbage_never_panics_and_what_is_accepted_round_trips() {
        // A small deterministic generator: xorshift64*.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            state.wrapping_mul(0x2545_f491_4f6c_dd1d)
        };
        for round in 0..20_000 {
            let len = (next() % 80) as usize;
            let mut bytes: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            if round % 2 == 0 && len >= HEADER_LEN {
                // A valid header with a matching length, entries with plausible indexes and
                // small counts: so the entry checks are reached.
                let n = (len - HEADER_LEN) / ENTRY_LEN;
                bytes.truncate(HEADER_LEN + n * ENTRY_LEN);
                bytes[..16].copy_from_slice(&GOLDEN[..16]);
                bytes[16..18].copy_from_slice(&(n as u16).to_le_bytes());
                for e in bytes[HEADER_LEN..].chunks_exact_mut(ENTRY_LEN) {
                    e[1] = 0;
                    e[3..].fill(0);
                }
            }
            if let Ok(h) = Histogram::from_bytes(&bytes) {
                assert_eq!(Histogram::from_bytes(&h.to_bytes()), Ok(h));
            }
        }
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
        let mut reply = Reply::default();
        sut.write_answer(&mut reply);
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
