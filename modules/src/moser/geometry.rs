//! Plane geometry for the simulated building: points, wall segments, axis-aligned boxes, and
//! the three queries the sensors and the planner need (ray casting, segment crossing, clearance).
//!
//! Everything is in metres, angles in radians counter-clockwise from +x.

/// Tolerance for "parallel" and "on the line" decisions, in metres (or m² for cross products).
const EPS: f64 = 1e-9;

/// A point (or a vector) in the building's frame, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct P {
    pub x: f64,
    pub y: f64,
}

// Plain methods rather than `std::ops` traits: they read as words in the sensor code and need
// no trait import at the call site.
#[allow(clippy::should_implement_trait)]
impl P {
    pub const fn new(x: f64, y: f64) -> P {
        P { x, y }
    }

    /// Euclidean distance to `o`.
    pub fn dist(self, o: P) -> f64 {
        (o.x - self.x).hypot(o.y - self.y)
    }

    pub fn add(self, o: P) -> P {
        P::new(self.x + o.x, self.y + o.y)
    }

    pub fn sub(self, o: P) -> P {
        P::new(self.x - o.x, self.y - o.y)
    }

    pub fn scale(self, k: f64) -> P {
        P::new(self.x * k, self.y * k)
    }

    /// Bearing from `self` to `o`, radians in (-π, π].
    pub fn angle_to(self, o: P) -> f64 {
        (o.y - self.y).atan2(o.x - self.x)
    }

    fn dot(self, o: P) -> f64 {
        self.x * o.x + self.y * o.y
    }

    fn cross(self, o: P) -> f64 {
        self.x * o.y - self.y * o.x
    }
}

impl std::fmt::Display for P {
    /// `(x, y)` to the centimetre.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "({:.2}, {:.2})", self.x, self.y)
    }
}

/// A line segment: a wall, or a box's edge, or a leg of a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seg {
    pub a: P,
    pub b: P,
}

impl Seg {
    pub const fn new(a: P, b: P) -> Seg {
        Seg { a, b }
    }

    pub fn length(&self) -> f64 {
        self.a.dist(self.b)
    }
}

/// An axis-aligned box, `min` the lower-left and `max` the upper-right corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    pub min: P,
    pub max: P,
}

impl Rect {
    /// The box spanning `(x0, y0)`–`(x1, y1)`; the corners may come in any order.
    pub fn new(x0: f64, y0: f64, x1: f64, y1: f64) -> Rect {
        Rect {
            min: P::new(x0.min(x1), y0.min(y1)),
            max: P::new(x0.max(x1), y0.max(y1)),
        }
    }

    /// Whether `p` lies inside or on the border.
    pub fn contains(&self, p: P) -> bool {
        (self.min.x..=self.max.x).contains(&p.x) && (self.min.y..=self.max.y).contains(&p.y)
    }

    pub fn center(&self) -> P {
        self.min.add(self.max).scale(0.5)
    }

    /// The four sides, counter-clockwise from the bottom one.
    pub fn edges(&self) -> [Seg; 4] {
        let (a, c) = (self.min, self.max);
        let (b, d) = (P::new(c.x, a.y), P::new(a.x, c.y));
        [
            Seg::new(a, b),
            Seg::new(b, c),
            Seg::new(c, d),
            Seg::new(d, a),
        ]
    }

    /// Distance from `p` to the box, 0 inside it.
    pub fn dist(&self, p: P) -> f64 {
        let dx = (self.min.x - p.x).max(p.x - self.max.x).max(0.0);
        let dy = (self.min.y - p.y).max(p.y - self.max.y).max(0.0);
        dx.hypot(dy)
    }
}

/// Distance along the ray from `origin` at `angle_rad` to where it meets `seg`, if it does.
/// A ray running along a segment (parallel) does not hit it.
pub fn ray_seg(origin: P, angle_rad: f64, seg: &Seg) -> Option<f64> {
    let dir = P::new(angle_rad.cos(), angle_rad.sin());
    let s = seg.b.sub(seg.a);
    let denom = dir.cross(s);
    if denom.abs() < EPS {
        return None;
    }
    let w = seg.a.sub(origin);
    let t = w.cross(s) / denom; // along the ray
    let u = w.cross(dir) / denom; // along the segment, 0..=1 when hit
    (t >= 0.0 && (-EPS..=1.0 + EPS).contains(&u)).then_some(t)
}

