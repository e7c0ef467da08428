//! The phone book: module names to addresses, with liveness and method tables.
//!
//! It is filled from the domain's directory (iceoryx2 node liveness) and from `describe`
//! answers, which carry a module's methods and blackboard items. A module that starts later
//! is found on the next refresh; a dead module is marked unavailable; a restarted one (new pid)
//! is seen coming back and its method table is learned again.

use std::collections::HashMap;

use modbot_ipc_schema::{Addr, Args};

use crate::error::CallError;
use crate::transport::{Directory, PeerInfo, ReceiveMode, TransportError};

/// What the phone book knows about one module.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    pub addr: Addr,
    pub name: String,
    pub pid: u32,
    pub mode: ReceiveMode,
    pub alive: bool,
    /// Method names in id order, once learned by `describe`.
    pub methods: Option<Vec<String>>,
    /// Blackboard items (`name:kind[:rw]`), once learned.
    pub items: Option<String>,
    /// The digest of its method names, if the directory carries it (0: not known).
    pub methods_digest: u32,
    /// How often a live upgrade replaced its process (see [`PeerInfo::upgrades`]).
    pub upgrades: u16,
}

/// Name → address resolution with liveness.
#[derive(Debug, Default)]
pub struct PhoneBook {
    /// Indexed by address.
    entries: Vec<Option<Entry>>,
    /// Name → the address of the live module of that name, else of a dead one: a call
    /// resolves its callee without comparing every name of a full domain.
    by_name: HashMap<String, u8>,
    /// The last method resolved, so a module that calls one method again and again resolves
    /// it with two string comparisons; forgotten whenever the book changes.
    last: Resolved,
}

/// A method of a live module, resolved to its address and id.
#[derive(Debug)]
struct Resolved {
    valid: bool,
    module: String,
    method: String,
    addr: Addr,
    id: u8,
}

impl Default for Resolved {
    fn default() -> Self {
        Resolved {
            valid: false,
            module: String::new(),
            method: String::new(),
            addr: Addr::NONE,
            id: 0,
        }
    }
}

/// What a refresh saw change.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Changes {
    pub died: Vec<Addr>,
    pub appeared: Vec<Addr>,
    /// Of those that appeared: a live upgrade's new process (see [`PeerInfo::upgrades`]).
    pub upgraded: Vec<Addr>,
}

impl PhoneBook {
    pub fn new() -> PhoneBook {
        PhoneBook {
            entries: vec![None; 256],
            by_name: HashMap::new(),
            last: Resolved::default(),
        }
    }

    /// Re-reads the directory: new modules appear, dead ones are marked, restarted ones are
    /// seen as new.
    pub fn refresh(&mut self, dir: &dyn Directory) -> Result<Changes, TransportError> {
        let mut seen: Vec<Option<PeerInfo>> = vec![None; 256];
        dir.list(&mut |p| {
            let slot = &mut seen[usize::from(p.addr.0)];
            // A live node wins over a dead one left at the same address.
            if slot.as_ref().is_none_or(|s| !s.alive || p.alive) {
                *slot = Some(p);
            }
        })?;
        let mut changes = Changes::default();
        for (i, info) in seen.into_iter().enumerate() {
            let old = &mut self.entries[i];
            match (info, old.as_mut()) {
                (Some(p), Some(e)) if e.pid == p.pid && e.name == p.name => {
                    if e.alive && !p.alive {
                        changes.died.push(p.addr);
                    }
                    if !e.alive && p.alive {
                        changes.appeared.push(p.addr);
                    }
                    e.alive = p.alive;
                    e.methods_digest = p.methods_digest;
                }
                (Some(p), previous) => {
                    // A live upgrade: the new process took the old one's calls over, so the
                    // calls waiting for it go out again (`appeared`) and none fails.
                    let upgraded = previous.as_ref().is_some_and(|e| {
                        e.alive && p.alive && e.name == p.name && p.upgrades > e.upgrades
                    });
                    if previous.as_ref().is_some_and(|e| e.alive) && !upgraded {
                        changes.died.push(p.addr);
                    }
                    if p.alive {
                        changes.appeared.push(p.addr);
                    }
                    if upgraded {
                        changes.upgraded.push(p.addr);
                    }
                    // The same program back (same name, same method digest): its method
                    // table is still right, and need not be asked for again.
                    let (methods, items) = match previous {
                        Some(e)
                            if e.name == p.name
                                && p.methods_digest != 0
                                && e.methods_digest == p.methods_digest =>
                        {
                            (e.methods.take(), e.items.take())
                        }
                        _ => (None, None),
                    };
                    *old = Some(Entry {
                        addr: p.addr,
                        name: p.name,
                        pid: p.pid,
                        mode: p.mode,
                        alive: p.alive,
                        methods,
                        items,
                        methods_digest: p.methods_digest,
                        upgrades: p.upgrades,
                    });
                }
                (None, Some(e)) => {
                    if e.alive {
                        changes.died.push(e.addr);
                    }
                    e.alive = false;
                }
                (None, None) => {}
            }
        }
        self.index_names();
        Ok(changes)
    }

    /// The address and id of `module.method` if it was the last one resolved and the book has
    /// not changed since.
    pub fn resolved(&self, module: &str, method: &str) -> Option<(Addr, u8)> {
        let last = &self.last;
        (last.valid && last.method == method && last.module == module)
            .then_some((last.addr, last.id))
    }

    /// Remembers `module.method` at `addr` with `id` (reusing the strings' room: resolving
    /// another method allocates nothing once the names fit).
    pub fn remember(&mut self, module: &str, method: &str, addr: Addr, id: u8) {
        let last = &mut self.last;
        last.module.clear();
        last.module.push_str(module);
        last.method.clear();
        last.method.push_str(method);
        last.addr = addr;
        last.id = id;
        last.valid = true;
    }

