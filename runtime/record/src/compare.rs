//! Two recordings compared tick by tick, to the last bit (`modbot record compare A B`): two
//! lockstep runs of the same system give identical files, and where they do not, the first
//! tick, signal and values that differ say where to look. Beside the signals the files record,
//! the grid's state hash per row (`modbot_grid::state_hash`) compares the state of every
//! component, recorded or not: a difference no recorded signal shows yet is found at the
//! tick the state first differs.

use std::path::Path;

use super::read::{read_signal, read_state_hash, signals, ReadError, Series};

/// How two recordings compare.
#[derive(Debug, Clone, PartialEq)]
pub enum Comparison {
    /// Every signal equal in every row both have, bit for bit.
    Identical {
        /// The last tick both have (none: no rows).
        through: Option<i64>,
        /// Rows compared.
        rows: usize,
        /// Signals compared.
        signals: usize,
        /// Rows one has past the other's end: (which file, 0 or 1, how many).
        longer: Option<(usize, usize)>,
        /// Whether the grid's state hash was compared too (both files keep it).
        hashed: bool,
    },
    /// The first row where they differ.
    Differs {
        /// Its tick (in the first file).
        tick: i64,
        /// The signal (`tick` when the rows are of different ticks).
        signal: String,
        /// Which value of an array signal (0 for a scalar).
        index: usize,
        /// The two values.
        values: (f64, f64),
    },
    /// The first row where the grid's state hash differs, before (or without) any recorded
    /// signal differing: a component's state the recording does not show.
    StateDiffers {
        /// Its tick (in the first file).
        tick: i64,
        /// The two hashes.
        hashes: (u64, u64),
    },
}

/// Why two recordings cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error(
        "they record other signals: {only_a:?} only in the first, {only_b:?} only in the second"
    )]
    Signals {
        only_a: Vec<String>,
        only_b: Vec<String>,
    },
    #[error("signal '{signal}' has {a} values per row in the first and {b} in the second")]
    Width { signal: String, a: usize, b: usize },
}

/// Compares the recordings `a` and `b` row by row over the rows both have.
pub fn compare(a: &Path, b: &Path) -> Result<Comparison, CompareError> {
    let (names_a, names_b) = (signals(a)?, signals(b)?);
    if names_a != names_b {
        let only =
            |x: &[String], y: &[String]| x.iter().filter(|n| !y.contains(n)).cloned().collect();
        return Err(CompareError::Signals {
            only_a: only(&names_a, &names_b),
            only_b: only(&names_b, &names_a),
        });
    }
    let all = |path: &Path, signal: &str| read_signal(path, signal, i64::MIN, i64::MAX);
    let (ticks_a, ticks_b) = (all(a, "tick")?, all(b, "tick")?);
    let rows = ticks_a.ticks.len().min(ticks_b.ticks.len());
    let mut first: Option<(usize, Comparison)> = None;
    let mut consider = |row: usize, differs: Comparison| {
        if first.as_ref().is_none_or(|(r, _)| row < *r) {
            first = Some((row, differs));
        }
    };
    if let Some(row) = (0..rows).find(|&r| ticks_a.ticks[r] != ticks_b.ticks[r]) {
        let (ta, tb) = (ticks_a.ticks[row], ticks_b.ticks[row]);
        consider(
            row,
            Comparison::Differs {
                tick: ta,
                signal: "tick".into(),
                index: 0,
                values: (ta as f64, tb as f64),
            },
        );
    }
    for signal in names_a.iter().chain([&"generation".to_owned()]) {
        let (sa, sb): (Series, Series) = (all(a, signal)?, all(b, signal)?);
        if sa.width != sb.width {
            return Err(CompareError::Width {
                signal: signal.clone(),
                a: sa.width,
                b: sb.width,
            });
        }
        let differs = (0..rows).find_map(|r| {
            let (ra, rb) = (sa.row(r), sb.row(r));
            (0..sa.width)
                .find(|&i| ra[i].to_bits() != rb[i].to_bits())
                .map(|i| (r, i, ra[i], rb[i]))
        });
        if let Some((row, index, x, y)) = differs {
            consider(
                row,
                Comparison::Differs {
                    tick: ticks_a.ticks[row],
                    signal: signal.clone(),
                    index,
                    values: (x, y),
                },
            );
        }
    }
    // Last: at the same row a signal that differs says more.
    let (hash_a, hash_b) = (read_state_hash(a)?, read_state_hash(b)?);
    let hashed = hash_a.is_some() && hash_b.is_some();
    if let (Some(ha), Some(hb)) = (&hash_a, &hash_b) {
        let common = rows.min(ha.len()).min(hb.len());
        if let Some(row) = (0..common).find(|&r| ha[r] != hb[r]) {
            consider(
                row,
                Comparison::StateDiffers {
                    tick: ticks_a.ticks[row],
                    hashes: (ha[row], hb[row]),
                },
            );
        }
    }
    if let Some((_, differs)) = first {
        return Ok(differs);
    }
    let (la, lb) = (ticks_a.ticks.len(), ticks_b.ticks.len());
    Ok(Comparison::Identical {
        through: rows.checked_sub(1).map(|r| ticks_a.ticks[r]),
        rows,
        signals: names_a.len(),
        longer: match la.cmp(&lb) {
            std::cmp::Ordering::Greater => Some((0, la - lb)),
            std::cmp::Ordering::Less => Some((1, lb - la)),
            std::cmp::Ordering::Equal => None,
        },
        hashed,
    })
}

