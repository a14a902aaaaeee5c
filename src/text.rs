//! Text from files and arguments, made safe to show on a terminal.
//!
//! A name in a model file (a glTF camera, an OBJ material, a PLY comment),
//! a key in a scene or a path on the command line may hold control
//! characters: `ESC ] 0 ; … BEL` sets a terminal's title, `ESC [ 2 J`
//! clears it, a carriage return or a newline forges a line of output.
//! Every message that shows such text passes it through [`escape_controls`]
//! (or [`Shown`]), which writes each control character as Rust's `{:?}`
//! writes it (`\n`, `\r`, `\t`, `\u{1b}`) and leaves everything else as it is.

use std::borrow::Cow;
use std::fmt;

/// Whether `c` must not reach a terminal raw: the C0 controls, DEL, the C1
/// controls (U+0080–U+009F, among them CSI, which some terminals take as
/// `ESC [`), and the bidirectional overrides and isolates, which reorder
/// what a line appears to say.
pub fn is_unsafe_on_terminal(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// `text` with every character [`is_unsafe_on_terminal`] escaped as
/// `{:?}` escapes it; borrowed when there is none (the common case).
pub fn escape_controls(text: &str) -> Cow<'_, str> {
    if !text.chars().any(is_unsafe_on_terminal) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if is_unsafe_on_terminal(c) {
            // `escape_debug` is what `{:?}` uses: `\n`, `\r`, `\t`, `\0`
            // by name, the rest as `\u{…}`.
            out.extend(c.escape_debug());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// Shows a value's `Display` with [`escape_controls`] applied:
/// `format!("{}", Shown(path.display()))`.
pub struct Shown<T>(pub T);

impl<T: fmt::Display> fmt::Display for Shown<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = self.0.to_string();
        f.write_str(&escape_controls(&text))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_are_escaped_as_debug_escapes_them() {
        assert_eq!(escape_controls("plain name é ✓"), "plain name é ✓");
        assert!(matches!(escape_controls("plain"), Cow::Borrowed(_)));
        assert_eq!(escape_controls("a\nFAKE: error"), "a\\nFAKE: error");
        assert_eq!(
            escape_controls("\u{1b}]0;title\u{7}"),
            "\\u{1b}]0;title\\u{7}"
        );
        assert_eq!(escape_controls("\u{1b}[2J\r"), "\\u{1b}[2J\\r");
        assert_eq!(escape_controls("\u{9b}31m"), "\\u{9b}31m");
        assert_eq!(escape_controls("\u{202e}txt"), "\\u{202e}txt");
        assert_eq!(
            Shown(std::path::Path::new("a\tb").display()).to_string(),
            "a\\tb"
        );
    }

    #[test]
    fn no_control_character_survives_and_escaping_twice_changes_nothing() {
        let every: String = (0u32..0x2070).filter_map(char::from_u32).collect();
        let once = escape_controls(&every).into_owned();
        assert!(!once.chars().any(is_unsafe_on_terminal));
        assert_eq!(escape_controls(&once), once);
        // Each escaped character is what `{:?}` gives it.
        for c in every.chars().filter(|&c| is_unsafe_on_terminal(c)) {
            let debug = format!("{:?}", c.to_string());
            assert_eq!(
                escape_controls(&c.to_string()),
                debug[1..debug.len() - 1],
                "{c:?}"
            );
        }
    }
}
