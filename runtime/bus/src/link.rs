//! An Ethernet link to a fieldbus: a raw `AF_PACKET` socket bound to one network interface for
//! one ethertype (EtherCAT's 0x88A4), as the EtherCAT master and the slave emulator use it.
//!
//! Frames are whole Ethernet frames (destination, source, ethertype, payload); the kernel adds
//! nothing but the frame check sequence. Opening needs CAP_NET_RAW (root, or `setcap
//! cap_net_raw+ep` on the program); without it the error says so in one line.

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::time::Duration;

/// EtherCAT's ethertype.
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;

/// Why a link could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error(
        "interface name '{0}' is not a Linux interface name (1 to 15 bytes, no '/', NUL or space)"
    )]
    BadName(String),
    #[error("interface '{0}' does not exist (see `ip link`)")]
    NoInterface(String),
    #[error(
        "opening a raw socket on '{0}' needs CAP_NET_RAW: run as root or `setcap cap_net_raw+ep` the program"
    )]
    NoPermission(String),
    #[error("interface '{interface}': {source}")]
    Io {
        interface: String,
        #[source]
        source: io::Error,
    },
}

/// A raw socket on one interface that sends and receives frames of one ethertype.
#[derive(Debug)]
pub struct RawLink {
    fd: OwnedFd,
    interface: String,
}

/// Checks a Linux interface name (IFNAMSIZ is 16 with the NUL).
fn check_name(interface: &str) -> Result<CString, LinkError> {
    let bad = interface.is_empty()
        || interface.len() > 15
        || interface
            .bytes()
            .any(|b| b == b'/' || b == 0 || b.is_ascii_whitespace());
    if bad {
        return Err(LinkError::BadName(interface.to_owned()));
    }
    CString::new(interface).map_err(|_| LinkError::BadName(interface.to_owned()))
}

impl RawLink {
    /// Opens a non-blocking raw socket on `interface` for frames of `ethertype`.
    pub fn open(interface: &str, ethertype: u16) -> Result<RawLink, LinkError> {
        let name = check_name(interface)?;
        // SAFETY: `name` is a valid NUL-terminated string that outlives the call.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(LinkError::NoInterface(interface.to_owned()));
        }
        let io_error = |source: io::Error| {
            if source.raw_os_error() == Some(libc::EPERM) {
                LinkError::NoPermission(interface.to_owned())
            } else {
                LinkError::Io {
                    interface: interface.to_owned(),
                    source,
                }
            }
        };
        let protocol = i32::from(ethertype.to_be());
        // SAFETY: socket(2) with constant arguments; the result is checked before use.
        let fd = unsafe {
            libc::socket(
                libc::AF_PACKET,
                libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
                protocol,
            )
        };
        if fd < 0 {
            return Err(io_error(io::Error::last_os_error()));
        }
        // SAFETY: `fd` is a socket just opened and owned by nothing else.
        let fd = unsafe { OwnedFd::from_raw_fd(fd) };
        // SAFETY: an all-zero sockaddr_ll is a valid value of the plain C struct.
        let mut address: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        address.sll_family = libc::AF_PACKET as u16;
        address.sll_protocol = ethertype.to_be();
        address.sll_ifindex = index as i32;
        // SAFETY: `address` is a properly initialised sockaddr_ll and the length is its size.
        let bound = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&address as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if bound < 0 {
            return Err(io_error(io::Error::last_os_error()));
        }
        // Frames this socket sends are not delivered back to it (Linux 4.20 and later; on older
        // kernels the peers' source addresses tell them apart, so a refusal is not an error).
        let on: libc::c_int = 1;
        // SAFETY: `on` is a c_int that lives through the call, and its size is passed.
        unsafe {
            libc::setsockopt(
                fd.as_raw_fd(),
                libc::SOL_PACKET,
                libc::PACKET_IGNORE_OUTGOING,
                (&on as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        Ok(RawLink {
            fd,
            interface: interface.to_owned(),
        })
    }

    /// The interface's name.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// Sends one whole Ethernet frame.
    pub fn send(&self, frame: &[u8]) -> io::Result<()> {
        // SAFETY: the pointer and length describe `frame`, which lives through the call.
        let sent =
            unsafe { libc::send(self.fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0) };
        if sent < 0 {
            return Err(io::Error::last_os_error());
        }
        if sent as usize != frame.len() {
            return Err(io::Error::new(
                io::ErrorKind::WriteZero,
                format!("sent {sent} of {} bytes", frame.len()),
            ));
        }
        Ok(())
    }

    /// Receives one frame into `buf` if one is waiting: its length, or `None`.
    pub fn try_recv(&self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        // SAFETY: the pointer and length describe `buf`, writable and alive through the call.
        let n = unsafe { libc::recv(self.fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len(), 0) };
        if n < 0 {
            let e = io::Error::last_os_error();
            return match e.kind() {
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted => Ok(None),
                _ => Err(e),
            };
        }
        Ok(Some(n as usize))
    }

    /// Waits up to `timeout` for a frame to arrive: whether one is waiting.
    pub fn wait(&self, timeout: Duration) -> io::Result<bool> {
        let mut fds = [libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        }];
        let ms = timeout.as_micros().div_ceil(1000).min(i32::MAX as u128) as i32;
        // SAFETY: `fds` is a valid array of one pollfd for the duration of the call.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), 1, ms) };
        if ready < 0 {
            let e = io::Error::last_os_error();
            return if e.kind() == io::ErrorKind::Interrupted {
                Ok(false)
            } else {
                Err(e)
            };
        }
        Ok(ready > 0)
    }

    /// Receives one frame, waiting up to `timeout`: its length, or `None` if none came.
    pub fn recv(&self, buf: &mut [u8], timeout: Duration) -> io::Result<Option<usize>> {
        if let Some(n) = self.try_recv(buf)? {
            return Ok(Some(n));
        }
        if self.wait(timeout)? {
            return self.try_recv(buf);
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interface_name_linux_cannot_hold_is_refused_before_any_system_call() {
        for name in ["", "a-name-of-sixteen", "a/b", "a b"] {
            let e = RawLink::open(name, ETHERTYPE_ETHERCAT).unwrap_err();
            assert!(matches!(e, LinkError::BadName(_)), "{name}: {e}");
        }
    }

    #[test]
    fn a_missing_interface_is_named() {
        let e = RawLink::open("nosuchif0", ETHERTYPE_ETHERCAT).unwrap_err();
        assert_eq!(
            e.to_string(),
            "interface 'nosuchif0' does not exist (see `ip link`)"
        );
    }
}