    fn index_names(&mut self) {
        self.last.valid = false;
        self.by_name.clear();
        for e in self.entries.iter().flatten() {
            let live = e.alive;
            let addr = e.addr.0;
            let entries = &self.entries;
            self.by_name
                .entry(e.name.clone())
                .and_modify(|a| {
                    let held = entries[usize::from(*a)].as_ref().is_some_and(|h| h.alive);
                    if live && !held {
                        *a = addr;
                    }
                })
                .or_insert(addr);
        }
    }

    /// The live module named `name`.
    pub fn lookup(&self, name: &str) -> Result<&Entry, CallError> {
        let found = self
            .by_name
            .get(name)
            .and_then(|a| self.entries[usize::from(*a)].as_ref())
            .filter(|e| e.name == name);
        if let Some(e) = found.filter(|e| e.alive) {
            return Ok(e);
        }
        match found {
            Some(e) => Err(CallError::NotAvailable {
                name: name.to_owned(),
                why: format!("its process (pid {}) died; it has not come back", e.pid),
            }),
            None => Err(CallError::UnknownModule(name.to_owned())),
        }
    }

    pub fn get(&self, addr: Addr) -> Option<&Entry> {
        self.entries[usize::from(addr.0)].as_ref()
    }

    /// Every module known, by address.
    pub fn entries(&self) -> impl Iterator<Item = &Entry> {
        self.entries.iter().flatten()
    }

    /// Records a `describe` answer.
    pub fn learn(&mut self, addr: Addr, answer: &Args<'_>) -> Result<(), DescribeError> {
        self.last.valid = false;
        let entry = self.entries[usize::from(addr.0)]
            .as_mut()
            .ok_or(DescribeError::UnknownModule(addr))?;
        let methods = answer.text(3)?;
        let items = answer.text(4)?;
        entry.methods = Some(
            methods
                .split(',')
                .filter(|m| !m.is_empty())
                .map(str::to_owned)
                .collect(),
        );
        entry.items = Some(items.to_owned());
        Ok(())
    }

    /// The id of `method` at `addr`, if its table is known: `Some(Ok(id))`, `Some(Err)` if
    /// it has no such method, `None` if the table is not learned yet.
    pub fn method_id(&self, addr: Addr, method: &str) -> Option<Result<u8, CallError>> {
        let entry = self.get(addr)?;
        if let Some(id) = modbot_ipc_schema::sysmethod::id(method) {
            return Some(Ok(id));
        }
        let methods = entry.methods.as_ref()?;
        Some(match methods.iter().position(|m| m == method) {
            Some(i) => Ok(i as u8),
            None => Err(CallError::UnknownMethod {
                module: entry.name.clone(),
                method: method.to_owned(),
                known: methods.join(", "),
            }),
        })
    }
}

/// Why a `describe` answer is not learned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DescribeError {
    #[error("describe answer from module {0}, which the phone book does not know")]
    UnknownModule(Addr),
    #[error("describe answer: {0}")]
    Answer(#[from] modbot_ipc_schema::ArgError),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A directory of fixed peers.
    struct Fixed(Vec<PeerInfo>);

    impl Directory for Fixed {
        fn list(&self, f: &mut dyn FnMut(PeerInfo)) -> Result<(), TransportError> {
            self.0.iter().cloned().for_each(f);
            Ok(())
        }

        fn reap_dead(&self) -> usize {
            0
        }
    }

    fn peer(addr: u8, name: &str, pid: u32, alive: bool) -> PeerInfo {
        PeerInfo {
            addr: Addr(addr),
            name: name.into(),
            pid,
            mode: ReceiveMode::BusyPoll,
            alive,
            methods_digest: 0,
            upgrades: 0,
        }
    }

    #[test]
    fn a_remembered_method_resolves_until_the_book_changes() {
        let mut sut = PhoneBook::new();
        sut.refresh(&Fixed(vec![peer(5, "sonar", 10, true)]))
            .unwrap();
        assert_eq!(sut.resolved("sonar", "range"), None);
        sut.remember("sonar", "range", Addr(5), 0);
        assert_eq!(sut.resolved("sonar", "range"), Some((Addr(5), 0)));
        assert_eq!(sut.resolved("sonar", "reset"), None, "another method");
        assert_eq!(sut.resolved("base", "range"), None, "another module");
        sut.refresh(&Fixed(vec![peer(5, "sonar", 10, false)]))
            .unwrap();
        assert_eq!(
            sut.resolved("sonar", "range"),
            None,
            "the module died: the call must go the long way and learn it"
        );
    }

    #[test]
    fn a_new_process_with_a_higher_upgrade_count_appears_without_dying() {
        let mut book = PhoneBook::new();
        book.refresh(&Fixed(vec![peer(7, "nav", 100, true)]))
            .unwrap();
        let upgraded = PeerInfo {
            upgrades: 1,
            ..peer(7, "nav", 200, true)
        };
        let changes = book.refresh(&Fixed(vec![upgraded])).unwrap();
        assert_eq!(
            changes,
            Changes {
                died: vec![],
                appeared: vec![Addr(7)],
                upgraded: vec![Addr(7)],
            }
        );
        // A restart (same count, new pid) is a death and an appearance.
        let changes = book.refresh(&Fixed(vec![PeerInfo {
            upgrades: 1,
            ..peer(7, "nav", 300, true)
        }]));
        assert_eq!(changes.unwrap().died, vec![Addr(7)]);
    }
}
