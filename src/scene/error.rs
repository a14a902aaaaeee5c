//! Scene errors located by file, line and column.

use std::fmt;
use std::ops::Range;
use std::path::PathBuf;

use thiserror::Error;

/// One problem in a scene file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// What is wrong and what was expected.
    pub message: String,
}

/// Why a scene could not be loaded.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{}: cannot read the scene: {source}", crate::text::Shown(path.display()))]
    Read {
        /// The scene path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file was read but is not a valid scene; every problem found.
    #[error("{}", DiagnosticList { origin, diagnostics })]
    Invalid {
        /// The file name as shown in messages.
        origin: String,
        /// All problems, in file order.
        diagnostics: Vec<Diagnostic>,
    },
}

struct DiagnosticList<'a> {
    origin: &'a str,
    diagnostics: &'a [Diagnostic],
}

impl fmt::Display for DiagnosticList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, d) in self.diagnostics.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(
                f,
                "{}:{}:{}: error: {}",
                crate::text::Shown(self.origin),
                d.line,
                d.column,
                crate::text::Shown(&d.message)
            )?;
        }
        Ok(())
    }
}

/// Collects problems with byte spans into the source; turns them into
/// located diagnostics at the end.
pub struct Diagnostics<'a> {
    source: &'a str,
    found: Vec<(Range<usize>, String)>,
    /// Added to every span recorded: the start of the piece of `source`
    /// being parsed on its own (one `[[objects]]` table).
    offset: usize,
}

impl<'a> Diagnostics<'a> {
    /// An empty collection for `source`.
    pub fn new(source: &'a str) -> Self {
        Diagnostics {
            source,
            found: Vec::new(),
            offset: 0,
        }
    }

    /// The whole text the spans point into.
    pub fn source(&self) -> &'a str {
        self.source
    }

    /// From now on, spans are relative to byte `offset` of the source.
    pub fn set_offset(&mut self, offset: usize) {
        self.offset = offset;
    }

    fn absolute(&self, span: Range<usize>) -> Range<usize> {
        span.start + self.offset..span.end + self.offset
    }

    /// Records a problem at `span`. Messages are cut to a readable length:
    /// a value of 200 MB in a file is not echoed whole.
    pub fn error(&mut self, span: Range<usize>, message: impl Into<String>) {
        const MAX_CHARS: usize = 400;
        let mut message = message.into();
        if let Some((end, _)) = message.char_indices().nth(MAX_CHARS) {
            message.truncate(end);
            message.push_str("… (cut)");
        }
        let span = self.absolute(span);
        self.found.push((span, message));
    }

    /// The source text at `span`, cut to `max` characters (for naming a key
    /// an error points at).
    pub fn text_at(&self, span: Range<usize>, max: usize) -> String {
        let text = self.source.get(self.absolute(span)).unwrap_or_default();
        match text.char_indices().nth(max) {
            None => text.to_string(),
            Some((end, _)) => format!("{}…", &text[..end]),
        }
    }

    /// Whether any problem was recorded.
    pub fn is_empty(&self) -> bool {
        self.found.is_empty()
    }

    /// How many problems were recorded.
    pub fn len(&self) -> usize {
        self.found.len()
    }

    /// The problems sorted by position, with line and column.
    pub fn into_diagnostics(mut self) -> Vec<Diagnostic> {
        self.found.sort_by_key(|(span, _)| span.start);
        self.found.dedup();
        self.found
            .into_iter()
            .map(|(span, message)| {
                let (line, column) = line_column(self.source, span.start);
                Diagnostic {
                    line,
                    column,
                    // Messages quote names and values from files and
                    // arguments: shown with their control characters
                    // escaped, so a name cannot drive the terminal or
                    // forge a line.
                    message: crate::text::escape_controls(&message).into_owned(),
                }
            })
            .collect()
    }
}

/// 1-based line and column (in characters) of byte `offset` in `source`.
pub fn line_column(source: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(source.len());
    let before = source.get(..offset).unwrap_or(source);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_and_column_are_one_based() {
        let s = "a = 1\nbé = 2\n";
        assert_eq!(line_column(s, 0), (1, 1));
        assert_eq!(line_column(s, 6), (2, 1));
        // 'é' is two bytes but one column.
        assert_eq!(line_column(s, 9), (2, 3));
    }
}
