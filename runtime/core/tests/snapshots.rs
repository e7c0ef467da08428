//! Blackboard snapshots with bulk items, on both transport backends: a module publishes a
//! camera image (a bulk item of `u32` pixels) and a frame counter; another module views the
//! pixels as `&[u32]` in the snapshot, in place, and never sees an image of another frame
//! than the counter says — while the writer writes only what changed into the samples that
//! come back to it.

mod support;

use std::time::Duration;

use modbot_core::blackboard::Blackboard;
use modbot_core::{Ctx, ModuleBuilder};
use modbot_ipc_schema::{OwnedValue, Value};
use support::{pump, Backend, TestDomain};

/// 64 × 64 pixels.
const PIXELS: usize = 64 * 64;

/// A camera: every 2 ms a new frame, every pixel set to the frame's number.
#[derive(Debug, Default)]
struct Camera {
    frame: u32,
    image: Vec<u32>,
}

fn camera(b: ModuleBuilder<Camera>) -> ModuleBuilder<Camera> {
    let bb = Blackboard::builder()
        .bulk_item::<u32>("image", PIXELS)
        .item("frame", OwnedValue::I64(0))
        .item("exposure", OwnedValue::F64(0.01))
        .build()
        .expect("a valid blackboard");
    b.blackboard(bb)
        .snapshot_period(Duration::from_millis(5))
        .every(Duration::from_millis(2), shoot)
}

fn shoot(c: &mut Camera, ctx: &mut Ctx) {
    c.frame += 1;
    c.image.clear();
    c.image.resize(PIXELS, c.frame);
    let image = ctx.bb.id("image").expect("declared");
    ctx.bb
        .write_bulk(image, &c.image)
        .expect("as many pixels as declared");
    ctx.bb
        .write("frame", Value::I64(i64::from(c.frame)))
        .expect("an i64");
}

/// What a reader saw of one snapshot: the frame counter, the first and last pixel, whether
/// every pixel equals the first, and whether the pixels were read where the snapshot is.
type Seen = (i64, u32, u32, bool, bool);

fn a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("camera", 3, Camera::default(), camera);
    let mut reader = fx.caller();
    let mut frames = std::collections::BTreeSet::new();
    let mut last: Option<Seen> = None;
    let done = pump(&mut reader, Duration::from_secs(60), |m| {
        let seen = m.ctx().snapshot_of("camera", |v| -> Result<Seen, String> {
            let pixels: &[u32] = v.bulk("image").map_err(|e| e.to_string())?;
            let frame = v.value("frame").map_err(|e| e.to_string())?;
            let Value::I64(frame) = frame else {
                return Err(format!("frame is {frame:?}"));
            };
            let whole = v.get("image").map(|i| i.value);
            let Some(Value::Bytes(bytes)) = whole else {
                return Err("no image bytes".into());
            };
            let in_place = pixels.as_ptr().cast::<u8>() == bytes.as_ptr();
            let first = pixels.first().copied().unwrap_or_default();
            let same = pixels.iter().all(|p| *p == first);
            Ok((frame, first, pixels.len() as u32, same, in_place))
        });
        if let Ok(Some(Ok(seen))) = seen {
            if seen.0 > 0 {
                frames.insert(seen.0);
            }
            last = Some(seen);
        }
        frames.len() >= 5
    });
    let seen = last.expect("the camera's snapshots were read");
    assert!(done, "only frames {frames:?} seen; last {seen:?}");
    let (frame, first, len, same, in_place) = seen;
    assert_eq!(len as usize, PIXELS);
    assert!(same, "a torn image: pixels of two frames");
    assert_eq!(i64::from(first), frame, "the image is of another frame");
    assert!(in_place, "the pixels were copied");
}

mod local {
    #[test]
    fn a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn() {
        crate::support::run_test::<crate::support::Local>(
            "a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn",
            super::a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn,
        );
    }
}

mod ipc {
    #[test]
    fn a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn() {
        crate::support::run_test::<crate::support::Ipc>(
            "a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn",
            super::a_bulk_item_is_viewed_in_place_by_another_module_and_never_torn,
        );
    }
}
