//! Wake-ups of modules in blocking mode: futex words in one shared-memory table per domain.
//!
//! The table (`/dev/shm/modbot_<domain>.wake`, mode 0600, removed with the domain's other files)
//! holds one 32-bit word per module address, one for the broadcast bus, one per group and one
//! per named wake-up of the time grid (a group's or a name's word is chosen by a hash of its
//! name; two that share a word wake each other's listeners for nothing, which costs a look for
//! work that is not there). Each word has a cache line of its own.
//!
//! A module that sleeps waits on its own word and on the words of the buses it listens to, all
//! at once (`futex_waitv`): one wake-up source for every reason it can be woken, and nothing to
//! drain after a wake-up. A sender that delivered a frame looks at the receiver's word and
//! pays for a system call (`FUTEX_WAKE`) only when the receiver said it is going to sleep; a
//! spinning receiver never says so, and its senders never make the call.
//!
//! The words are event counts: bit 31 says "a waiter may sleep on this word", bits 0–30 count
//! wake-ups. A waiter sets bit 31, looks at its inboxes once more, and sleeps only while the
//! word still holds the value it set. A notifier, after its frame is in the inbox, reads the
//! word; if bit 31 is set it writes the count plus one (bit 31 clear) and wakes every sleeper.
//! Both sides order their two steps with sequentially consistent operations, so either the
//! notifier sees the bit or the waiter sees the frame; and because the count changes, a waiter
//! that has not slept yet returns at once even when another listener of a shared bus word has
//! set the bit again meanwhile.
//!
//! The grid's wake-ups ([`crate::channels::WakeListener`]) must also keep a notification that
//! came while nobody slept, until it is taken: their notifiers always count
//! ([`WakeTable::notify_counted`]) and each listener remembers the count it last took.

use core::num::NonZeroUsize;
use core::ptr::NonNull;
use core::sync::atomic::{fence, AtomicU32, Ordering};
use core::time::Duration;
use std::io::ErrorKind;
use std::os::unix::fs::OpenOptionsExt;
use std::path::PathBuf;

use modbot_ipc_schema::Addr;
use nix::sys::mman::{mmap, munmap, MapFlags, ProtFlags};
use rustix::thread::futex;

use crate::domain::Domain;
use crate::TransportError;

/// Bit 31: a waiter may sleep on the word.
const SLEEPING: u32 = 1 << 31;
/// Bytes per word: a cache line each, so two modules' words never share one.
const LINE: usize = 64;
/// The broadcast bus's word, after the 256 addresses'.
const BROADCAST: u16 = 256;
/// Words for multicast groups, after the broadcast's.
const GROUP_WORDS: u16 = 64;
/// Words for the grid's named wake-ups, after the groups'.
const NAMED_WORDS: u16 = 256;
/// Words in the table.
const WORDS: usize = (BROADCAST + 1 + GROUP_WORDS + NAMED_WORDS) as usize;
/// Bits 0–30: the count.
const COUNT: u32 = !SLEEPING;
/// The table's size in bytes.
pub(crate) const TABLE_LEN: usize = WORDS * LINE;
/// `FUTEX_WAKE`'s count for "every sleeper": the kernel reads the count as a signed `int`, so
/// `u32::MAX` is −1 there, and its loop stops after the *first* sleeper woken (`++woken >=
/// count`). A word with two listeners (a bus's, or a grid host's during a live upgrade, when
/// the running and the new process both wait on it) then wakes one of them; the other sleeps
/// until its timeout.
const EVERY_SLEEPER: u32 = i32::MAX as u32;
/// The most words one wait looks at (`futex_waitv` takes at most 128).
pub(crate) const MAX_WAIT_WORDS: usize = 2 + GROUP_WORDS as usize;
/// The table's file name after the domain's prefix.
pub(crate) const FILE_SUFFIX: &str = "wake";

/// One word of the table: whom it wakes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Word(u16);

impl Word {
    /// The word of the module at `addr`.
    pub fn module(addr: Addr) -> Word {
        Word(u16::from(addr.0))
    }

    /// The word of the listeners of bus `name` (`bcast` or `group.NAME`).
    pub fn bus(name: &str) -> Word {
        match name.strip_prefix("group.") {
            None => Word(BROADCAST),
            Some(group) => Word(BROADCAST + 1 + (fnv1a(group) % u32::from(GROUP_WORDS)) as u16),
        }
    }

    /// The word of the grid's wake-up `name`.
    pub fn named(name: &str) -> Word {
        Word(BROADCAST + 1 + GROUP_WORDS + (fnv1a(name) % u32::from(NAMED_WORDS)) as u16)
    }
}

