//! STRING's character set and the encodings a source file may be written in.
//!
//! A STRING holds one byte per character in Windows-1252 (ISO 8859-1 with printable
//! characters such as `€` in 0x80–0x9F), as CODESYS and TwinCAT keep it on a Western
//! Windows: `LEN('Grüße')` is 5 whatever encoding the source file is written in. The
//! five bytes Windows-1252 leaves undefined (0x81, 0x8D, 0x8F, 0x90, 0x9D) stand for the
//! control characters of the same number, so every byte is a character and back.

use std::borrow::Cow;

/// Characters of 0x80–0x9F (Windows-1252; the five undefined bytes map to themselves).
const HIGH_CONTROLS: [u16; 32] = [
    0x20AC, 0x0081, 0x201A, 0x0192, 0x201E, 0x2026, 0x2020, 0x2021, 0x02C6, 0x2030, 0x0160, 0x2039,
    0x0152, 0x008D, 0x017D, 0x008F, 0x0090, 0x2018, 0x2019, 0x201C, 0x201D, 0x2022, 0x2013, 0x2014,
    0x02DC, 0x2122, 0x0161, 0x203A, 0x0153, 0x009D, 0x017E, 0x0178,
];

/// The character a STRING byte stands for.
pub(crate) fn decode(b: u8) -> char {
    match b {
        0x80..=0x9f => char::from_u32(HIGH_CONTROLS[(b - 0x80) as usize] as u32).unwrap_or('?'),
        _ => b as char,
    }
}

/// The STRING byte of `ch`, if Windows-1252 has it.
pub(crate) fn encode(ch: char) -> Option<u8> {
    let c = ch as u32;
    match c {
        0..=0x7f | 0xa0..=0xff => Some(c as u8),
        _ => HIGH_CONTROLS
            .iter()
            .position(|&u| u as u32 == c)
            .map(|i| 0x80 + i as u8),
    }
}

/// How the bytes of a source file are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SourceEncoding {
    /// UTF-8 when the file is valid UTF-8 (a leading byte-order mark is dropped), else
    /// Windows-1252, which is what CODESYS 2.3 and TwinCAT 2 write.
    #[default]
    Auto,
    /// UTF-8 only: a file that is not valid UTF-8 is refused.
    Utf8,
    /// Windows-1252 (ISO 8859-1 and more) whatever the bytes look like.
    Windows1252,
}

/// Source text from a file's bytes, or `None` when `encoding` is
/// [`SourceEncoding::Utf8`] and the bytes are not UTF-8.
pub(crate) fn decode_source(bytes: &[u8], encoding: SourceEncoding) -> Option<Cow<'_, str>> {
    let utf8 = || {
        std::str::from_utf8(bytes)
            .ok()
            .map(|t| Cow::Borrowed(t.strip_prefix('\u{feff}').unwrap_or(t)))
    };
    let windows_1252 = || Cow::Owned(bytes.iter().map(|&b| decode(b)).collect());
    match encoding {
        SourceEncoding::Auto => Some(utf8().unwrap_or_else(windows_1252)),
        SourceEncoding::Utf8 => utf8(),
        SourceEncoding::Windows1252 => Some(windows_1252()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_decodes_to_a_character_that_encodes_back_to_it() {
        for b in 0..=255u8 {
            assert_eq!(encode(decode(b)), Some(b), "byte {b:#x}");
        }
    }

    #[test]
    fn windows_1252_places_the_euro_and_typographic_quotes_in_0x80_to_0x9f() {
        // Microsoft's table for code page 1252.
        assert_eq!(encode('€'), Some(0x80));
        assert_eq!(encode('„'), Some(0x84));
        assert_eq!(encode('Ÿ'), Some(0x9f));
        assert_eq!(encode('ä'), Some(0xe4));
        assert_eq!(encode('Ω'), None);
    }

    #[test]
    fn auto_reads_utf8_when_it_is_valid_and_windows_1252_otherwise() {
        let utf8 = "\u{feff}x := 'ä';".as_bytes();
        assert_eq!(
            decode_source(utf8, SourceEncoding::Auto).as_deref(),
            Some("x := 'ä';")
        );
        let latin = b"x := '\xe4\x80';";
        assert_eq!(
            decode_source(latin, SourceEncoding::Auto).as_deref(),
            Some("x := 'ä€';")
        );
        assert_eq!(decode_source(latin, SourceEncoding::Utf8), None);
        // Forced: the two UTF-8 bytes of ä are two characters.
        assert_eq!(
            decode_source("ä".as_bytes(), SourceEncoding::Windows1252).as_deref(),
            Some("Ã¤")
        );
    }
}
