//! The SII EEPROM image of a slave (ETG.2010): the fixed header (identity, mailbox
//! configuration, size) and the categories a master reads (strings, general, FMMU, sync
//! managers, RxPDO/TxPDO).
//!
//! ethercrab's `SubDevice::name()` is the string the General category's *order* index points
//! at, and `description()` the one its *name* index points at; the image sets both.

/// Word where the categories start.
pub const FIRST_CATEGORY_WORD: usize = 0x40;
/// Bytes of the EEPROM (16 Kbit, word 0x3E says 15).
pub const EEPROM_BYTES: usize = 2048;

/// Category types used here.
mod category {
    pub const STRINGS: u16 = 10;
    pub const GENERAL: u16 = 30;
    pub const FMMU: u16 = 40;
    pub const SYNC_MANAGER: u16 = 41;
    pub const TX_PDO: u16 = 50;
    pub const RX_PDO: u16 = 51;
    pub const END: u16 = 0xFFFF;
}

/// Mailbox protocol bits (SII word 0x1C).
pub mod protocols {
    /// ADS over EtherCAT.
    pub const AOE: u16 = 0x01;
    /// Ethernet over EtherCAT.
    pub const EOE: u16 = 0x02;
    /// CANopen over EtherCAT.
    pub const COE: u16 = 0x04;
    /// File access over EtherCAT.
    pub const FOE: u16 = 0x08;
}

/// General category CoE details bits.
pub mod coe_details {
    /// SDO supported.
    pub const SDO: u8 = 0x01;
    /// SDO information supported.
    pub const SDO_INFO: u8 = 0x02;
    /// PDO assignment configurable.
    pub const PDO_ASSIGN: u8 = 0x04;
    /// PDO mapping configurable.
    pub const PDO_CONFIG: u8 = 0x08;
}

/// Who the slave is (SII words 0x08–0x0F, object 0x1018).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Identity {
    /// Vendor id (ETG-assigned).
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
}

/// Where the mailboxes are and what they speak.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxLayout {
    /// Start of the receive mailbox (master → slave, SM0).
    pub receive_offset: u16,
    /// Bytes of the receive mailbox.
    pub receive_size: u16,
    /// Start of the send mailbox (slave → master, SM1).
    pub send_offset: u16,
    /// Bytes of the send mailbox.
    pub send_size: u16,
    /// Protocol bits, see [`protocols`].
    pub protocols: u16,
}

impl Default for MailboxLayout {
    fn default() -> Self {
        Self {
            receive_offset: 0x1000,
            receive_size: 128,
            send_offset: 0x1080,
            send_size: 128,
            protocols: protocols::COE,
        }
    }
}

/// One sync manager as the SII describes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SiiSyncManager {
    /// Physical start address.
    pub start: u16,
    /// Default length.
    pub length: u16,
    /// Control byte.
    pub control: u8,
    /// Enable byte (bit 0).
    pub enable: u8,
    /// Usage: 1 mailbox out, 2 mailbox in, 3 outputs, 4 inputs.
    pub usage: u8,
}

/// One PDO entry as the SII describes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SiiPdoEntry {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub sub_index: u8,
    /// CoE data type code.
    pub data_type: u8,
    /// Bits.
    pub bit_len: u8,
}

/// One PDO as the SII describes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiPdo {
    /// PDO index (0x16xx or 0x1Axx).
    pub index: u16,
    /// The sync manager it is assigned to.
    pub sync_manager: u8,
    /// Its entries.
    pub entries: Vec<SiiPdoEntry>,
}

/// Everything the image is built from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiDescription {
    /// Identity.
    pub identity: Identity,
    /// Configured station alias (word 4).
    pub alias: u16,
    /// Short name (the master's `name()`).
    pub name: String,
    /// Long name (the master's `description()`).
    pub description: String,
    /// Group name.
    pub group: String,
    /// Mailbox, if the slave has one.
    pub mailbox: Option<MailboxLayout>,
    /// General category CoE details, see [`coe_details`].
    pub coe_details: u8,
    /// Sync managers, in order (SM0, SM1, …).
    pub sync_managers: Vec<SiiSyncManager>,
    /// FMMU usage bytes (1 outputs, 2 inputs, 3 SM status).
    pub fmmus: Vec<u8>,
    /// RxPDOs (outputs).
    pub rx_pdos: Vec<SiiPdo>,
    /// TxPDOs (inputs).
    pub tx_pdos: Vec<SiiPdo>,
}

