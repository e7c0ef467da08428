use super::*;

fn timing(ns: u64) -> PassTiming {
    PassTiming {
        port0_ns: ns,
        port1_ns: Some(ns + 1_400),
    }
}

fn image() -> Vec<u8> {
    (0..2048u32).map(|i| i as u8).collect()
}

fn sut() -> Esc {
    Esc::new(EscIdentity::default(), image(), 1_000)
}

fn sm_config(start: u16, len: u16, control: u8) -> [u8; 8] {
    let mut bytes = [0u8; 8];
    bytes[0..2].copy_from_slice(&start.to_le_bytes());
    bytes[2..4].copy_from_slice(&len.to_le_bytes());
    bytes[4] = control;
    bytes[6] = 1;
    bytes
}

#[test]
fn the_identity_registers_read_as_an_et1100_with_dc() {
    let mut sut = sut();
    let mut out = [0u8; 10];
    assert!(sut.read(0x0000, &mut out, &timing(0)));
    assert_eq!(out[0], 0x11);
    assert_eq!(out[4], CHANNELS);
    assert_eq!(u16::from_le_bytes([out[8], out[9]]) & 0x0004, 0x0004);
}

#[test]
fn a_sii_read_command_leaves_eight_bytes_of_the_image_in_the_data_register() {
    let mut sut = sut();
    // Control: read command; address word 0x20 (byte 0x40).
    assert!(sut.write(0x0502, &[0x00, 0x01, 0x20, 0x00, 0x00, 0x00], &timing(0)));
    let mut control = [0u8; 2];
    sut.read(0x0502, &mut control, &timing(0));
    let control = u16::from_le_bytes(control);
    assert_eq!(control & 0x8000, 0, "not busy");
    assert_eq!(control & 0x0040, 0x0040, "8-byte reads");
    let mut data = [0u8; 8];
    sut.read(0x0508, &mut data, &timing(0));
    assert_eq!(data, [0x40, 0x41, 0x42, 0x43, 0x44, 0x45, 0x46, 0x47]);
}

#[test]
fn a_sii_read_past_the_eeprom_returns_erased_cells() {
    let mut sut = sut();
    sut.write(0x0502, &[0x00, 0x01, 0xFF, 0x03, 0x00, 0x00], &timing(0));
    let mut data = [0u8; 8];
    sut.read(0x0508, &mut data, &timing(0));
    assert_eq!(&data[2..], &[0xFF; 6]);
}

#[test]
fn a_sii_write_needs_write_access_enabled() {
    let mut sut = sut();
    sut.write(0x0508, &[0xAB, 0xCD], &timing(0));
    sut.write(0x0502, &[0x00, 0x02, 0x04, 0x00, 0x00, 0x00], &timing(0));
    let mut control = [0u8; 2];
    sut.read(0x0502, &mut control, &timing(0));
    assert_ne!(u16::from_le_bytes(control) & 0x2000, 0, "command error");
    sut.write(0x0502, &[0x01, 0x02, 0x04, 0x00, 0x00, 0x00], &timing(0));
    assert_eq!(sut.sii().word(4), 0xCDAB);
}

#[test]
fn a_write_to_a_read_only_register_counts_but_changes_nothing() {
    let mut sut = sut();
    assert!(sut.write(0x0130, &[0x08, 0x00], &timing(0)));
    assert_eq!(sut.al_status(), 0x0001);
    assert!(sut.write(0x0010, &[0x34, 0x12], &timing(0)));
    assert_eq!(sut.station_address(), 0x1234);
}

#[test]
fn an_al_control_write_is_an_event_for_the_firmware() {
    let mut sut = sut();
    sut.write(0x0120, &[0x02, 0x00], &timing(0));
    assert_eq!(sut.take_events(), vec![EscEvent::AlControl(0x0002)]);
}

#[test]
fn a_full_receive_mailbox_refuses_the_next_write() {
    let mut sut = sut();
    sut.write(0x0800, &sm_config(0x1000, 16, 0x26), &timing(0));
    assert!(sut.write(0x1000, &[1; 16], &timing(0)));
    assert_eq!(sut.take_events(), vec![EscEvent::MailboxReceived { sm: 0 }]);
    assert!(!sut.write(0x1000, &[2; 16], &timing(0)), "full mailbox");
    assert_eq!(sut.mailbox_take(0), Some(vec![1; 16]));
    assert!(sut.write(0x1000, &[3; 16], &timing(0)), "empty again");
}