impl std::fmt::Display for Comparison {
    /// One line: "identical through tick N (R rows, S signals and the state hash)" or "first
    /// differs at tick T: …".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Comparison::Identical {
                through,
                rows,
                signals,
                longer,
                hashed,
            } => {
                match through {
                    Some(t) => write!(f, "identical through tick {t}")?,
                    None => write!(f, "identical: no rows in common")?,
                }
                let hash = if *hashed { " and the state hash" } else { "" };
                let plural = if *signals == 1 { "" } else { "s" };
                write!(f, " ({rows} rows, {signals} signal{plural}{hash})")?;
                if let Some((which, n)) = longer {
                    let which = ["first", "second"][*which];
                    write!(f, "; the {which} has {n} more rows")?;
                }
                Ok(())
            }
            Comparison::Differs {
                tick,
                signal,
                index,
                values: (a, b),
            } => write!(
                f,
                "first differs at tick {tick}: {signal}[{index}] {a:?} in the first, {b:?} in the second"
            ),
            Comparison::StateDiffers {
                tick,
                hashes: (a, b),
            } => write!(
                f,
                "first differs at tick {tick}: the state hash {a:#018x} in the first, {b:#018x} \
                 in the second (no recorded signal differs there: a component's state the \
                 recording does not show)"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::file::{Header, RecordFile};
    use modbot_grid::component::PortType;
    use modbot_grid::record_type::Signal;

    /// A recording of `q` (f64[2]) and `n` (i64) at ticks 10.., `q` being `f(tick)`, the
    /// state hash `tick` except at `hash_off`.
    fn recording(path: &Path, rows: u64, f: impl Fn(u64) -> [f64; 2]) {
        recording_hashed(path, rows, f, None)
    }

    fn recording_hashed(
        path: &Path,
        rows: u64,
        f: impl Fn(u64) -> [f64; 2],
        hash_off: Option<u64>,
    ) {
        let signals = [
            Signal {
                name: "a.q".into(),
                ty: PortType::F64s(2),
            },
            Signal {
                name: "a.n".into(),
                ty: PortType::I64,
            },
        ];
        let mut file = RecordFile::create(path, &signals, &Header::default(), 16).unwrap();
        let ticks: Vec<u64> = (10..10 + rows).collect();
        let q = ticks.iter().flat_map(|&t| f(t).map(f64::to_bits)).collect();
        let n = ticks.iter().map(|&t| t * 2).collect();
        let generation = vec![0; rows as usize];
        let hashes = ticks
            .iter()
            .map(|&t| if Some(t) == hash_off { !t } else { t })
            .collect();
        let time = ticks.iter().map(|&t| (t as f64 * 1e-3).to_bits()).collect();
        file.append(rows as usize, &[q, n, generation, hashes, time, ticks])
            .unwrap();
        file.close().unwrap();
    }

    #[test]
    fn two_equal_recordings_are_identical_through_their_last_common_tick() {
        let dir = std::env::temp_dir().join(format!("modbot-compare-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b, c) = (dir.join("a.h5"), dir.join("b.h5"), dir.join("c.h5"));
        recording(&a, 50, |t| [t as f64, -(t as f64)]);
        recording(&b, 40, |t| [t as f64, -(t as f64)]);
        // One bit off at tick 33, index 1.
        recording(&c, 50, |t| {
            let x = -(t as f64);
            [
                t as f64,
                if t == 33 {
                    f64::from_bits(x.to_bits() ^ 1)
                } else {
                    x
                },
            ]
        });
        let same = compare(&a, &b).unwrap();
        assert_eq!(
            same.to_string(),
            "identical through tick 49 (40 rows, 2 signals and the state hash); the first has 10 more rows"
        );
        let differs = compare(&a, &c).unwrap();
        assert!(
            matches!(&differs, Comparison::Differs { tick: 33, signal, index: 1, .. } if signal == "a.q"),
            "{differs}"
        );
        assert!(differs
            .to_string()
            .starts_with("first differs at tick 33: a.q[1] -33.0"));
        // The state differs at 20, where no signal does; at 33 a signal does too.
        let (d, e) = (dir.join("d.h5"), dir.join("e.h5"));
        recording_hashed(&d, 50, |t| [t as f64, -(t as f64)], Some(20));
        let state = compare(&a, &d).unwrap();
        assert_eq!(
            state,
            Comparison::StateDiffers {
                tick: 20,
                hashes: (20, !20)
            }
        );
        assert_eq!(
            state.to_string(),
            "first differs at tick 20: the state hash 0x0000000000000014 in the first, \
             0xffffffffffffffeb in the second (no recorded signal differs there: a component's \
             state the recording does not show)"
        );
        recording_hashed(&e, 50, |t| [t as f64, -(t as f64)], Some(33));
        let both = compare(&c, &e).unwrap();
        assert!(
            matches!(&both, Comparison::Differs { tick: 33, signal, .. } if signal == "a.q"),
            "a signal that differs at the same tick names more: {both}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
