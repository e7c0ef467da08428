use super::*;
use crate::dictionary::{ObjectEntry, PdoMappable};

fn dictionary() -> ObjectDictionary {
    let mut od = ObjectDictionary::new();
    od.insert(ObjectEntry::new(0x6041, 0, "Statusword", 0x1234u16).tx_pdo());
    od.insert(ObjectEntry::new(0x6060, 0, "Mode", 0i8).read_write());
    od.insert(ObjectEntry::new(0x1C12, 0, "Assign", 0u8).with_access(Access::ReadWritePreOp));
    od.insert(ObjectEntry::string(
        0x1008,
        0,
        "Device name",
        "A rather long device name, 40 bytes long",
    ));
    od.insert(ObjectEntry::string(0x2000, 0, "Label", "abc").read_write());
    od
}

fn upload(index: u16, sub_index: u8) -> Vec<u8> {
    let mut out = coe_header(service::SDO_REQUEST).to_vec();
    out.push(CCS_UPLOAD << 5);
    out.extend_from_slice(&index.to_le_bytes());
    out.push(sub_index);
    out.extend_from_slice(&[0; 4]);
    out
}

fn expedited_download(index: u16, sub_index: u8, data: &[u8]) -> Vec<u8> {
    let mut out = coe_header(service::SDO_REQUEST).to_vec();
    out.push((CCS_DOWNLOAD << 5) | (((4 - data.len()) as u8) << 2) | 0x03);
    out.extend_from_slice(&index.to_le_bytes());
    out.push(sub_index);
    let mut field = [0u8; 4];
    field[..data.len()].copy_from_slice(data);
    out.extend_from_slice(&field);
    out
}

fn abort_code_of(response: &[u8]) -> Option<u32> {
    (response[2] >> 5 == CCS_ABORT).then(|| u32::from_le_bytes(response[6..10].try_into().unwrap()))
}

#[test]
fn an_upload_of_two_bytes_is_expedited_with_two_unused_bytes() {
    let mut sut = SdoServer::default();
    let response = sut
        .handle(&upload(0x6041, 0), &mut dictionary(), AlState::PreOp, 122)
        .unwrap();
    assert_eq!(response[0..2], [0x00, 0x30]);
    assert_eq!(response[2], 0x4B);
    assert_eq!(response[3..6], [0x41, 0x60, 0x00]);
    assert_eq!(response[6..8], [0x34, 0x12]);
}

#[test]
fn an_upload_longer_than_four_bytes_carries_its_size_and_data() {
    let mut sut = SdoServer::default();
    let response = sut
        .handle(&upload(0x1008, 0), &mut dictionary(), AlState::PreOp, 122)
        .unwrap();
    assert_eq!(response[2], 0x41);
    assert_eq!(u32::from_le_bytes(response[6..10].try_into().unwrap()), 40);
    assert_eq!(&response[10..14], b"A ra");
    assert_eq!(response.len(), 50);
}

#[test]
fn an_upload_longer_than_the_mailbox_continues_in_toggled_segments() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    let first = sut
        .handle(&upload(0x1008, 0), &mut od, AlState::PreOp, 20)
        .unwrap();
    assert_eq!(first.len(), SDO_LEN);
    let mut data = Vec::new();
    let mut toggle = false;
    loop {
        let request = [
            0x00,
            0x20,
            (CCS_UPLOAD_SEGMENT << 5) | (u8::from(toggle) << 4),
            0,
            0,
            0,
            0,
            0,
            0,
            0,
        ];
        let segment = sut.handle(&request, &mut od, AlState::PreOp, 20).unwrap();
        assert_eq!(segment[2] >> 5, 0, "upload segment response");
        assert_eq!(segment[2] & 0x10 != 0, toggle);
        let unused = usize::from((segment[2] >> 1) & 0x07);
        data.extend_from_slice(&segment[3..segment.len() - unused]);
        if segment[2] & 0x01 != 0 {
            break;
        }
        toggle = !toggle;
    }
    assert_eq!(data, b"A rather long device name, 40 bytes long");
}

#[test]
fn a_segment_with_the_wrong_toggle_bit_is_aborted() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    sut.handle(&upload(0x1008, 0), &mut od, AlState::PreOp, 20)
        .unwrap();
    let request = [
        0x00,
        0x20,
        (CCS_UPLOAD_SEGMENT << 5) | 0x10,
        0,
        0,
        0,
        0,
        0,
        0,
        0,
    ];
    let response = sut.handle(&request, &mut od, AlState::PreOp, 20).unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::TOGGLE_BIT));
}

