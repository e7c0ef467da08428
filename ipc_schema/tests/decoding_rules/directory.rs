//! The directory. The golden image lists `nav` at address 7: its header is bytes 0..16, its
//! entry 16..80 (address, mode, state, name length, pid, digest, upgrades, reserved, then the name
//! at 32).

use modbot_ipc_schema::addr::Addr;
use modbot_ipc_schema::directory::{self, DirectoryError, EntryError, Listing, View, IMAGE_LEN};
use modbot_ipc_schema::heartbeat::ModuleState;

use crate::support::golden;

/// The golden image, at its full size.
fn image() -> Vec<u8> {
    let mut image = golden("directory generation=5");
    image.resize(IMAGE_LEN, 0);
    image
}

fn refused(bytes: &[u8]) -> Option<DirectoryError> {
    View::parse(bytes).err()
}

/// The error of entry 0 of `image`.
fn entry_refused(image: &[u8]) -> Option<EntryError> {
    match refused(image) {
        Some(DirectoryError::Entry { index: 0, problem }) => Some(problem),
        _ => None,
    }
}

#[test]
fn bytes_shorter_than_the_header_are_refused() {
    assert_eq!(refused(&image()[..15]), Some(DirectoryError::Size(15)));
}

#[test]
fn an_image_of_another_magic_is_refused() {
    let mut bytes = image();
    bytes[0] = b'X';
    assert!(matches!(refused(&bytes), Some(DirectoryError::Magic(_))));
}

#[test]
fn an_image_of_another_version_is_refused() {
    let mut bytes = image();
    bytes[4] = 2;
    assert_eq!(refused(&bytes), Some(DirectoryError::Version(2)));
}

#[test]
fn more_than_254_entries_are_refused() {
    let mut bytes = image();
    bytes[6..8].copy_from_slice(&255u16.to_le_bytes());
    assert!(matches!(
        refused(&bytes),
        Some(DirectoryError::Count { count: 255, .. })
    ));
}

#[test]
fn entries_past_the_end_of_the_buffer_are_refused() {
    let mut bytes = golden("directory generation=5");
    bytes[6] = 2;
    assert!(matches!(
        refused(&bytes),
        Some(DirectoryError::Count { count: 2, .. })
    ));
}

#[test]
fn a_directory_reader_ignores_its_reserved_bytes() {
    let mut bytes = image();
    let listing = View::parse(&bytes).unwrap().entries()[0].listing();
    bytes[5] = 0xaa; // the header's
    bytes[16 + 14..16 + 16].fill(0xbb); // the entry's
    let view = View::parse(&bytes).unwrap();
    assert_eq!(
        (view.generation(), view.entries()[0].listing()),
        (5, listing)
    );
}

#[test]
fn a_directory_reader_ignores_the_unused_slots_after_the_last_entry() {
    let mut bytes = image();
    bytes[80..].fill(0xcc);
    assert_eq!(View::parse(&bytes).unwrap().entries().len(), 1);
}

#[test]
fn an_entry_at_an_address_that_is_not_a_module_address_is_refused() {
    let mut bytes = image();
    bytes[16] = 255;
    assert_eq!(entry_refused(&bytes), Some(EntryError::Address(255)));
}

#[test]
fn entries_out_of_address_order_are_refused() {
    let listing = |addr, name: &str| Listing {
        addr: Addr(addr),
        mode: b'b',
        state: ModuleState::Running,
        pid: 1,
        methods_digest: 0,
        upgrades: 0,
        name: name.into(),
    };
    let mut bytes = vec![0; IMAGE_LEN];
    directory::write(&mut bytes, 1, &[listing(3, "a"), listing(4, "b")]).unwrap();
    bytes[16 + 64] = 3; // the second entry at the first one's address
    assert_eq!(
        refused(&bytes),
        Some(DirectoryError::Entry {
            index: 1,
            problem: EntryError::Order { addr: 3, after: 3 }
        })
    );
}

#[test]
fn a_receive_mode_other_than_p_or_b_is_refused() {
    let mut bytes = image();
    bytes[17] = b'x';
    assert_eq!(entry_refused(&bytes), Some(EntryError::Mode(b'x')));
}

#[test]
fn an_unknown_state_is_refused() {
    let mut bytes = image();
    bytes[18] = 4;
    assert_eq!(entry_refused(&bytes), Some(EntryError::State(4)));
}

#[test]
fn a_name_length_outside_1_to_48_is_refused() {
    let mut bytes = image();
    bytes[19] = 49;
    assert_eq!(entry_refused(&bytes), Some(EntryError::NameLength(49)));
}

#[test]
fn a_name_with_a_byte_outside_the_module_name_alphabet_is_refused() {
    let mut bytes = image();
    bytes[32] = 0xff;
    assert_eq!(entry_refused(&bytes), Some(EntryError::NameBytes));
}

#[test]
fn a_name_followed_by_nonzero_padding_is_refused() {
    let mut bytes = image();
    bytes[35] = b'x'; // right after "nav"
    assert_eq!(entry_refused(&bytes), Some(EntryError::NamePadding));
}
