"""Text from Blender names, files and Prism's output, made safe to show.

The same rule as the library's `prism::text::escape_controls`: every
control character (C0, DEL, C1) and bidirectional override is written as
Rust's `{:?}` writes it (``\\n``, ``\\r``, ``\\t``, ``\\0``, ``\\u{1b}``), so a
name cannot set the terminal's title, clear it or forge a report line.
"""

_NAMED = {"\t": "\\t", "\r": "\\r", "\n": "\\n", "\0": "\\0"}
_BIDI = {0x200E, 0x200F, *range(0x202A, 0x202F), *range(0x2066, 0x206A)}


def is_unsafe(c):
    o = ord(c)
    return o < 0x20 or 0x7F <= o <= 0x9F or o in _BIDI


def escape_controls(text):
    """`text` with each unsafe character escaped; the rest as it is."""
    if not any(is_unsafe(c) for c in text):
        return text
    return "".join(
        (_NAMED.get(c) or "\\u{%x}" % ord(c)) if is_unsafe(c) else c for c in text
    )


def report_lines(message):
    """One report line per entry of `message` (a list of lines, or one
    string taken as a single line), each escaped whole."""
    lines = [message] if isinstance(message, str) else list(message)
    return [escape_controls(line) for line in lines] or [""]
