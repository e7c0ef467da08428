//! SDO information (ETG.1000.6 5.6.3): the object description list, so a master can list the
//! dictionary. Other SDO information requests get an SDO information error.

use crate::coe_codes::{abort, service};
use crate::dictionary::ObjectDictionary;

const GET_OD_LIST_REQUEST: u8 = 0x01;
const GET_OD_LIST_RESPONSE: u8 = 0x02;
const INFO_ERROR: u8 = 0x07;

fn header(op_code: u8, incomplete: bool, fragments_left: u16) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&(u16::from(service::SDO_INFORMATION) << 12).to_le_bytes());
    out.push(op_code | if incomplete { 0x80 } else { 0 });
    out.push(0);
    out.extend_from_slice(&fragments_left.to_le_bytes());
    out
}

/// Answers an SDO information request (CoE payload in, CoE payload out). Lists longer than
/// one mailbox are cut to what fits, in one fragment.
pub fn handle(request: &[u8], od: &ObjectDictionary, max_payload: usize) -> Vec<u8> {
    let op_code = request.get(2).map(|b| b & 0x7F).unwrap_or(0);
    if op_code != GET_OD_LIST_REQUEST {
        let mut out = header(INFO_ERROR, false, 0);
        out.extend_from_slice(&abort::UNSUPPORTED_ACCESS.to_le_bytes());
        return out;
    }
    let list_type = request
        .get(6..8)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .unwrap_or(1);
    let all = od.indices();
    let rx: Vec<u16> = all
        .iter()
        .copied()
        .filter(|&i| od.entries().any(|e| e.index == i && e.pdo.rx()))
        .collect();
    let tx: Vec<u16> = all
        .iter()
        .copied()
        .filter(|&i| od.entries().any(|e| e.index == i && e.pdo.tx()))
        .collect();
    let mut out = header(GET_OD_LIST_RESPONSE, false, 0);
    out.extend_from_slice(&list_type.to_le_bytes());
    let list: Vec<u16> = match list_type {
        0 => vec![all.len() as u16, rx.len() as u16, tx.len() as u16, 0, 0],
        1 => all,
        2 => rx,
        3 => tx,
        _ => Vec::new(),
    };
    for index in list {
        if out.len() + 2 > max_payload {
            break;
        }
        out.extend_from_slice(&index.to_le_bytes());
    }
    out
}
