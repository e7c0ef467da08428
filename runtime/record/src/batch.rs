//! The batch the writer gathers from rows before it appends them to the file: per dataset,
//! its words (an f64 as its bits), for the signals the file records — all of the recorder's,
//! or those a program chose ([`crate::control`]) — then generation, state hash, time and tick.

use modbot_grid::component::PortType;

use super::rows::HEAD_WORDS;

/// Rows gathered for one append.
pub struct Batch {
    /// Per recorded signal: where its words start in a row, and how many there are.
    picks: Vec<(usize, usize)>,
    base_period_s: f64,
    /// Per dataset: the recorded signals, then generation, state hash, time, tick.
    pub columns: Vec<Vec<u64>>,
    /// Rows gathered.
    pub rows: usize,
}

impl Batch {
    /// A batch of the signals of types `types` (a row's, in order) at the indices `recorded`.
    pub fn new(types: &[PortType], recorded: &[usize], base_period_s: f64) -> Batch {
        let mut starts = Vec::with_capacity(types.len());
        let mut at = HEAD_WORDS;
        for ty in types {
            let width = ty.wire_len() / 8;
            starts.push((at, width));
            at += width;
        }
        let picks: Vec<(usize, usize)> = recorded
            .iter()
            .filter_map(|&i| starts.get(i).copied())
            .collect();
        Batch {
            columns: vec![Vec::new(); picks.len() + 4],
            picks,
            base_period_s,
            rows: 0,
        }
    }

    /// Adds a row: the tick, the generation, the state hash, then every signal's words.
    pub fn add(&mut self, row: &[u64]) {
        let n = self.picks.len();
        for (column, &(at, width)) in self.columns.iter_mut().zip(&self.picks) {
            match row.get(at..at + width) {
                Some(words) => column.extend_from_slice(words),
                None => column.resize(column.len() + width, 0),
            }
        }
        let (tick, generation, state_hash) = (row[0], row[1], row[2]);
        self.columns[n].push(generation);
        self.columns[n + 1].push(state_hash);
        let time = tick as f64 * self.base_period_s;
        self.columns[n + 2].push(time.to_bits());
        self.columns[n + 3].push(tick);
        self.rows += 1;
    }

    pub fn clear(&mut self) {
        self.columns.iter_mut().for_each(Vec::clear);
        self.rows = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_of_chosen_signals_takes_their_words_from_each_row() {
        let types = [PortType::F64, PortType::F64s(2), PortType::I64];
        let mut sut = Batch::new(&types, &[1, 2], 0.001);
        sut.add(&[7, 1, 0xa, 10, 20, 21, 30]);
        sut.add(&[8, 1, 0xb, 11, 22, 23, 31]);
        assert_eq!(
            sut.columns[0],
            [20, 21, 22, 23],
            "the f64[2], row after row"
        );
        assert_eq!(sut.columns[1], [30, 31]);
        assert_eq!(
            (
                sut.columns[2].clone(),
                sut.columns[3].clone(),
                sut.columns[5].clone()
            ),
            (vec![1, 1], vec![0xa, 0xb], vec![7, 8])
        );
        assert_eq!(
            sut.columns[4],
            [(7.0 * 0.001f64).to_bits(), (8.0 * 0.001f64).to_bits()]
        );
        sut.clear();
        assert_eq!((sut.rows, sut.columns[0].len()), (0, 0));
    }
}
