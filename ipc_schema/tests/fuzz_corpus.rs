//! The fuzz targets' corpora (`fuzz/corpus/<target>`, kept in the repository) replayed through
//! the same entry points (`modbot_ipc_schema::fuzz`): every input the fuzzer found decodes
//! without a panic, on every machine, without the nightly toolchain.

use std::path::Path;

#[test]
fn every_corpus_input_of_every_decoder_target_is_taken_without_a_panic() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus");
    for (target, decode) in modbot_ipc_schema::fuzz::TARGETS {
        let dir = corpus.join(target);
        let inputs: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .flatten()
            .map(|entry| entry.path())
            .collect();
        assert!(!inputs.is_empty(), "{target}: an empty corpus");
        for input in inputs {
            let bytes = std::fs::read(&input).unwrap();
            decode(&bytes);
        }
    }
}