/// Whether the two segments share a point (crossing, touching or overlapping).
pub fn seg_seg_intersect(a: &Seg, b: &Seg) -> bool {
    let o1 = orient(a.a, a.b, b.a);
    let o2 = orient(a.a, a.b, b.b);
    let o3 = orient(b.a, b.b, a.a);
    let o4 = orient(b.a, b.b, a.b);
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return true;
    }
    (o1 == 0 && on_box(a, b.a))
        || (o2 == 0 && on_box(a, b.b))
        || (o3 == 0 && on_box(b, a.a))
        || (o4 == 0 && on_box(b, a.b))
}

/// Shortest distance from `p` to any point of `s`.
pub fn point_seg_dist(p: P, s: &Seg) -> f64 {
    let d = s.b.sub(s.a);
    let len2 = d.dot(d);
    if len2 < EPS * EPS {
        return p.dist(s.a);
    }
    let t = (p.sub(s.a).dot(d) / len2).clamp(0.0, 1.0);
    p.dist(s.a.add(d.scale(t)))
}

/// The cell of a square lattice holding `p`: cells of side `cell`, cell (0, 0) having its
/// lower-left corner at `origin`; (column, row).
pub fn lattice_cell(origin: P, cell: f64, p: P) -> (i64, i64) {
    let q = p.sub(origin).scale(1.0 / cell);
    (q.x.floor() as i64, q.y.floor() as i64)
}

/// Whether `ok(column, row)` holds for every lattice cell (see [`lattice_cell`]) the segment
/// `a`–`b` passes through, in order from `a`'s cell. Where the segment passes exactly through a
/// lattice corner, both cells beside the corner are asked too. Stops at the first `false`.
pub fn cells_on_segment(
    origin: P,
    cell: f64,
    a: P,
    b: P,
    mut ok: impl FnMut(i64, i64) -> bool,
) -> bool {
    let ((mut c, mut r), (tc, tr)) = (lattice_cell(origin, cell, a), lattice_cell(origin, cell, b));
    let d = b.sub(a);
    let (sc, sr) = (d.x.signum() as i64, d.y.signum() as i64);
    // The ray parameter (0 at a, 1 at b) where it next crosses a column or row boundary.
    let first = |from: f64, origin: f64, i: i64, d: f64| match d {
        0.0 => f64::INFINITY,
        _ => (origin + (i + i64::from(d > 0.0)) as f64 * cell - from) / d,
    };
    let (mut t_c, mut t_r) = (first(a.x, origin.x, c, d.x), first(a.y, origin.y, r, d.y));
    let (dt_c, dt_r) = (cell / d.x.abs(), cell / d.y.abs());
    if !ok(c, r) {
        return false;
    }
    // Each step moves towards b's cell, never past it, so the loop ends.
    while (c, r) != (tc, tr) {
        if c != tc && r != tr && (t_c - t_r).abs() < 1e-9 {
            if !ok(c + sc, r) || !ok(c, r + sr) {
                return false;
            }
            (c, r, t_c, t_r) = (c + sc, r + sr, t_c + dt_c, t_r + dt_r);
        } else if r == tr || (c != tc && t_c < t_r) {
            (c, t_c) = (c + sc, t_c + dt_c);
        } else {
            (r, t_r) = (r + sr, t_r + dt_r);
        }
        if !ok(c, r) {
            return false;
        }
    }
    true
}

/// -1, 0 or 1: `c` lies right of, on, or left of the line `a`→`b`.
fn orient(a: P, b: P, c: P) -> i8 {
    let v = b.sub(a).cross(c.sub(a));
    if v > EPS {
        1
    } else if v < -EPS {
        -1
    } else {
        0
    }
}

