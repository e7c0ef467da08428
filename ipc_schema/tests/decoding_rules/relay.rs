//! Relayed calls. The golden request is `03 nav 02 go`, a timeout of 4 bytes, then one value.

use modbot_ipc_schema::args::ArgError;
use modbot_ipc_schema::relay::{RelayError, Request, Response};

use crate::support::golden;

fn request() -> Vec<u8> {
    golden("relay_request module=nav")
}

#[test]
fn a_module_name_outside_the_module_name_alphabet_is_refused() {
    let mut bytes = request();
    bytes[1] = b'/';
    assert_eq!(
        Request::parse(&bytes).err(),
        Some(RelayError::BadName { what: "module" })
    );
}

#[test]
fn an_empty_method_name_is_refused() {
    let mut bytes = b"\x03nav\x00".to_vec();
    bytes.extend(&request()[7..]);
    assert_eq!(
        Request::parse(&bytes).err(),
        Some(RelayError::BadName { what: "method" })
    );
}

#[test]
fn a_request_cut_short_before_its_arguments_is_refused() {
    assert_eq!(
        Request::parse(&request()[..9]).err(),
        Some(RelayError::Truncated("timeout"))
    );
}

#[test]
fn arguments_that_are_not_well_formed_values_are_refused() {
    let mut bytes = request();
    *bytes.last_mut().unwrap() = 0xc1;
    assert!(matches!(
        Request::parse(&bytes).err(),
        Some(RelayError::Values(ArgError::Malformed(_)))
    ));
}

#[test]
fn more_than_16_arguments_are_refused() {
    let mut bytes = request();
    bytes.extend([0x01; 16]);
    assert_eq!(
        Request::parse(&bytes).err(),
        Some(RelayError::Values(ArgError::TooMany))
    );
}

#[test]
fn an_empty_response_is_refused() {
    assert_eq!(Response::parse(&[]), Err(RelayError::Truncated("status")));
}

#[test]
fn a_response_status_other_than_0_or_1_is_refused() {
    assert_eq!(Response::parse(&[2]), Err(RelayError::Status(2)));
}

#[test]
fn an_answer_that_is_not_well_formed_values_is_refused() {
    assert!(matches!(
        Response::parse(&[0, 0xc1]),
        Err(RelayError::Values(ArgError::Malformed(_)))
    ));
}

#[test]
fn a_reason_that_is_not_utf8_is_refused() {
    assert_eq!(Response::parse(&[1, 0xff]), Err(RelayError::Text));
}

#[test]
fn an_empty_reason_is_a_reason() {
    assert_eq!(Response::parse(&[1]), Ok(Response::Failed("")));
}
