//! The corpus of the fuzz target `description` (`fuzz/corpus/description`) replayed through
//! the same entry point: every description the fuzzer found is loaded or refused in the
//! sandbox, without a panic.

use std::path::Path;

#[test]
fn every_description_of_the_fuzz_corpus_is_loaded_or_refused_without_a_panic() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/description");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap().flatten() {
        let bytes = std::fs::read(entry.path()).unwrap();
        if let Ok(text) = std::str::from_utf8(&bytes) {
            modbot_system::fuzz::description(text);
            seen += 1;
        }
    }
    assert!(seen > 0, "an empty corpus in {}", dir.display());
}