/// FNV-1a, 32 bits: stable across processes and builds, unlike the std hasher.
fn fnv1a(name: &str) -> u32 {
    name.bytes().fold(0x811c_9dc5_u32, |h, b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}

/// The wake-up table of one domain, mapped into this process.
#[derive(Debug)]
pub struct WakeTable {
    base: NonNull<u8>,
    path: PathBuf,
}

// SAFETY: the table is shared memory that is only accessed through atomics; the mapping stays
// valid until `drop`, which only the last owner runs.
unsafe impl Send for WakeTable {}
// SAFETY: as above: every access is atomic.
unsafe impl Sync for WakeTable {}

impl WakeTable {
    /// Maps the table of `domain`, creating it if no process of the domain has yet.
    pub fn open(domain: &Domain) -> Result<WakeTable, TransportError> {
        let path = PathBuf::from(format!("/dev/shm/{}{FILE_SUFFIX}", domain.prefix()));
        let file = open_or_create(&path).map_err(|e| wake_err(&path, e))?;
        let len = file.metadata().map_err(|e| wake_err(&path, e))?.len();
        if len != TABLE_LEN as u64 {
            return Err(TransportError::WakeTableSize {
                path,
                len,
                expected: TABLE_LEN,
            });
        }
        // SAFETY: a shared mapping of a file of exactly TABLE_LEN bytes that this process
        // opened; nothing in this process maps it at a fixed address or truncates it.
        let base = unsafe {
            mmap(
                None,
                NonZeroUsize::new(TABLE_LEN).expect("not zero"),
                ProtFlags::PROT_READ | ProtFlags::PROT_WRITE,
                MapFlags::MAP_SHARED,
                &file,
                0,
            )
        }
        .map_err(|e| wake_err(&path, std::io::Error::from(e)))?;
        Ok(WakeTable {
            base: base.cast(),
            path,
        })
    }

    fn word(&self, w: Word) -> &AtomicU32 {
        let offset = usize::from(w.0) * LINE;
        debug_assert!(offset + 4 <= TABLE_LEN);
        // SAFETY: every `Word` indexes a line inside the TABLE_LEN bytes mapped at `base`
        // (addresses 0–255, the broadcast word, the group words), which is page aligned, so
        // the word is aligned; the memory lives as long as `self`, and every process touches
        // it only through atomics.
        unsafe { &*self.base.as_ptr().add(offset).cast::<AtomicU32>() }
    }

    /// Wakes whoever sleeps on `w`. Call it after the frame is in the receiver's inbox.
    pub fn notify(&self, w: Word) {
        let word = self.word(w);
        // Orders the frame's delivery before the look at the word (see the module docs).
        fence(Ordering::SeqCst);
        let seen = word.load(Ordering::Relaxed);
        if seen & SLEEPING == 0 {
            return;
        }
        word.store(seen.wrapping_add(1) & !SLEEPING, Ordering::SeqCst);
        // Every listener of a bus word, the one module of an address's word.
        if let Err(e) = futex::wake(word, futex::Flags::empty(), EVERY_SLEEPER) {
            tracing::debug!("futex wake of {}: {e}", self.path.display());
        }
    }

    /// Counts a notification on `w` whether or not anyone sleeps (a listener takes it later),
    /// and wakes whoever does.
    pub fn notify_counted(&self, w: Word) {
        let word = self.word(w);
        let mut seen = word.load(Ordering::Relaxed);
        loop {
            let next = seen.wrapping_add(1) & COUNT;
            match word.compare_exchange_weak(seen, next, Ordering::SeqCst, Ordering::Relaxed) {
                Ok(_) => break,
                Err(now) => seen = now,
            }
        }
        if seen & SLEEPING != 0 {
            if let Err(e) = futex::wake(word, futex::Flags::empty(), EVERY_SLEEPER) {
                tracing::debug!("futex wake of {}: {e}", self.path.display());
            }
        }
    }

    /// The count of `w` now (what a listener takes).
    pub fn count(&self, w: Word) -> u32 {
        self.word(w).load(Ordering::SeqCst) & COUNT
    }

    /// Sleeps on `w` until its count differs from `taken` or `timeout` passes (`None`: no
    /// limit) or a signal arrives; whether it differs.
    pub fn wait_for_count(&self, w: Word, taken: u32, timeout: Option<Duration>) -> bool {
        let word = self.word(w);
        let value = word.fetch_or(SLEEPING, Ordering::SeqCst) | SLEEPING;
        if value & COUNT != taken {
            return true;
        }
        let timeout = timeout.map(|t| {
            let t = t.min(Duration::from_secs(3600));
            futex::Timespec {
                tv_sec: t.as_secs() as i64,
                tv_nsec: i64::from(t.subsec_nanos()),
            }
        });
        // Woken, changed before the sleep, timed out or interrupted: the count says which.
        if let Err(e) = futex::wait(word, futex::Flags::empty(), value, timeout.as_ref()) {
            if !matches!(
                e,
                rustix::io::Errno::AGAIN | rustix::io::Errno::TIMEDOUT | rustix::io::Errno::INTR
            ) {
                tracing::debug!("futex wait of {}: {e}", self.path.display());
            }
        }
        self.count(w) != taken
    }

    /// Sleeps on `words` until one is notified, `timeout` passes or a signal arrives, unless
    /// `ready` (the look at the inboxes) finds something first. `waits` is scratch space of
    /// at least `words.len()` entries, kept by the caller so that a wait allocates nothing.
    pub fn wait(
        &self,
        words: &[Word],
        waits: &mut [futex::Wait],
        ready: &mut dyn FnMut() -> Result<bool, TransportError>,
        timeout: Duration,
    ) -> Result<(), TransportError> {
        let n = words.len().min(waits.len());
        for (w, wait) in words.iter().zip(waits.iter_mut()) {
            let word = self.word(*w);
            let value = word.fetch_or(SLEEPING, Ordering::SeqCst) | SLEEPING;
            wait.val = u64::from(value);
            wait.uaddr = futex::WaitPtr::new(core::ptr::from_ref(word).cast_mut().cast());
            wait.flags = futex::WaitFlags::SIZE_U32;
        }
        if ready()? {
            return Ok(());
        }
        let now = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
        let timeout = timeout.min(Duration::from_secs(60));
        let mut deadline = futex::Timespec {
            tv_sec: now.tv_sec + timeout.as_secs() as i64,
            tv_nsec: now.tv_nsec + i64::from(timeout.subsec_nanos()),
        };
        if deadline.tv_nsec >= 1_000_000_000 {
            deadline.tv_sec += 1;
            deadline.tv_nsec -= 1_000_000_000;
        }
        match futex::waitv(
            &waits[..n],
            futex::WaitvFlags::empty(),
            Some(&deadline),
            futex::ClockId::Monotonic,
        ) {
            // Woken, a word changed before the sleep, the time is up, or a signal came.
            Ok(_)
            | Err(rustix::io::Errno::AGAIN)
            | Err(rustix::io::Errno::TIMEDOUT)
            | Err(rustix::io::Errno::INTR) => Ok(()),
            Err(e) => Err(TransportError::WakeWait(e.into())),
        }
    }
}

impl Drop for WakeTable {
    fn drop(&mut self) {
        // SAFETY: the mapping made in `open`, of TABLE_LEN bytes; no reference into it outlives
        // `self` (`word` borrows `self`).
        if let Err(e) = unsafe { munmap(self.base.cast(), TABLE_LEN) } {
            tracing::debug!("unmapping {}: {e}", self.path.display());
        }
    }
}

/// Opens the table's file, or creates it whole: written at a name of this call's own, sized,
/// then linked to its real name, so no process ever maps a table that is not full size.
fn open_or_create(path: &std::path::Path) -> std::io::Result<std::fs::File> {
    let open = || {
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
    };
    match open() {
        Err(e) if e.kind() == ErrorKind::NotFound => {}
        other => return other,
    }
    // A name of this call's own: two threads of one process (two modules opening at once)
    // must not share one scratch file.
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let scratch = path.with_extension(format!("wake.{}.{call}.new", std::process::id()));
    let made = (|| {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .mode(0o600)
            .open(&scratch)?;
        file.set_len(TABLE_LEN as u64)?;
        match std::fs::hard_link(&scratch, path) {
            Err(e) if e.kind() == ErrorKind::AlreadyExists => Ok(()),
            other => other,
        }
    })();
    let _ = std::fs::remove_file(&scratch);
    made?;
    open()
}

fn wake_err(path: &std::path::Path, e: std::io::Error) -> TransportError {
    TransportError::WakeTable {
        path: path.to_owned(),
        failure: e.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Removes a test's table however the test ends.
    struct Removed(String);

    impl Removed {
        fn table_of(domain: &Domain) -> Removed {
            Removed(format!("/dev/shm/{}{FILE_SUFFIX}", domain.prefix()))
        }
    }

    impl Drop for Removed {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    #[test]
    fn the_table_is_laid_out_as_ipc_schema_readme_says() {
        assert_eq!(TABLE_LEN, 36_928);
        assert_eq!(WORDS, 577);
        assert_eq!(
            Word::named("grid.done.wake"),
            Word(321 + (fnv1a("grid.done.wake") % 256) as u16)
        );
        // FNV-1a of "arm" is 0x386f_27b5 ("group.arm" hashes the group's name only).
        assert_eq!(
            Word::bus("group.arm"),
            Word(257 + (0x386f_27b5_u32 % 64) as u16)
        );
    }

    #[test]
    fn threads_of_one_process_opening_the_table_at_once_all_map_it() {
        let domain = Domain::new(&format!("wakerace{}", std::process::id())).unwrap();
        let file = Removed::table_of(&domain);
        for _ in 0..20 {
            let _ = std::fs::remove_file(&file.0);
            let barrier = std::sync::Arc::new(std::sync::Barrier::new(8));
            let opened: Vec<_> = (0..8)
                .map(|_| {
                    let (domain, barrier) = (domain.clone(), barrier.clone());
                    std::thread::spawn(move || {
                        barrier.wait();
                        WakeTable::open(&domain).map(|_| ())
                    })
                })
                .collect();
            for t in opened {
                t.join().unwrap().unwrap();
            }
        }
    }

    #[test]
    fn a_waiter_returns_when_woken_and_at_once_when_the_word_changed_before_it_slept() {
        let domain = Domain::new(&format!("waketest{}", std::process::id())).unwrap();
        let _file = Removed::table_of(&domain);
        let table = std::sync::Arc::new(WakeTable::open(&domain).unwrap());
        let me = [Word::module(Addr(7))];
        let mut waits = [futex::Wait::new(); 1];
        // Notified between the announcement and the sleep: the wait does not sleep.
        let t = table.clone();
        let start = std::time::Instant::now();
        table
            .wait(
                &me,
                &mut waits,
                &mut || {
                    t.notify(Word::module(Addr(7)));
                    Ok(false)
                },
                Duration::from_secs(60),
            )
            .unwrap();
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "a changed word ends the wait"
        );
        // Asleep, then woken by another thread (which notifies until the wait is over: a
        // notification before the waiter announced itself is not one it waits for).
        let t = table.clone();
        let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let over = done.clone();
        let waker = std::thread::spawn(move || {
            while !over.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(10));
                t.notify(Word::module(Addr(7)));
            }
        });
        let start = std::time::Instant::now();
        table
            .wait(&me, &mut waits, &mut || Ok(false), Duration::from_secs(60))
            .unwrap();
        done.store(true, Ordering::SeqCst);
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the wake-up ended the wait"
        );
        waker.join().unwrap();
    }

    /// Whether thread `tid` of this process is asleep (state `S` in its `stat`).
    fn asleep(tid: i32) -> bool {
        let stat =
            std::fs::read_to_string(format!("/proc/self/task/{tid}/stat")).unwrap_or_default();
        // The state follows the command's closing parenthesis.
        stat.rsplit_once(')')
            .is_some_and(|(_, rest)| rest.trim_start().starts_with('S'))
    }

    #[test]
    fn one_notification_wakes_every_listener_asleep_on_a_word() {
        let domain = Domain::new(&format!("wakeall{}", std::process::id())).unwrap();
        let _file = Removed::table_of(&domain);
        let table = std::sync::Arc::new(WakeTable::open(&domain).unwrap());
        let word = Word::named("grid.wake.host.ctrl");
        let (tx, woken) = std::sync::mpsc::channel();
        let (tids_tx, tids) = std::sync::mpsc::channel();
        let taken = table.count(word);
        // Three listeners of one word (a host's running process and its new one, say), asleep
        // without a timeout: only the notification ends their waits.
        for listener in 0..3 {
            let (t, tx, tids_tx) = (table.clone(), tx.clone(), tids_tx.clone());
            std::thread::spawn(move || {
                tids_tx
                    .send(rustix::thread::gettid().as_raw_nonzero().get())
                    .unwrap();
                let changed = t.wait_for_count(word, taken, None);
                let _ = tx.send((listener, changed));
            });
        }
        let tids: Vec<i32> = tids.iter().take(3).collect();
        let deadline = std::time::Instant::now() + Duration::from_secs(30);
        while !tids.iter().all(|&tid| asleep(tid)) {
            assert!(
                std::time::Instant::now() < deadline,
                "the listeners never slept"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        table.notify_counted(word);
        let mut seen = Vec::new();
        for _ in 0..3 {
            match woken.recv_timeout(Duration::from_secs(30)) {
                Ok((listener, changed)) => {
                    assert!(
                        changed,
                        "listener {listener} woke without the count changing"
                    );
                    seen.push(listener);
                }
                Err(_) => panic!("one notification woke only listeners {seen:?} of 3"),
            }
        }
    }

    #[test]
    fn group_words_are_stable_and_apart_from_modules_and_broadcast() {
        assert_eq!(Word::bus("bcast"), Word(BROADCAST));
        let g = Word::bus("group.arm");
        assert_eq!(g, Word::bus("group.arm"));
        assert!(g.0 > BROADCAST && usize::from(g.0) < WORDS);
        assert_eq!(Word::module(Addr(254)), Word(254));
    }
}
