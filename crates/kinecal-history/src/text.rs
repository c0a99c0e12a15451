//! Text from the database, made safe to print on a terminal, and lists of names in messages.

use std::borrow::Cow;
use std::fmt::Write as _;

/// `s` with control characters (and the invisible bidirectional-text controls) escaped:
/// `\n`, `\r`, `\t`, `\x1b`, `\u{202e}`; backslashes are left alone. A serial or a note cannot
/// colour the terminal, move the cursor, or fake an extra line of output.
pub fn printable(s: &str) -> Cow<'_, str> {
    let unsafe_char = |c: char| {
        c.is_control()
            || matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
    };
    if !s.chars().any(unsafe_char) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if unsafe_char(c) && (c as u32) < 0x100 => {
                let _ = write!(out, "\\x{:02x}", c as u32);
            }
            c if unsafe_char(c) => {
                let _ = write!(out, "\\u{{{:x}}}", c as u32);
            }
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

/// Names (of tables, parameters) for a message: quoted, made printable, at most six and a
/// count of the others.
pub(crate) fn names<'a>(v: impl IntoIterator<Item = &'a String>) -> String {
    let v: Vec<String> = v
        .into_iter()
        .map(|s| format!("`{}`", printable(s)))
        .collect();
    if v.len() > 6 {
        format!("{} and {} more", v[..6].join(", "), v.len() - 6)
    } else {
        v.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::printable;

    #[test]
    fn control_characters_are_escaped() {
        assert_eq!(printable("A4-0042"), "A4-0042");
        assert_eq!(printable("é\\n"), "é\\n");
        assert_eq!(
            printable("a\u{1b}[31mb\nc\td\re\u{7f}\u{202e}"),
            "a\\x1b[31mb\\nc\\td\\re\\x7f\\u{202e}"
        );
    }
}
