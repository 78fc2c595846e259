//! The Slave Information Interface (SII) EEPROM image (ETG.1000.6 §5.4, ETG.2010): the
//! fixed header (PDI configuration and its CRC, identity, mailbox sizes and protocols, size)
//! and the categories a master reads to configure a device (strings, general, FMMU, sync
//! managers, TxPDO and RxPDO).

/// Vendor, product, revision and serial number (SII words 0x08-0x0F, object 0x1018).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Identity {
    /// Vendor ID assigned by the EtherCAT Technology Group.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    #[serde(default)]
    pub serial: u32,
}

/// The standard mailbox: where its two sync managers lie and which protocols it speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxLayout {
    /// Master-to-device mailbox (SM0) start address.
    pub receive_offset: u16,
    /// Its size in bytes.
    pub receive_size: u16,
    /// Device-to-master mailbox (SM1) start address.
    pub send_offset: u16,
    /// Its size in bytes.
    pub send_size: u16,
    /// Protocol bits (SII word 0x1C): 0x0004 is CoE.
    pub protocols: u16,
}

/// Mailbox protocol bit of CoE (SII word 0x1C).
pub const PROTOCOL_COE: u16 = 0x0004;

/// What a sync manager is used for (SII SyncM category, byte 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SyncManagerUse {
    /// Mailbox written by the master (SM0).
    MailboxOut = 1,
    /// Mailbox read by the master (SM1).
    MailboxIn = 2,
    /// Process data outputs (master writes).
    Outputs = 3,
    /// Process data inputs (master reads).
    Inputs = 4,
}

/// One sync manager's default configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncManagerDefault {
    /// Physical start address.
    pub start: u16,
    /// Default length in bytes (0 for process data sized by the mapping).
    pub length: u16,
    /// Control byte (register 0x0804): mode and direction.
    pub control: u8,
    /// Enabled by default.
    pub enable: bool,
    /// Its use.
    pub usage: SyncManagerUse,
}

/// FMMU use (SII FMMU category).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmmuUse {
    /// Outputs (master writes).
    Outputs = 1,
    /// Inputs (master reads).
    Inputs = 2,
    /// Sync manager status.
    SyncManagerStatus = 3,
}

/// One PDO entry: the object, its sub-index and its length in bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoEntry {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub_index: u8,
    /// Length in bits.
    pub bits: u8,
    /// CANopen data type code (0x0001 BOOL, 0x0006 UNSIGNED16, ...), low byte.
    pub data_type: u8,
}

impl PdoEntry {
    /// The 32-bit mapping value of a PDO mapping object (index, sub-index, bit length).
    pub const fn mapping_value(&self) -> u32 {
        ((self.index as u32) << 16) | ((self.sub_index as u32) << 8) | self.bits as u32
    }
}

/// One PDO: its mapping object index, the sync manager that carries it, and its entries.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Pdo {
    /// Mapping object index (0x1600.. receive, 0x1A00.. transmit).
    pub index: u16,
    /// The sync manager carrying it.
    pub sync_manager: u8,
    /// The entries in order.
    pub entries: Vec<PdoEntry>,
}

impl Pdo {
    /// Total length in bits.
    pub fn bits(&self) -> usize {
        self.entries.iter().map(|e| usize::from(e.bits)).sum()
    }
}

/// Everything the EEPROM describes.
#[derive(Debug, Clone, PartialEq)]
pub struct SiiContents {
    /// Identity.
    pub identity: Identity,
    /// Configured station alias (word 0x04).
    pub alias: u16,
    /// Device name (the general category's name string).
    pub name: String,
    /// The standard mailbox, if the device has one.
    pub mailbox: Option<MailboxLayout>,
    /// General category byte 5 (CoE details): bit 0 SDO, bit 2 PDO assign, bit 3 PDO config.
    pub coe_details: u8,
    /// FMMU uses, in FMMU order.
    pub fmmus: Vec<FmmuUse>,
    /// Sync managers, in order.
    pub sync_managers: Vec<SyncManagerDefault>,
    /// Default transmit PDOs (inputs).
    pub tx_pdos: Vec<Pdo>,
    /// Default receive PDOs (outputs).
    pub rx_pdos: Vec<Pdo>,
}

/// Size of the simulated EEPROM in bytes (16 Kibit, like the usual 24C16).
pub const EEPROM_BYTES: usize = 2048;

/// Category type codes (ETG.2010 Table 3).
mod category {
    pub const STRINGS: u16 = 10;
    pub const GENERAL: u16 = 30;
    pub const FMMU: u16 = 40;
    pub const SYNC_MANAGER: u16 = 41;
    pub const TX_PDO: u16 = 50;
    pub const RX_PDO: u16 = 51;
    pub const END: u16 = 0xFFFF;
}

/// The EEPROM's words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiImage {
    words: Vec<u16>,
}

/// CRC-8 of the SII header (words 0-6): polynomial x⁸+x²+x+1, initial value 0xFF, no
/// reflection (ETG.1000.6 §5.4).
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

