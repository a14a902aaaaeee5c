//! Finds the `[[objects]]` tables of scene text by its tokens, without
//! building a syntax tree, so that each object can be parsed and built on
//! its own: a file of a million objects is never a million syntax trees at
//! once (a tree takes about ten times the bytes of its text).
//!
//! A table header is a `[` at the start of a line outside any array or
//! inline table; the TOML lexer takes care of strings and comments. An
//! object's text runs from its `[[objects]]` header to the next header
//! that is not below `objects` (so `[[objects.transform]]` sub-tables stay
//! with their object). Nothing here judges validity: every piece is parsed
//! by the TOML parser afterwards, with its own errors.

use std::ops::Range;

use toml_parser::Source;
use toml_parser::lexer::{Token, TokenKind};

/// Scene text cut into `[[objects]]` tables and the rest.
#[derive(Debug, PartialEq)]
pub struct Tables {
    /// Byte range of each `[[objects]]` table, header included, in order.
    pub objects: Vec<Range<usize>>,
}

impl Tables {
    /// Cuts `source`.
    pub fn find(source: &str) -> Tables {
        let text = Source::new(source);
        let mut tokens = text.lex().peekable();
        let mut objects: Vec<Range<usize>> = Vec::new();
        // Open `[` and `{` of values (not of headers).
        let mut depth = 0usize;
        let mut line_start = true;
        // Whether the table being read is an `[[objects]]` one.
        let mut in_object = false;
        while let Some(token) = tokens.next() {
            match token.kind() {
                TokenKind::Eof => break,
                TokenKind::Newline => {
                    line_start = true;
                    continue;
                }
                TokenKind::Whitespace => continue,
                TokenKind::LeftSquareBracket if depth == 0 && line_start => {
                    let start = token.span().start();
                    let header = header(&text, &token, &mut tokens);
                    let object_part = header.path.first().is_some_and(|k| k == "objects");
                    if in_object {
                        if object_part && !(header.array && header.path.len() == 1) {
                            // A sub-table of the current object.
                            line_start = false;
                            continue;
                        }
                        if let Some(last) = objects.last_mut() {
                            last.end = start;
                        }
                    }
                    in_object = header.array && header.path == ["objects"];
                    if in_object {
                        objects.push(start..source.len());
                    }
                }
                TokenKind::LeftSquareBracket | TokenKind::LeftCurlyBracket => depth += 1,
                TokenKind::RightSquareBracket | TokenKind::RightCurlyBracket => {
                    depth = depth.saturating_sub(1)
                }
                _ => {}
            }
            line_start = false;
        }
        Tables { objects }
    }

    /// `source` with each object table turned into one long comment (every
    /// byte offset stays where it was, and a blank table costs the parser
    /// one token), cut after the last text that is not an object's; `None`
    /// when there are no object tables.
    pub fn rest(&self, source: &str) -> Option<String> {
        if self.objects.is_empty() {
            return None;
        }
        // Object tables that run without a break to the end of the text
        // are cut off rather than blanked.
        let mut end = source.len();
        for range in self.objects.iter().rev() {
            if range.end != end {
                break;
            }
            end = range.start;
        }
        let mut rest = source.as_bytes()[..end].to_vec();
        for range in &self.objects {
            if range.start >= end {
                break;
            }
            // A table starts a line and ends before the next header (it is
            // at least `[[objects]]` long): `#`, spaces, a newline.
            let blank = &mut rest[range.clone()];
            blank.fill(b' ');
            blank[0] = b'#';
            if let Some(last) = blank.last_mut() {
                *last = b'\n';
            }
        }
        // Whole characters were replaced, byte by byte, with ASCII.
        Some(String::from_utf8(rest).unwrap_or_default())
    }

    /// How many bytes of `source` lie outside the object tables.
    pub fn rest_len(&self, source_len: usize) -> usize {
        source_len - self.objects.iter().map(|r| r.len()).sum::<usize>()
    }
}

/// A table header: its dotted key and whether it is `[[...]]`.
struct Header {
    path: Vec<String>,
    array: bool,
}