#[test]
fn an_expedited_download_is_stored_and_confirmed() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    let response = sut
        .handle(
            &expedited_download(0x6060, 0, &[0xFF]),
            &mut od,
            AlState::Op,
            122,
        )
        .unwrap();
    assert_eq!(response[2], 0x60);
    assert_eq!(od.get::<i8>(0x6060, 0), Some(-1));
}

#[test]
fn unknown_objects_and_subindices_are_aborted_with_their_codes() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    let response = sut
        .handle(&upload(0x7777, 0), &mut od, AlState::PreOp, 122)
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::NOT_FOUND));
    assert_eq!(response[3..6], [0x77, 0x77, 0x00]);
    let response = sut
        .handle(&upload(0x6041, 3), &mut od, AlState::PreOp, 122)
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::SUBINDEX_NOT_FOUND));
}

#[test]
fn downloads_of_the_wrong_size_are_aborted() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    let response = sut
        .handle(
            &expedited_download(0x6060, 0, &[1, 0]),
            &mut od,
            AlState::PreOp,
            122,
        )
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::DATA_TOO_LONG));
    od.insert(ObjectEntry::new(0x6061, 0, "Wide", 0u32).read_write());
    let response = sut
        .handle(
            &expedited_download(0x6061, 0, &[1, 0]),
            &mut od,
            AlState::PreOp,
            122,
        )
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::DATA_TOO_SHORT));
}

#[test]
fn read_only_and_pre_op_only_objects_refuse_writes() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    let response = sut
        .handle(
            &expedited_download(0x6041, 0, &[1, 0]),
            &mut od,
            AlState::PreOp,
            122,
        )
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::READ_ONLY));
    let response = sut
        .handle(
            &expedited_download(0x1C12, 0, &[0]),
            &mut od,
            AlState::SafeOp,
            122,
        )
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::WRONG_STATE));
    let response = sut
        .handle(
            &expedited_download(0x1C12, 0, &[0]),
            &mut od,
            AlState::PreOp,
            122,
        )
        .unwrap();
    assert_eq!(response[2], 0x60);
}

#[test]
fn a_normal_download_then_a_segmented_one_store_a_string() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    let mut request = coe_header(service::SDO_REQUEST).to_vec();
    request.push((CCS_DOWNLOAD << 5) | 0x01);
    request.extend_from_slice(&[0x00, 0x20, 0x00]);
    request.extend_from_slice(&6u32.to_le_bytes());
    request.extend_from_slice(b"hello!");
    let response = sut.handle(&request, &mut od, AlState::PreOp, 122).unwrap();
    assert_eq!(response[2], 0x60);
    assert_eq!(od.raw(0x2000, 0), Some(&b"hello!"[..]));

    // 10 bytes announced, 2 in the initiate request, 8 in one last segment.
    let mut request = coe_header(service::SDO_REQUEST).to_vec();
    request.push((CCS_DOWNLOAD << 5) | 0x01);
    request.extend_from_slice(&[0x00, 0x20, 0x00]);
    request.extend_from_slice(&10u32.to_le_bytes());
    request.extend_from_slice(b"ab");
    sut.handle(&request, &mut od, AlState::PreOp, 122).unwrap();
    let mut segment = coe_header(service::SDO_REQUEST).to_vec();
    segment.push((CCS_DOWNLOAD_SEGMENT << 5) | 0x01);
    segment.extend_from_slice(b"cdefghij");
    let response = sut.handle(&segment, &mut od, AlState::PreOp, 122).unwrap();
    assert_eq!(response[2], 0x20);
    assert_eq!(od.raw(0x2000, 0), Some(&b"abcdefghij"[..]));
}

#[test]
fn a_truncated_request_is_answered_with_an_abort_not_a_panic() {
    let mut sut = SdoServer::default();
    let mut od = dictionary();
    for len in 0..10 {
        let request = &upload(0x6041, 0)[..len];
        let _ = sut.handle(request, &mut od, AlState::PreOp, 122);
    }
    let response = sut
        .handle(&[0x00, 0x20], &mut od, AlState::PreOp, 122)
        .unwrap();
    assert_eq!(abort_code_of(&response), Some(abort::INVALID_COMMAND));
    assert_eq!(od.entry(0x6041, 0).unwrap().pdo, PdoMappable::Tx);
}
