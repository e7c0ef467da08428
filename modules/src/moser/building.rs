//! The simulated office building MOSER patrols, and what a sensor or a wheel can ask of it.
//!
//! ```text
//!  y=20 +---------+---------+-------------------+---------+---------+
//!       | office  | office  |        lab        | store-  | office  |
//!       |   1A    |   1B    |                   |  room   |   3A    |
//!  y=12 +---] [---+---] [---+-------] [---------+---] [---+---] [---+
//!       | S->  lobby / corridor                                    | fire door
//!  y=8  +-------] [----------+---] [---+---] [---+--------] [-------+ (closed)
//!       |  conference room   | off. 2A | off. 2B |    server room    |
//!       |                    |         |         |       [box]       |
//!  y=0  +--------------------+---------+---------+-------------------+
//!      x=0        5         10  12.5  15  17.5  20        25        30
//!       |<------ wing 1 ---->|<----- wing 2 ---->|<---- wing 3 ----->|
//! ```
//!
//! Every door is a 1.4 m gap in the corridor wall, centred on its room. `S` is the start, in the
//! lobby at the corridor's west end, heading +x. `[box]` is the delivery box nobody put on the
//! map, right inside the server room's door.

use super::geometry::{point_seg_dist, ray_seg, seg_seg_intersect, Rect, Seg, P};

/// Width of every door gap, metres; the robot is 0.6 m across.
pub const DOOR_WIDTH: f64 = 1.4;

/// A box that stops the robot: furniture, a cabinet, a box someone left.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    pub rect: Rect,
    /// Whether the building map knows it. The planner's map holds only these; the others are
    /// found by the sonars when the robot gets close.
    pub on_map: bool,
    pub name: &'static str,
}

/// A room off the corridor, in the wing it belongs to.
#[derive(Debug, Clone, PartialEq)]
pub struct Room {
    pub name: &'static str,
    /// The wing a guard names in "patrol wing N".
    pub wing: u8,
    pub rect: Rect,
    /// A free spot inside, where the robot stops and looks around.
    pub patrol_point: P,
    /// The gap in the corridor wall, jamb to jamb: the only way in.
    pub door: Seg,
}

/// Walls, rooms and furniture of the building; the same for every module process.
#[derive(Debug, Clone, PartialEq)]
pub struct Building {
    /// Wall segments; the outer walls are closed.
    pub walls: Vec<Seg>,
    /// Rooms in patrol order: by wing, and in each wing in the order the robot visits them.
    pub rooms: Vec<Room>,
    pub obstacles: Vec<Obstacle>,
    /// Where the robot stands at t = 0: in the lobby.
    pub start: P,
    pub start_heading_deg: f64,
    /// The outer walls' box.
    pub bounds: Rect,
    /// The central corridor every door opens on; a patrol ends back in it.
    pub corridor: Rect,
}

