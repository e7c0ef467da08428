//! What a supervisor creates for its domain — the published directory, the relay for tools —
//! outlives it while another process holds it: a tool that opened it. The next supervisor of
//! the domain takes it over instead of failing to create it ("AlreadyExists"), and the tool
//! reads and calls through the new one. (A supervisor that stopped is the case here; one that
//! was SIGKILLed, cleaned up after by the next one's sweep, is `tests/supervisor.rs`'s.)

use std::time::Duration;

use modbot_ipc_schema::directory::Listing;
use modbot_ipc_schema::heartbeat::ModuleState;
use modbot_ipc_schema::Addr;
use modbot_testkit::TestDomain;
use modbot_transport::domain::Domain;
use modbot_transport::ipc::{DirectoryWriter, IpcTransport, RelayClient, RelayServer};
use modbot_transport::{Directory, Transport};

fn listing(name: &str, addr: u8) -> Listing {
    Listing {
        addr: Addr(addr),
        mode: b'b',
        state: ModuleState::Running,
        pid: std::process::id(),
        methods_digest: 0,
        upgrades: 0,
        name: name.to_owned(),
    }
}

fn names(directory: &dyn Directory) -> Vec<String> {
    let mut names = Vec::new();
    directory.list(&mut |p| names.push(p.name)).unwrap();
    names
}

#[test]
fn the_next_supervisor_takes_over_the_directory_a_tool_holds_and_its_generations_go_on() {
    let domain = TestDomain::new("tko", "directory");
    let first = IpcTransport::for_supervisor(&domain).unwrap();
    let node = first.node("directory.first").unwrap();
    let mut writer = DirectoryWriter::create(&node).unwrap();
    writer.publish(&[listing("a", 3)]).unwrap();
    writer.publish(&[listing("a", 3), listing("b", 4)]).unwrap();
    let tool = IpcTransport::new(&domain).unwrap();
    let sut = tool.directory().unwrap();
    assert_eq!(sut.generation(), 2);
    drop(writer);
    drop(node);

    let second = IpcTransport::for_supervisor(&domain).unwrap();
    let node = second.node("directory.second").unwrap();
    let mut writer = DirectoryWriter::create(&node).expect("the held directory is taken over");
    assert_eq!(
        writer.generation(),
        3,
        "what the first left is replaced at once, by a generation a reader that saw the last \
         one sees as new"
    );
    assert_eq!(
        names(&*sut),
        Vec::<String>::new(),
        "the first supervisor's modules are not read as the new one's"
    );
    writer.publish(&[listing("c", 5)]).unwrap();
    assert!(
        sut.published(),
        "the tool reads the new supervisor's directory"
    );
    assert_eq!(sut.generation(), 4);
    assert_eq!(names(&*sut), ["c"]);
}

#[test]
fn the_next_supervisor_takes_over_the_relay_a_tool_holds_and_answers_its_calls() {
    let domain = TestDomain::new("tko", "relay");
    let first = IpcTransport::for_supervisor(&domain).unwrap();
    let server = RelayServer::create(&first).unwrap();
    let tool = IpcTransport::new(&domain).unwrap();
    let sut = RelayClient::open(&tool, Addr(254))
        .unwrap()
        .expect("the supervisor's relay");
    drop(server);

    // The next supervisor, on a thread of its own (its ports stay on it), answers one call.
    let name = domain.name().to_owned();
    let (ready_tx, ready) = std::sync::mpsc::channel();
    let next = std::thread::spawn(move || {
        let second = IpcTransport::for_supervisor(&Domain::new(&name).unwrap()).unwrap();
        let server = RelayServer::create(&second);
        let server = match server {
            Ok(s) => s,
            Err(e) => {
                ready_tx.send(Err(e.to_string())).unwrap();
                return;
            }
        };
        ready_tx.send(Ok(())).unwrap();
        let deadline = std::time::Instant::now() + Duration::from_secs(60);
        while std::time::Instant::now() < deadline {
            if let Some(request) = server.receive().unwrap() {
                assert_eq!(request.payload(), b"ping");
                request.answer(b"pong").unwrap();
                return;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        panic!("no call reached the new relay within 60 s");
    });
    ready.recv().unwrap().expect("the held relay is taken over");
    let answer = sut
        .call(b"ping", Duration::from_secs(60), |bytes| bytes.to_vec())
        .expect("answered by the new supervisor");
    assert_eq!(answer, b"pong");
    next.join().unwrap();
}
