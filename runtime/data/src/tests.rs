use std::path::PathBuf;

use modbot_ipc_schema::OwnedValue;

use super::{Run, Store};

/// A store file in a directory of the test's own (made by the store), removed on drop.
struct TempFile {
    /// Keeps the directory until the test ends.
    _dir: modbot_testkit::TempDir,
    path: PathBuf,
}

impl TempFile {
    fn new(test: &str) -> TempFile {
        let dir = modbot_testkit::TempDir::new(test);
        let path = dir.path().join("sub").join("test.redb");
        TempFile { _dir: dir, path }
    }
}

fn run(command: &str, peak: f64) -> Run {
    Run {
        command: command.into(),
        assembly: "goto".into(),
        origin: "prog.lua:3".into(),
        start_tick: 100,
        end_tick: 1800,
        outcome: "ok".into(),
        values: vec![
            ("peak_following".into(), OwnedValue::F64(peak)),
            ("axes".into(), OwnedValue::I64(6)),
        ],
    }
}

#[test]
fn a_value_put_is_read_back_with_its_kind() {
    let file = TempFile::new("roundtrip");
    let sut = Store::open(&file.path).unwrap();
    let q = OwnedValue::F64s(vec![0.1, -0.2, 0.3]);
    sut.put("goto.q", &q).unwrap();
    sut.put("note", &OwnedValue::Text("hello".into())).unwrap();
    assert_eq!(sut.get("goto.q").unwrap(), Some(q));
    assert_eq!(sut.get("missing").unwrap(), None);
    let keys: Vec<String> = sut.entries().unwrap().into_iter().map(|(k, _)| k).collect();
    assert_eq!(keys, ["goto.q", "note"]);
    assert!(sut.remove("note").unwrap());
    assert_eq!(sut.get("note").unwrap(), None);
}

#[test]
fn runs_are_numbered_in_order_and_decoded_whole() {
    let file = TempFile::new("runs");
    let sut = Store::open(&file.path).unwrap();
    assert_eq!(sut.add_run(&run("ptp", 0.25)).unwrap(), 1);
    assert_eq!(sut.add_run(&run("hold", 0.5)).unwrap(), 2);
    let runs = sut.runs().unwrap();
    assert_eq!(runs.len(), 2);
    assert_eq!(runs[1], (2, run("hold", 0.5)));
    assert_eq!(sut.run(1).unwrap(), Some(run("ptp", 0.25)));
    assert_eq!(sut.run(3).unwrap(), None);
    assert_eq!(
        run("ptp", 0.25).to_string(),
        "ptp (goto) at prog.lua:3, ticks 100..1800, ok: peak_following=0.25 axes=6"
    );
}

#[test]
fn data_survives_closing_and_reopening_the_store() {
    let file = TempFile::new("reopen");
    {
        let sut = Store::open(&file.path).unwrap();
        sut.put("goto.v", &OwnedValue::F64(0.5)).unwrap();
        sut.add_run(&run("ptp", 1.0)).unwrap();
    }
    let sut = Store::open_existing(&file.path)
        .unwrap()
        .expect("the file is there");
    assert_eq!(sut.get("goto.v").unwrap(), Some(OwnedValue::F64(0.5)));
    assert_eq!(sut.runs().unwrap().len(), 1);
}

#[test]
fn a_store_that_was_never_made_is_none_and_not_made_by_looking() {
    let file = TempFile::new("absent");
    assert!(Store::open_existing(&file.path).unwrap().is_none());
    assert!(!file.path.exists());
}

#[test]
fn a_reader_open_beside_a_writer_sees_its_commits() {
    let file = TempFile::new("shared");
    let writer = Store::open(&file.path).unwrap();
    let reader = Store::open_existing(&file.path).unwrap().unwrap();
    writer.put("k", &OwnedValue::I64(1)).unwrap();
    assert_eq!(reader.get("k").unwrap(), Some(OwnedValue::I64(1)));
    writer.put("k", &OwnedValue::I64(2)).unwrap();
    assert_eq!(reader.get("k").unwrap(), Some(OwnedValue::I64(2)));
}

#[test]
fn keys_with_spaces_or_too_long_are_refused() {
    let file = TempFile::new("keys");
    let sut = Store::open(&file.path).unwrap();
    assert!(sut.put("a b", &OwnedValue::I64(1)).is_err());
    assert!(sut.put("", &OwnedValue::I64(1)).is_err());
    assert!(sut.put(&"x".repeat(129), &OwnedValue::I64(1)).is_err());
    let e = sut.put("a b", &OwnedValue::I64(1)).unwrap_err().to_string();
    assert!(e.contains("'a b' is not a key"), "{e}");
}

#[test]
fn a_domains_file_is_named_after_it_in_the_data_directory() {
    let sut = super::path_for("arm");
    assert_eq!(sut.file_name().unwrap(), "arm.redb");
}
