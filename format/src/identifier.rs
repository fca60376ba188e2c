//! Names that become file names, HDF5 group names and lines of messages (a scene's `name`, a
//! VOI's `name`, a space of a basis file, a load case): one rule every one of them keeps, so that
//! no name can leave its directory or group, hide in a terminal, or break a one-line error in two.
//! A scene's load case names keep a stricter rule on top (plain ASCII identifiers, checked where
//! the scene is parsed: they also become array names in the XDMF and VTK files).

/// Longest identifier, bytes: a name becomes `<name>.h5` plus a temporary suffix, and file names
/// stop at 255 bytes.
pub const MAX_IDENTIFIER_BYTES: usize = 128;

/// Characters that are not control characters but still change how a line reads: bidirectional
/// overrides and isolates (text shown in another order than stored), invisible marks and
/// zero-width characters, and Unicode's line and paragraph separators.
fn is_hidden(c: char) -> bool {
    // Unicode's default-ignorable code points (shown as nothing), the bidirectional controls
    // among them, and the line and paragraph separators.
    matches!(
        c,
        '\u{00AD}'
            | '\u{034F}'
            | '\u{061C}'
            | '\u{115F}'..='\u{1160}'
            | '\u{17B4}'..='\u{17B5}'
            | '\u{180B}'..='\u{180F}'
            | '\u{200B}'..='\u{200F}'
            | '\u{2028}'..='\u{202E}'
            | '\u{2060}'..='\u{206F}'
            | '\u{3164}'
            | '\u{FE00}'..='\u{FE0F}'
            | '\u{FEFF}'
            | '\u{FFA0}'
            | '\u{FFF0}'..='\u{FFFB}'
            | '\u{1BCA0}'..='\u{1BCA3}'
            | '\u{1D173}'..='\u{1D17A}'
            | '\u{E0000}'..='\u{E0FFF}'
    )
}

/// What a name must be written with instead, said at the end of every refusal.
const ADVICE: &str = "use letters, digits, '-', '_' and '.', e.g. \"rib_1\"";

/// A name that is not an identifier: one line naming the key and saying what to change. The
/// name is quoted with its hidden characters escaped (see [`escape_for_terminal`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum IdentifierError {
    /// The name is empty.
    #[error("{what} is empty; {ADVICE}")]
    Empty {
        /// The key, e.g. `voi[2].name`.
        what: String,
    },
    /// The name is longer than [`MAX_IDENTIFIER_BYTES`].
    #[error("{what} = \"{head}…\" is {bytes} bytes long; at most {MAX_IDENTIFIER_BYTES}")]
    TooLong {
        /// The key.
        what: String,
        /// Its first 24 characters, escaped.
        head: String,
        /// Its length, bytes.
        bytes: usize,
    },
    /// The name holds a control, bidirectional or zero-width character.
    #[error(
        "{what} = \"{name}\" holds the invisible character U+{code:04X} (a control, bidirectional or zero-width \
         character); {ADVICE}"
    )]
    Hidden {
        /// The key.
        what: String,
        /// The name, escaped.
        name: String,
        /// The first such character's code point.
        code: u32,
    },
    /// The name begins or ends with a space.
    #[error("{what} = \"{name}\" begins or ends with a space (a file name no one can tell apart); {ADVICE}")]
    Space {
        /// The key.
        what: String,
        /// The name, escaped.
        name: String,
    },
    /// The name holds '/' or '\\'.
    #[error("{what} = \"{name}\" holds a path separator ('/' or '\\'); {ADVICE}")]
    Separator {
        /// The key.
        what: String,
        /// The name, escaped.
        name: String,
    },
    /// The name is "." or holds "..".
    #[error("{what} = \"{name}\" is \".\" or holds \"..\" (a path to another directory); {ADVICE}")]
    Dots {
        /// The key.
        what: String,
        /// The name, escaped.
        name: String,
    },
}

/// Checks that `name` is an identifier: not empty, at most [`MAX_IDENTIFIER_BYTES`] bytes, no
/// '/' or '\\', not "." and no "..", no space at either end, no control character
/// (U+0000–U+001F, U+007F–U+009F) and no default-ignorable (invisible), bidirectional or
/// line-separating character (U+00AD, U+061C, U+200B–U+200F, U+2028–U+202E, U+2060–U+206F,
/// U+FEFF, tags U+E0000–U+E0FFF and the others Unicode lists as default-ignorable). `what` names the key in the message (e.g.
/// `voi[2].name`); the message is one line and says what to change.
pub fn check_identifier(what: &str, name: &str) -> Result<(), IdentifierError> {
    let what = what.to_string();
    if name.is_empty() {
        return Err(IdentifierError::Empty { what });
    }
    if name.len() > MAX_IDENTIFIER_BYTES {
        let head: String = name.chars().take(24).collect();
        return Err(IdentifierError::TooLong {
            what,
            head: shown(&head),
            bytes: name.len(),
        });
    }
    let shown_name = || shown(name);
    if let Some(c) = name.chars().find(|&c| c.is_control() || is_hidden(c)) {
        Err(IdentifierError::Hidden {
            what,
            name: shown_name(),
            code: u32::from(c),
        })
    } else if name.starts_with(char::is_whitespace) || name.ends_with(char::is_whitespace) {
        Err(IdentifierError::Space {
            what,
            name: shown_name(),
        })
    } else if name.contains(['/', '\\']) {
        Err(IdentifierError::Separator {
            what,
            name: shown_name(),
        })
    } else if name == "." || name.contains("..") {
        Err(IdentifierError::Dots {
            what,
            name: shown_name(),
        })
    } else {
        Ok(())
    }
}

