//! Grid path planning for the high-level module: an occupancy grid of the building *as the map
//! knows it*, A* over it, and the goal sequence of "patrol wing N".
//!
//! A cell is free only if a robot centred anywhere in it keeps its radius plus a margin from
//! every wall and mapped obstacle: the inflation includes half a cell's diagonal. So a straight
//! leg through free cells is a collision-free leg, and smoothing may join any two waypoints
//! whose segment crosses only free cells.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::f64::consts::FRAC_1_SQRT_2;
use std::fmt;

use super::building::Building;
use super::geometry::{cells_on_segment, lattice_cell, point_seg_dist, Rect, P};

/// Clearance kept beyond the robot's radius, metres.
pub const MARGIN: f64 = 0.05;

const FREE: u8 = 0;
/// Too close to something for the robot's centre, but nothing is in the cell itself.
const INFLATED: u8 = 1;
/// A wall or an obstacle is in (or touches) the cell.
const OCCUPIED: u8 = 2;
/// Step costs of A*, in thousandths of a cell: straight, diagonal.
const STRAIGHT: u32 = 1000;
const DIAGONAL: u32 = 1414;
/// The 8 neighbours of a cell, as (column, row) steps.
#[rustfmt::skip]
const STEPS: [(i64, i64); 8] = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)];

/// Why no plan came out. Points are the ones the caller passed.
#[derive(Debug, Clone, PartialEq)]
pub enum PlanError {
    /// The start is in or on a wall or obstacle, or off the map.
    StartBlocked { at: P },
    /// The goal is too close to a wall or obstacle for the robot, or off the map.
    GoalBlocked { at: P },
    /// Start and goal are free but no free path joins them.
    NoPath { from: P, to: P },
    /// "Patrol wing N" for a wing the building does not have.
    UnknownWing { wing: u8, wings: Vec<u8> },
}

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlanError::StartBlocked { at } => write!(f, "start {at} is blocked or off the map"),
            PlanError::GoalBlocked { at } => {
                write!(
                    f,
                    "goal {at} is too close to a wall or obstacle, or off the map"
                )
            }
            PlanError::NoPath { from, to } => write!(f, "no free path from {from} to {to}"),
            PlanError::UnknownWing { wing, wings } => {
                let names: Vec<String> = wings.iter().map(u8::to_string).collect();
                write!(
                    f,
                    "unknown wing {wing}; the building has wings {}",
                    names.join(", ")
                )
            }
        }
    }
}

impl std::error::Error for PlanError {}

/// An occupancy grid over the building's bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Lower-left corner of cell (0, 0).
    origin: P,
    /// Cell side, metres.
    cell: f64,
    cols: usize,
    rows: usize,
    /// FREE, INFLATED or OCCUPIED, row-major.
    cells: Vec<u8>,
    /// How far a cell centre must be from anything to be free: radius + margin + half diagonal.
    inflate: f64,
}

impl Grid {
    /// The grid of what the map knows: walls and on-map obstacles, inflated for a robot of
    /// `robot_radius`. Off-map obstacles are left out; [`Grid::mark_blocked`] adds them.
    pub fn from_building(b: &Building, cell: f64, robot_radius: f64) -> Grid {
        let cols = ((b.bounds.max.x - b.bounds.min.x) / cell).ceil() as usize;
        let rows = ((b.bounds.max.y - b.bounds.min.y) / cell).ceil() as usize;
        let mut grid = Grid {
            origin: b.bounds.min,
            cell,
            cols,
            rows,
            cells: vec![FREE; cols * rows],
            inflate: robot_radius + MARGIN + cell * FRAC_1_SQRT_2,
        };
        for w in &b.walls {
            let extent = Rect::new(w.a.x, w.a.y, w.b.x, w.b.y);
            grid.mark(extent.min, extent.max, |p| point_seg_dist(p, w));
        }
        for o in b.obstacles.iter().filter(|o| o.on_map) {
            grid.mark(o.rect.min, o.rect.max, |p| o.rect.dist(p));
        }
        grid
    }

