//! CANopen over EtherCAT: the SDO server (expedited, normal and segmented upload and
//! download, aborts) and the object description list of SDO information.
//!
//! A CoE payload is what follows the 6-byte mailbox header: a 2-byte CoE header (service in
//! bits 12–15), then for SDO a command byte, the index, the subindex and 4 bytes of data or
//! size.

use crate::al::AlState;
use crate::dictionary::{Access, DataType, ObjectDictionary};
use crate::pdo;

pub use crate::coe_codes::{abort, service};

const CCS_DOWNLOAD_SEGMENT: u8 = 0;
const CCS_DOWNLOAD: u8 = 1;
const CCS_UPLOAD: u8 = 2;
const CCS_UPLOAD_SEGMENT: u8 = 3;
const CCS_ABORT: u8 = 4;

/// Bytes of CoE header + SDO command + index + subindex + data/size.
const SDO_LEN: usize = 10;

#[derive(Debug, Clone)]
struct UploadInProgress {
    data: Vec<u8>,
    sent: usize,
    toggle: bool,
}

#[derive(Debug, Clone)]
struct DownloadInProgress {
    index: u16,
    sub_index: u8,
    size: usize,
    data: Vec<u8>,
    toggle: bool,
}

/// The SDO server of one slave: stateless except for a segmented transfer in progress.
#[derive(Debug, Clone, Default)]
pub struct SdoServer {
    upload: Option<UploadInProgress>,
    download: Option<DownloadInProgress>,
}

fn coe_header(service: u8) -> [u8; 2] {
    (u16::from(service) << 12).to_le_bytes()
}

/// An SDO frame of `service`: the command byte, index:subindex and 4 bytes of data or size.
fn sdo_frame(service: u8, command: u8, index: u16, sub_index: u8, data: [u8; 4]) -> Vec<u8> {
    let mut out = Vec::with_capacity(SDO_LEN);
    out.extend_from_slice(&coe_header(service));
    out.push(command);
    out.extend_from_slice(&index.to_le_bytes());
    out.push(sub_index);
    out.extend_from_slice(&data);
    out
}

/// An abort response for index:subindex.
pub fn abort_response(index: u16, sub_index: u8, code: u32) -> Vec<u8> {
    sdo_frame(
        service::SDO_REQUEST,
        CCS_ABORT << 5,
        index,
        sub_index,
        code.to_le_bytes(),
    )
}

fn sdo_response(command: u8, index: u16, sub_index: u8, data: [u8; 4]) -> Vec<u8> {
    sdo_frame(service::SDO_RESPONSE, command, index, sub_index, data)
}

impl SdoServer {
    /// Answers one CoE payload. `max_payload` is the room for a CoE payload in the send
    /// mailbox (its size minus the mailbox header). `None` if the request needs no answer (an
    /// abort from the master).
    pub fn handle(
        &mut self,
        request: &[u8],
        od: &mut ObjectDictionary,
        state: AlState,
        max_payload: usize,
    ) -> Option<Vec<u8>> {
        let kind = request
            .get(0..2)
            .map(|header| (u16::from_le_bytes([header[0], header[1]]) >> 12) as u8);
        match kind {
            Some(service::SDO_REQUEST) => {}
            Some(service::SDO_INFORMATION) => {
                return Some(crate::coe_info::handle(request, od, max_payload))
            }
            _ => return Some(abort_response(0, 0, abort::INVALID_COMMAND)),
        }
        // An SDO request.
        let Some(&command) = request.get(2) else {
            return Some(abort_response(0, 0, abort::INVALID_COMMAND));
        };
        let ccs = command >> 5;
        if ccs == CCS_UPLOAD_SEGMENT {
            return Some(self.upload_segment(command, max_payload));
        }
        if ccs == CCS_DOWNLOAD_SEGMENT {
            return Some(self.download_segment(request, od, state));
        }
        let (Some(index), Some(&sub_index)) = (
            request.get(3..5).map(|b| u16::from_le_bytes([b[0], b[1]])),
            request.get(5),
        ) else {
            return Some(abort_response(0, 0, abort::INVALID_COMMAND));
        };
        match ccs {
            CCS_UPLOAD => {
                self.upload = None;
                if command & 0x10 != 0 {
                    return Some(abort_response(index, sub_index, abort::NO_COMPLETE_ACCESS));
                }
                Some(self.upload(index, sub_index, od, max_payload))
            }
            CCS_DOWNLOAD => {
                self.download = None;
                if command & 0x10 != 0 {
                    return Some(abort_response(index, sub_index, abort::NO_COMPLETE_ACCESS));
                }
                Some(self.download(command, index, sub_index, request, od, state))
            }
            CCS_ABORT => {
                self.upload = None;
                self.download = None;
                None
            }
            _ => Some(abort_response(index, sub_index, abort::INVALID_COMMAND)),
        }
    }

