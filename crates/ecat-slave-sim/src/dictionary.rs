//! The CANopen object dictionary behind the CoE mailbox: objects addressed by index and
//! sub-index, each with a value, an access right and whether it may be mapped into a PDO;
//! the SDO abort codes of CiA 301 / ETG.1000.6.

use crate::esc::AlState;

/// SDO abort codes (ETG.1000.6 Table 41, CiA 301).
pub mod abort {
    /// Toggle bit not changed.
    pub const TOGGLE: u32 = 0x0503_0000;
    /// Client/server command specifier not valid or unknown.
    pub const COMMAND: u32 = 0x0504_0001;
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// Sub-index cannot be written: sub-index 0 must be 0 for write access.
    pub const SUB_INDEX_0_NOT_ZERO: u32 = 0x0601_0003;
    /// The object does not exist in the object dictionary.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// The object cannot be mapped into the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const PDO_TOO_LONG: u32 = 0x0604_0042;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH: u32 = 0x0607_0010;
    /// Sub-index does not exist.
    pub const NO_SUB_INDEX: u32 = 0x0609_0011;
    /// Value range of parameter exceeded.
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// General error.
    pub const GENERAL: u32 = 0x0800_0000;
    /// Data cannot be transferred or stored because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

/// Who may write an object, and when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Read only.
    ReadOnly,
    /// Read and write in any state with a mailbox.
    ReadWrite,
    /// Read always, write in PRE-OP only (PDO mapping and assignment, sync parameters).
    ReadWritePreOp,
}

/// Whether an object may be mapped, and in which direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mapping {
    /// Not mappable.
    None,
    /// Into a receive PDO (outputs of the master).
    Rx,
    /// Into a transmit PDO (inputs of the master).
    Tx,
}

/// One sub-index of an object.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub_index: u8,
    /// The value, little-endian.
    pub value: Vec<u8>,
    /// Fixed length in bytes, or `None` for a string of at most `value`'s capacity.
    pub fixed_len: Option<usize>,
    /// Largest length of a variable-length value.
    pub max_len: usize,
    /// Access right.
    pub access: Access,
    /// PDO mapping.
    pub mapping: Mapping,
}

/// The dictionary: entries sorted by (index, sub-index).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Dictionary {
    entries: Vec<Entry>,
}

impl Dictionary {
    /// An empty dictionary.
    pub fn new() -> Self {
        Self::default()
    }

    fn position(&self, index: u16, sub_index: u8) -> Result<usize, usize> {
        self.entries
            .binary_search_by_key(&(index, sub_index), |e| (e.index, e.sub_index))
    }

    /// Adds (or replaces) a fixed-length entry.
    pub fn insert(
        &mut self,
        index: u16,
        sub_index: u8,
        value: &[u8],
        access: Access,
        mapping: Mapping,
    ) {
        self.put(Entry {
            index,
            sub_index,
            value: value.to_vec(),
            fixed_len: Some(value.len()),
            max_len: value.len(),
            access,
            mapping,
        });
    }

    /// Adds (or replaces) a string entry of at most `max_len` bytes.
    pub fn insert_string(
        &mut self,
        index: u16,
        sub_index: u8,
        value: &str,
        max_len: usize,
        access: Access,
    ) {
        self.put(Entry {
            index,
            sub_index,
            value: value.as_bytes().to_vec(),
            fixed_len: None,
            max_len,
            access,
            mapping: Mapping::None,
        });
    }

    fn put(&mut self, entry: Entry) {
        match self.position(entry.index, entry.sub_index) {
            Ok(at) => self.entries[at] = entry,
            Err(at) => self.entries.insert(at, entry),
        }
    }

    /// The entry at (index, sub-index).
    pub fn entry(&self, index: u16, sub_index: u8) -> Option<&Entry> {
        self.position(index, sub_index)
            .ok()
            .map(|at| &self.entries[at])
    }

    /// The value at (index, sub-index).
    pub fn value(&self, index: u16, sub_index: u8) -> Option<&[u8]> {
        self.entry(index, sub_index).map(|e| e.value.as_slice())
    }

    /// The value as an unsigned integer of up to 8 bytes (0 if absent).
    pub fn unsigned(&self, index: u16, sub_index: u8) -> u64 {
        let mut bytes = [0u8; 8];
        if let Some(value) = self.value(index, sub_index) {
            for (b, v) in bytes.iter_mut().zip(value) {
                *b = *v;
            }
        }
        u64::from_le_bytes(bytes)
    }

    /// Overwrites a value from the device's side (no access check); ignored if the entry is
    /// absent or the length differs from a fixed length.
    pub fn set(&mut self, index: u16, sub_index: u8, value: &[u8]) {
        if let Ok(at) = self.position(index, sub_index) {
            let entry = &mut self.entries[at];
            if entry.fixed_len.is_none_or(|len| len == value.len()) {
                entry.value.clear();
                entry.value.extend_from_slice(value);
            }
        }
    }

    /// Whether the object exists at all (any sub-index).
    pub fn has_object(&self, index: u16) -> bool {
        let at = self.position(index, 0).unwrap_or_else(|at| at);
        self.entries.get(at).is_some_and(|e| e.index == index)
    }

    /// An SDO upload: the value, or the abort code.
    pub fn upload(&self, index: u16, sub_index: u8) -> Result<&[u8], u32> {
        match self.entry(index, sub_index) {
            Some(entry) => Ok(&entry.value),
            None if self.has_object(index) => Err(abort::NO_SUB_INDEX),
            None => Err(abort::NO_OBJECT),
        }
    }

    /// The generic checks of an SDO download (existence, access right and state, length),
    /// before the device's own; returns the entry's fixed length if any.
    pub fn check_download(
        &self,
        index: u16,
        sub_index: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), u32> {
        let entry = match self.entry(index, sub_index) {
            Some(entry) => entry,
            None if self.has_object(index) => return Err(abort::NO_SUB_INDEX),
            None => return Err(abort::NO_OBJECT),
        };
        match entry.access {
            Access::ReadOnly => return Err(abort::READ_ONLY),
            Access::ReadWritePreOp if state != AlState::PreOp => return Err(abort::DEVICE_STATE),
            _ => {}
        }
        match entry.fixed_len {
            Some(len) if len != data.len() => Err(abort::LENGTH),
            None if data.len() > entry.max_len => Err(abort::LENGTH),
            _ => Ok(()),
        }
    }
}
