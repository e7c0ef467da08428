//! The call latency histogram a module answers in `stats()` (`modbot call MODULE.stats`): its
//! buckets and their wire layout. `modbot_core::stats::Histogram` records into these buckets.
//!
//! The buckets are log-linear, as in HdrHistogram: each power of two from 128 ns (2^7) to
//! 2^38 ns (about 275 s) is split into [`SUB_BUCKETS`] = 8 equal buckets, so a bucket is at
//! most 12.5 % of its lower bound wide. Values below 128 ns share bucket 0; values of 2^38 ns
//! and more share the last bucket ([`bucket_of`], [`bucket_range`]).
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
//! 18     10*n  bucket index (u16 LE, < 250), count (u64 LE, > 0); indexes strictly increasing
//! ```
//!
//! Only buckets that counted something are sent: a typical latency histogram is a few hundred
//! bytes. A reader checks every field: the length is exactly 18 + 10·n, the counts add up
//! without overflowing u64, and the largest value lies in the highest bucket listed.

use core::ops::Range;

use thiserror::Error;
use zerocopy::byteorder::little_endian::{U16, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

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

/// The first four bytes.
pub const MAGIC: [u8; 4] = *b"MBLH";
/// The format version this crate writes and reads.
pub const VERSION: u8 = 1;
/// Bytes before the bucket entries.
pub const HEADER_LEN: usize = 18;
/// Bytes per bucket entry.
pub const ENTRY_LEN: usize = 10;

/// The bucket layout the header names: version, sub-bucket bits, first and overflow exponent.
const LAYOUT: [u8; 4] = [
    VERSION,
    SUB_BUCKET_BITS as u8,
    FIRST_EXP as u8,
    OVERFLOW_EXP as u8,
];

/// The header, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct Header {
    magic: [u8; 4],
    /// [`LAYOUT`].
    layout: [u8; 4],
    max: U64,
    count: U16,
}

/// One bucket that counted something, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Entry {
    index: U16,
    count: U64,
}

impl Entry {
    pub fn index(&self) -> usize {
        usize::from(self.index.get())
    }

    pub fn count(&self) -> u64 {
        self.count.get()
    }
}

/// Why bytes are not a latency histogram.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum HistogramError {
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
}

/// The bucket that holds `ns`. A few integer operations: recording never allocates.
#[inline]
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
pub fn bucket_range(index: usize) -> Range<u64> {
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

/// Appends a histogram to `out`: the count of every bucket, and the largest value recorded.
/// Buckets that counted nothing are left out.
pub fn encode(counts: &[u64; BUCKETS], max: u64, out: &mut Vec<u8>) {
    let n = counts.iter().filter(|&&c| c > 0).count();
    out.reserve(HEADER_LEN + ENTRY_LEN * n);
    let header = Header {
        magic: MAGIC,
        layout: LAYOUT,
        max: U64::new(max),
        // BUCKETS < u16::MAX, so n fits.
        count: U16::new(n as u16),
    };
    out.extend_from_slice(header.as_bytes());
    for (index, &count) in counts.iter().enumerate().filter(|(_, c)| **c > 0) {
        let entry = Entry {
            index: U16::new(index as u16),
            count: U64::new(count),
        };
        out.extend_from_slice(entry.as_bytes());
    }
}

/// A histogram read in place.
#[derive(Debug, Clone, Copy)]
pub struct View<'a> {
    max: u64,
    total: u64,
    entries: &'a [Entry],
}

impl<'a> View<'a> {
    /// Reads and checks a histogram (see the [module docs](self)).
    pub fn parse(bytes: &'a [u8]) -> Result<View<'a>, HistogramError> {
        let (header, rest) =
            Header::ref_from_prefix(bytes).map_err(|_| HistogramError::Length {
                expected: HEADER_LEN,
                got: bytes.len(),
            })?;
        if header.magic != MAGIC {
            return Err(HistogramError::Magic(header.magic));
        }
        if header.layout != LAYOUT {
            let [version, sub_bits, first_exp, overflow_exp] = header.layout;
            return Err(HistogramError::Layout {
                version,
                sub_bits,
                first_exp,
                overflow_exp,
            });
        }
        let n = usize::from(header.count.get());
        let entries =
            <[Entry]>::ref_from_bytes_with_elems(rest, n).map_err(|_| HistogramError::Length {
                expected: HEADER_LEN + ENTRY_LEN * n,
                got: bytes.len(),
            })?;
        let mut total = 0u64;
        let mut after: Option<u16> = None;
        for e in entries {
            let index = e.index.get();
            if usize::from(index) >= BUCKETS || after.is_some_and(|a| index <= a) {
                return Err(HistogramError::Bucket { index, after });
            }
            if e.count() == 0 {
                return Err(HistogramError::EmptyBucket(index));
            }
            after = Some(index);
            total = total
                .checked_add(e.count())
                .ok_or(HistogramError::Overflow)?;
        }
        // The largest value lies in the highest bucket that counted something (0 when none).
        let max = header.max.get();
        let highest = after.map_or(0, usize::from);
        let fits = match after {
            None => max == 0,
            Some(_) => {
                bucket_range(highest).contains(&max) || (highest == BUCKETS - 1 && max == u64::MAX)
            }
        };
        if !fits {
            return Err(HistogramError::Max {
                max,
                bucket: highest,
            });
        }
        Ok(View {
            max,
            total,
            entries,
        })
    }

    /// The largest value recorded, ns.
    pub fn max(&self) -> u64 {
        self.max
    }

    /// The values recorded: the sum of the counts.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// The buckets that counted something, in index order.
    pub fn entries(&self) -> &'a [Entry] {
        self.entries
    }

