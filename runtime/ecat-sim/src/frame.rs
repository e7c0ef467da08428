//! EtherCAT frames: the Ethernet II header, the EtherCAT header and the chain of datagrams,
//! decoded in place over the caller's `&mut [u8]` so every slave of a chain works on the one
//! buffer that goes back on the wire.
//!
//! Layout (all little endian except the Ethernet header):
//!
//! ```text
//! | dst MAC (6) | src MAC (6) | ethertype 0x88A4 (2) | length:11 res:1 type:4 (2) | datagram... |
//! datagram: | cmd (1) | idx (1) | address (4) | len:11 res:3 circ:1 more:1 (2) | irq (2) | data (len) | wkc (2) |
//! ```

use crate::datagram::{Command, Datagram, DATAGRAM_HEADER_LEN, WKC_LEN};

/// The ethertype of EtherCAT frames.
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// Bytes of the Ethernet II header (two MACs and the ethertype; no VLAN tag).
pub const ETHERNET_HEADER_LEN: usize = 14;
/// Bytes of the EtherCAT frame header.
pub const ECAT_HEADER_LEN: usize = 2;
/// The EtherCAT header type of a frame of datagrams (DLPDU).
pub const ECAT_TYPE_DLPDU: u8 = 1;
/// Where the datagrams start in the Ethernet frame.
pub const DATAGRAMS_START: usize = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
/// The locally administered bit of the first MAC byte: the first slave sets it in the source
/// address, so the master can tell its own frame (10:10:…) from the processed one (12:10:…).
pub const LOCALLY_ADMINISTERED_BIT: u8 = 0x02;

/// Why a frame from the wire could not be decoded. Nothing in this crate panics on a malformed
/// frame: every path ends in one of these.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Fewer bytes than an Ethernet II header.
    #[error("a frame of {len} bytes is shorter than the 14-byte Ethernet header")]
    ShorterThanEthernetHeader {
        /// Bytes received.
        len: usize,
    },
    /// The ethertype is not 0x88A4 (a VLAN tag also lands here).
    #[error("ethertype {ethertype:#06x} is not EtherCAT (0x88a4)")]
    NotEtherCat {
        /// The ethertype found.
        ethertype: u16,
    },
    /// No room for the 2-byte EtherCAT header.
    #[error("a frame of {len} bytes has no room for the EtherCAT header")]
    ShorterThanEtherCatHeader {
        /// Bytes received.
        len: usize,
    },
    /// The EtherCAT header's type is not 1 (datagrams).
    #[error("EtherCAT header type {kind} is not a frame of datagrams (type 1)")]
    UnsupportedType {
        /// The type found.
        kind: u8,
    },
    /// The EtherCAT header announces more bytes than the frame holds.
    #[error(
        "the EtherCAT header announces {declared} bytes of datagrams, the frame holds {available}"
    )]
    LengthBeyondFrame {
        /// Bytes announced.
        declared: usize,
        /// Bytes present after the header.
        available: usize,
    },
    /// The EtherCAT header announces zero bytes: no datagram to process.
    #[error("the frame holds no datagram")]
    NoDatagram,
    /// A datagram header runs past the announced length.
    #[error("datagram {position} (byte {offset}) has a truncated 10-byte header")]
    DatagramHeaderTruncated {
        /// Datagram number in the frame, from 0.
        position: usize,
        /// Its offset in the Ethernet frame.
        offset: usize,
    },
    /// A datagram's data and working counter run past the announced length.
    #[error("datagram {position} announces {len} data bytes and a working counter, only {available} bytes remain")]
    DatagramDataTruncated {
        /// Datagram number in the frame, from 0.
        position: usize,
        /// Data bytes announced.
        len: usize,
        /// Bytes left in the frame for data and working counter.
        available: usize,
    },
}

/// Where one datagram sits in the frame buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DatagramSpan {
    /// Offset of the datagram header in the Ethernet frame.
    pub offset: usize,
    /// Header + data + working counter.
    pub total_len: usize,
    /// For an FPRD, FPWR or FPRW: the station address it is for. Only the slave of that
    /// address acts on it (an FRMW is not one of these: every other slave writes it), so the
    /// others pass it untouched — a chain skips them without a look at the datagram.
    pub only_for_station: Option<u16>,
}