    /// Marks a round obstacle of `radius` at `center` (one the sonars found), inflated like the
    /// rest.
    pub fn mark_blocked(&mut self, center: P, radius: f64) {
        let r = P::new(radius, radius);
        self.mark(center.sub(r), center.add(r), |p| {
            (p.dist(center) - radius).max(0.0)
        });
    }

    /// Whether a robot centred at `p` is clear of everything the grid knows.
    /// The cells (FREE, INFLATED or OCCUPIED, row-major).
    pub fn cells(&self) -> &[u8] {
        &self.cells
    }

    /// This grid with `cells` instead (from [`Grid::cells`] of a grid of the same building);
    /// refused if their number or a value does not fit.
    pub fn with_cells(&self, cells: Vec<u8>) -> Result<Grid, String> {
        if cells.len() != self.cells.len() {
            return Err(format!(
                "a grid of {} cells; this building's has {}",
                cells.len(),
                self.cells.len()
            ));
        }
        if let Some(v) = cells
            .iter()
            .find(|&&c| ![FREE, INFLATED, OCCUPIED].contains(&c))
        {
            return Err(format!("a grid cell holds {v}"));
        }
        Ok(Grid {
            cells,
            ..self.clone()
        })
    }

    pub fn is_free(&self, p: P) -> bool {
        self.cell_of(p).is_some_and(|c| self.cells[c] == FREE)
    }

    /// Marks every cell whose centre is near the shape in the box `lo`..`hi`; `dist` gives a
    /// point's distance to the shape.
    fn mark(&mut self, lo: P, hi: P, dist: impl Fn(P) -> f64) {
        let pad = P::new(self.inflate + self.cell, self.inflate + self.cell);
        let (c0, r0) = self.clamped_cell(lo.sub(pad));
        let (c1, r1) = self.clamped_cell(hi.add(pad));
        let half_diag = self.cell * FRAC_1_SQRT_2;
        for r in r0..=r1 {
            for c in c0..=c1 {
                let i = r * self.cols + c;
                let d = dist(self.center(i));
                if d <= half_diag {
                    self.cells[i] = OCCUPIED;
                } else if d <= self.inflate {
                    self.cells[i] = self.cells[i].max(INFLATED);
                }
            }
        }
    }

    fn clamped_cell(&self, p: P) -> (usize, usize) {
        let c = ((p.x - self.origin.x) / self.cell)
            .floor()
            .clamp(0.0, (self.cols - 1) as f64);
        let r = ((p.y - self.origin.y) / self.cell)
            .floor()
            .clamp(0.0, (self.rows - 1) as f64);
        (c as usize, r as usize)
    }

    /// The index of the cell holding `p`, if `p` is on the grid.
    fn cell_of(&self, p: P) -> Option<usize> {
        let (c, r) = self.coords(p);
        self.index(c, r)
    }

    fn coords(&self, p: P) -> (i64, i64) {
        lattice_cell(self.origin, self.cell, p)
    }

    fn index(&self, c: i64, r: i64) -> Option<usize> {
        let inside = (0..self.cols as i64).contains(&c) && (0..self.rows as i64).contains(&r);
        inside.then(|| r as usize * self.cols + c as usize)
    }

    fn free_at(&self, c: i64, r: i64) -> bool {
        self.index(c, r).is_some_and(|i| self.cells[i] == FREE)
    }

    /// The centre of the cell with index `i`.
    fn center(&self, i: usize) -> P {
        let (c, r) = ((i % self.cols) as f64 + 0.5, (i / self.cols) as f64 + 0.5);
        self.origin.add(P::new(c, r).scale(self.cell))
    }

    /// Whether the segment `a`–`b` crosses no occupied cell (inflated ones are fine).
    fn reachable(&self, a: P, b: P) -> bool {
        let not_occupied = |c, r| self.index(c, r).is_some_and(|i| self.cells[i] != OCCUPIED);
        cells_on_segment(self.origin, self.cell, a, b, not_occupied)
    }

