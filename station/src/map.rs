//! MOSER's building for the page's map: walls, rooms with their patrol points, and the
//! furniture — the boxes the building map knows, and the one it does not (the page draws that
//! one once the robot has been near it). The same building every MOSER module simulates
//! (`modbot_modules::moser::building`).

use modbot_modules::moser::building::moser_building;
use modbot_modules::moser::geometry::{Rect, P};
use serde::Serialize;

#[derive(Debug, Clone, Serialize)]
pub struct Map {
    pub bounds: [f64; 4],
    /// Each wall as `[x0, y0, x1, y1]`.
    pub walls: Vec<[f64; 4]>,
    pub rooms: Vec<Room>,
    pub boxes: Vec<MapBox>,
    pub start: [f64; 2],
}

#[derive(Debug, Clone, Serialize)]
pub struct Room {
    pub name: &'static str,
    pub wing: u8,
    pub rect: [f64; 4],
    pub patrol_point: [f64; 2],
}

#[derive(Debug, Clone, Serialize)]
pub struct MapBox {
    pub name: &'static str,
    pub rect: [f64; 4],
    /// Whether the building map knows it; the others the sonars find.
    pub on_map: bool,
}

fn rect(r: &Rect) -> [f64; 4] {
    [r.min.x, r.min.y, r.max.x, r.max.y]
}

fn point(p: P) -> [f64; 2] {
    [p.x, p.y]
}

/// MOSER's building.
pub fn moser() -> Map {
    let b = moser_building();
    Map {
        bounds: rect(&b.bounds),
        walls: b
            .walls
            .iter()
            .map(|w| [w.a.x, w.a.y, w.b.x, w.b.y])
            .collect(),
        rooms: b
            .rooms
            .iter()
            .map(|r| Room {
                name: r.name,
                wing: r.wing,
                rect: rect(&r.rect),
                patrol_point: point(r.patrol_point),
            })
            .collect(),
        boxes: b
            .obstacles
            .iter()
            .map(|o| MapBox {
                name: o.name,
                rect: rect(&o.rect),
                on_map: o.on_map,
            })
            .collect(),
        start: point(b.start),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_map_has_the_building_its_rooms_and_the_unknown_box() {
        let m = super::moser();
        assert_eq!(m.bounds, [0.0, 0.0, 30.0, 20.0]);
        assert!(m.walls.len() > 10);
        assert!(m.rooms.iter().any(|r| r.name.contains("server")));
        assert!(m.boxes.iter().any(|b| !b.on_map));
    }
}
