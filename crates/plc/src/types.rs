//! Data types, their byte layout and the IEC implicit conversion (widening) rules.
//!
//! Memory is laid out as CODESYS 3 and TwinCAT 3 lay it out on x86-64: every elementary
//! value little-endian at its own size and aligned to it (BOOL, BYTE, SINT, USINT 1 byte;
//! WORD, INT, UINT 2; DWORD, DINT, UDINT, REAL 4; LWORD, LINT, ULINT, LREAL 8; pointers,
//! references and interfaces 8), structures padded to their largest member's alignment,
//! arrays contiguous, a STRING(n) n + 1 bytes ending in a zero byte, a WSTRING(n) n + 1
//! UTF-16 code units ending in a zero unit. TIME, DATE, TIME_OF_DAY and DATE_AND_TIME
//! count nanoseconds in 8 bytes (as LTIME, LDATE ... do), enumerations take a DINT.

use std::sync::Arc;

/// Longest STRING accepted (IEC leaves the maximum to the implementation).
pub const MAX_STRING_LEN: u16 = 255;
/// Capacity of a STRING declared without one.
pub const DEFAULT_STRING_LEN: u16 = 80;

/// Elementary type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[allow(missing_docs)]
pub enum Elem {
    Bool,
    SInt,
    Int,
    DInt,
    LInt,
    USInt,
    UInt,
    UDInt,
    ULInt,
    Byte,
    Word,
    DWord,
    LWord,
    Real,
    LReal,
    Time,
    /// DATE (and LDATE): nanoseconds from 1970-01-01 to midnight of the day.
    Date,
    /// TIME_OF_DAY (TOD, LTOD): nanoseconds from midnight.
    Tod,
    /// DATE_AND_TIME (DT, LDT): nanoseconds from 1970-01-01-00:00:00.
    Dt,
}

impl Elem {
    /// All elementary types, for name look-ups.
    pub const ALL: [Elem; 19] = [
        Elem::Bool,
        Elem::SInt,
        Elem::Int,
        Elem::DInt,
        Elem::LInt,
        Elem::USInt,
        Elem::UInt,
        Elem::UDInt,
        Elem::ULInt,
        Elem::Byte,
        Elem::Word,
        Elem::DWord,
        Elem::LWord,
        Elem::Real,
        Elem::LReal,
        Elem::Time,
        Elem::Date,
        Elem::Tod,
        Elem::Dt,
    ];
    /// IEC name.
    pub fn name(self) -> &'static str {
        match self {
            Elem::Bool => "BOOL",
            Elem::SInt => "SINT",
            Elem::Int => "INT",
            Elem::DInt => "DINT",
            Elem::LInt => "LINT",
            Elem::USInt => "USINT",
            Elem::UInt => "UINT",
            Elem::UDInt => "UDINT",
            Elem::ULInt => "ULINT",
            Elem::Byte => "BYTE",
            Elem::Word => "WORD",
            Elem::DWord => "DWORD",
            Elem::LWord => "LWORD",
            Elem::Real => "REAL",
            Elem::LReal => "LREAL",
            Elem::Time => "TIME",
            Elem::Date => "DATE",
            Elem::Tod => "TIME_OF_DAY",
            Elem::Dt => "DATE_AND_TIME",
        }
    }
    /// Look up by (upper-case) name; LTIME is accepted as TIME (both count nanoseconds).
    pub fn from_name(n: &str) -> Option<Elem> {
        match n {
            "LTIME" => return Some(Elem::Time),
            "LDATE" => return Some(Elem::Date),
            "TOD" | "LTOD" | "LTIME_OF_DAY" => return Some(Elem::Tod),
            "DT" | "LDT" | "LDATE_AND_TIME" => return Some(Elem::Dt),
            _ => {}
        }
        Elem::ALL.iter().copied().find(|e| e.name() == n)
    }
    /// Signed or unsigned integer types.
    pub fn is_int(self) -> bool {
        self.int_kind().is_some() && !self.is_bit() && !self.is_moment()
    }
    /// DATE, TIME_OF_DAY, DATE_AND_TIME.
    pub fn is_moment(self) -> bool {
        matches!(self, Elem::Date | Elem::Tod | Elem::Dt)
    }
    /// BYTE, WORD, DWORD, LWORD (BOOL is handled apart).
    pub fn is_bit(self) -> bool {
        matches!(self, Elem::Byte | Elem::Word | Elem::DWord | Elem::LWord)
    }
    /// REAL or LREAL.
    pub fn is_real(self) -> bool {
        matches!(self, Elem::Real | Elem::LReal)
    }
    /// Integer or real.
    pub fn is_num(self) -> bool {
        self.is_int() || self.is_real()
    }
    /// Width and signedness of integer-like types (integers, bit strings, TIME).
    pub fn int_kind(self) -> Option<IntKind> {
        Some(match self {
            Elem::SInt => IntKind::I8,
            Elem::Int => IntKind::I16,
            Elem::DInt => IntKind::I32,
            Elem::LInt | Elem::Time | Elem::Date | Elem::Tod | Elem::Dt => IntKind::I64,
            Elem::USInt | Elem::Byte => IntKind::U8,
            Elem::UInt | Elem::Word => IntKind::U16,
            Elem::UDInt | Elem::DWord => IntKind::U32,
            Elem::ULInt | Elem::LWord => IntKind::U64,
            Elem::Bool => IntKind::U1,
            Elem::Real | Elem::LReal => return None,
        })
    }
    /// Range of an integer type.
    pub fn int_range(self) -> Option<(i128, i128)> {
        self.int_kind().map(|k| k.range())
    }
    /// Bytes the value takes in memory (and its alignment).
    pub fn size(self) -> u32 {
        match self {
            Elem::Bool | Elem::SInt | Elem::USInt | Elem::Byte => 1,
            Elem::Int | Elem::UInt | Elem::Word => 2,
            Elem::DInt | Elem::UDInt | Elem::DWord | Elem::Real => 4,
            _ => 8,
        }
    }
    /// Size in bits.
    pub fn bits(self) -> u32 {
        match self {
            Elem::Bool => 1,
            Elem::SInt | Elem::USInt | Elem::Byte => 8,
            Elem::Int | Elem::UInt | Elem::Word => 16,
            Elem::DInt | Elem::UDInt | Elem::DWord | Elem::Real => 32,
            _ => 64,
        }
    }
}