    fn upload(
        &mut self,
        index: u16,
        sub_index: u8,
        od: &ObjectDictionary,
        max_payload: usize,
    ) -> Vec<u8> {
        let entry = match lookup(od, index, sub_index) {
            Ok(entry) => entry,
            Err(code) => return abort_response(index, sub_index, code),
        };
        if entry.access == Access::WriteOnly {
            return abort_response(index, sub_index, abort::WRITE_ONLY);
        }
        let data = entry.value.to_vec();
        if (1..=4).contains(&data.len()) {
            let unused = (4 - data.len()) as u8;
            let mut bytes = [0u8; 4];
            bytes[..data.len()].copy_from_slice(&data);
            // scs 2, size indicated, expedited, n unused bytes.
            return sdo_response(
                (CCS_UPLOAD << 5) | (unused << 2) | 0x03,
                index,
                sub_index,
                bytes,
            );
        }
        let size = (data.len() as u32).to_le_bytes();
        let mut out = sdo_response((CCS_UPLOAD << 5) | 0x01, index, sub_index, size);
        if SDO_LEN + data.len() <= max_payload {
            out.extend_from_slice(&data);
        } else {
            // Too long for the mailbox: the data follows in segments.
            self.upload = Some(UploadInProgress {
                data,
                sent: 0,
                toggle: false,
            });
        }
        out
    }

    fn upload_segment(&mut self, command: u8, max_payload: usize) -> Vec<u8> {
        let toggle = command & 0x10 != 0;
        let Some(upload) = self.upload.as_mut() else {
            return abort_response(0, 0, abort::INVALID_COMMAND);
        };
        if toggle != upload.toggle {
            self.upload = None;
            return abort_response(0, 0, abort::TOGGLE_BIT);
        }
        let room = max_payload.saturating_sub(3).max(7);
        let rest = &upload.data[upload.sent..];
        let n = rest.len().min(room);
        let last = upload.sent + n == upload.data.len();
        let mut segment = rest[..n].to_vec();
        let unused = if n < 7 { (7 - n) as u8 } else { 0 };
        segment.resize(n.max(7), 0);
        let mut out = Vec::with_capacity(3 + segment.len());
        out.extend_from_slice(&coe_header(service::SDO_RESPONSE));
        out.push((u8::from(toggle) << 4) | (unused << 1) | u8::from(last));
        out.extend_from_slice(&segment);
        upload.sent += n;
        upload.toggle = !upload.toggle;
        if last {
            self.upload = None;
        }
        out
    }

