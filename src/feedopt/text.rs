//! The program as text: where a line's F words are, how to give a line a
//! new feed without touching anything else, and the sub-block lines split
//! mode inserts (marked, so a second run can take them out again).

use crate::gcode::Dialect;

/// The comment that marks a line feedopt inserted when splitting a block.
pub const MARK: &str = "feedopt split";

/// A source line: its text without the line end, and the line end.
#[derive(Debug, Clone, Copy)]
pub struct Line<'a> {
    /// The line's text without its end.
    pub body: &'a str,
    /// `\n`, `\r\n`, or empty on a last line without an end.
    pub eol: &'a str,
}

/// The lines of `text`, each with its own line end (`\n`, `\r\n` or none
/// on a last line without one).
pub fn lines(text: &str) -> Vec<Line<'_>> {
    text.split_inclusive('\n')
        .map(|l| {
            let body = l.trim_end_matches(['\n', '\r']);
            Line {
                body,
                eol: &l[body.len()..],
            }
        })
        .collect()
}

/// True for a line feedopt inserted (it ends with the marker comment).
pub fn is_marked(body: &str, dialect: Dialect) -> bool {
    let b = body.trim_end();
    match dialect {
        Dialect::Iso => b.ends_with(&format!("({MARK})")),
        Dialect::Pmac => b.ends_with(&format!(";{MARK}")),
    }
}

/// Where the code of a line ends: the start of its comment, or its end.
/// ISO: `(` or `;`; PMAC: `;` outside a `"` string.
pub fn code_end(body: &str, dialect: Dialect) -> usize {
    let mut quoted = false;
    for (i, c) in body.bytes().enumerate() {
        match (dialect, c) {
            (Dialect::Pmac, b'"') => quoted = !quoted,
            (_, b';') if !quoted => return i,
            (Dialect::Iso, b'(') => return i,
            _ => {}
        }
    }
    body.len()
}

/// The byte ranges of the F words of a line (letter and value), outside
/// comments. An F counts when the character before it is not a letter
/// (so PMAC `IF`, `OFF` are not feeds) and a value follows: a number, an
/// ISO `#n` parameter or `[...]` expression, or a PMAC `(...)` expression.
pub fn f_words(body: &str, dialect: Dialect) -> Vec<(usize, usize)> {
    let b = body.as_bytes();
    let end = code_end(body, dialect);
    let mut out = Vec::new();
    let mut i = 0;
    let mut quoted = false;
    while i < end {
        let c = b[i];
        if dialect == Dialect::Iso && c == b'(' {
            break;
        }
        if dialect == Dialect::Pmac && c == b'"' {
            quoted = !quoted;
        }
        let prev_letter = i > 0 && b[i - 1].is_ascii_alphabetic();
        if !quoted && (c == b'F' || c == b'f') && !prev_letter {
            let mut j = i + 1;
            while j < end && b[j] == b' ' {
                j += 1;
            }
            let v0 = j;
            match b.get(j) {
                Some(b'[') | Some(b'(') => {
                    let (open, close) = if b[j] == b'[' { (b'[', b']') } else { (b'(', b')') };
                    let mut depth = 0;
                    while j < end {
                        if b[j] == open {
                            depth += 1;
                        } else if b[j] == close {
                            depth -= 1;
                            if depth == 0 {
                                j += 1;
                                break;
                            }
                        }
                        j += 1;
                    }
                }
                Some(b'#') => {
                    j += 1;
                    while j < end && (b[j].is_ascii_digit()) {
                        j += 1;
                    }
                }
                _ => {
                    if j < end && (b[j] == b'-' || b[j] == b'+') {
                        j += 1;
                    }
                    while j < end && (b[j].is_ascii_digit() || b[j] == b'.') {
                        j += 1;
                    }
                }
            }
            // A value must follow (and it must not run into a letter word
            // such as PMAC `FRAX`).
            let has_value = j > v0 && b[v0..j].iter().any(|c| c.is_ascii_digit() || b"[(#".contains(c));
            if has_value && !(dialect == Dialect::Pmac && j < end && b[j].is_ascii_alphabetic() && b[j - 1] == b'F') {
                out.push((i, j));
                i = j;
                continue;
            }
        }
        i += 1;
    }
    out
}

/// A feed as a word value: PMAC (mm/s) to 0.0001, ISO (mm/min) to 0.01,
/// trailing zeros dropped. `feed` is already on that grid.
pub fn format_feed(feed: f64, dialect: Dialect) -> String {
    let digits = match dialect {
        Dialect::Pmac => 4,
        Dialect::Iso => 2,
    };
    trim(format!("{feed:.digits$}"))
}

/// Round a feed down onto the grid [`format_feed`] prints, never below one
/// grid step.
pub fn floor_feed(feed: f64, dialect: Dialect) -> f64 {
    let q = match dialect {
        Dialect::Pmac => 1e4,
        Dialect::Iso => 1e2,
    };
    // The small bias keeps a value already on the grid where it is.
    ((feed * q + 1e-6).floor() / q).max(1.0 / q)
}