/// Width and signedness of an integer register value, for wrap-around after arithmetic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[allow(missing_docs)]
pub enum IntKind {
    U1,
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
}

impl IntKind {
    /// Wraps a 64-bit result to this width (two's complement, as the PLCs do).
    #[inline(always)]
    pub fn wrap(self, v: u64) -> u64 {
        match self {
            IntKind::U1 => v & 1,
            IntKind::I8 => v as i8 as i64 as u64,
            IntKind::I16 => v as i16 as i64 as u64,
            IntKind::I32 => v as i32 as i64 as u64,
            IntKind::I64 | IntKind::U64 => v,
            IntKind::U8 => v & 0xff,
            IntKind::U16 => v & 0xffff,
            IntKind::U32 => v & 0xffff_ffff,
        }
    }
    /// Signed kinds compare and divide as i64, unsigned as u64.
    #[inline(always)]
    pub fn signed(self) -> bool {
        matches!(
            self,
            IntKind::I8 | IntKind::I16 | IntKind::I32 | IntKind::I64
        )
    }
    /// Number of bits.
    pub fn bits(self) -> u32 {
        match self {
            IntKind::U1 => 1,
            IntKind::I8 | IntKind::U8 => 8,
            IntKind::I16 | IntKind::U16 => 16,
            IntKind::I32 | IntKind::U32 => 32,
            IntKind::I64 | IntKind::U64 => 64,
        }
    }
    /// Inclusive value range.
    pub fn range(self) -> (i128, i128) {
        let b = self.bits();
        if self.signed() {
            (-(1i128 << (b - 1)), (1i128 << (b - 1)) - 1)
        } else {
            (0, (1i128 << b) - 1)
        }
    }
    /// [`range`](Self::range) as the nearest `f64`s, without 128-bit conversions (which
    /// cost a library call on every signal written to the PLC).
    #[inline]
    pub fn range_f64(self) -> (f64, f64) {
        match self {
            IntKind::U1 => (0.0, 1.0),
            IntKind::I8 => (f64::from(i8::MIN), f64::from(i8::MAX)),
            IntKind::I16 => (f64::from(i16::MIN), f64::from(i16::MAX)),
            IntKind::I32 => (f64::from(i32::MIN), f64::from(i32::MAX)),
            IntKind::I64 => (i64::MIN as f64, i64::MAX as f64),
            IntKind::U8 => (0.0, f64::from(u8::MAX)),
            IntKind::U16 => (0.0, f64::from(u16::MAX)),
            IntKind::U32 => (0.0, f64::from(u32::MAX)),
            IntKind::U64 => (0.0, u64::MAX as f64),
        }
    }
}

/// Identifier of a composite type in the program's type tables.
pub type TypeId = u32;

