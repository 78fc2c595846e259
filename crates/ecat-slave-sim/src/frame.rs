//! The EtherCAT frame as it travels on the wire: an Ethernet II header with EtherType
//! 0x88A4, the 2-byte EtherCAT header, then datagrams (ETG.1000.4 §5.4). Every accessor
//! here works on a byte slice and checks its bounds: a malformed frame is refused, never a
//! panic.

/// EtherType of EtherCAT frames.
pub const ETHERTYPE: u16 = 0x88A4;
/// Ethernet II header: destination, source, EtherType.
pub const ETHERNET_HEADER_LEN: usize = 14;
/// EtherCAT frame header (length and type).
pub const ECAT_HEADER_LEN: usize = 2;
/// Datagram header: command, index, address, length/flags, IRQ.
pub const DATAGRAM_HEADER_LEN: usize = 10;
/// The working counter that closes every datagram.
pub const WKC_LEN: usize = 2;
/// EtherCAT header type "datagrams" (bits 12-15).
const TYPE_DATAGRAMS: u16 = 1;
/// Datagram length field: bits 0-10 hold the data length.
const LEN_MASK: u16 = 0x07FF;
/// Datagram length field bit 15: another datagram follows.
const MORE_FOLLOWS: u16 = 0x8000;
/// Datagram length field bit 14: the frame has circulated (passed a closed port once).
const CIRCULATING: u16 = 0x4000;

/// The datagram commands (ETG.1000.4 Table 12).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// No operation.
    Nop,
    /// Auto-increment physical read.
    Aprd,
    /// Auto-increment physical write.
    Apwr,
    /// Auto-increment physical read-write.
    Aprw,
    /// Configured-address physical read.
    Fprd,
    /// Configured-address physical write.
    Fpwr,
    /// Configured-address physical read-write.
    Fprw,
    /// Broadcast read.
    Brd,
    /// Broadcast write.
    Bwr,
    /// Broadcast read-write.
    Brw,
    /// Logical read.
    Lrd,
    /// Logical write.
    Lwr,
    /// Logical read-write.
    Lrw,
    /// Auto-increment read, multiple write.
    Armw,
    /// Configured-address read, multiple write.
    Frmw,
}

impl Command {
    /// The command of a datagram's first byte; `None` for the reserved codes.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => Self::Nop,
            1 => Self::Aprd,
            2 => Self::Apwr,
            3 => Self::Aprw,
            4 => Self::Fprd,
            5 => Self::Fpwr,
            6 => Self::Fprw,
            7 => Self::Brd,
            8 => Self::Bwr,
            9 => Self::Brw,
            10 => Self::Lrd,
            11 => Self::Lwr,
            12 => Self::Lrw,
            13 => Self::Armw,
            14 => Self::Frmw,
            _ => return None,
        })
    }

    /// The command's code on the wire.
    pub const fn code(self) -> u8 {
        match self {
            Self::Nop => 0,
            Self::Aprd => 1,
            Self::Apwr => 2,
            Self::Aprw => 3,
            Self::Fprd => 4,
            Self::Fpwr => 5,
            Self::Fprw => 6,
            Self::Brd => 7,
            Self::Bwr => 8,
            Self::Brw => 9,
            Self::Lrd => 10,
            Self::Lwr => 11,
            Self::Lrw => 12,
            Self::Armw => 13,
            Self::Frmw => 14,
        }
    }
}

/// Where one datagram lies in a frame (offsets into the Ethernet frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DatagramSpan {
    /// Offset of the datagram header.
    pub header: usize,
    /// Length of its data.
    pub data_len: usize,
}

impl DatagramSpan {
    /// Offset of the data.
    pub const fn data(&self) -> usize {
        self.header + DATAGRAM_HEADER_LEN
    }
    /// Offset of the working counter.
    pub const fn wkc(&self) -> usize {
        self.data() + self.data_len
    }
}

/// Why a frame was not processed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Shorter than its headers say.
    #[error("frame truncated")]
    Truncated,
    /// Not EtherType 0x88A4.
    #[error("not an EtherCAT frame (EtherType {0:#06x})")]
    NotEthercat(u16),
    /// The EtherCAT header's type is not "datagrams".
    #[error("EtherCAT header type {0} is not datagrams")]
    UnsupportedType(u16),
    /// More datagrams than the caller has room to list.
    #[error("more than {0} datagrams in one frame")]
    TooManyDatagrams(usize),
}

