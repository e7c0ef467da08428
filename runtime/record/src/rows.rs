//! The hand-over of rows from the real-time thread to the writer: a fixed pool of row buffers
//! passed back and forth through two lock-free queues, so that recording a row takes no lock,
//! allocates nothing and never waits (unless the recorder is told it may: `lossless`).
//!
//! A row is the words of one release: the tick, the generation, the grid's state hash at the
//! tick, then every signal's values
//! (an f64 as its bits, an i64 as itself, a bool as 0 or 1) in signal order.

use crossbeam::queue::ArrayQueue;
use modbot_grid::component::PortValue;

/// The words of a row before the signals: the tick, the generation and the state hash.
pub const HEAD_WORDS: usize = 3;

/// Rows going to the writer, and empty ones coming back.
pub struct Rows {
    /// Filled rows, oldest first.
    full: ArrayQueue<Box<[u64]>>,
    /// Empty rows to fill.
    free: ArrayQueue<Box<[u64]>>,
    /// Words per row.
    width: usize,
}

impl Rows {
    /// A pool of `capacity` rows of `width` words.
    pub fn new(capacity: usize, width: usize) -> Rows {
        let capacity = capacity.max(1);
        let free = ArrayQueue::new(capacity);
        for _ in 0..capacity {
            let _ = free.push(vec![0; width].into_boxed_slice());
        }
        Rows {
            full: ArrayQueue::new(capacity),
            free,
            width,
        }
    }

    /// Words per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows waiting for the writer.
    pub fn pending(&self) -> usize {
        self.full.len()
    }

    /// Records a row: the tick, the generation, the grid's state hash at the tick and
    /// `values`, if an empty row is free; `false` when every row is full (the writer is
    /// behind). Lock-free; no allocation.
    pub fn push(&self, tick: u64, generation: u16, state_hash: u64, values: &[PortValue]) -> bool {
        let Some(mut row) = self.free.pop() else {
            return false;
        };
        row[0] = tick;
        row[1] = u64::from(generation);
        row[2] = state_hash;
        put_values(&mut row, values);
        // Both queues hold every row at most once, so there is room.
        let _ = self.full.push(row);
        true
    }

    /// The oldest filled row, for the writer.
    pub fn pop(&self) -> Option<Box<[u64]>> {
        self.full.pop()
    }

    /// Gives an emptied row back.
    pub fn give_back(&self, row: Box<[u64]>) {
        let _ = self.free.push(row);
    }
}

/// Writes `values` into a row after its head words (an f64 as its bits, an i64 as itself, a
/// bool as 0 or 1; a value wider than the row has room for is cut).
pub fn put_values(row: &mut [u64], values: &[PortValue]) {
    let mut at = HEAD_WORDS;
    for v in values {
        match v {
            PortValue::F64(x) => put(row, &mut at, x.to_bits()),
            PortValue::I64(i) => put(row, &mut at, *i as u64),
            PortValue::Bool(b) => put(row, &mut at, u64::from(*b)),
            PortValue::F64s(xs) => xs.iter().for_each(|x| put(row, &mut at, x.to_bits())),
        }
    }
}

/// Puts `word` at `at` (if the row has room: a value wider than declared is cut) and moves on.
fn put(row: &mut [u64], at: &mut usize, word: u64) {
    if let Some(slot) = row.get_mut(*at) {
        *slot = word;
    }
    *at += 1;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_arrive_in_order_and_a_full_pool_refuses_without_waiting() {
        let sut = Rows::new(2, HEAD_WORDS + 3);
        let values = [
            PortValue::F64(1.5),
            PortValue::Bool(true),
            PortValue::I64(-1),
        ];
        assert!(sut.push(7, 1, 0xab, &values));
        assert!(sut.push(8, 1, 0xab, &values));
        assert!(!sut.push(9, 1, 0xab, &values), "the third row has no room");
        let row = sut.pop().unwrap();
        assert_eq!(&row[..], &[7, 1, 0xab, 1.5f64.to_bits(), 1, u64::MAX]);
        sut.give_back(row);
        assert!(sut.push(9, 2, 0xab, &values));
        assert_eq!(sut.pop().unwrap()[0], 8);
        assert_eq!(sut.pop().unwrap()[0], 9);
        assert!(sut.pop().is_none());
    }
}