/// A resolved data type.
#[derive(Debug, Clone, PartialEq)]
pub enum Type {
    /// Elementary type.
    Elem(Elem),
    /// STRING with its capacity in bytes.
    String(u16),
    /// WSTRING with its capacity in UTF-16 code units.
    WString(u16),
    /// Enumeration (index into the enum table).
    Enum(TypeId),
    /// Subrange of an integer type.
    Subrange(Elem, i64, i64),
    /// Array.
    Array(Arc<ArrayType>),
    /// Structure (index into the struct table).
    Struct(TypeId),
    /// Function block instance (index into the FB type table).
    Fb(TypeId),
    /// `POINTER TO T`: 8 bytes holding a byte address, 0 for none.
    Pointer(Arc<Type>),
    /// `REFERENCE TO T`: as a pointer, but every use reads or writes the target.
    Reference(Arc<Type>),
    /// An interface: 8 bytes holding the byte address of a function block instance that
    /// implements it, 0 for none.
    Interface(TypeId),
}

/// An array type: dimensions and element.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayType {
    /// Inclusive bounds of every dimension.
    pub dims: Vec<(i64, i64)>,
    /// Element type.
    pub elem: Type,
    /// Bytes per element (a structure's size includes its padding).
    pub elem_size: u32,
}

impl ArrayType {
    /// Number of elements.
    pub fn len(&self) -> u64 {
        self.dims.iter().map(|(l, h)| (h - l + 1) as u64).product()
    }
    /// True if the array has no element (never: bounds are checked at declaration).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// An enumeration.
#[derive(Debug, Clone, PartialEq)]
pub struct EnumType {
    /// Name (upper case, or a generated name for anonymous ones).
    pub name: String,
    /// Values in declaration order.
    pub values: Vec<(String, i64)>,
}

/// A structure.
#[derive(Debug, Clone, PartialEq)]
pub struct StructType {
    /// Name.
    pub name: String,
    /// Fields with their byte offset.
    pub fields: Vec<Field>,
    /// Bytes, padded to a multiple of `align`.
    pub size: u32,
    /// Alignment: the largest of its members'.
    pub align: u32,
}

/// A field of a structure or a member of a function block instance.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Upper-case name.
    pub name: String,
    /// Type.
    pub ty: Type,
    /// Offset in bytes from the start of the structure or instance.
    pub offset: u32,
}

impl Type {
    /// BOOL.
    pub const BOOL: Type = Type::Elem(Elem::Bool);
    /// The representation of a scalar type in memory.
    pub(crate) fn repr(&self) -> Option<Repr> {
        self.scalar().map(Repr::of)
    }
    /// The elementary type this type is stored as, if scalar.
    pub fn scalar(&self) -> Option<Elem> {
        match self {
            Type::Elem(e) => Some(*e),
            Type::Subrange(e, _, _) => Some(*e),
            Type::Enum(_) => Some(Elem::DInt),
            Type::Pointer(_) | Type::Reference(_) | Type::Interface(_) => Some(Elem::LWord),
            _ => None,
        }
    }
    /// Pointers, references and interfaces: 8 bytes holding an address.
    pub fn is_address(&self) -> bool {
        matches!(
            self,
            Type::Pointer(_) | Type::Reference(_) | Type::Interface(_)
        )
    }
    /// The elementary type, if this is exactly an elementary type or a subrange of one.
    pub fn elem(&self) -> Option<Elem> {
        match self {
            Type::Elem(e) | Type::Subrange(e, _, _) => Some(*e),
            _ => None,
        }
    }
    /// STRING or WSTRING.
    pub fn is_string(&self) -> bool {
        matches!(self, Type::String(_) | Type::WString(_))
    }
    /// Bytes of a STRING or WSTRING, `None` for other types.
    pub fn string_bytes(&self) -> Option<u32> {
        match self {
            Type::String(n) => Some(string_bytes(*n)),
            Type::WString(n) => Some(wstring_bytes(*n)),
            _ => None,
        }
    }
    /// True for BOOL.
    pub fn is_bool(&self) -> bool {
        self.elem() == Some(Elem::Bool)
    }
}

/// Bytes of a STRING with capacity `cap`: its characters and the terminating zero.
pub fn string_bytes(cap: u16) -> u32 {
    cap as u32 + 1
}

/// Bytes of a WSTRING with capacity `cap`: its code units and the terminating zero unit.
pub fn wstring_bytes(cap: u16) -> u32 {
    2 * (cap as u32 + 1)
}