#[test]
fn the_send_mailbox_reads_only_when_full_and_empties_on_its_last_byte() {
    let mut sut = sut();
    sut.write(0x0808, &sm_config(0x1080, 16, 0x22), &timing(0));
    let mut out = [0u8; 16];
    assert!(!sut.read(0x1080, &mut out, &timing(0)), "empty mailbox");
    assert!(sut.mailbox_put(1, &[7; 10]));
    assert!(!sut.mailbox_put(1, &[8; 10]), "still full");
    let mut status = [0u8; 1];
    sut.read(0x080D, &mut status, &timing(0));
    assert_eq!(status[0] & 0x08, 0x08);
    assert!(sut.read(0x1080, &mut out, &timing(0)));
    assert_eq!(&out[..10], &[7; 10]);
    assert_eq!(sut.take_events(), vec![EscEvent::MailboxRead { sm: 1 }]);
    sut.read(0x080D, &mut status, &timing(0));
    assert_eq!(status[0] & 0x08, 0);
}

#[test]
fn a_sync_manager_deactivated_by_the_firmware_refuses_the_master() {
    let mut sut = sut();
    sut.write(0x0810, &sm_config(0x1100, 4, 0x64), &timing(0));
    sut.set_sm_deactivated(2, true);
    assert!(!sut.write(0x1100, &[1, 2, 3, 4], &timing(0)));
    sut.set_sm_deactivated(2, false);
    assert!(sut.write(0x1100, &[1, 2, 3, 4], &timing(0)));
    assert_eq!(sut.take_events(), vec![EscEvent::BufferWritten { sm: 2 }]);
}

#[test]
fn an_enabled_sync_manager_keeps_its_start_address() {
    let mut sut = sut();
    sut.write(0x0810, &sm_config(0x1100, 4, 0x64), &timing(0));
    sut.write(0x0810, &[0x00, 0x12], &timing(0));
    assert_eq!(sut.sync_manager(2).start, 0x1100);
    sut.write(0x0816, &[0], &timing(0));
    sut.write(0x0810, &[0x00, 0x12], &timing(0));
    assert_eq!(sut.sync_manager(2).start, 0x1200);
}

#[test]
fn access_beyond_the_memory_is_not_counted() {
    let mut sut = sut();
    let mut out = [0u8; 4];
    assert!(!sut.read(0x3000, &mut out, &timing(0)));
    assert!(!sut.write(0xFFF0, &[1; 4], &timing(0)));
}

#[test]
fn a_write_to_0x0900_latches_the_local_receive_times() {
    let mut sut = sut();
    sut.write(0x0900, &[0; 4], &timing(11_000));
    let mut times = [0u8; 8];
    sut.read(0x0900, &mut times, &timing(20_000));
    assert_eq!(u32::from_le_bytes(times[0..4].try_into().unwrap()), 10_000);
    assert_eq!(u32::from_le_bytes(times[4..8].try_into().unwrap()), 11_400);
    let mut pu = [0u8; 8];
    sut.read(0x0918, &mut pu, &timing(20_000));
    assert_eq!(u64::from_le_bytes(pu), 10_000);
}

#[test]
fn the_system_time_is_local_time_plus_offset() {
    let mut sut = sut();
    sut.write(0x0920, &5_000_000u64.to_le_bytes(), &timing(0));
    let mut out = [0u8; 8];
    sut.read(0x0910, &mut out, &timing(3_000));
    assert_eq!(u64::from_le_bytes(out), 5_002_000);
}

#[test]
fn a_system_time_write_publishes_the_difference_and_slews_the_offset() {
    let mut sut = sut();
    // Local time 9_000 at t = 10_000; the reference says 9_500 (+ delay 0): we are 500 behind.
    sut.write(0x0910, &9_500u64.to_le_bytes(), &timing(10_000));
    let mut diff = [0u8; 4];
    sut.read(0x092C, &mut diff, &timing(10_000));
    assert_eq!(u32::from_le_bytes(diff), 0x8000_0000 | 500);
    assert_eq!(sut.system_time(10_000), 9_500);
}