/// Decodes the headers of `frame` and lists its datagrams into `spans` (cleared first; the
/// caller keeps the vector to reuse its allocation from frame to frame).
pub fn decode(frame: &[u8], spans: &mut Vec<DatagramSpan>) -> Result<(), FrameError> {
    spans.clear();
    if frame.len() < ETHERNET_HEADER_LEN {
        return Err(FrameError::ShorterThanEthernetHeader { len: frame.len() });
    }
    let ethertype = u16::from_be_bytes([frame[12], frame[13]]);
    if ethertype != ETHERTYPE_ETHERCAT {
        return Err(FrameError::NotEtherCat { ethertype });
    }
    let Some(header) = frame.get(ETHERNET_HEADER_LEN..DATAGRAMS_START) else {
        return Err(FrameError::ShorterThanEtherCatHeader { len: frame.len() });
    };
    let raw = u16::from_le_bytes([header[0], header[1]]);
    let declared = usize::from(raw & 0x07FF);
    let kind = (raw >> 12) as u8;
    if kind != ECAT_TYPE_DLPDU {
        return Err(FrameError::UnsupportedType { kind });
    }
    let available = frame.len() - DATAGRAMS_START;
    if declared > available {
        return Err(FrameError::LengthBeyondFrame {
            declared,
            available,
        });
    }
    if declared == 0 {
        return Err(FrameError::NoDatagram);
    }
    let end = DATAGRAMS_START + declared;
    let mut offset = DATAGRAMS_START;
    let mut position = 0;
    loop {
        let Some(header) = frame
            .get(offset..offset + DATAGRAM_HEADER_LEN)
            .filter(|_| offset + DATAGRAM_HEADER_LEN <= end)
        else {
            return Err(FrameError::DatagramHeaderTruncated { position, offset });
        };
        let flags = u16::from_le_bytes([header[6], header[7]]);
        let len = usize::from(flags & 0x07FF);
        let more_follows = flags & 0x8000 != 0;
        let remaining = end - offset - DATAGRAM_HEADER_LEN;
        if len + WKC_LEN > remaining {
            return Err(FrameError::DatagramDataTruncated {
                position,
                len,
                available: remaining,
            });
        }
        let total_len = DATAGRAM_HEADER_LEN + len + WKC_LEN;
        let only_for_station = matches!(
            Command::from_code(header[0]),
            Some(Command::Fprd | Command::Fpwr | Command::Fprw)
        )
        .then(|| u16::from_le_bytes([header[2], header[3]]));
        spans.push(DatagramSpan {
            offset,
            total_len,
            only_for_station,
        });
        offset += total_len;
        position += 1;
        if !more_follows {
            return Ok(());
        }
    }
}

/// A view of the datagram at `span` in `frame`: `None` only for a span that [`decode`] did
/// not produce from this frame.
pub fn datagram_at(frame: &mut [u8], span: DatagramSpan) -> Option<Datagram<'_>> {
    frame
        .get_mut(span.offset..span.offset + span.total_len)
        .map(Datagram::new_unchecked)
}

/// Sets the locally administered bit of the source MAC, as the first slave of a real ring
/// does; the master ignores frames whose source is its own address.
pub fn mark_source_mac(frame: &mut [u8]) {
    if let Some(first) = frame.get_mut(6) {
        *first |= LOCALLY_ADMINISTERED_BIT;
    }
}

/// The source MAC of a frame, if it has an Ethernet header.
pub fn source_mac(frame: &[u8]) -> Option<[u8; 6]> {
    frame.get(6..12).and_then(|s| s.try_into().ok())
}

/// Builds EtherCAT frames, for tests and tools that talk to a chain without a master.
#[derive(Debug, Clone)]
pub struct FrameBuilder {
    bytes: Vec<u8>,
    last_header: Option<usize>,
}

impl Default for FrameBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameBuilder {
    /// The master's source address, as ethercrab sends it.
    pub const MASTER_MAC: [u8; 6] = [0x10; 6];

    /// An empty frame from [`Self::MASTER_MAC`] to the broadcast address.
    pub fn new() -> Self {
        let mut bytes = Vec::with_capacity(64);
        bytes.extend_from_slice(&[0xFF; 6]);
        bytes.extend_from_slice(&Self::MASTER_MAC);
        bytes.extend_from_slice(&ETHERTYPE_ETHERCAT.to_be_bytes());
        bytes.extend_from_slice(&[0, 0]);
        Self {
            bytes,
            last_header: None,
        }
    }

