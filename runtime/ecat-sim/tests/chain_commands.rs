//! A chain answers hand-built frames as a line of ESCs would: working counters per command,
//! auto-increment and broadcast addressing, FRMW, logical access through FMMUs, the reply
//! MAC, and the injected faults.

mod support;

use modbot_ecat_sim::frame::{self, physical_address, DatagramSpan};
use modbot_ecat_sim::{Chain, FrameBuilder, FrameError, ManualClock, Reply};

const APRD: u8 = 1;
const APWR: u8 = 2;
const FPRD: u8 = 4;
const FPWR: u8 = 5;
const FPRW: u8 = 6;
const BRD: u8 = 7;
const BWR: u8 = 8;
const LRW: u8 = 12;
const ARMW: u8 = 13;
const FRMW: u8 = 14;

/// (working counter, address field, data) of every datagram of a processed frame.
fn results(chain: &mut Chain, mut frame: Vec<u8>) -> Vec<(u16, u32, Vec<u8>)> {
    assert_eq!(chain.process(&mut frame), Ok(Reply::Frame));
    let mut spans: Vec<DatagramSpan> = Vec::new();
    frame::decode(&frame, &mut spans).unwrap();
    spans
        .iter()
        .map(|&span| {
            let d = frame::datagram_at(&mut frame, span).unwrap();
            (d.working_counter(), d.logical_address(), d.data().to_vec())
        })
        .collect()
}

fn addressed_chain(count: usize) -> Chain {
    addressed_chain_with(count, ManualClock::new(1_000_000))
}

fn addressed_chain_with(count: usize, clock: ManualClock) -> Chain {
    let mut sut = support::chain(count, clock);
    let mut builder = FrameBuilder::new();
    for position in 0..count as u16 {
        let adp = 0u16.wrapping_sub(position);
        builder = builder.datagram(
            APWR,
            position as u8,
            physical_address(adp, 0x0010),
            &(0x1000 + position).to_le_bytes(),
        );
    }
    for (wkc, _, _) in results(&mut sut, builder.build()) {
        assert_eq!(wkc, 1);
    }
    sut
}

#[test]
fn a_broadcast_read_is_counted_by_every_slave_and_ors_their_data() {
    let mut sut = support::chain(3, ManualClock::new(0));
    let out = results(
        &mut sut,
        FrameBuilder::new().datagram(BRD, 0, 0, &[0, 0]).build(),
    );
    assert_eq!(out[0].0, 3);
    assert_eq!(out[0].2, [0x11, 0x00]);
    // Each slave incremented ADP.
    assert_eq!(out[0].1 & 0xFFFF, 3);
}

#[test]
fn a_broadcast_write_is_counted_by_every_slave() {
    let mut sut = support::chain(4, ManualClock::new(0));
    let out = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(BWR, 0, physical_address(0, 0x0600), &[0; 16])
            .build(),
    );
    assert_eq!(out[0].0, 4);
}

#[test]
fn auto_increment_addressing_reaches_the_slave_that_sees_zero() {
    let mut sut = addressed_chain(3);
    let frame = FrameBuilder::new()
        .datagram(
            APRD,
            0,
            physical_address(0u16.wrapping_sub(2), 0x0010),
            &[0, 0],
        )
        .datagram(
            APRD,
            1,
            physical_address(0u16.wrapping_sub(7), 0x0010),
            &[0, 0],
        )
        .build();
    let out = results(&mut sut, frame);
    assert_eq!(out[0].0, 1);
    assert_eq!(out[0].2, 0x1002u16.to_le_bytes());
    assert_eq!(
        out[0].1 & 0xFFFF,
        1,
        "ADP incremented by each of the three slaves"
    );
    assert_eq!(out[1].0, 0, "nobody at position 7");
}

