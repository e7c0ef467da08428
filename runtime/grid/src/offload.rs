//! Writing off the real-time thread: a [`Write`] that gathers bytes in buffers and hands each
//! full one to a thread of normal priority that writes it out, so the coordinator's tick thread
//! never does file I/O for its trace. Buffers come back to be filled again: after the first few,
//! writing allocates nothing.
//!
//! Create it on a thread of normal priority (the writer thread inherits its scheduling); drop
//! it (or call [`Offload::finish`]) to have everything written and the writer thread joined.

use std::io::{self, Write};
use std::sync::mpsc::{channel, sync_channel, Receiver, Sender, SyncSender, TrySendError};
use std::thread::JoinHandle;

/// Bytes gathered before a buffer is handed over.
const CHUNK: usize = 64 * 1024;
/// Buffers in flight to the writer thread at most before the writing side waits for it.
const IN_FLIGHT: usize = 16;

/// A writer whose bytes are written by a thread of its own.
pub struct Offload<W: Write + Send + 'static> {
    current: Vec<u8>,
    full: Option<SyncSender<Vec<u8>>>,
    empty: Receiver<Vec<u8>>,
    thread: Option<JoinHandle<io::Result<W>>>,
}

impl<W: Write + Send + 'static> Offload<W> {
    /// Starts the thread that writes to `out`.
    pub fn new(out: W) -> io::Result<Offload<W>> {
        let (full, to_write) = sync_channel::<Vec<u8>>(IN_FLIGHT);
        let (give_back, empty): (Sender<Vec<u8>>, _) = channel();
        let thread = std::thread::Builder::new()
            .name("trace writer".into())
            .spawn(move || {
                let mut out = out;
                for mut buf in to_write {
                    out.write_all(&buf)?;
                    buf.clear();
                    let _ = give_back.send(buf);
                }
                out.flush()?;
                Ok(out)
            })?;
        Ok(Offload {
            current: Vec::with_capacity(CHUNK),
            full: Some(full),
            empty,
            thread: Some(thread),
        })
    }

    /// Hands the current buffer to the writer thread and takes an empty one.
    fn hand_over(&mut self) -> io::Result<()> {
        if self.current.is_empty() {
            return Ok(());
        }
        let next = self
            .empty
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(CHUNK));
        let buf = std::mem::replace(&mut self.current, next);
        let Some(full) = &self.full else {
            return Err(io::Error::other("the trace writer has finished"));
        };
        match full.try_send(buf) {
            Ok(()) => Ok(()),
            // The writer is far behind: wait for it rather than lose the trace.
            Err(TrySendError::Full(buf)) => full
                .send(buf)
                .map_err(|_| io::Error::other("the trace writer thread has stopped")),
            Err(TrySendError::Disconnected(_)) => {
                Err(io::Error::other("the trace writer thread has stopped"))
            }
        }
    }

    /// Writes everything out and returns the writer, or the first error writing it.
    pub fn finish(mut self) -> io::Result<W> {
        self.close()
    }

    fn close(&mut self) -> io::Result<W> {
        self.hand_over()?;
        self.full = None;
        match self.thread.take() {
            Some(t) => t
                .join()
                .map_err(|_| io::Error::other("the trace writer thread panicked"))?,
            None => Err(io::Error::other("the trace writer has finished")),
        }
    }
}

impl<W: Write + Send + 'static> Write for Offload<W> {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        self.current.extend_from_slice(bytes);
        if self.current.len() >= CHUNK {
            self.hand_over()?;
        }
        Ok(bytes.len())
    }

    /// Hands what was written to the writer thread (it is written soon after; [`finish`]
    /// waits for it).
    ///
    /// [`finish`]: Offload::finish
    fn flush(&mut self) -> io::Result<()> {
        self.hand_over()
    }
}

impl<W: Write + Send + 'static> Drop for Offload<W> {
    fn drop(&mut self) {
        if self.thread.is_some() {
            if let Err(e) = self.close() {
                tracing::error!("the trace was not written completely: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn everything_written_arrives_in_order_and_buffers_are_reused() {
        let mut sut = Offload::new(Vec::new()).unwrap();
        let mut want = Vec::new();
        for i in 0..50_000u32 {
            let line = format!("{i} A.y={}\n", i * 3);
            sut.write_all(line.as_bytes()).unwrap();
            want.extend_from_slice(line.as_bytes());
        }
        sut.flush().unwrap();
        let got = sut.finish().unwrap();
        assert_eq!(got, want);
    }

    #[test]
    fn a_dropped_writer_still_writes_everything() {
        let path = std::env::temp_dir().join(format!("offload_{}.txt", std::process::id()));
        {
            let mut sut = Offload::new(std::fs::File::create(&path).unwrap()).unwrap();
            sut.write_all(b"last words\n").unwrap();
        }
        assert_eq!(std::fs::read(&path).unwrap(), b"last words\n");
        let _ = std::fs::remove_file(&path);
    }
}