    fn download(
        &mut self,
        command: u8,
        index: u16,
        sub_index: u8,
        request: &[u8],
        od: &mut ObjectDictionary,
        state: AlState,
    ) -> Vec<u8> {
        let expedited = command & 0x02 != 0;
        let size_indicated = command & 0x01 != 0;
        let Some(field) = request.get(6..10) else {
            return abort_response(index, sub_index, abort::DATA_TOO_SHORT);
        };
        if expedited {
            let len = if size_indicated {
                4 - usize::from((command >> 2) & 0x03)
            } else {
                od.entry(index, sub_index)
                    .map(|e| e.value.len().min(4))
                    .unwrap_or(4)
            };
            let data = field[..len].to_vec();
            return match store(od, index, sub_index, &data, state) {
                Ok(()) => sdo_response(SCS_DOWNLOAD_RESPONSE, index, sub_index, [0; 4]),
                Err(code) => abort_response(index, sub_index, code),
            };
        }
        let size = u32::from_le_bytes([field[0], field[1], field[2], field[3]]) as usize;
        let data = request.get(SDO_LEN..).unwrap_or(&[]);
        if data.len() >= size {
            return match store(od, index, sub_index, &data[..size], state) {
                Ok(()) => sdo_response(SCS_DOWNLOAD_RESPONSE, index, sub_index, [0; 4]),
                Err(code) => abort_response(index, sub_index, code),
            };
        }
        if let Err(code) = lookup(od, index, sub_index) {
            return abort_response(index, sub_index, code);
        }
        self.download = Some(DownloadInProgress {
            index,
            sub_index,
            size,
            data: data.to_vec(),
            toggle: false,
        });
        sdo_response(SCS_DOWNLOAD_RESPONSE, index, sub_index, [0; 4])
    }

    fn download_segment(
        &mut self,
        request: &[u8],
        od: &mut ObjectDictionary,
        state: AlState,
    ) -> Vec<u8> {
        let command = request[2];
        let toggle = command & 0x10 != 0;
        let last = command & 0x01 != 0;
        let unused = usize::from((command >> 1) & 0x07);
        let Some(download) = self.download.as_mut() else {
            return abort_response(0, 0, abort::INVALID_COMMAND);
        };
        if toggle != download.toggle {
            self.download = None;
            return abort_response(0, 0, abort::TOGGLE_BIT);
        }
        let payload = request.get(3..).unwrap_or(&[]);
        let n = if payload.len() <= 7 {
            payload.len().saturating_sub(unused)
        } else {
            payload.len()
        };
        download.data.extend_from_slice(&payload[..n]);
        download.toggle = !download.toggle;
        let mut out = Vec::with_capacity(SDO_LEN);
        out.extend_from_slice(&coe_header(service::SDO_RESPONSE));
        out.push((1 << 5) | (u8::from(toggle) << 4));
        out.extend_from_slice(&[0; 7]);
        if last {
            let done = self.download.take();
            if let Some(done) = done {
                let data = &done.data[..done.size.min(done.data.len())];
                if let Err(code) = store(od, done.index, done.sub_index, data, state) {
                    return abort_response(done.index, done.sub_index, code);
                }
            }
        }
        out
    }
}

/// scs 3 (download initiate response) in the command byte.
const SCS_DOWNLOAD_RESPONSE: u8 = 3 << 5;

fn lookup(od: &ObjectDictionary, index: u16, sub_index: u8) -> Result<&crate::ObjectEntry, u32> {
    match od.entry(index, sub_index) {
        Some(entry) => Ok(entry),
        None if od.has_object(index) => Err(abort::SUBINDEX_NOT_FOUND),
        None => Err(abort::NOT_FOUND),
    }
}

/// Stores an SDO download after every check: existence, access right and state, size, and
/// the PDO rules.
fn store(
    od: &mut ObjectDictionary,
    index: u16,
    sub_index: u8,
    data: &[u8],
    state: AlState,
) -> Result<(), u32> {
    let entry = lookup(od, index, sub_index)?;
    match entry.access {
        Access::ReadOnly => return Err(abort::READ_ONLY),
        Access::ReadWritePreOp if state != AlState::PreOp => return Err(abort::WRONG_STATE),
        _ => {}
    }
    match entry.data_type.byte_len() {
        Some(expected) if data.len() > expected => return Err(abort::DATA_TOO_LONG),
        Some(expected) if data.len() < expected => return Err(abort::DATA_TOO_SHORT),
        _ => {}
    }
    if entry.data_type == DataType::Boolean && data.first().is_some_and(|b| *b > 1) {
        return Err(abort::VALUE_OUT_OF_RANGE);
    }
    pdo::check_write(od, index, sub_index, data)?;
    od.set_raw(index, sub_index, data)
        .map_err(|_| abort::NOT_FOUND)?;
    tracing::debug!(index, sub_index, len = data.len(), "SDO download stored");
    Ok(())
}

#[cfg(test)]
mod tests;
