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
fn a_system_time_write_publishes_the_difference_and_corrects_the_speed_not_the_offset() {
    let mut sut = sut();
    // Local time 9_000 at t = 10_000; the reference says 9_500 (+ delay 0): we are 500 behind.
    sut.write(0x0910, &9_500u64.to_le_bytes(), &timing(10_000));
    let mut diff = [0u8; 4];
    sut.read(0x092C, &mut diff, &timing(10_000));
    assert_eq!(u32::from_le_bytes(diff), 0x8000_0000 | 500);
    // No step: the offset is the master's, the loop slews the clock.
    assert_eq!(sut.system_time(10_000), 9_000);
    let mut offset = [0u8; 8];
    sut.read(0x0920, &mut offset, &timing(10_000));
    assert_eq!(u64::from_le_bytes(offset), 0);
    // A tenth of the difference (50 ns) slewed in at most 500 ppm: 50 ns within 100 us.
    assert_eq!(sut.system_time(60_000), 59_025);
    assert_eq!(sut.system_time(210_000), 209_050);
}

/// The reference time as a master writes it: `period` apart, `lead` ns ahead of the chain's
/// time, written into `sut` at every step for `steps`; returns the last difference seen.
fn follow(sut: &mut Esc, t: &mut u64, period: u64, steps: usize, lead: u64) -> i64 {
    let mut difference = 0;
    for _ in 0..steps {
        *t += period;
        sut.write(0x0910, &(*t + lead).to_le_bytes(), &timing(*t));
        let mut raw = [0u8; 4];
        sut.read(0x092C, &mut raw, &timing(*t));
        let raw = u32::from_le_bytes(raw);
        let magnitude = i64::from(raw & 0x7FFF_FFFF);
        difference = if raw & 0x8000_0000 != 0 {
            -magnitude
        } else {
            magnitude
        };
    }
    difference
}

#[test]
fn a_drifting_clock_follows_the_written_time_and_learns_its_drift() {
    let mut sut = sut();
    sut.write(0x0920, &1_000u64.to_le_bytes(), &timing(1_000));
    sut.set_clock_drift_ppm(100.0, 1_000);
    let mut t = 1_000;
    // Unfollowed, 100 ppm is 100 ns per millisecond.
    assert_eq!(sut.system_time(1_001_000), 1_001_100);
    let settled = follow(&mut sut, &mut t, 1_000_000, 500, 0);
    assert!(
        settled.abs() <= 5,
        "difference {settled} ns after 500 writes"
    );
    let learnt = sut.clock().speed_correction_ppm();
    assert!(
        (learnt + 100.0).abs() < 1.0,
        "speed correction {learnt} ppm"
    );
}

#[test]
fn the_loop_slews_a_large_difference_at_its_bounded_speed() {
    let mut sut = sut();
    // 200 us behind: the clock runs at most 1000 ppm fast, so it needs 200 ms at least.
    sut.write(0x0920, &1_000u64.to_le_bytes(), &timing(1_000));
    let mut t = 1_000;
    let after_100 = follow(&mut sut, &mut t, 1_000_000, 100, 200_000).abs();
    assert!(after_100 > 90_000, "{after_100} ns left after 100 ms");
    let after_1000 = follow(&mut sut, &mut t, 1_000_000, 900, 200_000).abs();
    assert!(after_1000 < 1_000, "{after_1000} ns left after 1 s");
}

#[test]
fn writing_the_control_loop_parameters_resets_the_loop() {
    let mut sut = sut();
    sut.set_clock_drift_ppm(-50.0, 1_000);
    let mut t = 1_000;
    follow(&mut sut, &mut t, 1_000_000, 300, 0);
    assert!(sut.clock().speed_correction_ppm() > 40.0);
    sut.write(0x0930, &0x1000u16.to_le_bytes(), &timing(t));
    assert_eq!(sut.clock().speed_correction_ppm(), 0.0);
    assert_eq!(sut.clock().drift_ppm(), -50.0);
}

#[test]
fn the_sync0_phase_counts_from_the_start_time_in_system_time() {
    let mut sut = sut();
    sut.write(0x0990, &5_000u64.to_le_bytes(), &timing(1_000));
    sut.write(0x09A0, &1_000u32.to_le_bytes(), &timing(1_000));
    assert_eq!(sut.sync0_phase_ns(4_000), None, "not active yet");
    sut.write(0x0981, &[0x03], &timing(1_000));
    // Local time = chain time - 1_000 (powered on at 1_000), offset 0.
    assert_eq!(sut.sync0_phase_ns(5_500), None, "before the first pulse");
    assert_eq!(sut.sync0_phase_ns(6_000), Some(0));
    assert_eq!(sut.sync0_phase_ns(8_250), Some(250));
}
