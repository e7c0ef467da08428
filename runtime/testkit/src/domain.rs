//! A domain per test, cleaned up on drop.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};

use modbot_transport::domain::Domain;

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A domain of its own for one test; its shared-memory files are removed on drop.
#[derive(Debug)]
pub struct TestDomain {
    domain: Domain,
}

impl TestDomain {
    /// A fresh domain `{tag}{pid}_{n}_{test}`: `tag` names the suite (a few lowercase
    /// letters), `test` is shortened to what a domain name may hold.
    ///
    /// # Panics
    /// If `tag` makes the name invalid (a bug in the suite, not in the code under test).
    pub fn new(tag: &str, test: &str) -> TestDomain {
        let n = COUNTER.fetch_add(1, Ordering::SeqCst);
        let short: String = test
            .chars()
            .filter(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
            .take(14)
            .collect();
        let name = format!("{tag}{}_{n}_{short}", std::process::id());
        let domain = Domain::new(&name)
            .unwrap_or_else(|e| panic!("test domain name {name:?} is not valid: {e}"));
        TestDomain { domain }
    }

    /// The domain.
    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// The domain's name.
    pub fn name(&self) -> &str {
        self.domain.name()
    }

    /// The domain's files still in `/dev/shm` or `/tmp/iceoryx2`.
    pub fn leftover_files(&self) -> Vec<PathBuf> {
        self.domain.files()
    }
}

impl std::ops::Deref for TestDomain {
    type Target = Domain;

    fn deref(&self) -> &Domain {
        &self.domain
    }
}

impl Drop for TestDomain {
    fn drop(&mut self) {
        self.domain.remove_files();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_test_domains_of_one_test_have_different_names() {
        let a = TestDomain::new("tk", "same test");
        let b = TestDomain::new("tk", "same test");
        assert_ne!(a.name(), b.name());
        assert!(a.name().starts_with(&format!("tk{}_", std::process::id())));
        assert!(a.name().ends_with("_sametest"), "{}", a.name());
    }

    #[test]
    fn a_dropped_test_domain_leaves_no_file() {
        let sut = TestDomain::new("tk", "drop");
        let path = PathBuf::from("/dev/shm").join(format!("{}probe", sut.prefix()));
        std::fs::write(&path, b"x").unwrap();
        assert_eq!(sut.leftover_files(), vec![path.clone()]);
        drop(sut);
        assert!(!path.exists(), "{} is left", path.display());
    }
}