/// Reads the header that `open` (a `[` at the start of a line) begins, up to
/// its closing bracket or the end of the line.
fn header<'i>(
    text: &Source<'i>,
    open: &Token,
    tokens: &mut std::iter::Peekable<toml_parser::lexer::Lexer<'i>>,
) -> Header {
    let mut array = false;
    if let Some(next) = tokens.peek()
        && next.kind() == TokenKind::LeftSquareBracket
        && next.span().start() == open.span().end()
    {
        array = true;
        tokens.next();
    }
    let mut path = Vec::new();
    while let Some(token) = tokens.peek() {
        match token.kind() {
            TokenKind::Newline | TokenKind::Eof => break,
            TokenKind::RightSquareBracket => {
                tokens.next();
                break;
            }
            TokenKind::Atom
            | TokenKind::BasicString
            | TokenKind::LiteralString
            | TokenKind::MlBasicString
            | TokenKind::MlLiteralString => {
                let mut key = String::new();
                if let Some(raw) = text.get(*token) {
                    raw.decode_key(&mut key, &mut ());
                }
                path.push(key);
                tokens.next();
            }
            _ => {
                tokens.next();
            }
        }
    }
    // The second `]` of `]]`, if any.
    if array
        && tokens
            .peek()
            .is_some_and(|t| t.kind() == TokenKind::RightSquareBracket)
    {
        tokens.next();
    }
    Header { path, array }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texts(source: &str) -> Vec<&str> {
        Tables::find(source)
            .objects
            .into_iter()
            .map(|r| &source[r])
            .collect()
    }

    #[test]
    fn each_object_table_runs_to_the_next_other_header() {
        let s = "[camera]\nx = 1\n[[objects]]\na = 1\n[[ objects ]] # c\nb = [\n[1],\n]\n\
                 [[objects.transform]]\nt = 1\n[materials.m]\nk = 2\n[[\"objects\"]]\nc = 3\n";
        assert_eq!(
            texts(s),
            [
                "[[objects]]\na = 1\n",
                "[[ objects ]] # c\nb = [\n[1],\n]\n[[objects.transform]]\nt = 1\n",
                "[[\"objects\"]]\nc = 3\n",
            ]
        );
    }

    #[test]
    fn brackets_in_strings_comments_and_values_are_not_headers() {
        let s = "[[objects]]\nname = \"\"\"\n[[objects]]\n\"\"\"\n# [[objects]]\nv = [\n  [0, 0, 0],\n]\n";
        assert_eq!(texts(s), [s]);
        // Only `[[objects]]` starts an object: `[objects]` and
        // `[[objects.x]]` before any object do not.
        assert!(texts("[objects]\n[[objects.x]]\n[[objectsx]]\n").is_empty());
    }

    #[test]
    fn the_rest_keeps_every_offset() {
        let s = "[render]\nw = 1\n[[objects]]\né = 1\n  [camera]\nx = 2\n[[objects]]\ny = 3\n";
        let t = Tables::find(s);
        let rest = t.rest(s).unwrap();
        // Cut after the camera; the first object's text is one comment.
        assert_eq!(rest.len(), s.find("[[objects]]\ny").unwrap());
        let camera = s.find("[camera]").unwrap();
        assert_eq!(&rest[camera..], "[camera]\nx = 2\n");
        let object = s.find("[[objects]]").unwrap();
        assert_eq!(&rest[..object], &s[..object]);
        assert!(rest[object..camera].starts_with("# "));
        assert!(rest[object..camera].ends_with(" \n"));
        let first = "[[objects]]\né = 1\n  ".len();
        assert_eq!(
            t.rest_len(s.len()),
            s.len() - first - "[[objects]]\ny = 3\n".len()
        );
        assert_eq!(Tables::find("[camera]\n").rest("[camera]\n"), None);
        // What the rest holds parses as the same tables.
        let doc: toml::Table = toml::from_str(&rest).unwrap();
        assert_eq!(doc["camera"]["x"].as_integer(), Some(2));
    }
}