/// CRC-8 of the SII header (polynomial 0x07, initial value 0xFF), over words 0–6.
pub fn header_crc(bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for &byte in bytes {
        crc ^= byte;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

fn push_category(image: &mut Vec<u8>, kind: u16, mut data: Vec<u8>) {
    if data.len() % 2 == 1 {
        data.push(0);
    }
    image.extend_from_slice(&kind.to_le_bytes());
    image.extend_from_slice(&((data.len() / 2) as u16).to_le_bytes());
    image.extend_from_slice(&data);
}

fn pdo_category(pdos: &[SiiPdo]) -> Vec<u8> {
    let mut data = Vec::new();
    for pdo in pdos {
        data.extend_from_slice(&pdo.index.to_le_bytes());
        data.push(pdo.entries.len() as u8);
        data.push(pdo.sync_manager);
        data.push(0); // DC sync
        data.push(0); // name string index
        data.extend_from_slice(&0u16.to_le_bytes()); // flags
        for entry in &pdo.entries {
            data.extend_from_slice(&entry.index.to_le_bytes());
            data.push(entry.sub_index);
            data.push(0); // name string index
            data.push(entry.data_type);
            data.push(entry.bit_len);
            data.extend_from_slice(&0u16.to_le_bytes());
        }
    }
    data
}

/// Builds the EEPROM contents (2 KiB; unused cells read 0xFF).
pub fn build_image(description: &SiiDescription) -> Vec<u8> {
    let mut image = vec![0u8; FIRST_CATEGORY_WORD * 2];
    let put_u16 = |image: &mut Vec<u8>, word: usize, value: u16| {
        image[word * 2..word * 2 + 2].copy_from_slice(&value.to_le_bytes());
    };
    // PDI control: 0x0C80-style value is irrelevant here; an SPI-less "digital I/O" PDI of 0.
    put_u16(&mut image, 0, 0x0000);
    put_u16(&mut image, 4, description.alias);
    let crc = header_crc(&image[0..14]);
    put_u16(&mut image, 7, u16::from(crc));
    let id = description.identity;
    for (word, value) in [
        (8, id.vendor_id),
        (10, id.product_code),
        (12, id.revision),
        (14, id.serial),
    ] {
        put_u16(&mut image, word, value as u16);
        put_u16(&mut image, word + 1, (value >> 16) as u16);
    }
    if let Some(mailbox) = description.mailbox {
        for word in [0x14, 0x18] {
            put_u16(&mut image, word, mailbox.receive_offset);
            put_u16(&mut image, word + 1, mailbox.receive_size);
            put_u16(&mut image, word + 2, mailbox.send_offset);
            put_u16(&mut image, word + 3, mailbox.send_size);
        }
        put_u16(&mut image, 0x1C, mailbox.protocols);
    }
    put_u16(&mut image, 0x3E, (EEPROM_BYTES * 8 / 1024 - 1) as u16);
    put_u16(&mut image, 0x3F, 1);

    let strings = [
        description.name.as_str(),
        description.description.as_str(),
        description.group.as_str(),
    ];
    let mut data = vec![strings.len() as u8];
    for s in strings {
        let bytes: Vec<u8> = s.bytes().take(255).collect();
        data.push(bytes.len() as u8);
        data.extend_from_slice(&bytes);
    }
    push_category(&mut image, category::STRINGS, data);

    let mut general = vec![0u8; 32];
    general[0] = 3; // group string
    general[1] = 0; // image string
    general[2] = 1; // order string: the short name
    general[3] = 2; // name string: the long name
    general[5] = if description.mailbox.is_some() {
        description.coe_details & 0x3F
    } else {
        0
    };
    general[11] = 0x00; // flags
    general[12..14].copy_from_slice(&0i16.to_le_bytes()); // E-bus current
    general[14] = 0; // ports (ethercrab reads this word as port types; 0 = unused)
    push_category(&mut image, category::GENERAL, general);

    let mut fmmus = description.fmmus.clone();
    if fmmus.len() % 2 == 1 {
        fmmus.push(0xFF);
    }
    push_category(&mut image, category::FMMU, fmmus);

    let mut sms = Vec::new();
    for sm in &description.sync_managers {
        sms.extend_from_slice(&sm.start.to_le_bytes());
        sms.extend_from_slice(&sm.length.to_le_bytes());
        sms.push(sm.control);
        sms.push(0);
        sms.push(sm.enable);
        sms.push(sm.usage);
    }
    push_category(&mut image, category::SYNC_MANAGER, sms);
    if !description.tx_pdos.is_empty() {
        push_category(
            &mut image,
            category::TX_PDO,
            pdo_category(&description.tx_pdos),
        );
    }
    if !description.rx_pdos.is_empty() {
        push_category(
            &mut image,
            category::RX_PDO,
            pdo_category(&description.rx_pdos),
        );
    }
    image.extend_from_slice(&category::END.to_le_bytes());
    image.extend_from_slice(&0u16.to_le_bytes());
    if image.len() < EEPROM_BYTES {
        image.resize(EEPROM_BYTES, 0xFF);
    }
    image
}

/// Finds category `kind` in an image: its data, if present. For tests and tools.
pub fn find_category(image: &[u8], kind: u16) -> Option<&[u8]> {
    let mut at = FIRST_CATEGORY_WORD * 2;
    while let Some(header) = image.get(at..at + 4) {
        let found = u16::from_le_bytes([header[0], header[1]]);
        let words = usize::from(u16::from_le_bytes([header[2], header[3]]));
        if found == category::END {
            return None;
        }
        let data = image.get(at + 4..at + 4 + words * 2)?;
        if found == kind {
            return Some(data);
        }
        at += 4 + words * 2;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn description() -> SiiDescription {
        SiiDescription {
            identity: Identity {
                vendor_id: 0x0000_0B0B,
                product_code: 0x0001_0001,
                revision: 0x0002_0000,
                serial: 42,
            },
            alias: 0,
            name: "MB-IO".into(),
            description: "modbot test I/O".into(),
            group: "modbot".into(),
            mailbox: Some(MailboxLayout::default()),
            coe_details: coe_details::SDO | coe_details::PDO_ASSIGN | coe_details::PDO_CONFIG,
            sync_managers: vec![],
            fmmus: vec![1, 2, 3],
            rx_pdos: vec![],
            tx_pdos: vec![],
        }
    }

    #[test]
    fn the_header_checksum_matches_the_known_el2828_value() {
        // ethercrab's test vector: EL2828's first 14 bytes have checksum 0xE2.
        let bytes = [
            0x04, 0x01, 0x00, 0x00, 0x00, 0x00, 0xff, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        ];
        assert_eq!(header_crc(&bytes), 0xE2);
    }

    #[test]
    fn the_identity_sits_at_words_8_to_15() {
        let sut = build_image(&description());
        assert_eq!(&sut[16..20], &0x0000_0B0Bu32.to_le_bytes());
        assert_eq!(&sut[20..24], &0x0001_0001u32.to_le_bytes());
        assert_eq!(&sut[28..32], &42u32.to_le_bytes());
    }

    #[test]
    fn the_strings_category_holds_name_description_and_group() {
        let sut = build_image(&description());
        let strings = find_category(&sut, category::STRINGS).unwrap();
        assert_eq!(strings[0], 3);
        assert_eq!(&strings[2..7], b"MB-IO");
    }

    #[test]
    fn the_general_category_points_its_order_index_at_the_short_name() {
        let sut = build_image(&description());
        let general = find_category(&sut, category::GENERAL).unwrap();
        assert_eq!(general[2], 1);
        assert_eq!(general[3], 2);
        assert_eq!(general[5], 0x0D);
    }

    #[test]
    fn an_odd_fmmu_list_is_padded_with_an_unused_entry() {
        let sut = build_image(&description());
        assert_eq!(
            find_category(&sut, category::FMMU),
            Some(&[1, 2, 3, 0xFF][..])
        );
    }

    #[test]
    fn the_image_fills_the_eeprom_with_erased_cells() {
        let sut = build_image(&description());
        assert_eq!(sut.len(), EEPROM_BYTES);
        assert_eq!(sut[EEPROM_BYTES - 1], 0xFF);
        assert_eq!(u16::from_le_bytes([sut[0x7C], sut[0x7D]]), 15);
    }
}