/// For a point `p` collinear with `s`: whether it lies within the segment's extent.
fn on_box(s: &Seg, p: P) -> bool {
    p.x >= s.a.x.min(s.b.x) - EPS
        && p.x <= s.a.x.max(s.b.x) + EPS
        && p.y >= s.a.y.min(s.b.y) - EPS
        && p.y <= s.a.y.max(s.b.y) + EPS
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn seg(x0: f64, y0: f64, x1: f64, y1: f64) -> Seg {
        Seg::new(P::new(x0, y0), P::new(x1, y1))
    }

    #[test]
    fn ray_meets_a_wall_ahead_at_its_distance() {
        let sut = ray_seg(P::new(0.0, 0.0), 0.0, &seg(3.0, -1.0, 3.0, 1.0));
        assert!((sut.unwrap() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn ray_misses_walls_behind_beside_and_parallel() {
        let o = P::new(0.0, 0.0);
        assert_eq!(ray_seg(o, PI, &seg(3.0, -1.0, 3.0, 1.0)), None);
        assert_eq!(ray_seg(o, 0.0, &seg(3.0, 0.5, 3.0, 1.0)), None);
        assert_eq!(ray_seg(o, 0.0, &seg(1.0, 0.0, 2.0, 0.0)), None);
        let diagonal = ray_seg(o, FRAC_PI_2 / 2.0, &seg(2.0, 0.0, 2.0, 5.0)).unwrap();
        assert!((diagonal - 2.0 * 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn segments_that_cross_or_touch_intersect_and_disjoint_ones_do_not() {
        let sut = seg(0.0, 0.0, 2.0, 2.0);
        assert!(seg_seg_intersect(&sut, &seg(0.0, 2.0, 2.0, 0.0)));
        assert!(seg_seg_intersect(&sut, &seg(2.0, 2.0, 3.0, 0.0)));
        assert!(seg_seg_intersect(&sut, &seg(1.0, 1.0, 5.0, 5.0)));
        assert!(!seg_seg_intersect(&sut, &seg(3.0, 3.0, 5.0, 5.0)));
        assert!(!seg_seg_intersect(&sut, &seg(1.0, 0.0, 3.0, 0.5)));
    }

    #[test]
    fn point_to_segment_distance_uses_the_nearest_end_or_the_foot() {
        let sut = seg(0.0, 0.0, 4.0, 0.0);
        assert!((point_seg_dist(P::new(2.0, 1.5), &sut) - 1.5).abs() < 1e-12);
        assert!((point_seg_dist(P::new(7.0, 4.0), &sut) - 5.0).abs() < 1e-12);
        assert!((point_seg_dist(P::new(1.0, 1.0), &seg(1.0, 1.0, 1.0, 1.0))).abs() < 1e-12);
    }

    #[test]
    fn rect_knows_its_inside_centre_edges_and_distance() {
        let sut = Rect::new(2.0, 1.0, 0.0, 0.0);
        assert!(sut.contains(P::new(1.0, 0.5)) && sut.contains(P::new(2.0, 1.0)));
        assert!(!sut.contains(P::new(2.1, 0.5)));
        assert_eq!(sut.center(), P::new(1.0, 0.5));
        let perimeter: f64 = sut.edges().iter().map(Seg::length).sum();
        assert!((perimeter - 6.0).abs() < 1e-12);
        assert_eq!(sut.dist(P::new(1.0, 0.5)), 0.0);
        assert!((sut.dist(P::new(5.0, 5.0)) - 5.0).abs() < 1e-12);
    }

    #[test]
    fn segment_visits_every_lattice_cell_it_crosses_and_both_cells_at_a_corner() {
        let cells = |a: P, b: P| {
            let mut seen = vec![];
            assert!(cells_on_segment(P::new(0.0, 0.0), 1.0, a, b, |c, r| {
                seen.push((c, r));
                true
            }));
            seen
        };
        let sut = cells(P::new(0.5, 0.5), P::new(3.5, 0.5));
        assert_eq!(sut, [(0, 0), (1, 0), (2, 0), (3, 0)]);
        let sut = cells(P::new(0.5, 0.5), P::new(1.5, 1.5));
        assert_eq!(sut, [(0, 0), (1, 0), (0, 1), (1, 1)]);
        let sut = cells(P::new(0.5, 0.2), P::new(2.5, 0.9));
        assert_eq!(sut, [(0, 0), (1, 0), (2, 0)]);
        let sut = cells(P::new(0.9, 0.1), P::new(0.1, 2.9));
        assert_eq!(sut.first(), Some(&(0, 0)));
        assert_eq!(sut.last(), Some(&(0, 2)));
        assert!(!cells_on_segment(
            P::new(0.0, 0.0),
            1.0,
            P::new(0.5, 0.5),
            P::new(5.5, 0.5),
            |c, _| c < 3
        ));
    }

    #[test]
    fn point_arithmetic_and_bearing() {
        let sut = P::new(1.0, 2.0);
        assert_eq!(
            sut.add(P::new(1.0, 1.0)).sub(P::new(0.0, 1.0)).scale(2.0),
            P::new(4.0, 4.0)
        );
        assert!((sut.angle_to(P::new(1.0, 5.0)) - FRAC_PI_2).abs() < 1e-12);
        assert!((sut.dist(P::new(4.0, 6.0)) - 5.0).abs() < 1e-12);
    }
}