    /// Appends a datagram with `data` (its length is the datagram's length) and working
    /// counter 0. `address` is the 4-byte address field as a little-endian u32 (ADP in the
    /// low half, ADO in the high half, or a logical address).
    pub fn datagram(mut self, command: u8, index: u8, address: u32, data: &[u8]) -> Self {
        if let Some(previous) = self.last_header {
            self.bytes[previous + 7] |= 0x80;
        }
        let offset = self.bytes.len();
        self.bytes.push(command);
        self.bytes.push(index);
        self.bytes.extend_from_slice(&address.to_le_bytes());
        let len = (data.len() as u16) & 0x07FF;
        self.bytes.extend_from_slice(&len.to_le_bytes());
        self.bytes.extend_from_slice(&[0, 0]);
        self.bytes.extend_from_slice(data);
        self.bytes.extend_from_slice(&[0, 0]);
        self.last_header = Some(offset);
        self
    }

    /// The finished frame (padded to the 60-byte Ethernet minimum).
    pub fn build(mut self) -> Vec<u8> {
        let declared = (self.bytes.len() - DATAGRAMS_START) as u16;
        let header = (declared & 0x07FF) | (u16::from(ECAT_TYPE_DLPDU) << 12);
        self.bytes[ETHERNET_HEADER_LEN..DATAGRAMS_START].copy_from_slice(&header.to_le_bytes());
        if self.bytes.len() < 60 {
            self.bytes.resize(60, 0);
        }
        self.bytes
    }
}