    /// Whether every cell the segment `a`–`b` passes through is free.
    fn segment_free(&self, a: P, b: P) -> bool {
        cells_on_segment(self.origin, self.cell, a, b, |c, r| self.free_at(c, r))
    }

    /// The free cell nearest `p` within `limit` metres that a straight move from `p` reaches
    /// without crossing an occupied cell, if any.
    fn nearest_free(&self, p: P, limit: f64) -> Option<usize> {
        let (c0, r0) = self.coords(p);
        let n = (limit / self.cell).ceil() as i64 + 1;
        let mut best: Option<(f64, usize)> = None;
        for r in r0 - n..=r0 + n {
            for c in c0 - n..=c0 + n {
                let Some(i) = self.index(c, r).filter(|&i| self.cells[i] == FREE) else {
                    continue;
                };
                let d = self.center(i).dist(p);
                let closer = d <= limit && best.is_none_or(|(bd, _)| d < bd);
                if closer && self.reachable(p, self.center(i)) {
                    best = Some((d, i));
                }
            }
        }
        best.map(|(_, i)| i)
    }
}

/// A path from `from` to `to`: the waypoints after `from`, ending exactly at `to`, each leg
/// straight through free cells. A start squeezed into the inflation near a wall is first moved
/// to the nearest free cell, which becomes the first waypoint.
pub fn plan(grid: &Grid, from: P, to: P) -> Result<Vec<P>, PlanError> {
    let goal = grid
        .cell_of(to)
        .filter(|&i| grid.cells[i] == FREE)
        .ok_or(PlanError::GoalBlocked { at: to })?;
    let (start, start_pt, mut out) = match grid.cell_of(from).map(|i| (i, grid.cells[i])) {
        Some((i, FREE)) => (i, from, vec![]),
        Some((_, INFLATED)) => {
            let i = grid
                .nearest_free(from, 2.0 * grid.inflate)
                .ok_or(PlanError::StartBlocked { at: from })?;
            let p = grid.center(i);
            (i, p, vec![p])
        }
        _ => return Err(PlanError::StartBlocked { at: from }),
    };
    let cells = astar(grid, start, goal).ok_or(PlanError::NoPath { from, to })?;
    let mut pts = vec![start_pt];
    let inner = cells.iter().skip(1).take(cells.len().saturating_sub(2));
    pts.extend(inner.map(|&i| grid.center(i)));
    pts.push(to);
    // Line-of-sight smoothing: from each waypoint, jump to the farthest point of the cell path
    // it sees (a neighbour always qualifies).
    let mut anchor = 0;
    while anchor + 1 < pts.len() {
        let mut far = (anchor + 2..pts.len()).rev();
        let seen = far.find(|&j| grid.segment_free(pts[anchor], pts[j]));
        let j = seen.unwrap_or(anchor + 1);
        out.push(pts[j]);
        anchor = j;
    }
    Ok(out)
}