/// `name` with its control and hidden characters written as `\u{…}`, and its quotes and
/// backslashes escaped, so a message quoting it shows them and stays one line.
fn shown(name: &str) -> String {
    escape_for_terminal(&name.replace('\\', "\\\\").replace('"', "\\\""))
}

/// `text` from a file, safe to print to a terminal: control, bidirectional and other hidden
/// characters are written as `\u{…}` escapes, everything else as is.
pub fn escape_for_terminal(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c.is_control() || is_hidden(c) {
            out.push_str(&format!("\\u{{{:x}}}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::check_identifier;

    #[test]
    fn identifiers_keep_to_one_name_in_one_place() {
        for good in ["rib1", "rib_1", "Rippe-2", "v1.2", "ärmel", "梁"] {
            assert_eq!(check_identifier("voi[0].name", good), Ok(()), "{good}");
        }
        for bad in [
            "",
            "a/b",
            "a\\b",
            ".",
            "..",
            "a..b",
            "../x",
            "a\0b",
            "a\nb",
            "a\u{7f}",
            "a\u{85}",
            "a\u{202E}b",
            "a\u{2066}b",
            "a\u{200B}b",
            "a\u{2028}b",
            "\u{FEFF}a",
            "w\u{2060}j",
            "a\u{AD}b",
            "a\u{E0041}",
            "a\u{3164}",
            " ",
            " a",
            "a ",
        ] {
            let e = check_identifier("voi[0].name", bad).expect_err(bad).to_string();
            assert!(e.starts_with("voi[0].name") && !e.contains('\n'), "{e}");
        }
        let long = "x".repeat(10_000);
        let e = check_identifier("name", &long).expect_err("long").to_string();
        assert!(e.len() < 200, "the message repeats the whole name: {e}");
        let e = check_identifier("voi[1].name", "a\u{202E}b")
            .expect_err("bidi")
            .to_string();
        assert!(e.contains("U+202E") && !e.contains('\u{202E}'), "{e}");
    }

    /// The limit counts UTF-8 bytes (a file name's limit is in bytes), not characters: at 127
    /// and 128 bytes a name passes, at 129 it is refused, whether its last character is one
    /// byte or several; a count of characters would pass every multi-byte name below.
    #[test]
    fn the_length_limit_is_128_bytes_of_utf8() {
        use super::MAX_IDENTIFIER_BYTES;
        assert_eq!(MAX_IDENTIFIER_BYTES, 128);
        let x = |n: usize| "x".repeat(n);
        for (name, bytes, ok) in [
            (x(127), 127, true),
            (x(128), 128, true),
            (x(129), 129, false),
            // 'ä' is 2 bytes, '梁' 3, '🦀' 4: each ends exactly at the limit, or straddles it.
            (x(126) + "ä", 128, true),
            (x(127) + "ä", 129, false),
            (x(125) + "梁", 128, true),
            (x(126) + "梁", 129, false),
            (x(124) + "🦀", 128, true),
            (x(125) + "🦀", 129, false),
            // Only multi-byte characters: 43 of 3 bytes are 43 characters but 129 bytes.
            ("梁".repeat(42), 126, true),
            ("梁".repeat(43), 129, false),
            ("🦀".repeat(32), 128, true),
            ("🦀".repeat(32) + "x", 129, false),
        ] {
            assert_eq!(name.len(), bytes, "{name}");
            let got = check_identifier("voi[0].name", &name);
            if ok {
                assert_eq!(got, Ok(()), "{bytes} bytes, {} characters", name.chars().count());
            } else {
                let e = got.expect_err(&name).to_string();
                // One line naming the key, the length in bytes and the limit; the quoted head is
                // cut at a character boundary (no panic inside a multi-byte character).
                assert!(e.starts_with("voi[0].name = \"") && !e.contains('\n'), "{e}");
                assert!(e.contains(&format!("is {bytes} bytes long; at most 128")), "{e}");
                assert!(e.len() < 200, "{e}");
            }
        }
    }
}