#[test]
fn configured_addressing_reaches_one_slave_and_read_write_counts_three() {
    let mut sut = addressed_chain(3);
    let frame = FrameBuilder::new()
        .datagram(FPRD, 0, physical_address(0x1001, 0x0130), &[0, 0])
        .datagram(FPWR, 1, physical_address(0x1002, 0x0120), &[0x01, 0x00])
        .datagram(FPRW, 2, physical_address(0x1000, 0x0400), &[0x00, 0x10])
        .datagram(FPRD, 3, physical_address(0x0999, 0x0130), &[0, 0])
        .build();
    let out = results(&mut sut, frame);
    assert_eq!(out[0].0, 1);
    assert_eq!(out[0].2, [0x01, 0x00], "INIT");
    assert_eq!(out[1].0, 1);
    assert_eq!(out[2].0, 3);
    assert_eq!(
        out[2].2,
        0x09C2u16.to_le_bytes(),
        "the old watchdog divider"
    );
    assert_eq!(out[3].0, 0);
}

#[test]
fn read_multiple_write_reads_at_the_addressed_slave_and_writes_at_the_others() {
    let clock = ManualClock::new(1_000_000);
    let mut sut = addressed_chain_with(3, clock.clone());
    clock.advance(5_000);
    let frame = FrameBuilder::new()
        .datagram(FRMW, 0, physical_address(0x1000, 0x0910), &[0; 8])
        .datagram(ARMW, 1, physical_address(0, 0x0910), &[0; 8])
        .build();
    let out = results(&mut sut, frame);
    assert_eq!(out[0].0, 3);
    assert_eq!(out[1].0, 3);
    let system_time = u64::from_le_bytes(out[0].2.clone().try_into().unwrap());
    assert_eq!(
        system_time, 5_000,
        "the reference's system time: 5 µs after power-on"
    );
}

#[test]
fn a_logical_read_write_counts_one_for_the_read_and_two_for_the_write() {
    let mut sut = addressed_chain(2);
    // Slave 0x1000: FMMU0 writes logical 0x100..0x104 to RAM 0x2000, FMMU1 reads RAM 0x2100
    // to logical 0x104..0x108.
    let fmmu = |logical: u32, physical: u16, kind: u8| {
        let mut b = [0u8; 16];
        b[0..4].copy_from_slice(&logical.to_le_bytes());
        b[4..6].copy_from_slice(&4u16.to_le_bytes());
        b[7] = 7;
        b[8..10].copy_from_slice(&physical.to_le_bytes());
        b[11] = kind;
        b[12] = 1;
        b
    };
    let setup = FrameBuilder::new()
        .datagram(
            FPWR,
            0,
            physical_address(0x1000, 0x0600),
            &fmmu(0x100, 0x2000, 2),
        )
        .datagram(
            FPWR,
            1,
            physical_address(0x1000, 0x0610),
            &fmmu(0x104, 0x2100, 1),
        )
        .datagram(FPWR, 2, physical_address(0x1000, 0x2100), &[9, 8, 7, 6])
        .build();
    results(&mut sut, setup);
    let out = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(LRW, 0, 0x100, &[1, 2, 3, 4, 0, 0, 0, 0])
            .build(),
    );
    assert_eq!(out[0].0, 3);
    assert_eq!(out[0].2, [1, 2, 3, 4, 9, 8, 7, 6]);
    let check = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(FPRD, 0, physical_address(0x1000, 0x2000), &[0; 4])
            .build(),
    );
    assert_eq!(check[0].2, [1, 2, 3, 4]);
}

#[test]
fn a_station_address_set_in_a_frame_addresses_the_next_datagram_of_that_frame() {
    let mut sut = support::chain(2, ManualClock::new(0));
    // Slave 1 (ADP -1) gets 0x2001; the FPRD behind it in the same frame reaches it and only
    // it, and an FPRD for an address no slave holds is counted by none.
    let out = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(
                APWR,
                0,
                physical_address(0xFFFF, 0x0010),
                &0x2001u16.to_le_bytes(),
            )
            .datagram(FPRD, 1, physical_address(0x2001, 0x0010), &[0; 2])
            .datagram(FPRD, 2, physical_address(0x2002, 0x0010), &[0; 2])
            .build(),
    );
    assert_eq!(out[0].0, 1);
    assert_eq!((out[1].0, out[1].2.clone()), (1, vec![0x01, 0x20]));
    assert_eq!(out[2].0, 0);
}