impl SiiImage {
    /// Lays out `contents`. Returns `None` if they do not fit the EEPROM.
    pub fn build(contents: &SiiContents) -> Option<Self> {
        let mut bytes = vec![0u8; 0x80];
        // Word 0: PDI control (0x05: none used here), 1: PDI configuration, 2: SYNC
        // impulse length (10 ns units), 3: extended PDI configuration.
        bytes[4..6].copy_from_slice(&100u16.to_le_bytes());
        bytes[8..10].copy_from_slice(&contents.alias.to_le_bytes());
        let crc = header_crc(&bytes[0..14]);
        bytes[14] = crc;
        let id = contents.identity;
        bytes[0x10..0x14].copy_from_slice(&id.vendor_id.to_le_bytes());
        bytes[0x14..0x18].copy_from_slice(&id.product_code.to_le_bytes());
        bytes[0x18..0x1C].copy_from_slice(&id.revision.to_le_bytes());
        bytes[0x1C..0x20].copy_from_slice(&id.serial.to_le_bytes());
        if let Some(mailbox) = contents.mailbox {
            for (word, value) in [
                (0x18, mailbox.receive_offset),
                (0x19, mailbox.receive_size),
                (0x1A, mailbox.send_offset),
                (0x1B, mailbox.send_size),
                (0x1C, mailbox.protocols),
            ] {
                bytes[word * 2..word * 2 + 2].copy_from_slice(&value.to_le_bytes());
            }
        }
        // Word 0x3E: size in Kibit minus one; 0x3F: version 1.
        let kibit = (EEPROM_BYTES * 8 / 1024) as u16;
        bytes[0x7C..0x7E].copy_from_slice(&(kibit - 1).to_le_bytes());
        bytes[0x7E..0x80].copy_from_slice(&1u16.to_le_bytes());

        // Strings: index 1 is the device name.
        let mut strings = vec![1u8];
        let name = contents.name.as_bytes();
        strings.push(u8::try_from(name.len()).ok()?);
        strings.extend_from_slice(name);
        push_category(&mut bytes, category::STRINGS, &strings)?;

        let mut general = [0u8; 32];
        general[3] = 1; // name string index
        general[5] = contents.coe_details;
        // Physical ports 0 and 1: MII.
        general[14..16].copy_from_slice(&0x0011u16.to_le_bytes());
        push_category(&mut bytes, category::GENERAL, &general)?;

        let fmmus: Vec<u8> = contents.fmmus.iter().map(|f| *f as u8).collect();
        push_category(&mut bytes, category::FMMU, &fmmus)?;

        let mut sms = Vec::new();
        for sm in &contents.sync_managers {
            sms.extend_from_slice(&sm.start.to_le_bytes());
            sms.extend_from_slice(&sm.length.to_le_bytes());
            sms.extend_from_slice(&[sm.control, 0, u8::from(sm.enable), sm.usage as u8]);
        }
        push_category(&mut bytes, category::SYNC_MANAGER, &sms)?;

        for (code, pdos) in [
            (category::TX_PDO, &contents.tx_pdos),
            (category::RX_PDO, &contents.rx_pdos),
        ] {
            if pdos.is_empty() {
                continue;
            }
            let mut data = Vec::new();
            for pdo in pdos {
                data.extend_from_slice(&pdo.index.to_le_bytes());
                data.push(u8::try_from(pdo.entries.len()).ok()?);
                data.extend_from_slice(&[pdo.sync_manager, 0, 0]);
                data.extend_from_slice(&0u16.to_le_bytes());
                for entry in &pdo.entries {
                    data.extend_from_slice(&entry.index.to_le_bytes());
                    data.extend_from_slice(&[entry.sub_index, 0, entry.data_type, entry.bits]);
                    data.extend_from_slice(&0u16.to_le_bytes());
                }
            }
            push_category(&mut bytes, code, &data)?;
        }
        bytes.extend_from_slice(&category::END.to_le_bytes());
        if bytes.len() > EEPROM_BYTES {
            return None;
        }
        bytes.resize(EEPROM_BYTES, 0xFF);
        let words = bytes
            .chunks_exact(2)
            .map(|w| u16::from_le_bytes([w[0], w[1]]))
            .collect();
        Some(Self { words })
    }

    /// The word at `address`, 0xFFFF past the end (an erased cell).
    pub fn word(&self, address: u32) -> u16 {
        usize::try_from(address)
            .ok()
            .and_then(|a| self.words.get(a))
            .copied()
            .unwrap_or(0xFFFF)
    }

    /// Writes one word; returns false past the end.
    pub fn write_word(&mut self, address: u32, value: u16) -> bool {
        match usize::try_from(address)
            .ok()
            .and_then(|a| self.words.get_mut(a))
        {
            Some(word) => {
                *word = value;
                true
            }
            None => false,
        }
    }

    /// Whether the header's CRC matches its words 0-6.
    pub fn header_crc_valid(&self) -> bool {
        let mut bytes = [0u8; 14];
        for (i, chunk) in bytes.chunks_exact_mut(2).enumerate() {
            chunk.copy_from_slice(&self.word(i as u32).to_le_bytes());
        }
        header_crc(&bytes) == (self.word(7) & 0xFF) as u8
    }

    /// The configured station alias of word 4.
    pub fn alias(&self) -> u16 {
        self.word(4)
    }
}

fn push_category(bytes: &mut Vec<u8>, code: u16, data: &[u8]) -> Option<()> {
    let words = u16::try_from(data.len().div_ceil(2)).ok()?;
    bytes.extend_from_slice(&code.to_le_bytes());
    bytes.extend_from_slice(&words.to_le_bytes());
    bytes.extend_from_slice(data);
    if data.len() % 2 == 1 {
        bytes.push(0);
    }
    Some(())
}