/// A* over the 8-connected grid with the octile heuristic; diagonal steps may not cut corners.
/// Costs are integers, so the open list needs no float ordering and ties break on the cell
/// index: the same query always gives the same path. Returns the cells from `start` to `goal`.
fn astar(grid: &Grid, start: usize, goal: usize) -> Option<Vec<usize>> {
    let xy = |i: usize| ((i % grid.cols) as i64, (i / grid.cols) as i64);
    let (gc, gr) = xy(goal);
    let h = |c: i64, r: i64| {
        let (dx, dy) = (
            (c - gc).unsigned_abs() as u32,
            (r - gr).unsigned_abs() as u32,
        );
        STRAIGHT * dx.max(dy) + (DIAGONAL - STRAIGHT) * dx.min(dy)
    };
    let mut g = vec![u32::MAX; grid.cells.len()];
    let mut parent = vec![usize::MAX; grid.cells.len()];
    let mut open = BinaryHeap::new();
    g[start] = 0;
    let (sc, sr) = xy(start);
    open.push(Reverse((h(sc, sr), start)));
    while let Some(Reverse((f, cell))) = open.pop() {
        let (c, r) = xy(cell);
        if cell == goal {
            let mut path = vec![goal];
            while let Some(&last) = path.last().filter(|&&i| i != start) {
                path.push(parent[last]);
            }
            path.reverse();
            return Some(path);
        }
        if f > g[cell] + h(c, r) {
            continue; // a stale entry: the cell was reached more cheaply since
        }
        for (dc, dr) in STEPS {
            let (nc, nr) = (c + dc, r + dr);
            let diagonal = dc != 0 && dr != 0;
            let corner_free = !diagonal || (grid.free_at(c + dc, r) && grid.free_at(c, r + dr));
            if !grid.free_at(nc, nr) || !corner_free {
                continue;
            }
            let next = nr as usize * grid.cols + nc as usize;
            let cost = g[cell] + if diagonal { DIAGONAL } else { STRAIGHT };
            if cost < g[next] {
                g[next] = cost;
                parent[next] = cell;
                open.push(Reverse((cost + h(nc, nr), next)));
            }
        }
    }
    None
}

/// The goals of "patrol wing `wing`": each of its rooms' patrol points in patrol order, then
/// back to the corridor in front of the wing.
pub fn patrol_route(b: &Building, wing: u8) -> Result<Vec<P>, PlanError> {
    let rooms = b.wing_rooms(wing);
    if rooms.is_empty() {
        return Err(PlanError::UnknownWing {
            wing,
            wings: b.wings(),
        });
    }
    let x = rooms.iter().map(|r| r.rect.center().x).sum::<f64>() / rooms.len() as f64;
    let mut goals: Vec<P> = rooms.iter().map(|r| r.patrol_point).collect();
    goals.push(P::new(x, b.corridor.center().y));
    Ok(goals)
}

#[cfg(test)]
mod tests {
    use super::super::building::{moser_building, Building};
    use super::*;

    const RADIUS: f64 = 0.3;
    /// Cell sizes the guarantees must hold for: a fine one and the high-level module's 0.2 m.
    const CELLS: [f64; 2] = [0.1, 0.2];

    /// Points every 5 cm along the legs from `from` through `path`.
    fn samples(from: P, path: &[P]) -> Vec<P> {
        let mut prev = from;
        let mut out = vec![from];
        for &p in path {
            let n = (prev.dist(p) / 0.05).ceil().max(1.0) as usize;
            out.extend((1..=n).map(|i| prev.add(p.sub(prev).scale(i as f64 / n as f64))));
            prev = p;
        }
        out
    }

    /// Plans every leg of "patrol wing `wing`" from the start; returns the sampled route.
    fn patrol(grid: &Grid, b: &Building, wing: u8) -> Vec<P> {
        let mut at = b.start;
        let mut route = vec![];
        for goal in patrol_route(b, wing).unwrap() {
            route.extend(samples(at, &plan(grid, at, goal).unwrap()));
            at = goal;
        }
        route
    }

    #[test]
    fn every_patrol_point_is_free_and_reached_from_the_start_without_collision() {
        let b = moser_building();
        let mut mapped = b.clone();
        mapped.obstacles.retain(|o| o.on_map);
        for cell in CELLS {
            let sut = Grid::from_building(&b, cell, RADIUS);
            for room in &b.rooms {
                assert!(sut.is_free(room.patrol_point), "{}", room.name);
                let path = plan(&sut, b.start, room.patrol_point).unwrap();
                assert_eq!(path.last(), Some(&room.patrol_point));
                assert_ne!(path.first(), Some(&b.start));
                for p in samples(b.start, &path) {
                    assert!(
                        !mapped.collides(p, RADIUS),
                        "{}: touches at {p:?}",
                        room.name
                    );
                }
            }
        }
    }