#[test]
fn an_fmmu_configured_in_a_frame_maps_the_logical_datagram_behind_it() {
    let mut sut = addressed_chain(2);
    let mut fmmu = [0u8; 16];
    fmmu[0..4].copy_from_slice(&0x40u32.to_le_bytes());
    fmmu[4..6].copy_from_slice(&2u16.to_le_bytes());
    fmmu[7] = 7;
    fmmu[8..10].copy_from_slice(&0x2000u16.to_le_bytes());
    fmmu[11] = 2;
    fmmu[12] = 1;
    let out = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(FPWR, 0, physical_address(0x1001, 0x0600), &fmmu)
            .datagram(LRW, 1, 0x40, &[0xAB, 0xCD])
            .datagram(FPRD, 2, physical_address(0x1001, 0x2000), &[0; 2])
            .build(),
    );
    assert_eq!(
        out[1].0, 2,
        "the write half counted by the one slave mapping it"
    );
    assert_eq!(out[2].2, [0xAB, 0xCD]);
    // Disabled again (activate 0): the same logical datagram maps nothing.
    fmmu[12] = 0;
    let out = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(FPWR, 0, physical_address(0x1001, 0x0600), &fmmu)
            .datagram(LRW, 1, 0x40, &[0x11, 0x22])
            .build(),
    );
    assert_eq!(out[1].0, 0);
}

#[test]
fn the_reply_comes_from_the_locally_administered_master_address() {
    let mut sut = support::chain(1, ManualClock::new(0));
    let mut frame = FrameBuilder::new().datagram(BRD, 0, 0, &[0]).build();
    sut.process(&mut frame).unwrap();
    assert_eq!(
        frame::source_mac(&frame),
        Some([0x12, 0x10, 0x10, 0x10, 0x10, 0x10])
    );
}

#[test]
fn a_malformed_frame_is_refused_with_a_typed_error() {
    let mut sut = support::chain(1, ManualClock::new(0));
    let mut frame = vec![0u8; 8];
    assert_eq!(
        sut.process(&mut frame),
        Err(FrameError::ShorterThanEthernetHeader { len: 8 })
    );
}

#[test]
fn lost_frames_get_no_reply_and_are_not_processed() {
    let mut sut = support::chain(2, ManualClock::new(0));
    sut.lose_next_frames(2);
    for _ in 0..2 {
        let mut frame = FrameBuilder::new().datagram(BRD, 0, 0, &[0]).build();
        assert_eq!(sut.process(&mut frame), Ok(Reply::Lost));
    }
    assert_eq!(
        results(
            &mut sut,
            FrameBuilder::new().datagram(BRD, 0, 0, &[0]).build()
        )[0]
        .0,
        2
    );
}

#[test]
fn a_slave_without_power_takes_the_slaves_behind_it_off_the_line() {
    let mut sut = addressed_chain(4);
    sut.power_off(2);
    assert_eq!(
        results(
            &mut sut,
            FrameBuilder::new().datagram(BRD, 0, 0, &[0]).build()
        )[0]
        .0,
        2
    );
    // The last reachable slave reports port 1 without link.
    let dl = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(FPRD, 0, physical_address(0x1001, 0x0110), &[0, 0])
            .build(),
    );
    assert_eq!(dl[0].2[0] & 0x20, 0);
    sut.power_on(2);
    assert_eq!(
        results(
            &mut sut,
            FrameBuilder::new().datagram(BRD, 0, 0, &[0]).build()
        )[0]
        .0,
        4
    );
    let station = results(
        &mut sut,
        FrameBuilder::new()
            .datagram(
                APRD,
                0,
                physical_address(0u16.wrapping_sub(2), 0x0010),
                &[0, 0],
            )
            .build(),
    );
    assert_eq!(
        station[0].2,
        [0, 0],
        "power-cycled: station address cleared"
    );
    sut.power_off(0);
    let mut frame = FrameBuilder::new().datagram(BRD, 0, 0, &[0]).build();
    assert_eq!(sut.process(&mut frame), Ok(Reply::Lost));
}