/// The fixed building of the MOSER demo: 30 m × 20 m, a corridor along x, three wings.
pub fn moser_building() -> Building {
    let bounds = Rect::new(0.0, 0.0, 30.0, 20.0);
    let corridor = Rect::new(0.0, 8.0, 30.0, 12.0);
    #[rustfmt::skip]
    let table: [(&str, u8, Rect, P); 9] = [
        ("office 1A", 1, Rect::new(0.0, 12.0, 5.0, 20.0), P::new(2.5, 15.5)),
        ("office 1B", 1, Rect::new(5.0, 12.0, 10.0, 20.0), P::new(7.5, 15.5)),
        ("conference room", 1, Rect::new(0.0, 0.0, 10.0, 8.0), P::new(5.0, 6.0)),
        ("lab", 2, Rect::new(10.0, 12.0, 20.0, 20.0), P::new(15.0, 16.0)),
        ("office 2A", 2, Rect::new(10.0, 0.0, 15.0, 8.0), P::new(12.5, 4.0)),
        ("office 2B", 2, Rect::new(15.0, 0.0, 20.0, 8.0), P::new(17.5, 4.0)),
        ("storeroom", 3, Rect::new(20.0, 12.0, 25.0, 20.0), P::new(22.5, 15.5)),
        ("office 3A", 3, Rect::new(25.0, 12.0, 30.0, 20.0), P::new(27.5, 15.5)),
        ("server room", 3, Rect::new(20.0, 0.0, 30.0, 8.0), P::new(25.0, 3.5)),
    ];
    let rooms: Vec<Room> = table
        .into_iter()
        .map(|(name, wing, rect, patrol_point)| {
            // The door is in whichever of the room's walls is a corridor wall.
            let y = if rect.min.y >= corridor.max.y {
                rect.min.y
            } else {
                rect.max.y
            };
            let x = rect.center().x;
            let half = DOOR_WIDTH / 2.0;
            let door = Seg::new(P::new(x - half, y), P::new(x + half, y));
            Room {
                name,
                wing,
                rect,
                patrol_point,
                door,
            }
        })
        .collect();

    let mut walls: Vec<Seg> = bounds.edges().to_vec();
    for y in [corridor.min.y, corridor.max.y] {
        let doors: Vec<&Seg> = rooms
            .iter()
            .map(|r| &r.door)
            .filter(|d| d.a.y == y)
            .collect();
        walls.extend(wall_with_doors(y, bounds.min.x, bounds.max.x, &doors));
    }
    for x in [5.0, 10.0, 20.0, 25.0] {
        walls.push(Seg::new(P::new(x, corridor.max.y), P::new(x, bounds.max.y)));
    }
    for x in [10.0, 15.0, 20.0] {
        walls.push(Seg::new(P::new(x, bounds.min.y), P::new(x, corridor.min.y)));
    }

    #[rustfmt::skip]
    let obstacles = [
        ("desk 1A", Rect::new(0.5, 17.5, 2.5, 19.0), true),
        ("desk 1B", Rect::new(7.5, 17.5, 9.5, 19.0), true),
        ("conference table", Rect::new(3.0, 2.5, 7.0, 4.5), true),
        ("lab bench", Rect::new(11.0, 18.8, 19.0, 19.6), true),
        ("lab cabinet", Rect::new(19.2, 13.0, 19.8, 14.5), true),
        ("desk 2A", Rect::new(10.5, 0.5, 12.0, 2.5), true),
        ("desk 2B", Rect::new(18.0, 0.5, 19.5, 2.5), true),
        ("shelves", Rect::new(20.2, 18.8, 24.8, 19.8), true),
        ("filing cabinet", Rect::new(20.2, 13.0, 20.8, 15.0), true),
        ("desk 3A", Rect::new(27.5, 17.5, 29.5, 19.0), true),
        ("server racks", Rect::new(20.3, 1.0, 21.3, 6.0), true),
        // Left inside the server room's door this morning: not on any map.
        ("delivery box", Rect::new(24.5, 5.4, 25.5, 6.2), false),
    ]
    .into_iter()
    .map(|(name, rect, on_map)| Obstacle { rect, on_map, name })
    .collect();

    Building {
        walls,
        rooms,
        obstacles,
        start: P::new(2.0, 10.0),
        start_heading_deg: 0.0,
        bounds,
        corridor,
    }
}

/// A horizontal wall at `y` from `x0` to `x1`, broken by the (horizontal) `doors` on it.
fn wall_with_doors(y: f64, x0: f64, x1: f64, doors: &[&Seg]) -> Vec<Seg> {
    let mut gaps: Vec<(f64, f64)> = doors
        .iter()
        .map(|d| (d.a.x.min(d.b.x), d.a.x.max(d.b.x)))
        .collect();
    gaps.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut walls = Vec::new();
    let mut x = x0;
    for (g0, g1) in gaps {
        walls.push(Seg::new(P::new(x, y), P::new(g0, y)));
        x = g1;
    }
    walls.push(Seg::new(P::new(x, y), P::new(x1, y)));
    walls
}

impl Building {
    /// Range from `origin` along `angle_rad` to the nearest wall or obstacle (on the map or
    /// not), capped at `max_range`: what a sonar or a range sensor measures.
    pub fn ray(&self, origin: P, angle_rad: f64, max_range: f64) -> f64 {
        let obstacle_edges = self.obstacles.iter().flat_map(|o| o.rect.edges());
        self.walls
            .iter()
            .copied()
            .chain(obstacle_edges)
            .filter_map(|s| ray_seg(origin, angle_rad, &s))
            .fold(max_range, f64::min)
    }

    /// Whether a disc at `center` touches a wall or any obstacle.
    pub fn collides(&self, center: P, radius: f64) -> bool {
        self.walls
            .iter()
            .any(|w| point_seg_dist(center, w) <= radius)
            || self.obstacles.iter().any(|o| o.rect.dist(center) <= radius)
    }

    /// Whether no wall stands between `a` and `b`. Obstacles are low: they do not block sight.
    pub fn line_of_sight(&self, a: P, b: P) -> bool {
        let sight = Seg::new(a, b);
        !self.walls.iter().any(|w| seg_seg_intersect(&sight, w))
    }

    /// The room `p` is in; `None` in the corridor (or outside).
    pub fn room_at(&self, p: P) -> Option<&Room> {
        self.rooms.iter().find(|r| r.rect.contains(p))
    }

    /// The rooms of `wing`, in patrol order; empty for a wing that does not exist.
    pub fn wing_rooms(&self, wing: u8) -> Vec<&Room> {
        self.rooms.iter().filter(|r| r.wing == wing).collect()
    }

