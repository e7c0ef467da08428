//! MOSER's simulated world: the office building the mobile security robot patrols, the
//! intruder it must find, and the planner that takes it from room to room.
//!
//! Every MOSER module is its own process and computes what its virtual devices sense from
//! this library: the sonar casts rays into the building, the intrusion detector asks where
//! the intruder is, the high-level module plans over the map. So nothing here has threads,
//! I/O or a clock: everything is a pure function of its inputs, time being simulated seconds
//! passed in, and every process sees the same world.
//!
//! # Layout
//!
//! - [`geometry`]: points, wall segments, axis-aligned boxes; ray casting, segment crossing,
//!   point-to-segment distance.
//! - [`building`]: the fixed building (30 m × 20 m, a corridor, three wings of rooms, mapped
//!   furniture and one box that is not on the map) and its queries: range along a ray,
//!   collision of a disc, line of sight, which room a point is in.
//! - [`intruder`]: the person who walks in through wing 3 and lingers in the server room; where
//!   it is at a given time, and what its body gives off.
//! - [`planner`]: the occupancy grid of the map (walls and on-map obstacles, inflated by the
//!   robot's radius, plus what the sonars found), A* with line-of-sight smoothing, and the goals
//!   of "patrol wing N".

pub mod building;
pub mod geometry;
pub mod intruder;
pub mod planner;