/// A coordinate to 0.0001 mm, trailing zeros dropped.
pub fn format_coord(v: f64) -> String {
    let s = trim(format!("{v:.4}"));
    if s == "-0" { "0".into() } else { s }
}

fn trim(mut s: String) -> String {
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    s
}

/// The line with every F word's value set to `feed`, or an F word added
/// after the code (before any comment) when it has none.
pub fn set_feed(body: &str, dialect: Dialect, feed: &str) -> String {
    let words = f_words(body, dialect);
    if words.is_empty() {
        let end = code_end(body, dialect);
        let code = body[..end].trim_end();
        let mut s = String::with_capacity(body.len() + feed.len() + 3);
        s.push_str(code);
        if !code.is_empty() {
            s.push(' ');
        }
        s.push('F');
        s.push_str(feed);
        if end < body.len() {
            s.push(' ');
            s.push_str(&body[end..]);
        } else {
            s.push_str(&body[code.len()..]);
        }
        return s;
    }
    let mut s = String::with_capacity(body.len() + 8);
    let mut at = 0;
    for (a, b) in words {
        s.push_str(&body[at..a]);
        s.push(body.as_bytes()[a] as char);
        s.push_str(feed);
        at = b;
    }
    s.push_str(&body[at..]);
    s
}

/// The axis words of a line that may be split: `None` unless the code is
/// only an optional N word, a linear motion word (G1/G01 or LINEAR), X/Y/Z
/// with plain numbers and F words. Returns the axes present and their values.
pub fn plain_linear(body: &str, dialect: Dialect) -> Option<[Option<f64>; 3]> {
    let code = &body[..code_end(body, dialect)];
    if !code.is_ascii() {
        return None;
    }
    let up = code.to_ascii_uppercase();
    let mut rest = up.as_str().trim();
    let mut axes = [None; 3];
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("LINEAR") {
            if dialect != Dialect::Pmac {
                return None;
            }
            rest = r.trim_start();
            continue;
        }
        let letter = rest.as_bytes()[0];
        let r = rest[1..].trim_start();
        let n = r
            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+'))
            .unwrap_or(r.len());
        let (num, after) = r.split_at(n);
        let v: f64 = num.parse().ok()?;
        match letter {
            b'N' => {}
            b'G' if v == 1.0 && dialect == Dialect::Iso => {}
            b'X' => axes[0] = Some(v),
            b'Y' => axes[1] = Some(v),
            b'Z' => axes[2] = Some(v),
            b'F' => {}
            _ => return None,
        }
        rest = after.trim_start();
    }
    Some(axes)
}

/// An inserted sub-block line: a linear move to `to` (the axes given) at
/// `feed`, marked.
pub fn sub_block(dialect: Dialect, to: [Option<f64>; 3], feed: &str) -> String {
    let mut s = String::from(match dialect {
        Dialect::Iso => "G1",
        Dialect::Pmac => "LINEAR",
    });
    for (k, v) in to.iter().enumerate() {
        if let Some(v) = v {
            s.push(' ');
            s.push(['X', 'Y', 'Z'][k]);
            s.push_str(&format_coord(*v));
        }
    }
    s.push_str(" F");
    s.push_str(feed);
    match dialect {
        Dialect::Iso => s.push_str(&format!(" ({MARK})")),
        Dialect::Pmac => s.push_str(&format!(" ;{MARK}")),
    }
    s
}

/// True when the program switches to incremental positions anywhere
/// (ISO G91, PMAC INC): sub-blocks are then not written.
pub fn has_incremental(text: &str, dialect: Dialect) -> bool {
    lines(text).iter().any(|l| {
        let code = l.body[..code_end(l.body, dialect)].to_ascii_uppercase();
        match dialect {
            Dialect::Iso => word_present(&code, "G91"),
            // `INC(R)` (incremental arc centres) leaves positions absolute.
            Dialect::Pmac => code.match_indices("INC").any(|(i, _)| {
                let before_ok = i == 0 || !code.as_bytes()[i - 1].is_ascii_alphabetic();
                let rest = &code[i + 3..];
                let axes = match rest.strip_prefix('(') {
                    Some(r) => r.split(')').next().unwrap_or("").contains(['X', 'Y', 'Z']),
                    None => !rest.starts_with(|c: char| c.is_ascii_alphanumeric()),
                };
                before_ok && axes
            }),
        }
    })
}

/// True when ISO text sets inch units (G20) anywhere.
pub fn has_inch(text: &str) -> bool {
    lines(text)
        .iter()
        .any(|l| word_present(&l.body[..code_end(l.body, Dialect::Iso)].to_ascii_uppercase(), "G20"))
}

