//! Who may command the system through the station.
//!
//! On a loopback address only this machine's users reach the page, as they reach the domain
//! with `modbot call`: they may command, unless a token was given. On any other address a
//! token is required; without `--token` the station makes one at start and prints it. A
//! connection without the right token sees everything and commands nothing.

use std::net::SocketAddr;

/// The station's rule for commands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Access {
    token: Option<String>,
}

/// How the station's access came about, to tell the operator at start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// Loopback, no token: everyone on this machine commands.
    Loopback,
    /// The operator's `--token`.
    Given,
    /// Made at start, because the address is not loopback.
    Made,
}

impl Access {
    /// The rule for a station listening on `listen` with the operator's `token`, if any:
    /// `random` makes a token when one is needed and none was given.
    pub fn new(
        listen: SocketAddr,
        token: Option<String>,
        random: impl FnOnce() -> String,
    ) -> (Access, Origin) {
        match token {
            Some(t) => (Access { token: Some(t) }, Origin::Given),
            None if listen.ip().is_loopback() => (Access { token: None }, Origin::Loopback),
            None => (
                Access {
                    token: Some(random()),
                },
                Origin::Made,
            ),
        }
    }

    /// Whether a connection that showed `shown` may command.
    pub fn may_command(&self, shown: Option<&str>) -> bool {
        match &self.token {
            None => true,
            Some(t) => shown.is_some_and(|s| constant_time_eq(s.as_bytes(), t.as_bytes())),
        }
    }

    /// The token, if one is needed.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }
}

/// Compares without stopping at the first difference, so that the time an answer takes does
/// not tell how much of a guess was right.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// 128 random bits as hex, from the kernel's generator.
pub fn random_token() -> std::io::Result<String> {
    use std::io::Read;
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(s: &str) -> SocketAddr {
        s.parse().unwrap()
    }

    #[test]
    fn loopback_without_a_token_lets_everyone_command() {
        let (a, origin) = Access::new(addr("127.0.0.1:8080"), None, || unreachable!());
        assert_eq!(origin, Origin::Loopback);
        assert!(a.may_command(None));
        assert!(a.may_command(Some("anything")));
    }

    #[test]
    fn another_address_without_a_token_makes_one_and_requires_it() {
        let (a, origin) = Access::new(addr("0.0.0.0:8080"), None, || "s3cret".into());
        assert_eq!(origin, Origin::Made);
        assert!(!a.may_command(None));
        assert!(!a.may_command(Some("wrong")));
        assert!(!a.may_command(Some("s3cre")));
        assert!(a.may_command(Some("s3cret")));
    }

    #[test]
    fn a_given_token_is_required_on_loopback_too() {
        let (a, origin) = Access::new(addr("127.0.0.1:1"), Some("t".into()), || unreachable!());
        assert_eq!(origin, Origin::Given);
        assert!(!a.may_command(None));
        assert!(a.may_command(Some("t")));
    }

    #[test]
    fn random_tokens_are_128_bits_of_hex_and_differ() {
        let (a, b) = (random_token().unwrap(), random_token().unwrap());
        assert_eq!(a.len(), 32);
        assert!(a.chars().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }
}
