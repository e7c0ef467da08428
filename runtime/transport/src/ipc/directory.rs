//! Who is in the domain: the directory a supervisor publishes, or a scan of iceoryx2's nodes.
//!
//! - [`PublishedDirectory`]: a module of a supervised domain reads the supervisor's image (one
//!   iceoryx2 blackboard entry, [`modbot_ipc_schema::directory`]) when its generation changes.
//!   Nothing is scanned and nothing is cleaned: the supervisor learns every death from
//!   `waitpid` or from silence, removes what the dead process left, and publishes anew.
//! - [`ScannedDirectory`]: without a supervisor (modules started by hand, tools in a domain of
//!   such modules) the node directory is read (one details file per node) and dead nodes are
//!   cleaned by whoever sees them.
//! - [`DirectoryWriter`]: the supervisor's side of the published one.

use std::cell::{Cell, RefCell};
use std::time::{Duration, Instant};

use iceoryx2::config::Config;
use iceoryx2::identifiers::UniqueNodeId;
use iceoryx2::node::NodeView;
use iceoryx2::port::reader::{BlackboardValue, EntryHandle, Reader};
use iceoryx2::port::writer::{EntryHandleMut, Writer};
use iceoryx2::prelude::*;
use iceoryx2::service::builder::blackboard::BlackboardCreateError;
use iceoryx2::service::port_factory::blackboard::PortFactory;
use modbot_ipc_schema::directory::{self, Image, Listing, View, IMAGE_LEN};
use modbot_ipc_schema::heartbeat::ModuleState;

use super::directory_slots as slots;
use super::{parse_node_name, MAX_NODES};
use crate::{Directory, IpcResult, PeerInfo, ReceiveMode, TransportError};

/// The directory's one key.
const KEY: u8 = 0;
/// How often a reader looks whether the supervisor still lives.
const WRITER_CHECK: Duration = Duration::from_millis(50);

/// Whether a supervisor publishes the directory of the domain with `config`.
pub(super) fn is_published(config: &Config) -> bool {
    slots::any_exists(config)
}

/// The supervisor's directory, read in place.
pub(crate) struct PublishedDirectory {
    entry: EntryHandle<ipc::Service, u8, Image>,
    _reader: Reader<ipc::Service, u8>,
    _service: PortFactory<ipc::Service, u8>,
    /// The value read last, boxed: it is 16 KiB.
    last: RefCell<Option<Box<BlackboardValue<Image>>>>,
    /// Its generation.
    last_generation: Cell<u64>,
    /// The node the reader belongs to, when the directory has one of its own (a tool's).
    _node: Option<Node<ipc::Service>>,
    /// What stands in when the supervisor is gone (it stopped, or died).
    scan: ScannedDirectory,
    /// When the writer was last seen alive, and whether it was.
    writer_seen: Cell<Option<(Instant, bool)>>,
}

impl PublishedDirectory {
    /// Opens the directory of the domain `node` belongs to; `Ok(None)` if nobody publishes one.
    pub(super) fn open(
        node: &Node<ipc::Service>,
        config: &Config,
    ) -> Result<Option<PublishedDirectory>, TransportError> {
        let Some(service) = slots::open_current(node)? else {
            return Ok(None);
        };
        let (reader, entry) = read(&service)?;
        Ok(Some(PublishedDirectory {
            entry,
            _reader: reader,
            _service: service,
            last: RefCell::new(None),
            last_generation: Cell::new(0),
            _node: None,
            scan: ScannedDirectory {
                config: config.clone(),
            },
            writer_seen: Cell::new(None),
        }))
    }

    /// This directory, keeping `node` (the one it was opened with) alive as long as it lives.
    pub(super) fn owning(mut self, node: Node<ipc::Service>) -> PublishedDirectory {
        self._node = Some(node);
        self
    }
}

impl PublishedDirectory {
    /// Copies the image if it changed since the last copy (an atomic compare otherwise), and
    /// reads its generation once per change: a full image has 254 entries to check.
    fn refresh(&self) {
        let mut last = self.last.borrow_mut();
        if last.as_ref().is_none_or(|v| !self.entry.is_up_to_date(v)) {
            let value = Box::new(self.entry.get());
            self.last_generation
                .set(View::parse(&value[..]).map_or(0, |v| v.generation()));
            *last = Some(value);
        }
    }

