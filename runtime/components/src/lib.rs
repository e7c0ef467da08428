//! modbot-components: every built-in component type of the time grid in one [`Registry`].
//!
//! The types live with their concepts: the grid's sources, arithmetic and test helpers and the
//! data recorder's declaration in `modbot-grid`, the robot controllers in `modbot-control`,
//! the bus and `drive_enable` in `modbot-bus`. This crate sits above the three and assembles
//! them, so a process that checks or runs a description knows every type a description may
//! name. A program with types of its own starts from [`builtin`] and registers them.

pub use modbot_grid::Registry;

/// A registry of every built-in type: the grid's ([`modbot_grid::builtin`]), the controllers
/// ([`modbot_control::register`]), the bus ([`modbot_bus::robot::register`]), and the data
/// recorder's declaration (the component is made by the program `modbot-recorder`, which
/// writes the file off the real-time path).
pub fn builtin() -> Registry {
    let mut registry = Registry::new();
    register_all(&mut registry);
    modbot_grid::record_type::declare(&mut registry);
    registry
}

/// Adds every built-in type but the recorder to `registry`.
pub fn register_all(registry: &mut Registry) {
    modbot_grid::builtin::register_all(registry);
    modbot_control::register(registry);
    modbot_bus::robot::register(registry);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_builtin_registry_holds_the_grid_the_controllers_the_bus_and_the_recorder() {
        let sut = builtin();
        assert_eq!(
            sut.type_names().len(),
            24,
            "23 built in, and the data recorder"
        );
        for name in ["counter", "ptp", "monitor", "bus", "drive_enable", "record"] {
            assert!(sut.describe(name).is_some(), "{name}");
        }
    }
}
