//! Text rules shared by every input format (scene, OBJ): where lines end, how a
//! position is counted, and how a token is quoted in a message.
//!
//! - A line ends at LF, CRLF or a lone CR (old Mac files), in every format.
//! - Positions are 1-based; a column counts characters (a tab is one).
//! - A token quoted in a message is [`escaped`]: control characters, escape sequences
//!   and invisible characters (a byte-order mark, U+200B, bidirectional overrides) are
//!   shown as `\u{..}`, so a message can neither rewrite the terminal nor hide why a
//!   token was refused; a long token is cut.

use std::fmt;
use std::io::{self, BufRead};

/// Line and column of the next character, under the line-end rule of this module.
/// Feed it every character in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Position {
    /// 1-based.
    pub line: usize,
    /// 1-based, in characters.
    pub col: usize,
    /// The last character was a CR: an LF now completes a CRLF, not a second line.
    after_cr: bool,
}

impl Default for Position {
    fn default() -> Self {
        Position {
            line: 1,
            col: 1,
            after_cr: false,
        }
    }
}

impl Position {
    /// Moves past `c`.
    pub fn advance(&mut self, c: char) {
        match c {
            '\n' if self.after_cr => {}
            '\n' | '\r' => {
                self.line += 1;
                self.col = 1;
            }
            _ => self.col += 1,
        }
        self.after_cr = c == '\r';
    }

    /// Whether `c` ends a line (LF or CR; an LF after a CR belongs to the same end).
    pub fn is_line_end(c: char) -> bool {
        c == '\n' || c == '\r'
    }
}

/// The lines of `text` without their ends (LF, CRLF or a lone CR); like
/// [`str::lines`], a final line end does not start an empty line.
pub fn lines(text: &str) -> Lines<'_> {
    Lines { rest: text }
}

/// Iterator of [`lines`].
#[derive(Clone, Debug)]
pub struct Lines<'a> {
    rest: &'a str,
}

impl<'a> Iterator for Lines<'a> {
    type Item = &'a str;

    fn next(&mut self) -> Option<&'a str> {
        if self.rest.is_empty() {
            return None;
        }
        let Some(end) = self.rest.find(['\n', '\r']) else {
            return Some(std::mem::take(&mut self.rest));
        };
        let line = &self.rest[..end];
        let skip = if self.rest[end..].starts_with("\r\n") {
            2
        } else {
            1
        };
        self.rest = &self.rest[end + skip..];
        Some(line)
    }
}

/// Reads lines from a stream under the same rule as [`lines`], one at a time, so a
/// file is never held whole.
pub struct LineReader<R> {
    inner: R,
    /// A CR ended the last line: an LF opening the next read belongs to it.
    after_cr: bool,
}

impl<R: BufRead> LineReader<R> {
    pub fn new(inner: R) -> Self {
        LineReader {
            inner,
            after_cr: false,
        }
    }

    /// Replaces `line` with the next line's bytes, without its end; `false` at the end
    /// of the stream. A line longer than `max` bytes is an error (`InvalidData`): the
    /// reader's memory stays bounded by `max`.
    pub fn read_line(&mut self, line: &mut Vec<u8>, max: usize) -> io::Result<bool> {
        line.clear();
        let mut any = false;
        loop {
            let buf = match self.inner.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if buf.is_empty() {
                return Ok(any);
            }
            let mut start = 0;
            if std::mem::take(&mut self.after_cr) && buf[0] == b'\n' {
                start = 1;
            }
            match buf[start..].iter().position(|&b| b == b'\n' || b == b'\r') {
                Some(i) => {
                    self.after_cr = buf[start + i] == b'\r';
                    line.extend_from_slice(&buf[start..start + i]);
                    self.inner.consume(start + i + 1);
                    return if line.len() > max {
                        Err(too_long(max))
                    } else {
                        Ok(true)
                    };
                }
                None => {
                    let n = buf.len();
                    line.extend_from_slice(&buf[start..]);
                    self.inner.consume(n);
                    any = true;
                    if line.len() > max {
                        return Err(too_long(max));
                    }
                }
            }
        }
    }
}

fn too_long(max: usize) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("a line longer than {max} bytes"),
    )
}

/// Characters of a token shown in a message before it is cut.
pub const SHOWN_CHARS: usize = 100;