    /// The count of every bucket.
    pub fn counts(&self) -> [u64; BUCKETS] {
        let mut counts = [0; BUCKETS];
        for e in self.entries {
            // Checked by `parse`: every index is below BUCKETS.
            counts[e.index()] = e.count();
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    /// 100 ns, 1 µs twice and 300 s.
    fn golden_counts() -> [u64; BUCKETS] {
        let mut counts = [0; BUCKETS];
        for v in [100, 1_000, 1_000, 300_000_000_000] {
            counts[bucket_of(v)] += 1;
        }
        counts
    }

    /// The wire layout documented above, byte for byte.
    const GOLDEN: &str = concat!(
        "4d424c48",              // magic
        "01 03 07 26",           // version, sub-bucket bits, first and overflow exponent
        "00b864d945000000",      // max = 300_000_000_000 ns
        "0300",                  // 3 buckets
        "0000 0100000000000000", // bucket 0 (100 ns): 1
        "1800 0200000000000000", // bucket 24 (960..1024 ns): 2
        "f900 0100000000000000", // bucket 249 (overflow): 1
    );

    fn golden() -> Vec<u8> {
        hex::decode(GOLDEN).unwrap()
    }

    #[test]
    fn bytes_match_the_golden_vector_and_read_back() {
        assert_eq!(bucket_of(1_000), 24);
        let mut bytes = Vec::new();
        encode(&golden_counts(), 300_000_000_000, &mut bytes);
        assert_eq!(bytes, golden());
        let view = View::parse(&bytes).unwrap();
        assert_eq!((view.max(), view.total()), (300_000_000_000, 4));
        let buckets: Vec<_> = view
            .entries()
            .iter()
            .map(|e| (e.index(), e.count()))
            .collect();
        assert_eq!(buckets, [(0, 1), (24, 2), (249, 1)]);
        let mut empty = Vec::new();
        encode(&[0; BUCKETS], 0, &mut empty);
        assert_eq!(empty.len(), HEADER_LEN);
        assert_eq!(View::parse(&empty).unwrap().total(), 0);
    }

    #[test]
    fn buckets_are_contiguous_and_each_value_lands_in_the_bucket_whose_range_holds_it() {
        let mut end = 0;
        for i in 0..BUCKETS {
            let r = bucket_range(i);
            assert_eq!(r.start, end, "bucket {i} starts where the one before ends");
            assert!(r.end > r.start);
            assert_eq!(bucket_of(r.start), i);
            assert_eq!(bucket_of(r.end - 1), i);
            if i > 0 && i < BUCKETS - 1 {
                // 12.5 % resolution: a bucket is at most an eighth of its lower bound wide.
                assert!((r.end - r.start) * 8 <= r.start, "bucket {i}: {r:?}");
            }
            end = r.end;
        }
        assert_eq!(end, u64::MAX);
        assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
        assert_eq!(BUCKETS, 250);
    }

    #[test]
    fn inconsistent_bytes_are_refused_with_what_is_wrong() {
        let with = |at: usize, b: u8| {
            let mut v = golden();
            v[at] = b;
            View::parse(&v).map(|v| v.total())
        };
        assert!(matches!(with(0, b'X'), Err(HistogramError::Magic(_))));
        assert!(matches!(
            with(4, 2),
            Err(HistogramError::Layout { version: 2, .. })
        ));
        assert!(matches!(with(16, 4), Err(HistogramError::Length { .. })));
        assert!(matches!(
            with(28, 0),
            Err(HistogramError::Bucket { index: 0, .. })
        ));
        assert!(matches!(
            with(38, 250),
            Err(HistogramError::Bucket { index: 250, .. })
        ));
        assert!(matches!(with(30, 0), Err(HistogramError::EmptyBucket(24))));
        assert!(matches!(with(12, 0), Err(HistogramError::Max { .. })));
        let mut overflow = golden();
        overflow[20..28].copy_from_slice(&u64::MAX.to_le_bytes());
        assert_eq!(
            View::parse(&overflow).map(|v| v.total()),
            Err(HistogramError::Overflow)
        );
        let golden = golden();
        assert!(matches!(
            View::parse(&golden[..golden.len() - 1]),
            Err(HistogramError::Length { .. })
        ));
        let mut longer = golden.clone();
        longer.push(0);
        assert!(matches!(
            View::parse(&longer),
            Err(HistogramError::Length { .. })
        ));
        assert!(matches!(
            View::parse(&golden[..10]),
            Err(HistogramError::Length { .. })
        ));
    }

    #[test]
    fn garbage_never_panics_and_what_is_accepted_reads_back_the_same() {
        // A small deterministic generator: xorshift64*.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            state.wrapping_mul(0x2545_f491_4f6c_dd1d)
        };
        let golden = golden();
        for round in 0..20_000 {
            let len = (next() % 80) as usize;
            let mut bytes: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            if round % 2 == 0 && len >= HEADER_LEN {
                // A valid header with a matching length, entries with plausible indexes and
                // small counts: so the entry checks are reached.
                let n = (len - HEADER_LEN) / ENTRY_LEN;
                bytes.truncate(HEADER_LEN + n * ENTRY_LEN);
                bytes[..16].copy_from_slice(&golden[..16]);
                bytes[16..18].copy_from_slice(&(n as u16).to_le_bytes());
                for e in bytes[HEADER_LEN..].chunks_exact_mut(ENTRY_LEN) {
                    e[1] = 0;
                    e[3..].fill(0);
                }
            }
            if let Ok(view) = View::parse(&bytes) {
                let mut again = Vec::new();
                encode(&view.counts(), view.max(), &mut again);
                assert_eq!(again, bytes);
            }
        }
    }
}
