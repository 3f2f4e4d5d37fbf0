//! What Delta Tau's downloader does to a file before the controller sees
//! it: `#define NAME text` substitution, `#undefine`, `#include "file"`,
//! and comments.
//!
//! Rules (those of the PMAC Executive / Pewin downloader as far as public
//! sources show them; points marked (unconfirmed) follow the C
//! preprocessor, whose syntax the downloader borrows):
//!
//! - A directive is a line whose first non-blank character is `#` followed
//!   by `define`, `undefine`/`undef` or `include` (any case). `#1->X` and
//!   `#2J+` are motor commands, not directives.
//! - `#define NAME text`: NAME is a word of letters, digits and `_`, not
//!   starting with a digit; the text runs to the end of the line less its
//!   `;` or `//` comment, trimmed. A later `#define` of the same name
//!   replaces it. Names are case-sensitive (unconfirmed; Diamond Light
//!   Source's downloader, dls-pmaclib, compares them exactly too).
//! - Substitution is by whole word (a name inside a longer word, after a
//!   `$` hex sign or inside a number such as `1000X` is left alone), outside
//!   `"strings"` and comments; the substituted text is scanned again, so
//!   defines may use other defines, whichever order they were written in;
//!   a name is not substituted inside its own expansion (as in C), and
//!   nesting deeper than [`MAX_EXPANSION_DEPTH`] is an error.
//! - `//` starts a comment as `;` does (Power PMAC files use it; in Turbo
//!   PMAC text `//` cannot occur otherwise).
//! - `#include "file"` (or `<file>` or a bare name) reads the file, named
//!   relative to the including file, in place; defines made there stay.
//!   Nesting is limited to [`MAX_INCLUDE_DEPTH`]; a missing file or a file
//!   that includes itself (directly or not) is an error naming the line.

use std::borrow::Cow;
use std::collections::HashMap;

/// Deepest chain of `#include`s.
pub(super) const MAX_INCLUDE_DEPTH: usize = 16;
/// Deepest chain of defines used inside defines.
pub(super) const MAX_EXPANSION_DEPTH: usize = 32;

/// A malformed preprocessor directive, or a line whose `#define` names
/// could not be substituted.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub(super) enum DefineError {
    #[error("#include needs a file name, e.g. #include \"defs.pmc\"")]
    IncludeNoName,
    #[error("#{0} needs a name (letters, digits and '_', not starting with a digit)")]
    NoName(String),
    #[error("#define {0}: the name ends at a character that cannot be in a name")]
    BadName(String),
    #[error("#define {0} nests defines deeper than {MAX_EXPANSION_DEPTH} levels")]
    TooDeep(String),
}