/// How an elementary value is stored in memory: its width, and how it widens to the
/// 64-bit register value the interpreter computes with (integers sign- or zero-extended,
/// REAL as the f64 of its single, BOOL as 0 or 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Repr {
    /// One byte, any non-zero value TRUE.
    Bool,
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    /// IEEE-754 single precision.
    F32,
    /// Eight bytes as they are (LINT, ULINT, LREAL bits, TIME, addresses).
    U64,
}

impl Repr {
    /// The representation of an elementary type.
    pub(crate) fn of(e: Elem) -> Repr {
        match e {
            Elem::Bool => Repr::Bool,
            Elem::SInt => Repr::I8,
            Elem::USInt | Elem::Byte => Repr::U8,
            Elem::Int => Repr::I16,
            Elem::UInt | Elem::Word => Repr::U16,
            Elem::DInt => Repr::I32,
            Elem::UDInt | Elem::DWord => Repr::U32,
            Elem::Real => Repr::F32,
            _ => Repr::U64,
        }
    }
    /// The register value of the bytes at `a` in `mem`; 0 outside it. Exactly the value's
    /// bytes are read: a wider read would overlap a neighbour just stored (adjacent BOOLs)
    /// and wait for that store to retire.
    #[inline(always)]
    pub(crate) fn load(self, mem: &[u8], a: usize) -> u64 {
        // BOOL first, on a branch of its own: the commonest load of a PLC program, taken
        // without the jump on the width.
        if self == Repr::Bool {
            return mem.get(a).map_or(0, |b| (*b != 0) as u64);
        }
        self.load_wide(mem, a)
    }
    /// [`load`](Self::load) of the types other than BOOL: one copy of the jump on the
    /// width, out of the interpreter's loop, which stays small.
    #[inline(never)]
    fn load_wide(self, mem: &[u8], a: usize) -> u64 {
        match self {
            Repr::Bool => mem.get(a).map_or(0, |b| (*b != 0) as u64),
            Repr::I8 => mem.get(a).map_or(0, |b| *b as i8 as i64 as u64),
            Repr::U8 => mem.get(a).map_or(0, |b| *b as u64),
            Repr::I16 => bytes::<2>(mem, a).map_or(0, |b| i16::from_le_bytes(b) as i64 as u64),
            Repr::U16 => bytes::<2>(mem, a).map_or(0, |b| u16::from_le_bytes(b) as u64),
            Repr::I32 => bytes::<4>(mem, a).map_or(0, |b| i32::from_le_bytes(b) as i64 as u64),
            Repr::U32 => bytes::<4>(mem, a).map_or(0, |b| u32::from_le_bytes(b) as u64),
            Repr::F32 => bytes::<4>(mem, a).map_or(0, |b| (f32::from_le_bytes(b) as f64).to_bits()),
            Repr::U64 => bytes::<8>(mem, a).map_or(0, u64::from_le_bytes),
        }
    }
    /// Stores register value `v` at `a` in `mem`: exactly the value's bytes, nothing
    /// outside `mem`.
    #[inline(always)]
    pub(crate) fn store(self, mem: &mut [u8], a: usize, v: u64) {
        if self == Repr::Bool {
            return put(mem, a, [(v & 1) as u8]);
        }
        self.store_wide(mem, a, v)
    }
    #[inline(never)]
    fn store_wide(self, mem: &mut [u8], a: usize, v: u64) {
        match self {
            Repr::Bool => put(mem, a, [(v & 1) as u8]),
            Repr::I8 | Repr::U8 => put(mem, a, [v as u8]),
            Repr::I16 | Repr::U16 => put(mem, a, (v as u16).to_le_bytes()),
            Repr::I32 | Repr::U32 => put(mem, a, (v as u32).to_le_bytes()),
            Repr::F32 => put(mem, a, (f64::from_bits(v) as f32).to_le_bytes()),
            Repr::U64 => put(mem, a, v.to_le_bytes()),
        }
    }
}

#[inline(always)]
fn bytes<const N: usize>(mem: &[u8], a: usize) -> Option<[u8; N]> {
    mem.get(a..a.checked_add(N)?)
        .and_then(|s| s.try_into().ok())
}

#[inline(always)]
fn put<const N: usize>(mem: &mut [u8], a: usize, b: [u8; N]) {
    if let Some(d) = a.checked_add(N).and_then(|e| mem.get_mut(a..e)) {
        d.copy_from_slice(&b);
    }
}

/// The unsigned integer of a bit string's width (BYTE → USINT ...), for CODESYS's
/// arithmetic on bit strings; other types stay.
pub fn as_unsigned(e: Elem) -> Elem {
    match e {
        Elem::Byte => Elem::USInt,
        Elem::Word => Elem::UInt,
        Elem::DWord => Elem::UDInt,
        Elem::LWord => Elem::ULInt,
        e => e,
    }
}