/// `s` as a message quotes it: control characters, invisible and format characters
/// (U+FEFF, U+200B, bidirectional overrides, combining marks: whatever `escape_debug`
/// escapes) as `\u{..}`, `\t`, `\r`, `\n`, a backslash as `\\` (so an escape cannot
/// be mistaken for the file's text), quotes and everything else as they are; past
/// [`SHOWN_CHARS`] characters cut, with the token's length in bytes. Write it inside
/// quotes: `format!("found '{}'", escaped(token))`.
pub fn escaped(s: &str) -> Escaped<'_> {
    Escaped(s)
}

/// Display of [`escaped`].
#[derive(Clone, Copy, Debug)]
pub struct Escaped<'a>(&'a str);

impl fmt::Display for Escaped<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let cut = s.char_indices().nth(SHOWN_CHARS).map(|(i, _)| i);
        for c in s[..cut.unwrap_or(s.len())].chars() {
            match c {
                '"' | '\'' => write!(f, "{c}")?,
                c => write!(f, "{}", c.escape_debug())?,
            }
        }
        match cut {
            Some(_) => write!(f, "…({} bytes)", s.len()),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Line of every character of `text` by [`Position`].
    fn numbered(text: &str) -> Vec<(usize, String)> {
        let mut p = Position::default();
        let mut out: Vec<(usize, String)> = Vec::new();
        for c in text.chars() {
            if !Position::is_line_end(c) {
                match out.last_mut() {
                    Some((l, s)) if *l == p.line => s.push(c),
                    _ => out.push((p.line, c.to_string())),
                }
            }
            p.advance(c);
        }
        out
    }

    #[test]
    fn lf_crlf_and_lone_cr_each_end_one_line() {
        let text = "a\nb\r\nc\rd\r\r\ne\n\nf";
        let got: Vec<&str> = lines(text).collect();
        assert_eq!(got, ["a", "b", "c", "d", "", "e", "", "f"]);
        // the position counter agrees with the iterator on every non-empty line
        let counted = numbered(text);
        let expected: Vec<(usize, String)> = got
            .iter()
            .enumerate()
            .filter(|(_, l)| !l.is_empty())
            .map(|(i, l)| (i + 1, l.to_string()))
            .collect();
        assert_eq!(counted, expected);
        assert_eq!(lines("x\r\n").collect::<Vec<_>>(), ["x"]);
        assert_eq!(lines("").count(), 0);
    }

    #[test]
    fn columns_count_characters() {
        let mut p = Position::default();
        "é\tx".chars().for_each(|c| p.advance(c));
        assert_eq!((p.line, p.col), (1, 4));
        "\r\n".chars().for_each(|c| p.advance(c));
        assert_eq!((p.line, p.col), (2, 1));
    }

    #[test]
    fn the_reader_splits_as_the_iterator_does_at_any_buffer_size() {
        let text = "v 1\r\nv 2\rv 3\n\r\nf 1 2 3\r";
        let expected: Vec<&str> = lines(text).collect();
        for cap in 1..8 {
            let mut r = LineReader::new(io::BufReader::with_capacity(cap, text.as_bytes()));
            let mut line = Vec::new();
            let mut got = Vec::new();
            while r.read_line(&mut line, 100).unwrap() {
                got.push(String::from_utf8(line.clone()).unwrap());
            }
            assert_eq!(got, expected, "buffer of {cap}");
        }
        let mut r = LineReader::new("short\nmuch too long\n".as_bytes());
        let mut line = Vec::new();
        assert!(r.read_line(&mut line, 5).unwrap());
        assert_eq!(
            r.read_line(&mut line, 5).unwrap_err().kind(),
            io::ErrorKind::InvalidData
        );
    }

    #[test]
    fn escaping_shows_what_a_terminal_would_hide_or_obey() {
        let e = |s: &str| escaped(s).to_string();
        assert_eq!(e("0.3\u{200b}"), "0.3\\u{200b}");
        assert_eq!(e("\u{feff}0.3"), "\\u{feff}0.3");
        assert_eq!(e("a\u{1b}[2Jb"), "a\\u{1b}[2Jb");
        assert_eq!(e("x\ty\r"), "x\\ty\\r");
        assert_eq!(e("\u{202e}cba"), "\\u{202e}cba");
        assert_eq!(e("sphère"), "sphère");
        assert_eq!(e("a'b\"c\\"), "a'b\"c\\\\");
        let long = "7".repeat(5000);
        let shown = e(&long);
        assert!(shown.starts_with(&"7".repeat(SHOWN_CHARS)), "{shown}");
        assert!(shown.ends_with("…(5000 bytes)"), "{shown}");
        assert_eq!(e(&"7".repeat(SHOWN_CHARS)), "7".repeat(SHOWN_CHARS));
    }
}