/// A preprocessor directive line.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Directive<'a> {
    Define { name: &'a str, text: &'a str },
    Undefine(&'a str),
    Include(&'a str),
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// The line less its `;` or `//` comment (outside `"strings"`).
pub(super) fn strip_comment(text: &str) -> &str {
    let b = text.as_bytes();
    let mut quoted = false;
    for (i, &c) in b.iter().enumerate() {
        match c {
            b'"' => quoted = !quoted,
            b';' if !quoted => return &text[..i],
            b'/' if !quoted && b.get(i + 1) == Some(&b'/') => return &text[..i],
            _ => {}
        }
    }
    text
}

/// The directive on this line, if it is one; `Err` for a malformed one.
pub(super) fn directive(text: &str) -> Option<Result<Directive<'_>, DefineError>> {
    let t = text.trim_start();
    let rest = t.strip_prefix('#')?.trim_start();
    let end = rest
        .bytes()
        .position(|c| !c.is_ascii_alphabetic())
        .unwrap_or(rest.len());
    let word = &rest[..end];
    let is = |w: &str| word.eq_ignore_ascii_case(w);
    if !(is("define") || is("undefine") || is("undef") || is("include")) {
        return None;
    }
    let arg = strip_comment(&rest[end..]);
    if !arg.is_empty() && !arg.starts_with([' ', '\t']) {
        return None;
    }
    let arg = arg.trim();
    Some(if is("include") {
        let name = arg
            .strip_prefix('"')
            .and_then(|a| a.strip_suffix('"'))
            .or_else(|| arg.strip_prefix('<').and_then(|a| a.strip_suffix('>')))
            .unwrap_or(arg)
            .trim();
        if name.is_empty() {
            Err(DefineError::IncludeNoName)
        } else {
            Ok(Directive::Include(name))
        }
    } else {
        let n = arg.bytes().position(|c| !is_ident(c)).unwrap_or(arg.len());
        let name = &arg[..n];
        if name.is_empty() || name.as_bytes()[0].is_ascii_digit() {
            Err(DefineError::NoName(word.to_string()))
        } else if is("define") {
            let after = &arg[n..];
            if !after.is_empty() && !after.starts_with([' ', '\t']) {
                Err(DefineError::BadName(arg.to_string()))
            } else {
                Ok(Directive::Define {
                    name,
                    text: after.trim(),
                })
            }
        } else {
            Ok(Directive::Undefine(name))
        }
    })
}

/// The defines made so far.
#[derive(Default)]
pub(super) struct Defines {
    map: HashMap<String, String>,
}

impl Defines {
    pub(super) fn define(&mut self, name: &str, text: &str) {
        self.map.insert(name.to_string(), text.to_string());
    }

    pub(super) fn undefine(&mut self, name: &str) {
        self.map.remove(name);
    }

    /// The line with every defined name substituted and any `//` comment
    /// cut (the `;` comment is kept for the reader, which skips it).
    pub(super) fn expand<'a>(&self, text: &'a str) -> Result<Cow<'a, str>, DefineError> {
        let has_slashes = text.contains("//");
        if self.map.is_empty() && !has_slashes {
            return Ok(Cow::Borrowed(text));
        }
        let text = if has_slashes { strip_comment(text) } else { text };
        if self.map.is_empty() {
            return Ok(Cow::Borrowed(text));
        }
        let mut out = String::with_capacity(text.len() + 16);
        let mut active = Vec::new();
        self.expand_into(text, &mut active, &mut out)?;
        Ok(Cow::Owned(out))
    }

    fn expand_into<'s>(&'s self, text: &str, active: &mut Vec<&'s str>, out: &mut String) -> Result<(), DefineError> {
        let b = text.as_bytes();
        let mut i = 0;
        let mut quoted = false;
        while i < b.len() {
            let c = b[i];
            if quoted {
                let j = b[i..].iter().position(|&c| c == b'"').map_or(b.len(), |k| i + k + 1);
                out.push_str(&text[i..j]);
                quoted = false;
                i = j;
                continue;
            }
            if c == b'"' {
                quoted = true;
                out.push('"');
                i += 1;
                continue;
            }
            if c == b';' {
                out.push_str(&text[i..]);
                return Ok(());
            }
            if !is_ident(c) {
                // One character (a whole UTF-8 sequence when not ASCII).
                let n = text[i..].chars().next().map_or(1, char::len_utf8);
                out.push_str(&text[i..i + n]);
                i += n;
                continue;
            }
            let j = b[i..].iter().position(|&c| !is_ident(c)).map_or(b.len(), |k| i + k);
            let word = &text[i..j];
            let after_dollar = i > 0 && b[i - 1] == b'$';
            match self.map.get_key_value(word) {
                Some((name, value)) if !c.is_ascii_digit() && !after_dollar && !active.contains(&name.as_str()) => {
                    if active.len() >= MAX_EXPANSION_DEPTH {
                        return Err(DefineError::TooDeep(
                            active.first().copied().unwrap_or(word).to_string(),
                        ));
                    }
                    active.push(name.as_str());
                    self.expand_into(value, active, out)?;
                    active.pop();
                }
                _ => out.push_str(word),
            }
            i = j;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn defs(pairs: &[(&str, &str)]) -> Defines {
        let mut d = Defines::default();
        for (n, t) in pairs {
            d.define(n, t);
        }
        d
    }

    #[test]
    fn directives_are_recognised_in_any_case_and_motor_commands_are_not() {
        assert_eq!(
            directive("  #define RECOVERYSTA Q69   ; state"),
            Some(Ok(Directive::Define {
                name: "RECOVERYSTA",
                text: "Q69"
            }))
        );
        assert_eq!(
            directive("#DEFINE Center Q81   // Axis A"),
            Some(Ok(Directive::Define {
                name: "Center",
                text: "Q81"
            }))
        );
        assert_eq!(
            directive("#define EMPTY"),
            Some(Ok(Directive::Define {
                name: "EMPTY",
                text: ""
            }))
        );
        assert_eq!(
            directive("#include \"a b.pmc\""),
            Some(Ok(Directive::Include("a b.pmc")))
        );
        assert_eq!(
            directive("#INCLUDE <defs.h> ; x"),
            Some(Ok(Directive::Include("defs.h")))
        );
        assert_eq!(directive("#undef J1X"), Some(Ok(Directive::Undefine("J1X"))));
        assert_eq!(directive("#1->10000X"), None);
        assert_eq!(directive("#2J+"), None);
        assert_eq!(directive("#defined"), None);
        assert_eq!(directive("P1=2 ; #define X"), None);
        assert!(directive("#define").unwrap().is_err());
        assert!(directive("#define 1X Q1").unwrap().is_err());
        assert!(directive("#define A(x) x").unwrap().is_err());
        assert!(directive("#include").unwrap().is_err());
    }

    #[test]
    fn substitution_is_by_whole_word_case_sensitive_and_nested() {
        let d = defs(&[
            ("J1X", "Q20"),
            ("OFF", "P(4900+J1)"),
            ("J1", "2"),
            ("X", "Y"),
            ("FF", "EE"),
        ]);
        let e = |t: &str| d.expand(t).unwrap().into_owned();
        assert_eq!(e("J1X = 5"), "Q20 = 5");
        assert_eq!(e("J1XY=J1X+j1x"), "J1XY=Q20+j1x");
        assert_eq!(e("Q1=OFF*2"), "Q1=P(4900+2)*2");
        // Numbers, hex constants, strings and comments are left alone.
        assert_eq!(e("#1->1000X X 1 X1 $FF FF"), "#1->1000X Y 1 X1 $FF EE");
        assert_eq!(e("CMD\"X J1\" X ; X J1"), "CMD\"X J1\" Y ; X J1");
        assert_eq!(e("X 1 // X"), "Y 1 ");
        // A define using one written after it still expands at use.
        let mut d = defs(&[("A", "B+1")]);
        d.define("B", "P7");
        assert_eq!(d.expand("Q1=A").unwrap(), "Q1=P7+1");
        // Self reference stops, as in C; a cycle of two stops as well.
        let d = defs(&[("P1", "P1+1"), ("U", "V"), ("V", "U")]);
        assert_eq!(d.expand("P1").unwrap(), "P1+1");
        assert_eq!(d.expand("U").unwrap(), "U");
        // No defines: the text is borrowed, not copied.
        let d = Defines::default();
        assert!(matches!(d.expand("X1 Y2").unwrap(), Cow::Borrowed(_)));
        assert_eq!(d.expand("X1 // comment").unwrap(), "X1 ");
        let mut d = defs(&[("A", "B")]);
        d.undefine("A");
        assert_eq!(d.expand("A").unwrap(), "A");
    }

    #[test]
    fn deep_nesting_is_an_error() {
        let mut d = Defines::default();
        for k in 0..40 {
            d.define(&format!("N{k}"), &format!("N{}", k + 1));
        }
        assert!(d.expand("N0").unwrap_err().to_string().contains("deeper than"));
        assert_eq!(d.expand("N20").unwrap(), "N40");
    }
}