/// CODESYS's implicit conversion in assignments and arguments: besides IEC's, any integer
/// or bit string to any other (narrowing keeps the low bits) or to a real.
pub fn codesys_converts(from: Elem, to: Elem) -> bool {
    let integer = |e: Elem| e.is_int() || e.is_bit();
    widens(from, to) || (integer(from) && (integer(to) || to.is_real()))
}

/// IEC 61131-3 (3rd edition) implicit conversion: may a value of `from` be used where `to`
/// is expected without an explicit *_TO_* call?
pub fn widens(from: Elem, to: Elem) -> bool {
    use Elem::*;
    if from == to {
        return true;
    }
    match from {
        SInt => matches!(to, Int | DInt | LInt | Real | LReal),
        Int => matches!(to, DInt | LInt | Real | LReal),
        DInt => matches!(to, LInt | LReal),
        USInt => matches!(to, UInt | UDInt | ULInt | Int | DInt | LInt | Real | LReal),
        UInt => matches!(to, UDInt | ULInt | DInt | LInt | Real | LReal),
        UDInt => matches!(to, ULInt | LInt | LReal),
        Real => matches!(to, LReal),
        Byte => matches!(to, Word | DWord | LWord),
        Word => matches!(to, DWord | LWord),
        DWord => matches!(to, LWord),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_and_stores_read_and_write_only_the_values_own_bytes() {
        let all = [
            Repr::Bool,
            Repr::I8,
            Repr::U8,
            Repr::I16,
            Repr::U16,
            Repr::I32,
            Repr::U32,
            Repr::F32,
            Repr::U64,
        ];
        let pattern = 0x8899_AABB_CCDD_EEFF_u64.to_le_bytes();
        for r in all {
            // With 8 bytes after it or only its own: the same value.
            let mut mem = [0u8; 24];
            mem[4..12].copy_from_slice(&pattern);
            let fast = r.load(&mem, 4);
            let width = match r {
                Repr::Bool | Repr::I8 | Repr::U8 => 1,
                Repr::I16 | Repr::U16 => 2,
                Repr::I32 | Repr::U32 | Repr::F32 => 4,
                Repr::U64 => 8,
            };
            let near = r.load(&mem[..4 + width], 4);
            assert_eq!(fast, near, "{r:?}");
            let want = match r {
                Repr::Bool => 1,
                Repr::I8 => 0xFF_u8 as i8 as i64 as u64,
                Repr::U8 => 0xFF,
                Repr::I16 => 0xEEFF_u16 as i16 as i64 as u64,
                Repr::U16 => 0xEEFF,
                Repr::I32 => 0xCCDD_EEFF_u32 as i32 as i64 as u64,
                Repr::U32 => 0xCCDD_EEFF,
                Repr::F32 => (f32::from_bits(0xCCDD_EEFF) as f64).to_bits(),
                Repr::U64 => 0x8899_AABB_CCDD_EEFF,
            };
            assert_eq!(fast, want, "{r:?}");
            // A store changes the value's bytes and no other.
            let v = match r {
                Repr::F32 => 1.0f64.to_bits(),
                _ => 0x0102_0304_0506_0708,
            };
            let mut a = mem;
            r.store(&mut a, 4, v);
            let mut b = mem;
            r.store(&mut b[..4 + width], 4, v);
            assert_eq!(a, b, "{r:?}");
            assert_eq!(a[..4], mem[..4], "{r:?}");
            assert_eq!(a[4 + width..], mem[4 + width..], "{r:?}");
            let back = match r {
                Repr::Bool => 0,
                Repr::I8 | Repr::U8 => 0x08,
                Repr::I16 | Repr::U16 => 0x0708,
                Repr::I32 | Repr::U32 => 0x0506_0708,
                Repr::F32 => 1.0f64.to_bits(),
                Repr::U64 => v,
            };
            assert_eq!(r.load(&a, 4), back, "{r:?}");
        }
    }

    #[test]
    fn the_f64_range_is_the_integer_range_rounded() {
        let kinds = [
            IntKind::U1,
            IntKind::I8,
            IntKind::I16,
            IntKind::I32,
            IntKind::I64,
            IntKind::U8,
            IntKind::U16,
            IntKind::U32,
            IntKind::U64,
        ];
        for k in kinds {
            let (lo, hi) = k.range();
            let (flo, fhi) = k.range_f64();
            assert_eq!(
                (flo.to_bits(), fhi.to_bits()),
                ((lo as f64).to_bits(), (hi as f64).to_bits()),
                "{k:?}"
            );
        }
    }
}