    /// Nobody writes the directory any more: the supervisor stopped or died, and what it
    /// published last is no longer true. The node directory is scanned instead.
    /// A killed supervisor's writer stays registered until someone cleans up after it, so
    /// its process is looked for too (at most every [`WRITER_CHECK`]).
    fn orphaned(&self) -> bool {
        if let Some((at, alive)) = self.writer_seen.get() {
            if at.elapsed() < WRITER_CHECK {
                return !alive;
            }
        }
        let alive = slots::live_writer(&self._service).is_some();
        self.writer_seen.set(Some((Instant::now(), alive)));
        !alive
    }
}

impl Directory for PublishedDirectory {
    fn list(&self, f: &mut dyn FnMut(PeerInfo)) -> Result<(), TransportError> {
        if self.orphaned() {
            return self.scan.list(f);
        }
        self.refresh();
        let last = self.last.borrow();
        let value = last.as_ref().expect("read by refresh");
        let view = View::parse(&value[..]).map_err(|error| TransportError::DirectoryImage {
            op: "read the directory",
            error,
        })?;
        for e in view.entries() {
            let Some(mode) = ReceiveMode::from_code(char::from(e.mode())) else {
                continue;
            };
            f(PeerInfo {
                addr: e.addr(),
                name: e.name().to_owned(),
                pid: e.pid(),
                mode,
                alive: e.state() == ModuleState::Running,
                methods_digest: e.methods_digest(),
                upgrades: e.upgrades(),
            });
        }
        Ok(())
    }

    fn reap_dead(&self) -> usize {
        if self.orphaned() {
            self.scan.reap_dead()
        } else {
            0
        }
    }

    fn generation(&self) -> u64 {
        self.refresh();
        self.last_generation.get()
    }

    fn published(&self) -> bool {
        !self.orphaned()
    }
}

/// The supervisor's side: publishes a new image when a module comes, goes or restarts.
pub struct DirectoryWriter {
    entry: EntryHandleMut<ipc::Service, u8, Image>,
    _writer: Writer<ipc::Service, u8>,
    _service: PortFactory<ipc::Service, u8>,
    image: Box<Image>,
    generation: u64,
}

impl DirectoryWriter {
    /// Creates the directory of the domain `node` belongs to, empty (generation 0), in the
    /// first free slot ([`slots`]). A slot another process still holds is taken over if its
    /// writer stopped cleanly (an empty image replaces the one it left); one a dead supervisor
    /// wrote cannot be written again and is passed by. Generations go on from the highest an
    /// earlier supervisor published, so a reader that saw it sees the next one as new.
    pub fn create(node: &Node<ipc::Service>) -> Result<DirectoryWriter, TransportError> {
        let mut image: Box<Image> = vec![0u8; IMAGE_LEN]
            .into_boxed_slice()
            .try_into()
            .expect("IMAGE_LEN bytes");
        write_image(&mut image, 0, &[])?;
        let mut generation = 0;
        let mut slot = 0;
        // The last process holding an earlier directory may leave between a refused create
        // and the open: then the slot is tried again.
        let mut vanished = 0;
        while slot < slots::SLOTS {
            let created = node
                .service_builder(&slots::slot_name(slot)?)
                .blackboard_creator::<u8>()
                .max_readers(MAX_NODES)
                .max_nodes(MAX_NODES)
                .add::<Image>(KEY, *image)
                .create();
            match created {
                Ok(service) => return DirectoryWriter::write_in(service, image, generation),
                Err(BlackboardCreateError::AlreadyExists) => {}
                Err(e) => return Err(TransportError::ipc("create the directory", e)),
            }
            let Some(service) = slots::open_slot_settled(node, slot)? else {
                vanished += 1;
                if vanished > 3 {
                    return Err(TransportError::Contended {
                        op: "create the directory",
                    });
                }
                continue;
            };
            if let Some(pid) = slots::live_writer(&service) {
                return Err(TransportError::AnotherSupervisor {
                    pid: Some(pid as u32),
                });
            }
            generation = generation.max(last_generation(&service)?);
            match DirectoryWriter::write_in(service, image.clone(), generation) {
                // What the stopped supervisor published last is not true any more (its own
                // entry among it): it is replaced at once, before anyone reads it as ours.
                Ok(mut writer) => {
                    writer.publish(&[])?;
                    return Ok(writer);
                }
                Err(e) => tracing::debug!("directory slot {slot} taken by a dead writer: {e}"),
            }
            slot += 1;
        }
        Err(TransportError::DirectorySlotsHeld {
            slots: slots::SLOTS,
        })
    }

