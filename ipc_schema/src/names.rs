//! The names the wire formats carry, and the one rule each kind of name follows, so that every
//! decoder that reads a name checks it the same way.
//!
//! - A module name (the directory, relayed calls, the supervisor's status rows) is 1 to
//!   [`MODULE_NAME_MAX`] bytes of `a-z A-Z 0-9 _ -`: it names an iceoryx2 service and a process.
//! - An assembly name (the coordinator's answers about switches) is 1 to
//!   [`ASSEMBLY_NAME_MAX`] bytes of `a-z 0-9 _`: it names a file.

/// The longest module name, in bytes.
pub const MODULE_NAME_MAX: usize = 48;

/// The longest assembly name, in bytes.
pub const ASSEMBLY_NAME_MAX: usize = 32;

/// Whether `name` is a module name: 1 to 48 bytes of `a-z A-Z 0-9 _ -`.
pub fn is_module_name(name: &[u8]) -> bool {
    (1..=MODULE_NAME_MAX).contains(&name.len())
        && name
            .iter()
            .all(|b| b.is_ascii_alphanumeric() || *b == b'_' || *b == b'-')
}

/// Whether `name` is an assembly name: 1 to 32 bytes of `a-z 0-9 _`.
pub fn is_assembly_name(name: &[u8]) -> bool {
    (1..=ASSEMBLY_NAME_MAX).contains(&name.len())
        && name
            .iter()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || *b == b'_')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_module_name_is_1_to_48_bytes_of_letters_digits_underscore_and_dash() {
        assert!(is_module_name(b"host_bus-2"));
        assert!(is_module_name(&[b'a'; 48]));
        for bad in [&b""[..], &[b'a'; 49], b"a b", b"a/b", "é".as_bytes()] {
            assert!(!is_module_name(bad), "{bad:?}");
        }
    }

    #[test]
    fn an_assembly_name_is_1_to_32_bytes_of_lowercase_letters_digits_and_underscore() {
        assert!(is_assembly_name(b"ptp_2"));
        assert!(is_assembly_name(b"none"));
        for bad in [&b""[..], &[b'a'; 33], b"Ptp", b"p-t", b"p t"] {
            assert!(!is_assembly_name(bad), "{bad:?}");
        }
    }
}