/// The name of a feed mode other than G94 that ISO text sets anywhere
/// (G93 inverse time, G95 per revolution): there F is no mm/min.
pub fn feed_mode(text: &str) -> Option<&'static str> {
    lines(text).iter().find_map(|l| {
        let code = l.body[..code_end(l.body, Dialect::Iso)].to_ascii_uppercase();
        if word_present(&code, "G93") {
            Some("inverse time (G93)")
        } else if word_present(&code, "G95") {
            Some("feed per revolution (G95)")
        } else {
            None
        }
    })
}

/// `w` occurs in `code` not followed by a digit or point and not preceded
/// by a letter (`G20` but not `G200`, `G91` but not `G91.1`, `INC` but not
/// `SINC`).
fn word_present(code: &str, w: &str) -> bool {
    let b = code.as_bytes();
    let mut from = 0;
    while let Some(k) = code[from..].find(w) {
        let i = from + k;
        let j = i + w.len();
        let before_ok = i == 0 || !b[i - 1].is_ascii_alphabetic();
        let after_ok = j >= b.len() || !(b[j].is_ascii_digit() || b[j] == b'.');
        if before_ok && after_ok {
            return true;
        }
        from = j;
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f_words_are_found_outside_comments_and_other_words() {
        let iso = Dialect::Iso;
        assert_eq!(f_words("G1 X1 F600 (F9)", iso), vec![(6, 10)]);
        assert_eq!(f_words("G1 X1F#3 ;F2", iso), vec![(5, 8)]);
        assert_eq!(f_words("G1 F[2*300]", iso), vec![(3, 11)]);
        assert_eq!(f_words("o100 if [#1 GT 2]", iso), vec![]);
        let pm = Dialect::Pmac;
        assert_eq!(f_words("LINEAR X1 F2 M33==1 ;F3", pm), vec![(10, 12)]);
        assert_eq!(f_words("IF(P1>0)", pm), vec![]);
        assert_eq!(f_words("X1F2.5Y2", pm), vec![(2, 6)]);
    }

    #[test]
    fn set_feed_changes_only_the_f_word() {
        let iso = Dialect::Iso;
        assert_eq!(set_feed("N10 G1 X1 F600 (cut)", iso, "750"), "N10 G1 X1 F750 (cut)");
        assert_eq!(set_feed("N10 G1 X1 (cut)", iso, "750"), "N10 G1 X1 F750 (cut)");
        assert_eq!(set_feed("G1 X1", iso, "7"), "G1 X1 F7");
        assert_eq!(set_feed("X1 Y2 ;c", Dialect::Pmac, "2.5"), "X1 Y2 F2.5 ;c");
        // Idempotent.
        let once = set_feed("G1 X1 (c)", iso, "7");
        assert_eq!(set_feed(&once, iso, "7"), once);
    }

    #[test]
    fn plain_linear_lines_are_recognised() {
        assert_eq!(
            plain_linear("N5 G1 X1.5 Y-2 F120 (a)", Dialect::Iso),
            Some([Some(1.5), Some(-2.0), None])
        );
        assert_eq!(plain_linear("G1 X1 M3", Dialect::Iso), None);
        assert_eq!(plain_linear("G2 X1", Dialect::Iso), None);
        assert_eq!(
            plain_linear("LINEAR X1 F2", Dialect::Pmac),
            Some([Some(1.0), None, None])
        );
        assert_eq!(plain_linear("X1 M33==1", Dialect::Pmac), None);
        let s = sub_block(Dialect::Pmac, [Some(0.5), None, Some(-0.1)], "2.5");
        assert_eq!(s, "LINEAR X0.5 Z-0.1 F2.5 ;feedopt split");
        assert!(is_marked(&s, Dialect::Pmac));
        assert!(has_incremental("G0 X1\nG91 G1 X2\n", Dialect::Iso));
        assert!(!has_incremental("G90 G91.1\n", Dialect::Iso));
        assert!(!has_incremental("NORMAL K-1 ABS INC(R)\n", Dialect::Pmac));
        assert!(has_incremental("INC\nX1\n", Dialect::Pmac));
        assert!(has_incremental("INC(X,Y)\n", Dialect::Pmac));
        assert!(has_inch("G20 G0 X1\n"));
        assert_eq!(feed_mode("G0 X1 (G93)\nG95 G1 X2\n"), Some("feed per revolution (G95)"));
        assert_eq!(feed_mode("G94 G1 X1 F2 G930\n"), None);
        assert!(!has_inch("G200\n(G20)\n"));
    }

    #[test]
    fn feeds_round_down_onto_the_printed_grid() {
        assert_eq!(floor_feed(2.99999, Dialect::Pmac), 2.9999);
        assert_eq!(format_feed(floor_feed(3.0, Dialect::Pmac), Dialect::Pmac), "3");
        assert_eq!(format_feed(floor_feed(157.567, Dialect::Iso), Dialect::Iso), "157.56");
        assert_eq!(format_coord(-0.00001), "0");
    }
}