    #[test]
    fn a_straight_free_stretch_is_one_waypoint() {
        let b = moser_building();
        let sut = Grid::from_building(&b, 0.1, RADIUS);
        let goal = P::new(20.0, 10.0);
        assert_eq!(plan(&sut, b.start, goal), Ok(vec![goal]));
        let into_lab = plan(&sut, b.start, P::new(15.0, 16.0)).unwrap();
        assert!(into_lab.len() <= 3, "too many waypoints: {into_lab:?}");
    }

    #[test]
    fn unmapped_box_is_on_the_wing_3_route_until_it_is_marked_then_planned_around() {
        let b = moser_building();
        let the_box = b.obstacles.iter().find(|o| !o.on_map).unwrap();
        for cell in CELLS {
            let mut sut = Grid::from_building(&b, cell, RADIUS);
            let blind = patrol(&sut, &b, 3);
            let near = blind.iter().any(|&p| the_box.rect.dist(p) <= RADIUS);
            assert!(near, "the wing 3 route never comes near the box");
            let half_diagonal = the_box.rect.center().dist(the_box.rect.max);
            sut.mark_blocked(the_box.rect.center(), half_diagonal);
            for p in patrol(&sut, &b, 3) {
                assert!(!b.collides(p, RADIUS), "route touches something at {p:?}");
            }
        }
    }

    #[test]
    fn a_start_squeezed_against_a_wall_first_steps_out_to_a_free_cell() {
        let b = moser_building();
        let (squeezed, goal) = (P::new(6.0, 8.32), P::new(20.0, 10.0));
        assert!(!b.collides(squeezed, RADIUS));
        for cell in CELLS {
            let sut = Grid::from_building(&b, cell, RADIUS);
            assert!(!sut.is_free(squeezed));
            let path = plan(&sut, squeezed, goal).unwrap();
            assert!(
                sut.is_free(path[0]) && path[0].dist(squeezed) < 0.5,
                "{path:?}"
            );
            assert_eq!(path.last(), Some(&goal));
        }
    }

    #[test]
    fn blocked_start_or_goal_and_walled_off_goal_are_errors() {
        let b = moser_building();
        let mut sut = Grid::from_building(&b, 0.1, RADIUS);
        let (wall, outside, server) = (P::new(4.0, 12.0), P::new(-5.0, 10.0), P::new(25.0, 3.5));
        assert_eq!(
            plan(&sut, b.start, wall),
            Err(PlanError::GoalBlocked { at: wall })
        );
        assert_eq!(
            plan(&sut, wall, b.start),
            Err(PlanError::StartBlocked { at: wall })
        );
        assert_eq!(
            plan(&sut, outside, b.start),
            Err(PlanError::StartBlocked { at: outside })
        );
        sut.mark_blocked(P::new(25.0, 8.0), 0.8); // the server room's door
        let no_path = PlanError::NoPath {
            from: b.start,
            to: server,
        };
        assert_eq!(plan(&sut, b.start, server), Err(no_path));
        let msg = PlanError::GoalBlocked { at: wall }.to_string();
        assert!(msg.contains("(4.00, 12.00)"), "{msg}");
    }

    #[test]
    fn patrol_route_visits_the_wing_rooms_in_order_then_returns_to_the_corridor() {
        let b = moser_building();
        let sut = patrol_route(&b, 3).unwrap();
        let rooms = [(22.5, 15.5), (27.5, 15.5), (25.0, 3.5), (25.0, 10.0)];
        assert_eq!(sut, rooms.map(|(x, y)| P::new(x, y)));
        assert_eq!(b.room_at(sut[3]), None, "ends in the corridor");
    }

    #[test]
    fn unknown_wing_is_an_error_naming_the_wings_that_exist() {
        let b = moser_building();
        let sut = patrol_route(&b, 7).unwrap_err();
        assert_eq!(
            sut,
            PlanError::UnknownWing {
                wing: 7,
                wings: vec![1, 2, 3]
            }
        );
        assert_eq!(
            sut.to_string(),
            "unknown wing 7; the building has wings 1, 2, 3"
        );
    }
}