    /// The writer of the directory `service`, starting at `generation`.
    fn write_in(
        service: PortFactory<ipc::Service, u8>,
        image: Box<Image>,
        generation: u64,
    ) -> Result<DirectoryWriter, TransportError> {
        let writer = service.writer_builder().create().ipc("directory writer")?;
        let entry = writer.entry::<Image>(&KEY).ipc("directory entry")?;
        Ok(DirectoryWriter {
            entry,
            _writer: writer,
            _service: service,
            image,
            generation,
        })
    }

    /// Publishes `listings` as the next generation.
    pub fn publish(&mut self, listings: &[Listing]) -> Result<u64, TransportError> {
        let generation = self.generation + 1;
        write_image(&mut self.image, generation, listings)?;
        self.entry.update_with_copy(*self.image);
        self.generation = generation;
        Ok(generation)
    }

    pub fn generation(&self) -> u64 {
        self.generation
    }
}

/// Writes `listings` into `image` as generation `generation`.
fn write_image(
    image: &mut Image,
    generation: u64,
    listings: &[Listing],
) -> Result<(), TransportError> {
    directory::write(&mut image[..], generation, listings)
        .map(|_| ())
        .map_err(|error| TransportError::DirectoryImage {
            op: "write the directory",
            error,
        })
}

/// A directory's reader port and its entry.
type ReadHandles = (
    Reader<ipc::Service, u8>,
    EntryHandle<ipc::Service, u8, Image>,
);

/// A reader of the directory `service` and its entry.
fn read(service: &PortFactory<ipc::Service, u8>) -> Result<ReadHandles, TransportError> {
    let reader = service.reader_builder().create().ipc("directory reader")?;
    let entry = reader.entry::<Image>(&KEY).ipc("directory entry")?;
    Ok((reader, entry))
}

/// The generation of the image `service` holds: 0 for a new directory, the last an earlier
/// supervisor published for one taken over (a reader that saw it must see the next as new).
fn last_generation(service: &PortFactory<ipc::Service, u8>) -> Result<u64, TransportError> {
    let (_reader, entry) = read(service)?;
    let value = Box::new(entry.get());
    Ok(View::parse(&value[..]).map_or(0, |v| v.generation()))
}

/// Lists the nodes of the domain.
#[derive(Debug)]
pub(crate) struct ScannedDirectory {
    pub(super) config: Config,
}

impl ScannedDirectory {
    /// Like [`Directory::list`], with each module's iceoryx2 node id.
    pub(super) fn list_with_ids(
        &self,
        f: &mut dyn FnMut(&UniqueNodeId, PeerInfo),
    ) -> Result<(), TransportError> {
        let mut visit = |view: &dyn NodeView, alive: bool| {
            if let Some(details) = view.details() {
                if let Some((addr, mode, name)) = parse_node_name(&details.name().to_string()) {
                    let pid = view
                        .id()
                        .pid::<ipc::Service>()
                        .map(|p| p.value() as u32)
                        .unwrap_or(0);
                    f(
                        view.id(),
                        PeerInfo {
                            addr,
                            name,
                            pid,
                            mode,
                            alive,
                            methods_digest: 0,
                            upgrades: 0,
                        },
                    );
                }
            }
        };
        Node::<ipc::Service>::list(&self.config, |state| {
            match &state {
                NodeState::Alive(v) => visit(v, true),
                NodeState::Dead(v) => visit(v, false),
                NodeState::Inaccessible(_) | NodeState::Undefined(_) => {}
            }
            CallbackProgression::Continue
        })
        .ipc("node list")
    }
}

impl Directory for ScannedDirectory {
    fn list(&self, f: &mut dyn FnMut(PeerInfo)) -> Result<(), TransportError> {
        self.list_with_ids(&mut |_, p| f(p))
    }

    fn reap_dead(&self) -> usize {
        let mut dead = Vec::new();
        let _ = Node::<ipc::Service>::list(&self.config, |state| {
            if let NodeState::Dead(v) = state {
                dead.push(v);
            }
            CallbackProgression::Continue
        });
        dead.into_iter()
            .filter(|v| v.clone().try_remove_stale_resources().is_ok())
            .count()
    }
}