/// Lists the datagrams of `frame` into `spans` (which bounds how many are accepted) and
/// returns how many there are.
pub fn datagrams(frame: &[u8], spans: &mut [DatagramSpan]) -> Result<usize, FrameError> {
    let ethertype = read_u16_be(frame, 12).ok_or(FrameError::Truncated)?;
    if ethertype != ETHERTYPE {
        return Err(FrameError::NotEthercat(ethertype));
    }
    let header = read_u16(frame, ETHERNET_HEADER_LEN).ok_or(FrameError::Truncated)?;
    let kind = header >> 12;
    if kind != TYPE_DATAGRAMS {
        return Err(FrameError::UnsupportedType(kind));
    }
    let end = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN + usize::from(header & LEN_MASK);
    if end > frame.len() {
        return Err(FrameError::Truncated);
    }
    let mut offset = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
    let mut count = 0;
    loop {
        let flags = read_u16(frame, offset + 6).ok_or(FrameError::Truncated)?;
        let data_len = usize::from(flags & LEN_MASK);
        let span = DatagramSpan {
            header: offset,
            data_len,
        };
        if span.wkc() + WKC_LEN > end {
            return Err(FrameError::Truncated);
        }
        let slot = spans
            .get_mut(count)
            .ok_or(FrameError::TooManyDatagrams(count))?;
        *slot = span;
        count += 1;
        offset = span.wkc() + WKC_LEN;
        if flags & MORE_FOLLOWS == 0 {
            return Ok(count);
        }
    }
}

/// Marks every datagram of a frame as having circulated (a frame that reaches a closed
/// port of the first device comes back with this bit set; the master drops it).
pub fn mark_circulating(frame: &mut [u8], spans: &[DatagramSpan]) {
    for span in spans {
        if let Some(flags) = read_u16(frame, span.header + 6) {
            write_u16(frame, span.header + 6, flags | CIRCULATING);
        }
    }
}

/// Builds one frame holding the given datagrams into `out`, returning its length: the
/// helper that tests and the independent checks use to speak to a segment.
pub fn build(
    out: &mut [u8],
    source_mac: [u8; 6],
    datagrams: &[(Command, u8, u32, &[u8])],
) -> Option<usize> {
    let mut offset = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
    for (n, (command, index, address, data)) in datagrams.iter().enumerate() {
        let end = offset + DATAGRAM_HEADER_LEN + data.len() + WKC_LEN;
        let slice = out.get_mut(offset..end)?;
        let len = u16::try_from(data.len()).ok().filter(|l| *l <= LEN_MASK)?;
        let more = if n + 1 < datagrams.len() {
            MORE_FOLLOWS
        } else {
            0
        };
        slice[0] = command.code();
        slice[1] = *index;
        slice[2..6].copy_from_slice(&address.to_le_bytes());
        slice[6..8].copy_from_slice(&(len | more).to_le_bytes());
        slice[8..10].copy_from_slice(&[0, 0]);
        slice[10..10 + data.len()].copy_from_slice(data);
        slice[10 + data.len()..].copy_from_slice(&[0, 0]);
        offset = end;
    }
    let payload = u16::try_from(offset - ETHERNET_HEADER_LEN - ECAT_HEADER_LEN).ok()?;
    let header = out.get_mut(..ETHERNET_HEADER_LEN + ECAT_HEADER_LEN)?;
    header[0..6].copy_from_slice(&[0xFF; 6]);
    header[6..12].copy_from_slice(&source_mac);
    header[12..14].copy_from_slice(&ETHERTYPE.to_be_bytes());
    header[14..16].copy_from_slice(&((payload & LEN_MASK) | (TYPE_DATAGRAMS << 12)).to_le_bytes());
    Some(offset)
}

/// A little-endian u16 at `offset`, if the slice holds it.
pub fn read_u16(bytes: &[u8], offset: usize) -> Option<u16> {
    let b = bytes.get(offset..offset.checked_add(2)?)?;
    Some(u16::from_le_bytes([b[0], b[1]]))
}

fn read_u16_be(bytes: &[u8], offset: usize) -> Option<u16> {
    let b = bytes.get(offset..offset.checked_add(2)?)?;
    Some(u16::from_be_bytes([b[0], b[1]]))
}

/// A little-endian u32 at `offset`, if the slice holds it.
pub fn read_u32(bytes: &[u8], offset: usize) -> Option<u32> {
    let b = bytes.get(offset..offset.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// A little-endian u64 at `offset`, if the slice holds it.
pub fn read_u64(bytes: &[u8], offset: usize) -> Option<u64> {
    let b = bytes.get(offset..offset.checked_add(8)?)?;
    let mut a = [0u8; 8];
    a.copy_from_slice(b);
    Some(u64::from_le_bytes(a))
}

/// Writes a little-endian u16 at `offset` if the slice has room; otherwise nothing.
pub fn write_u16(bytes: &mut [u8], offset: usize, value: u16) {
    if let Some(b) = offset
        .checked_add(2)
        .and_then(|end| bytes.get_mut(offset..end))
    {
        b.copy_from_slice(&value.to_le_bytes());
    }
}

/// Writes a little-endian u32 at `offset` if the slice has room; otherwise nothing.
pub fn write_u32(bytes: &mut [u8], offset: usize, value: u32) {
    if let Some(b) = offset
        .checked_add(4)
        .and_then(|end| bytes.get_mut(offset..end))
    {
        b.copy_from_slice(&value.to_le_bytes());
    }
}

/// Writes a little-endian u64 at `offset` if the slice has room; otherwise nothing.
pub fn write_u64(bytes: &mut [u8], offset: usize, value: u64) {
    if let Some(b) = offset
        .checked_add(8)
        .and_then(|end| bytes.get_mut(offset..end))
    {
        b.copy_from_slice(&value.to_le_bytes());
    }
}
