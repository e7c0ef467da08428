//! Latency histograms. The golden histogram: an 18-byte header (magic 0..4; version, sub-bucket
//! bits and the two exponents 4..8; max 8..16; count 16..18), then 10 bytes per bucket (index,
//! count): buckets 0, 24 and 249.

use modbot_ipc_schema::latency::{HistogramError, View};

use crate::support::golden;

fn histogram() -> Vec<u8> {
    golden("latency max=")
}

fn refused(bytes: &[u8]) -> Option<HistogramError> {
    View::parse(bytes).err()
}

/// Bucket entry `i`'s index field.
fn index_at(i: usize) -> usize {
    18 + 10 * i
}

#[test]
fn a_histogram_of_another_magic_is_refused() {
    let mut bytes = histogram();
    bytes[0] = b'X';
    assert!(matches!(refused(&bytes), Some(HistogramError::Magic(_))));
}

#[test]
fn a_histogram_of_another_bucket_layout_is_refused() {
    let mut bytes = histogram();
    bytes[5] = 4; // sub-bucket bits
    assert!(matches!(
        refused(&bytes),
        Some(HistogramError::Layout { sub_bits: 4, .. })
    ));
}

#[test]
fn a_byte_after_the_last_bucket_is_refused() {
    let mut bytes = histogram();
    bytes.push(0);
    assert_eq!(
        refused(&bytes),
        Some(HistogramError::Length {
            expected: 48,
            got: 49
        })
    );
}

#[test]
fn a_bucket_index_past_the_last_bucket_is_refused() {
    let mut bytes = histogram();
    bytes[index_at(2)] = 250;
    assert!(matches!(
        refused(&bytes),
        Some(HistogramError::Bucket { index: 250, .. })
    ));
}

#[test]
fn bucket_indexes_that_do_not_increase_are_refused() {
    let mut bytes = histogram();
    bytes[index_at(1)] = 0;
    assert_eq!(
        refused(&bytes),
        Some(HistogramError::Bucket {
            index: 0,
            after: Some(0)
        })
    );
}

#[test]
fn a_bucket_listed_with_a_count_of_0_is_refused() {
    let mut bytes = histogram();
    bytes[index_at(1) + 2] = 0;
    assert_eq!(refused(&bytes), Some(HistogramError::EmptyBucket(24)));
}

#[test]
fn counts_whose_sum_overflows_are_refused() {
    let mut bytes = histogram();
    let at = index_at(1) + 2;
    bytes[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    assert_eq!(refused(&bytes), Some(HistogramError::Overflow));
}

#[test]
fn a_largest_value_outside_the_highest_bucket_is_refused() {
    let mut bytes = histogram();
    bytes[8..16].copy_from_slice(&1_000u64.to_le_bytes());
    assert_eq!(
        refused(&bytes),
        Some(HistogramError::Max {
            max: 1_000,
            bucket: 249
        })
    );
}
