//! What a host's components put out, for the host's module to show: a copy the serving thread
//! refreshes after it served its releases, without ever waiting for it (`try_lock`; a copy
//! skipped is taken at the next serve), and without allocating (arrays are copied in place).
//! The host process shows it on its blackboard as items `<component>.<output>` and `tick`, so
//! a robot program reads a component's state as it reads any module's (`read("settle.settled")`).

use std::sync::{Arc, Mutex};

use super::component::PortValue;

/// The names and latest values of a host's outputs.
#[derive(Debug, Clone, Default)]
pub struct OutputsView {
    /// `<component>.<output>` for every output of every hosted component, in the order of
    /// `values`.
    pub names: Vec<String>,
    pub values: Vec<PortValue>,
    /// The newest release tick served: the values are those of that release (valid from
    /// tick + period by LET; a reader outside the grid sees them as soon as they are made).
    pub tick: u64,
    /// Counts refreshes, so a reader sees whether anything changed.
    pub seq: u64,
}

/// The view, shared between the serving thread and the module's.
pub type SharedOutputs = Arc<Mutex<OutputsView>>;

/// Copies `from` into `to` without allocating when the kinds and lengths agree (always, after
/// the first copy: a port keeps its type).
pub fn copy_port(to: &mut PortValue, from: &PortValue) {
    match (to, from) {
        (PortValue::F64s(t), PortValue::F64s(f)) if t.len() == f.len() => t.copy_from_slice(f),
        (to, from) => *to = from.clone(),
    }
}

/// Refreshes `view` with `outputs` (each component's, in order) at `tick`, if nobody holds it
/// — or, with `wait` (a grid in lockstep, where no deadline is kept), once its reader lets go:
/// then a reader that learns every release is done (a gated grid, held) finds their outputs
/// here.
pub fn refresh<'a>(
    view: &Mutex<OutputsView>,
    tick: u64,
    outputs: impl Iterator<Item = &'a [PortValue]>,
    wait: bool,
) {
    let locked = if wait {
        Ok(view.lock().unwrap_or_else(|p| p.into_inner()))
    } else {
        view.try_lock()
    };
    let Ok(mut v) = locked else {
        return;
    };
    let mut slots = v.values.iter_mut();
    for from in outputs.flatten() {
        match slots.next() {
            Some(to) => copy_port(to, from),
            None => break,
        }
    }
    v.tick = tick;
    v.seq += 1;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refresh_copies_every_output_in_order_and_counts() {
        let sut = Mutex::new(OutputsView {
            names: vec!["a.y".into(), "b.q".into()],
            values: vec![PortValue::F64(0.0), PortValue::F64s(vec![0.0; 2])],
            ..OutputsView::default()
        });
        let a = [PortValue::F64(1.5)];
        let b = [PortValue::F64s(vec![2.0, 3.0])];
        refresh(&sut, 7, [&a[..], &b[..]].into_iter(), false);
        let v = sut.lock().unwrap();
        assert_eq!(
            v.values,
            [PortValue::F64(1.5), PortValue::F64s(vec![2.0, 3.0])]
        );
        assert_eq!((v.tick, v.seq), (7, 1));
    }

    #[test]
    fn a_view_held_by_its_reader_is_not_waited_for() {
        let sut = Mutex::new(OutputsView {
            values: vec![PortValue::F64(0.0)],
            ..OutputsView::default()
        });
        let held = sut.lock().unwrap();
        refresh(&sut, 1, [&[PortValue::F64(1.0)][..]].into_iter(), false);
        assert_eq!(held.seq, 0);
    }

    #[test]
    fn a_waiting_refresh_copies_once_its_reader_lets_go() {
        let sut = std::sync::Arc::new(Mutex::new(OutputsView {
            values: vec![PortValue::F64(0.0)],
            ..OutputsView::default()
        }));
        let held = sut.lock().unwrap();
        let writer = {
            let sut = sut.clone();
            std::thread::spawn(move || {
                refresh(&sut, 3, [&[PortValue::F64(2.0)][..]].into_iter(), true)
            })
        };
        std::thread::sleep(std::time::Duration::from_millis(20));
        assert_eq!(held.seq, 0, "the writer waits");
        drop(held);
        writer.join().unwrap();
        let v = sut.lock().unwrap();
        assert_eq!(
            (v.values[0].clone(), v.tick, v.seq),
            (PortValue::F64(2.0), 3, 1)
        );
    }
}
