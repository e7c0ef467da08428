//! The AL state machine refuses what a slave stack refuses, with the error indication and
//! the status code a master reads, and accepts an acknowledged request afterwards.

mod support;

use modbot_ecat_sim::frame::{self, physical_address, DatagramSpan};
use modbot_ecat_sim::{AlState, Chain, FrameBuilder, ManualClock};

const FPRD: u8 = 4;
const FPWR: u8 = 5;
const APWR: u8 = 2;

fn send(chain: &mut Chain, builder: FrameBuilder) -> Vec<(u16, Vec<u8>)> {
    let mut frame = builder.build();
    chain.process(&mut frame).unwrap();
    let mut spans: Vec<DatagramSpan> = Vec::new();
    frame::decode(&frame, &mut spans).unwrap();
    spans
        .iter()
        .map(|&s| {
            let d = frame::datagram_at(&mut frame, s).unwrap();
            (d.working_counter(), d.data().to_vec())
        })
        .collect()
}

fn request(chain: &mut Chain, value: u16) -> (u16, u16) {
    let out = send(
        chain,
        FrameBuilder::new()
            .datagram(
                FPWR,
                0,
                physical_address(0x1000, 0x0120),
                &value.to_le_bytes(),
            )
            .datagram(FPRD, 1, physical_address(0x1000, 0x0130), &[0; 2])
            .datagram(FPRD, 2, physical_address(0x1000, 0x0134), &[0; 2]),
    );
    (
        u16::from_le_bytes([out[1].1[0], out[1].1[1]]),
        u16::from_le_bytes([out[2].1[0], out[2].1[1]]),
    )
}

fn one_slave() -> Chain {
    let mut chain = support::chain(1, ManualClock::new(0));
    send(
        &mut chain,
        FrameBuilder::new().datagram(
            APWR,
            0,
            physical_address(0, 0x0010),
            &0x1000u16.to_le_bytes(),
        ),
    );
    chain
}

fn configure_mailboxes(chain: &mut Chain) {
    let sm = |start: u16, control: u8| {
        let mut b = [0u8; 8];
        b[0..2].copy_from_slice(&start.to_le_bytes());
        b[2..4].copy_from_slice(&128u16.to_le_bytes());
        b[4] = control;
        b[6] = 1;
        b
    };
    send(
        chain,
        FrameBuilder::new()
            .datagram(FPWR, 0, physical_address(0x1000, 0x0800), &sm(0x1000, 0x26))
            .datagram(FPWR, 1, physical_address(0x1000, 0x0808), &sm(0x1080, 0x22)),
    );
}

#[test]
fn pre_op_without_mailbox_sync_managers_is_refused_with_code_0x0016() {
    let mut sut = one_slave();
    assert_eq!(request(&mut sut, 0x0002), (0x0011, 0x0016));
    assert!(sut.slave(0).unwrap().al_error());
}

#[test]
fn a_refused_slave_ignores_requests_until_the_error_is_acknowledged() {
    let mut sut = one_slave();
    request(&mut sut, 0x0002);
    configure_mailboxes(&mut sut);
    assert_eq!(
        request(&mut sut, 0x0002),
        (0x0011, 0x0016),
        "no acknowledge: ignored"
    );
    assert_eq!(
        request(&mut sut, 0x0012),
        (0x0002, 0x0000),
        "acknowledged and accepted"
    );
}

#[test]
fn skipping_a_state_is_an_invalid_state_change() {
    let mut sut = one_slave();
    assert_eq!(request(&mut sut, 0x0008), (0x0011, 0x0011));
    assert_eq!(request(&mut sut, 0x0011), (0x0001, 0x0000));
}

#[test]
fn bootstrap_and_unknown_states_are_refused_with_their_codes() {
    let mut sut = one_slave();
    assert_eq!(request(&mut sut, 0x0003), (0x0011, 0x0013));
    assert_eq!(request(&mut sut, 0x0016), (0x0011, 0x0012));
}

#[test]
fn safe_op_without_process_data_configuration_is_refused_with_code_0x001d() {
    let mut sut = one_slave();
    configure_mailboxes(&mut sut);
    assert_eq!(request(&mut sut, 0x0002), (0x0002, 0x0000));
    assert_eq!(request(&mut sut, 0x0004), (0x0012, 0x001D));
    assert_eq!(sut.slave(0).unwrap().al_state(), AlState::PreOp);
}

#[test]
fn going_down_to_init_is_always_accepted() {
    let mut sut = one_slave();
    configure_mailboxes(&mut sut);
    request(&mut sut, 0x0002);
    assert_eq!(request(&mut sut, 0x0001), (0x0001, 0x0000));
    // Mailbox deactivated again: a write to it is not counted.
    let out = send(
        &mut sut,
        FrameBuilder::new().datagram(FPWR, 0, physical_address(0x1000, 0x1000), &[0; 128]),
    );
    assert_eq!(out[0].0, 0);
}
