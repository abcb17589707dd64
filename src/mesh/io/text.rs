//! Byte-level helpers shared by the text formats: a whitespace tokenizer that counts lines,
//! number parsing without allocation, and quoting of file content in messages.

use crate::mesh::MeshError;
use crate::mesh::format::Format;

/// Longest piece of file content quoted in an error message, in characters.
const MAX_QUOTE_CHARS: usize = 40;

/// Whitespace-separated tokens of a text, with the 1-based line of the last token.
#[derive(Clone)]
pub(crate) struct Tokens<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Tokens<'a> {
    /// Tokens of `bytes`, starting at line `first_line` (1-based).
    pub(crate) fn new(bytes: &'a [u8], first_line: usize) -> Self {
        Self {
            bytes,
            pos: 0,
            line: first_line,
        }
    }

    /// The next token, skipping whitespace and line breaks.
    pub(crate) fn next_token(&mut self) -> Option<&'a [u8]> {
        while let Some(&b) = self.bytes.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self
            .bytes
            .get(self.pos)
            .is_some_and(|b| !b.is_ascii_whitespace())
        {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.bytes[start..self.pos])
    }

    /// The rest of the current line (without the line break), consuming the break.
    pub(crate) fn rest_of_line(&mut self) -> &'a [u8] {
        let rest = &self.bytes[self.pos..];
        let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        self.pos += len;
        if self.pos < self.bytes.len() {
            self.pos += 1;
            self.line += 1;
        }
        trim_cr(&rest[..len])
    }

    /// Whether only whitespace is left.
    pub(crate) fn at_end(&self) -> bool {
        self.bytes[self.pos..].iter().all(u8::is_ascii_whitespace)
    }

    /// The 1-based line the tokenizer is on.
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// `"line N"`, for error locations.
    pub(crate) fn at(&self) -> String {
        format!("line {}", self.line)
    }
}

/// `line` without a trailing carriage return.
pub(crate) fn trim_cr(line: &[u8]) -> &[u8] {
    line.strip_suffix(b"\r").unwrap_or(line)
}

/// Whitespace-separated tokens of one line.
pub(crate) fn words(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(u8::is_ascii_whitespace)
        .filter(|w| !w.is_empty())
}

/// A decimal floating-point number (also `nan`, `inf`; finiteness is checked later).
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// A decimal integer with optional sign.
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Bytes shown when quoting binary data in a message.
const MAX_QUOTE_BYTES: usize = 4;

/// A token quoted for a message, shortened; binary data is described by its first bytes.
pub(crate) fn quote(token: &[u8]) -> String {
    let Ok(text) = std::str::from_utf8(token) else {
        return binary_quote(token);
    };
    if text.chars().any(|c| c.is_control() && !c.is_whitespace()) {
        return binary_quote(token);
    }
    let mut short: String = text.chars().take(MAX_QUOTE_CHARS).collect();
    if text.chars().count() > MAX_QUOTE_CHARS {
        short.push('…');
    }
    format!("'{}'", short.escape_debug())
}

fn binary_quote(token: &[u8]) -> String {
    let bytes: Vec<String> = token
        .iter()
        .take(MAX_QUOTE_BYTES)
        .map(|b| format!("{b:02x}"))
        .collect();
    format!("binary data (bytes {} ...)", bytes.join(" "))
}

/// Rejects binary content in a text format: control bytes other than whitespace.
pub(crate) fn reject_binary(bytes: &[u8], format: Format) -> Result<(), MeshError> {
    let bad = bytes
        .iter()
        .position(|&b| (b < 0x20 && !b.is_ascii_whitespace() && b != 0x0b) || b == 0x7f);
    match bad {
        None => Ok(()),
        Some(offset) => {
            let line = 1 + bytes[..offset].iter().filter(|&&b| b == b'\n').count();
            Err(MeshError::parse(
                format,
                format!("line {line}"),
                format!(
                    "byte {offset} is the control byte 0x{:02x}, so this is binary data, not \
                     {format} text; check that the file really is {format} and that the \
                     chosen format matches the file",
                    bytes[offset]
                ),
            ))
        }
    }
}

/// English ordinal of a 0-based position: 0 → "1st", 11 → "12th", 21 → "22nd".
pub(crate) fn ordinal(index0: usize) -> String {
    let n = index0 + 1;
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_count_lines() {
        let mut t = Tokens::new(b"a b\r\n\n  c\nd", 1);
        assert_eq!(t.next_token(), Some(&b"a"[..]));
        assert_eq!(t.line(), 1);
        assert_eq!(t.next_token(), Some(&b"b"[..]));
        assert_eq!(t.next_token(), Some(&b"c"[..]));
        assert_eq!(t.line(), 3);
        assert_eq!(t.rest_of_line(), b"");
        assert_eq!(t.next_token(), Some(&b"d"[..]));
        assert_eq!(t.line(), 4);
        assert_eq!(t.next_token(), None);
    }

    #[test]
    fn numbers_and_quotes() {
        assert_eq!(parse_f64(b"-1.5e2"), Some(-150.0));
        assert!(parse_f64(b"nan").unwrap().is_nan());
        assert_eq!(parse_f64(b"1,5"), None);
        assert_eq!(parse_i64(b"-3"), Some(-3));
        assert_eq!(parse_i64(b"3.0"), None);
        assert_eq!(quote(b"abc"), "'abc'");
        assert_eq!(quote(&[b'x'; 50]).chars().count(), 43);
        assert_eq!(
            quote(&[0xff, 0x00, 0x41, 0x42, 0x43]),
            "binary data (bytes ff 00 41 42 ...)"
        );
        assert_eq!(quote(b"a\x01"), "binary data (bytes 61 01 ...)");
    }

    #[test]
    fn ordinals() {
        let got: Vec<String> = [0, 1, 2, 3, 10, 11, 12, 20, 21, 101].map(ordinal).to_vec();
        assert_eq!(
            got,
            [
                "1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "102nd"
            ]
        );
    }

    #[test]
    fn binary_is_rejected_with_line() {
        assert!(reject_binary(b"v 1 2 3\n\tf 1 2 3\r\n", Format::Obj).is_ok());
        let e = reject_binary(b"v 1 2 3\nv \x00", Format::Obj).unwrap_err();
        assert_eq!(e.code(), "mesh.parse_error");
        assert!(e.to_string().contains("line 2"), "{e}");
        assert!(e.to_string().contains("0x00"), "{e}");
    }
}