    /// The wings that exist, ascending.
    pub fn wings(&self) -> Vec<u8> {
        let mut wings: Vec<u8> = self.rooms.iter().map(|r| r.wing).collect();
        wings.sort_unstable();
        wings.dedup();
        wings
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn ray_hits_the_corridor_walls_at_their_distance() {
        let sut = moser_building();
        assert!(close(sut.ray(sut.start, -FRAC_PI_2, 50.0), 2.0));
        assert!(close(sut.ray(sut.start, PI, 50.0), 2.0));
        assert!(
            close(sut.ray(sut.start, 0.0, 50.0), 28.0),
            "down the corridor to the east wall"
        );
    }

    #[test]
    fn ray_passes_through_a_door_gap_to_what_is_behind_it() {
        let sut = moser_building();
        // Up through the lab door (x 14.3..15.7 at y 12) to the lab bench's front at y 18.8.
        assert!(close(sut.ray(P::new(15.0, 10.0), FRAC_PI_2, 50.0), 8.8));
        // Just beside the gap the wall stops it.
        assert!(close(sut.ray(P::new(14.0, 10.0), FRAC_PI_2, 50.0), 2.0));
    }

    #[test]
    fn ray_is_capped_at_max_range() {
        let sut = moser_building();
        assert_eq!(sut.ray(sut.start, 0.0, 10.0), 10.0);
    }

    #[test]
    fn ray_sees_off_map_obstacles_too() {
        let sut = moser_building();
        // Straight down through the server room door onto the delivery box's top at y 6.2.
        assert!(close(sut.ray(P::new(25.0, 10.0), -FRAC_PI_2, 50.0), 3.8));
    }

    #[test]
    fn walls_are_closed_no_ray_leaves_the_building() {
        let sut = moser_building();
        let inside = [
            sut.start,
            P::new(29.5, 10.0),
            P::new(15.0, 16.0),
            P::new(25.0, 3.5),
        ];
        for origin in inside
            .into_iter()
            .chain(sut.rooms.iter().map(|r| r.patrol_point))
        {
            for i in 0..720 {
                let angle = i as f64 * PI / 360.0 + 1e-4;
                let range = sut.ray(origin, angle, 1000.0);
                assert!(range < 1000.0, "ray from {origin:?} at {angle} escaped");
                let hit = origin.add(P::new(angle.cos(), angle.sin()).scale(range));
                assert!(
                    sut.bounds.dist(hit) < 1e-6,
                    "ray from {origin:?} hit {hit:?} outside"
                );
            }
        }
    }

    #[test]
    fn collides_when_the_disc_touches_a_wall_or_an_obstacle() {
        let sut = moser_building();
        assert!(!sut.collides(sut.start, 0.3));
        assert!(sut.collides(P::new(2.0, 8.25), 0.3), "corridor wall");
        assert!(
            !sut.collides(P::new(5.0, 8.0), 0.3),
            "standing in the conference room door"
        );
        assert!(
            sut.collides(P::new(25.0, 6.45), 0.3),
            "the off-map box counts"
        );
        assert!(
            sut.collides(P::new(5.0, 4.0), 0.1),
            "inside the conference table"
        );
    }

    #[test]
    fn line_of_sight_is_blocked_by_walls_but_not_by_obstacles() {
        let sut = moser_building();
        assert!(sut.line_of_sight(sut.start, P::new(29.0, 10.0)));
        assert!(
            !sut.line_of_sight(sut.start, P::new(12.5, 4.0)),
            "office 2A is behind a wall"
        );
        assert!(
            sut.line_of_sight(P::new(25.0, 10.0), P::new(25.0, 3.5)),
            "over the box"
        );
        assert!(
            sut.line_of_sight(P::new(5.0, 10.0), P::new(5.0, 4.0)),
            "over the table"
        );
    }

    #[test]
    fn every_room_has_a_wide_door_and_a_free_patrol_point_seen_from_the_corridor() {
        let sut = moser_building();
        for room in &sut.rooms {
            assert!(room.door.length() >= 1.2, "{}", room.name);
            assert!(room.rect.contains(room.patrol_point), "{}", room.name);
            assert!(
                !sut.collides(room.patrol_point, 0.6),
                "{} patrol point",
                room.name
            );
            let mid = room.door.a.add(room.door.b).scale(0.5);
            let in_corridor = P::new(mid.x, sut.corridor.center().y);
            assert!(
                sut.line_of_sight(in_corridor, room.patrol_point),
                "{}",
                room.name
            );
            assert_eq!(
                sut.room_at(room.patrol_point).map(|r| r.name),
                Some(room.name)
            );
        }
    }

    #[test]
    fn building_has_three_wings_with_rooms_in_patrol_order_and_one_off_map_box() {
        let sut = moser_building();
        assert_eq!(sut.wings(), vec![1, 2, 3]);
        let wing3: Vec<&str> = sut.wing_rooms(3).iter().map(|r| r.name).collect();
        assert_eq!(wing3, ["storeroom", "office 3A", "server room"]);
        assert!(sut.wing_rooms(4).is_empty());
        assert_eq!(sut.room_at(sut.start), None, "the lobby is corridor");
        let off_map: Vec<&Obstacle> = sut.obstacles.iter().filter(|o| !o.on_map).collect();
        assert_eq!(off_map.len(), 1);
        assert_eq!(
            sut.room_at(off_map[0].rect.center()).map(|r| r.wing),
            Some(3)
        );
    }
}
