//! Entry points for the fuzz targets (`fuzz/`) and for the test that replays their corpora:
//! each takes untrusted bytes the way a receiving process does — decodes them fully, walks
//! every value — and must neither panic nor loop, whatever the bytes.

use crate::args::Args;
use crate::directory::View;
use crate::grid::{Done, Prepare, Release};
use crate::heartbeat::Heartbeat;
use crate::relay::{Request, Response};
use crate::{Frame, SnapshotView, Value};

/// An RVMF* frame, as a module's inbox receives it.
pub fn frame(data: &[u8]) {
    if let Ok(frame) = Frame::decode(data) {
        let _ = (frame.dst(), frame.src(), frame.seq(), frame.kind());
        for value in frame.values() {
            let _ = value.map(|v| v.kind());
        }
        let _ = Args::decode(frame.values());
    }
}

/// A run of MessagePack values back to back (a payload).
pub fn values(data: &[u8]) {
    let mut at = 0;
    while at < data.len() {
        match Value::decode(&data[at..], at) {
            Ok((value, used)) if used > 0 => {
                let _ = value.kind();
                at += used;
            }
            _ => break,
        }
    }
}

/// A blackboard snapshot, as a reader receives it.
pub fn snapshot(data: &[u8]) {
    if let Ok(view) = SnapshotView::parse(data) {
        let _ = (view.addr(), view.seq());
        for item in view.iter() {
            // Viewed as typed slices of every alignment, as a reader of bulk items does.
            let _ = view.bulk::<u8>(item.name);
            let _ = view.bulk::<u32>(item.name);
            let _ = view.bulk::<[f64; 3]>(item.name);
        }
    }
}

/// A heartbeat, as the supervisor receives it.
pub fn heartbeat(data: &[u8]) {
    if let Ok(h) = Heartbeat::parse(data) {
        let _ = (h.addr(), h.state(), h.beat(), h.counters());
    }
}

/// A sample of grid notices: a release batch, a done batch, a prepare notice.
pub fn grid(data: &[u8]) {
    if let Ok(releases) = Release::batch(data) {
        for r in releases {
            let _ = r.versions().count();
        }
    }
    if let Ok(done) = Done::batch(data) {
        let _ = done.count();
    }
    if let Ok(p) = Prepare::parse(data) {
        let _ = p.name();
    }
}

/// The supervisor's directory image, as a module reads it.
pub fn directory(data: &[u8]) {
    if let Ok(view) = View::parse(data) {
        for entry in view.entries() {
            let _ = entry.listing();
        }
    }
}

/// A relayed call and its answer, as the supervisor and a tool read them.
pub fn relay(data: &[u8]) {
    if let Ok(request) = Request::parse(data) {
        let _ = request.values();
    }
    if let Ok(response) = Response::parse(data) {
        let _ = response;
    }
}

/// The coordinator's answer about switches, as `modbot assembly` reads it; what decodes
/// encodes to an answer that decodes the same.
pub fn switch(data: &[u8]) {
    if let Ok(status) = crate::switch::decode(data) {
        let _ = status.state.to_string();
        let mut again = Vec::new();
        status.encode(&mut again);
        assert_eq!(crate::switch::decode(&again), Ok(status));
    }
}

/// The supervisor's status rows, as `modbot ls` reads them; what decodes encodes to rows that
/// decode the same.
pub fn status(data: &[u8]) {
    if let Ok(rows) = crate::status::decode(data) {
        let mut again = Vec::new();
        crate::status::encode(&rows, &mut again);
        assert_eq!(crate::status::decode(&again), Ok(rows));
    }
}

/// A call latency histogram, as `modbot call MODULE.stats` reads it; what decodes encodes to
/// the same bytes (the layout has one form).
pub fn latency(data: &[u8]) {
    use crate::latency::{encode, View};
    if let Ok(view) = View::parse(data) {
        let mut again = Vec::new();
        encode(&view.counts(), view.max(), &mut again);
        // Reserved bytes: none; so the bytes come back exactly.
        assert_eq!(again, data);
    }
}

/// The bus bridge's record of switches, as `modbot bus --switches` reads it; what decodes
/// encodes to a record that decodes the same.
pub fn bus(data: &[u8]) {
    if let Ok(record) = crate::bus::decode(data) {
        let mut again = Vec::new();
        let encoded = crate::bus::encode(
            record.max_step,
            record.max_velocity_step,
            &record.switches,
            &mut again,
        );
        assert_eq!(encoded, Ok(()));
        assert_eq!(crate::bus::decode(&again), Ok(record));
    }
}

/// The checked grid, as a grid process reads it: every connection indexes the ports it names
/// (safe once the image decodes), and what decodes encodes to bytes that decode and encode to
/// the same bytes (compared as bytes: a parameter may be NaN).
pub fn grid_spec(data: &[u8]) {
    use crate::grid_spec::{decode, encode};
    if let Ok(image) = decode(data) {
        for c in &image.connections {
            let from = &image.components[c.from.component].info.outputs[c.from.port];
            let to = &image.components[c.to.component].info.inputs[c.to.port];
            assert_eq!(from.ty, to.ty);
        }
        let mut again = Vec::new();
        encode(&image, &mut again);
        let back = decode(&again).expect("an encoded image decodes");
        let mut twice = Vec::new();
        encode(&back, &mut twice);
        assert_eq!(again, twice);
    }
}

/// One of the decoders above.
pub type Decoder = fn(&[u8]);

/// Every decoder above, by the name of its fuzz target.
pub const TARGETS: &[(&str, Decoder)] = &[
    ("frame", frame),
    ("values", values),
    ("snapshot", snapshot),
    ("heartbeat", heartbeat),
    ("grid", grid),
    ("directory", directory),
    ("relay", relay),
    ("switch", switch),
    ("status", status),
    ("latency", latency),
    ("bus", bus),
    ("grid_spec", grid_spec),
];
