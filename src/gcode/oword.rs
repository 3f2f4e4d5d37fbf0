//! RS274/NGC O-word lines (LinuxCNC control flow): parsing only. The ISO
//! interpreter executes them.

/// The keyword of an O-word line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OKeyword {
    /// `sub`: opens a subroutine definition (its body is stored, not run).
    Sub,
    /// `endsub`: closes a definition; reached in a call, it returns.
    EndSub,
    /// `call [args]`: runs a subroutine with #1.. set from the arguments.
    Call,
    /// `do`: opens a loop whose condition is on its closing `while`.
    Do,
    /// `while [cond]`: opens a loop, or closes a `do` loop.
    While,
    /// `endwhile`: closes a `while` loop.
    EndWhile,
    /// `if [cond]`: opens a conditional.
    If,
    /// `elseif [cond]`: a further branch of an `if`.
    ElseIf,
    /// `else`: the last branch of an `if`.
    Else,
    /// `endif`: closes a conditional.
    EndIf,
    /// `break`: leaves the innermost loop with this label.
    Break,
    /// `continue`: starts the next pass of the loop with this label.
    Continue,
    /// `repeat [count]`: opens a loop run a given number of times.
    Repeat,
    /// `endrepeat`: closes a `repeat` loop.
    EndRepeat,
    /// `return [value]`: leaves the subroutine, setting `#<_value>`.
    Return,
}

/// A parsed O-word line over a normalised line: label, keyword and the
/// byte offset where the keyword's argument (an expression, call arguments
/// or nothing) starts.
#[derive(Debug, Clone, PartialEq)]
pub struct OLine {
    /// `100` for `O100`, `NAME` for `O<name>` (upper-cased like the line).
    pub label: Vec<u8>,
    /// What the line does.
    pub keyword: OKeyword,
    /// Byte offset, in the normalised line, just past the keyword.
    pub rest: usize,
}

// Longest first where one keyword is a prefix of another.
const KEYWORDS: [(&[u8], OKeyword); 15] = [
    (b"ENDSUB", OKeyword::EndSub),
    (b"ENDWHILE", OKeyword::EndWhile),
    (b"ENDIF", OKeyword::EndIf),
    (b"ENDREPEAT", OKeyword::EndRepeat),
    (b"ELSEIF", OKeyword::ElseIf),
    (b"ELSE", OKeyword::Else),
    (b"SUB", OKeyword::Sub),
    (b"CALL", OKeyword::Call),
    (b"DO", OKeyword::Do),
    (b"WHILE", OKeyword::While),
    (b"IF", OKeyword::If),
    (b"BREAK", OKeyword::Break),
    (b"CONTINUE", OKeyword::Continue),
    (b"REPEAT", OKeyword::Repeat),
    (b"RETURN", OKeyword::Return),
];

/// Why an O-word line could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OWordError {
    /// The line does not start with `O` (after any `N` word).
    #[error("not an O-word line")]
    NotOWord,
    /// `O<name` without its `>`.
    #[error("O-word name without closing '>'")]
    UnclosedName,
    /// `O<>`: a name with no characters.
    #[error("empty O-word name 'O<>'")]
    EmptyName,
    /// `O` followed by neither digits nor `<name>`.
    #[error("O word needs a number or <name>")]
    NoLabel,
    /// The label is followed by no keyword RS274 knows (the text found).
    #[error("unknown O-word keyword at '{0}'")]
    UnknownKeyword(String),
}

/// Parse a normalised line that starts with `O` (after any `N` word).
pub fn parse(s: &[u8]) -> Result<OLine, OWordError> {
    let mut pos = 0;
    if s.first() != Some(&b'O') {
        return Err(OWordError::NotOWord);
    }
    pos += 1;
    let label = if s.get(pos) == Some(&b'<') {
        let end = s[pos..]
            .iter()
            .position(|&c| c == b'>')
            .ok_or(OWordError::UnclosedName)?;
        let name = s[pos + 1..pos + end].to_vec();
        pos += end + 1;
        if name.is_empty() {
            return Err(OWordError::EmptyName);
        }
        name
    } else {
        let start = pos;
        while s.get(pos).is_some_and(u8::is_ascii_digit) {
            pos += 1;
        }
        if pos == start {
            return Err(OWordError::NoLabel);
        }
        // O0100 and O100 are the same label.
        let digits = &s[start..pos];
        let trimmed = match digits.iter().position(|&c| c != b'0') {
            Some(i) => &digits[i..],
            None => b"0",
        };
        trimmed.to_vec()
    };
    let (kw, keyword) = KEYWORDS
        .iter()
        .find(|(w, _)| s[pos..].starts_with(w))
        .ok_or_else(|| OWordError::UnknownKeyword(String::from_utf8_lossy(&s[pos..]).into_owned()))?;
    Ok(OLine {
        label,
        keyword: *keyword,
        rest: pos + kw.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_labels_and_keywords() {
        let l = parse(b"O0100WHILE[#1LT3]").unwrap();
        assert_eq!(
            (l.label.as_slice(), l.keyword, l.rest),
            (&b"100"[..], OKeyword::While, 10)
        );
        let l = parse(b"O<MYSUB>ENDSUB").unwrap();
        assert_eq!((l.label.as_slice(), l.keyword), (&b"MYSUB"[..], OKeyword::EndSub));
        assert_eq!(parse(b"O1ELSEIF[1]").unwrap().keyword, OKeyword::ElseIf);
        assert_eq!(parse(b"O1ELSE").unwrap().keyword, OKeyword::Else);
        assert!(parse(b"O<X").is_err());
        assert!(parse(b"OSUB").is_err());
        assert!(parse(b"O1GOTO").is_err());
    }
}