/// The address field of a physically addressed datagram: ADP (position or station address)
/// in the low half, ADO (register offset) in the high half.
pub fn physical_address(adp: u16, ado: u16) -> u32 {
    u32::from(adp) | (u32::from(ado) << 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An FPRD of AL status (0x0130, 2 bytes) to station 0x1000, as ethercrab sends it.
    const FPRD_AL_STATUS: [u8; 30] = [
        0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, // dst
        0x10, 0x10, 0x10, 0x10, 0x10, 0x10, // src
        0x88, 0xA4, // ethertype
        0x0E, 0x10, // 14 bytes of datagrams, type 1
        0x04, 0x07, // FPRD, index 7
        0x00, 0x10, 0x30, 0x01, // ADP 0x1000, ADO 0x0130
        0x02, 0x00, // len 2, last
        0x00, 0x00, // irq
        0x00, 0x00, // data
        0x00, 0x00, // wkc
    ];

    #[test]
    fn a_golden_fprd_decodes_to_one_datagram_with_its_fields() {
        let mut frame = FPRD_AL_STATUS.to_vec();
        let mut spans = Vec::new();
        decode(&frame, &mut spans).unwrap();
        assert_eq!(spans.len(), 1);
        let sut = datagram_at(&mut frame, spans[0]).unwrap();
        assert_eq!(sut.command_code(), 0x04);
        assert_eq!(sut.index(), 7);
        assert_eq!(sut.adp(), 0x1000);
        assert_eq!(sut.ado(), 0x0130);
        assert_eq!(sut.data().len(), 2);
        assert!(!sut.more_follows());
        assert_eq!(sut.working_counter(), 0);
    }

    #[test]
    fn two_chained_datagrams_are_both_listed_in_order() {
        let frame = FrameBuilder::new()
            .datagram(0x07, 1, physical_address(0, 0x0000), &[0])
            .datagram(0x0C, 2, 0x0001_0000, &[1, 2, 3, 4])
            .build();
        let mut spans = Vec::new();
        decode(&frame, &mut spans).unwrap();
        assert_eq!(spans.len(), 2);
        assert_eq!(spans[0].offset, DATAGRAMS_START);
        assert_eq!(spans[0].total_len, 13);
        assert_eq!(spans[1].offset, DATAGRAMS_START + 13);
        let mut frame = frame;
        let second = datagram_at(&mut frame, spans[1]).unwrap();
        assert_eq!(second.logical_address(), 0x0001_0000);
        assert_eq!(second.data(), &[1, 2, 3, 4]);
    }

    #[test]
    fn the_builder_reproduces_the_golden_bytes() {
        let mut built = FrameBuilder::new()
            .datagram(0x04, 7, physical_address(0x1000, 0x0130), &[0, 0])
            .build();
        built.truncate(FPRD_AL_STATUS.len());
        assert_eq!(built, FPRD_AL_STATUS);
    }

    #[test]
    fn a_frame_shorter_than_its_ethernet_header_is_refused() {
        let mut spans = Vec::new();
        assert_eq!(
            decode(&FPRD_AL_STATUS[..10], &mut spans),
            Err(FrameError::ShorterThanEthernetHeader { len: 10 })
        );
    }

    #[test]
    fn a_frame_without_room_for_the_ethercat_header_is_refused() {
        let mut spans = Vec::new();
        assert_eq!(
            decode(&FPRD_AL_STATUS[..15], &mut spans),
            Err(FrameError::ShorterThanEtherCatHeader { len: 15 })
        );
    }

    #[test]
    fn a_frame_of_another_ethertype_is_refused() {
        let mut frame = FPRD_AL_STATUS;
        frame[12] = 0x08;
        frame[13] = 0x00;
        let mut spans = Vec::new();
        assert_eq!(
            decode(&frame, &mut spans),
            Err(FrameError::NotEtherCat { ethertype: 0x0800 })
        );
    }

    #[test]
    fn a_frame_of_another_ethercat_type_is_refused() {
        let mut frame = FPRD_AL_STATUS;
        frame[15] = 0x40;
        let mut spans = Vec::new();
        assert_eq!(
            decode(&frame, &mut spans),
            Err(FrameError::UnsupportedType { kind: 4 })
        );
    }

    #[test]
    fn a_header_announcing_more_than_the_frame_holds_is_refused() {
        let mut frame = FPRD_AL_STATUS;
        frame[14] = 0x40;
        let mut spans = Vec::new();
        assert_eq!(
            decode(&frame, &mut spans),
            Err(FrameError::LengthBeyondFrame {
                declared: 0x40,
                available: 14
            })
        );
    }

    #[test]
    fn a_frame_announcing_no_datagram_is_refused() {
        let mut frame = FPRD_AL_STATUS;
        frame[14] = 0;
        let mut spans = Vec::new();
        assert_eq!(decode(&frame, &mut spans), Err(FrameError::NoDatagram));
    }

    #[test]
    fn a_datagram_longer_than_the_frame_is_refused() {
        let mut frame = FPRD_AL_STATUS;
        frame[22] = 0x20;
        let mut spans = Vec::new();
        assert_eq!(
            decode(&frame, &mut spans),
            Err(FrameError::DatagramDataTruncated {
                position: 0,
                len: 0x20,
                available: 4
            })
        );
    }

    #[test]
    fn a_more_follows_bit_without_a_next_datagram_is_refused() {
        let mut frame = FPRD_AL_STATUS;
        frame[23] |= 0x80;
        let mut spans = Vec::new();
        assert_eq!(
            decode(&frame, &mut spans),
            Err(FrameError::DatagramHeaderTruncated {
                position: 1,
                offset: 30
            })
        );
    }

    #[test]
    fn the_reply_source_mac_gets_the_locally_administered_bit() {
        let mut frame = FPRD_AL_STATUS;
        mark_source_mac(&mut frame);
        assert_eq!(
            source_mac(&frame),
            Some([0x12, 0x10, 0x10, 0x10, 0x10, 0x10])
        );
    }

    #[test]
    fn arbitrary_bytes_never_panic_the_decoder() {
        // A small deterministic fuzz: every prefix and every single-byte corruption of a
        // two-datagram frame either decodes or returns an error.
        let frame = FrameBuilder::new()
            .datagram(0x07, 1, 0, &[0; 2])
            .datagram(0x0C, 2, 0, &[0; 8])
            .build();
        let mut spans = Vec::new();
        for end in 0..=frame.len() {
            let _ = decode(&frame[..end], &mut spans);
        }
        for at in 0..frame.len() {
            for value in [0x00, 0x7F, 0x80, 0xFF] {
                let mut corrupted = frame.clone();
                corrupted[at] = value;
                if decode(&corrupted, &mut spans).is_ok() {
                    for span in spans.clone() {
                        assert!(datagram_at(&mut corrupted, span).is_some());
                    }
                }
            }
        }
    }
}
