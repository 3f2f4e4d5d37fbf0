//! RS274/NGC values: numbers, `#n` and `#<name>` parameters, `[ ]`
//! expressions and unary functions, evaluated over a normalised line
//! (comments and blanks removed, letters upper-cased).
//!
//! Angles are degrees, as in RS274. Binary operators follow RS274's three
//! precedence levels, highest first: `**`; `* / MOD`; `+ -`; then the
//! comparisons `EQ NE GT GE LT LE` and the logical `AND OR XOR` (LinuxCNC).

use std::collections::HashMap;
use thiserror::Error;

/// How many numbered parameters exist (`#1` .. `#5602`, LinuxCNC's range).
pub const NUM_PARAMS: usize = 5603;

/// Why an expression, number or parameter reference could not be read
/// (the messages are LinuxCNC's where it has one).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ExprError {
    /// A named parameter read before any assignment in its scope (the
    /// name, lower-cased).
    #[error("named parameter #<{0}> is used before it is set")]
    Unset(String),
    /// Something other than a number, parameter or expression where a
    /// value belongs (the text found there).
    #[error("expected a number at '{0}'")]
    ExpectedNumber(String),
    /// Digits and signs that do not make a number (the text).
    #[error("bad number '{0}'")]
    BadNumber(String),
    /// A literal with more digits than any real program writes; refused
    /// before parsing so hostile input stays cheap. `shown` is its start.
    #[error("number '{shown}...' ({digits} digits) is too large")]
    TooLong {
        /// The literal's first characters.
        shown: String,
        /// How many digits it has.
        digits: usize,
    },
    /// An operator produced infinity from finite operands.
    #[error("calculation result is not finite (overflow)")]
    Overflow,
    /// `[ ]` nesting deeper than the reader's stack limit (64).
    #[error("expression nested too deeply")]
    TooDeep,
    /// `##..#1` indirection deeper than the stack limit.
    #[error("parameter reference nested too deeply")]
    RefTooDeep,
    /// A parameter reference that does not start with `#`.
    #[error("expected '#'")]
    ExpectedHash,
    /// `#<name` without its `>`.
    #[error("named parameter without closing '>'")]
    UnclosedName,
    /// `#<>`: a name with no characters.
    #[error("empty parameter name '#<>'")]
    EmptyName,
    /// A numbered parameter outside `#1`..`#5602` or not a whole number.
    #[error("parameter number {0} out of range 1..{max}", max = NUM_PARAMS - 1)]
    ParamOutOfRange(f64),
    /// A function name not followed by its `[` argument.
    #[error("expected '['")]
    ExpectedOpen,
    /// An expression that ends before its closing `]`.
    #[error("missing ']' in expression")]
    MissingClose,
    /// Letters inside an expression that name no operator or function.
    #[error("unknown function or word at '{0}'")]
    UnknownWord(String),
    /// `EXISTS` applied to something other than a named parameter.
    #[error("EXISTS needs [#<name>]")]
    ExistsForm,
    /// `EXISTS[#<name>` without its closing `]`.
    #[error("missing ']' after EXISTS")]
    ExistsClose,
    /// `ATAN` not written as `ATAN[y]/[x]` (it takes two arguments).
    #[error("ATAN needs the form ATAN[y]/[x]")]
    AtanForm,
    /// The natural logarithm of zero or a negative number.
    #[error("LN of {0}: not positive")]
    LnNotPositive(f64),
    /// A function word the reader recognised but cannot evaluate.
    #[error("unknown function")]
    UnknownFunction,
    /// `/` with a zero divisor.
    #[error("division by zero")]
    DivisionByZero,
    /// `MOD` with a zero divisor.
    #[error("MOD by zero")]
    ModByZero,
    /// A result that is NaN or infinite for another reason than overflow.
    #[error("expression result is not finite")]
    NotFinite,
    /// A function applied outside its domain (`ASIN[2]`, `SQRT[-1]`):
    /// `f` is its name, `a` the argument.
    #[error("{f} of {a}: out of its domain")]
    Domain {
        /// The function's name.
        f: &'static str,
        /// The argument it was given.
        a: f64,
    },
}

/// The parameter store of an interpreter.
///
/// Named parameters follow LinuxCNC's scoping: a name starting with `_` is
/// global; any other name is local to the subroutine call (or the main
/// program) that set it, invisible to callers and callees.
#[derive(Debug, Clone)]
pub struct Params {
    numbered: Vec<f64>,
    global: HashMap<Vec<u8>, f64>,
    /// Local named parameters, one map per active call; `[0]` is the main
    /// program's.
    frames: Vec<HashMap<Vec<u8>, f64>>,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            numbered: vec![0.0; NUM_PARAMS],
            global: HashMap::new(),
            frames: vec![HashMap::new()],
        }
    }
}

/// Which parameter a `#` reference names: the target of an assignment
/// (applied after the whole line is read) or a value to look up.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamRef {
    /// `#n`, 1 ..= 5602 (checked when the reference is read).
    Num(usize),
    /// `#<name>`, upper-cased as the normalised line is; a leading `_`
    /// makes it global.
    Named(Vec<u8>),
}

impl Params {
    fn scope(&self, name: &[u8]) -> &HashMap<Vec<u8>, f64> {
        match (name.first(), self.frames.last()) {
            (Some(b'_'), _) | (_, None) => &self.global,
            (_, Some(frame)) => frame,
        }
    }

    /// The value of a parameter: numbered ones start at 0, a named one
    /// must have been set in its scope ([`ExprError::Unset`] otherwise).
    pub fn get(&self, r: &ParamRef) -> Result<f64, ExprError> {
        match r {
            ParamRef::Num(n) => Ok(self.numbered[*n]),
            ParamRef::Named(name) => self
                .scope(name)
                .get(name)
                .copied()
                .ok_or_else(|| ExprError::Unset(String::from_utf8_lossy(name).to_lowercase())),
        }
    }

    /// Assign a parameter; a named one goes to the current call's scope,
    /// or the global one when it starts with `_`.
    pub fn set(&mut self, r: &ParamRef, v: f64) {
        match r {
            ParamRef::Num(n) => self.numbered[*n] = v,
            ParamRef::Named(name) => {
                let scope = match (name.first(), self.frames.last_mut()) {
                    (Some(b'_'), _) | (_, None) => &mut self.global,
                    (_, Some(frame)) => frame,
                };
                scope.insert(name.clone(), v);
            }
        }
    }

    /// RS274's `EXISTS[#<name>]`: whether `name` (upper-cased, without
    /// `#< >`) is set in the scope it would be read from.
    pub fn exists(&self, name: &[u8]) -> bool {
        self.scope(name).contains_key(name)
    }

    /// Enter a subroutine call: a fresh scope for local named parameters.
    pub fn push_frame(&mut self) {
        self.frames.push(HashMap::new());
    }

    /// Leave a subroutine call, dropping its local named parameters.
    pub fn pop_frame(&mut self) {
        if self.frames.len() > 1 {
            self.frames.pop();
        }
    }
}

/// A cursor over a normalised line (no blanks or comments, upper case),
/// advanced by the readers of values below.
pub struct Cursor<'a> {
    /// The whole normalised line.
    pub s: &'a [u8],
    /// Index of the next unread byte of `s`.
    pub pos: usize,
}

/// Nesting limit for expressions, so hostile input cannot overflow the stack.
const MAX_DEPTH: u32 = 64;

impl<'a> Cursor<'a> {
    /// A cursor at the start of `s`.
    pub fn new(s: &'a [u8]) -> Self {
        Cursor { s, pos: 0 }
    }

    /// The next byte, without consuming it; `None` at the end.
    pub fn peek(&self) -> Option<u8> {
        self.s.get(self.pos).copied()
    }

    /// True when every byte has been read.
    pub fn at_end(&self) -> bool {
        self.pos >= self.s.len()
    }

    fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    fn eat_word(&mut self, w: &[u8]) -> bool {
        if self.s[self.pos.min(self.s.len())..].starts_with(w) {
            self.pos += w.len();
            true
        } else {
            false
        }
    }

    /// An unsigned or signed decimal number such as `-1.5`, `.5`, `+2.`.
    ///
    /// Fast path (Clinger): up to 19 significant digits go into an integer
    /// and, when that integer and the power of ten are exact doubles, one
    /// correctly rounded division gives the exact nearest double. G-code
    /// numbers almost always take it; anything longer falls back to the
    /// standard library's parser.
    pub fn number(&mut self) -> Result<f64, ExprError> {
        const POW10: [f64; 23] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
            1e19, 1e20, 1e21, 1e22,
        ];
        let start = self.pos;
        let neg = match self.peek() {
            Some(b'-') => {
                self.pos += 1;
                true
            }
            Some(b'+') => {
                self.pos += 1;
                false
            }
            _ => false,
        };
        let mut mantissa: u64 = 0;
        let mut digits = 0u32;
        let mut frac_digits = 0u32;
        let mut seen_point = false;
        let mut any = false;
        while let Some(c) = self.peek() {
            match c {
                b'0'..=b'9' => {
                    any = true;
                    if digits < 19 {
                        mantissa = mantissa * 10 + (c - b'0') as u64;
                        if mantissa > 0 {
                            digits += 1;
                        }
                        if seen_point {
                            frac_digits += 1;
                        }
                    } else {
                        // Too many digits for the fast path.
                        digits = u32::MAX;
                    }
                }
                b'.' if !seen_point => seen_point = true,
                _ => break,
            }
            self.pos += 1;
        }
        if !any {
            self.pos = start;
            return Err(ExprError::ExpectedNumber(self.rest_for_msg(start)));
        }
        if digits != u32::MAX && mantissa < (1u64 << 53) && (frac_digits as usize) < POW10.len() {
            let v = mantissa as f64 / POW10[frac_digits as usize];
            return Ok(if neg { -v } else { v });
        }
        let text = std::str::from_utf8(&self.s[start..self.pos]).unwrap_or("");
        let t = text.strip_prefix('+').unwrap_or(text);
        let v = t.parse::<f64>().map_err(|_| ExprError::BadNumber(text.to_string()))?;
        if !v.is_finite() {
            let shown: String = text.chars().take(24).collect();
            return Err(ExprError::TooLong {
                shown,
                digits: text.len(),
            });
        }
        Ok(v)
    }

    fn rest_for_msg(&self, from: usize) -> String {
        let end = (from + 12).min(self.s.len());
        String::from_utf8_lossy(&self.s[from.min(end)..end]).into_owned()
    }

    /// A real value: number, `#` parameter, `[expr]` or unary function.
    /// Like LinuxCNC, a calculation that overflows is an error, never an
    /// infinite value carried on.
    pub fn real_value(&mut self, p: &Params) -> Result<f64, ExprError> {
        let v = self.real_value_depth(p, 0)?;
        if !v.is_finite() {
            return Err(ExprError::Overflow);
        }
        Ok(v)
    }

    fn real_value_depth(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        if depth > MAX_DEPTH {
            return Err(ExprError::TooDeep);
        }
        match self.peek() {
            Some(b'[') => self.bracketed(p, depth + 1),
            Some(b'#') => {
                let r = self.param_ref_depth(p, depth + 1)?;
                p.get(&r)
            }
            Some(b'-') if matches!(self.s.get(self.pos + 1), Some(b'[' | b'#' | b'A'..=b'Z' | b'-' | b'+')) => {
                self.pos += 1;
                Ok(-self.real_value_depth(p, depth + 1)?)
            }
            Some(b'+') if matches!(self.s.get(self.pos + 1), Some(b'[' | b'#' | b'A'..=b'Z' | b'-' | b'+')) => {
                self.pos += 1;
                self.real_value_depth(p, depth + 1)
            }
            Some(b'A'..=b'Z') => self.unary(p, depth + 1),
            _ => self.number(),
        }
    }

    /// A parameter reference after `#`: `#12`, `#<name>`, `##3`, `#[1+2]`.
    pub fn param_ref(&mut self, p: &Params) -> Result<ParamRef, ExprError> {
        self.param_ref_depth(p, 0)
    }

    fn param_ref_depth(&mut self, p: &Params, depth: u32) -> Result<ParamRef, ExprError> {
        if depth > MAX_DEPTH {
            return Err(ExprError::RefTooDeep);
        }
        if !self.eat(b'#') {
            return Err(ExprError::ExpectedHash);
        }
        if self.eat(b'<') {
            let start = self.pos;
            while self.peek().is_some_and(|c| c != b'>') {
                self.pos += 1;
            }
            if self.at_end() {
                return Err(ExprError::UnclosedName);
            }
            let name = self.s[start..self.pos].to_vec();
            self.pos += 1;
            if name.is_empty() {
                return Err(ExprError::EmptyName);
            }
            return Ok(ParamRef::Named(name));
        }
        let v = self.real_value_depth(p, depth + 1)?;
        let n = v.round();
        if (v - n).abs() > 1e-6 || n < 1.0 || n >= NUM_PARAMS as f64 {
            return Err(ExprError::ParamOutOfRange(v));
        }
        Ok(ParamRef::Num(n as usize))
    }

    fn bracketed(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        if !self.eat(b'[') {
            return Err(ExprError::ExpectedOpen);
        }
        let v = self.expression(p, depth)?;
        if !self.eat(b']') {
            return Err(ExprError::MissingClose);
        }
        Ok(v)
    }

    fn unary(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        const FUNCS: [&[u8]; 14] = [
            b"ABS", b"ACOS", b"ASIN", b"ATAN", b"COS", b"EXP", b"EXISTS", b"FIX", b"FUP", b"ROUND", b"LN", b"SIN",
            b"SQRT", b"TAN",
        ];
        let start = self.pos;
        let Some(f) = FUNCS.iter().find(|f| self.s[self.pos..].starts_with(f)) else {
            return Err(ExprError::UnknownWord(self.rest_for_msg(start)));
        };
        self.pos += f.len();
        if *f == b"EXISTS" {
            if !self.eat(b'[') {
                return Err(ExprError::ExistsForm);
            }
            let r = self.param_ref_depth(p, depth + 1)?;
            if !self.eat(b']') {
                return Err(ExprError::ExistsClose);
            }
            return Ok(match r {
                ParamRef::Named(n) => p.exists(&n) as u8 as f64,
                ParamRef::Num(_) => 1.0,
            });
        }
        let a = self.bracketed(p, depth + 1)?;
        if *f == b"ATAN" {
            if !self.eat(b'/') {
                return Err(ExprError::AtanForm);
            }
            let b = self.bracketed(p, depth + 1)?;
            return Ok(a.atan2(b).to_degrees());
        }
        let v = match *f {
            b"ABS" => a.abs(),
            b"ACOS" => domain(a, -1.0, 1.0, "ACOS")?.acos().to_degrees(),
            b"ASIN" => domain(a, -1.0, 1.0, "ASIN")?.asin().to_degrees(),
            b"COS" => a.to_radians().cos(),
            b"EXP" => a.exp(),
            b"FIX" => a.floor(),
            b"FUP" => a.ceil(),
            b"ROUND" => a.round(),
            b"LN" => {
                if a <= 0.0 {
                    return Err(ExprError::LnNotPositive(a));
                }
                a.ln()
            }
            b"SIN" => a.to_radians().sin(),
            b"SQRT" => domain(a, 0.0, f64::INFINITY, "SQRT")?.sqrt(),
            b"TAN" => a.to_radians().tan(),
            _ => return Err(ExprError::UnknownFunction),
        };
        Ok(v)
    }

    /// Binary expression inside brackets, with RS274 precedence.
    fn expression(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        self.logical(p, depth)
    }

    fn logical(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        let mut v = self.comparison(p, depth)?;
        loop {
            if self.eat_word(b"AND") {
                let r = self.comparison(p, depth)?;
                v = ((v != 0.0) && (r != 0.0)) as u8 as f64;
            } else if self.eat_word(b"OR") {
                let r = self.comparison(p, depth)?;
                v = ((v != 0.0) || (r != 0.0)) as u8 as f64;
            } else if self.eat_word(b"XOR") {
                let r = self.comparison(p, depth)?;
                v = ((v != 0.0) ^ (r != 0.0)) as u8 as f64;
            } else {
                return Ok(v);
            }
        }
    }

    fn comparison(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        let mut v = self.additive(p, depth)?;
        loop {
            let op: Option<fn(f64, f64) -> bool> = if self.eat_word(b"EQ") {
                Some(|a, b| a == b)
            } else if self.eat_word(b"NE") {
                Some(|a, b| a != b)
            } else if self.eat_word(b"GT") {
                Some(|a, b| a > b)
            } else if self.eat_word(b"GE") {
                Some(|a, b| a >= b)
            } else if self.eat_word(b"LT") {
                Some(|a, b| a < b)
            } else if self.eat_word(b"LE") {
                Some(|a, b| a <= b)
            } else {
                None
            };
            match op {
                Some(f) => {
                    let r = self.additive(p, depth)?;
                    v = f(v, r) as u8 as f64;
                }
                None => return Ok(v),
            }
        }
    }

    fn additive(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        let mut v = self.multiplicative(p, depth)?;
        loop {
            if self.eat(b'+') {
                v += self.multiplicative(p, depth)?;
            } else if self.eat(b'-') {
                v -= self.multiplicative(p, depth)?;
            } else {
                return Ok(v);
            }
        }
    }

    fn multiplicative(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        let mut v = self.power(p, depth)?;
        loop {
            if self.s[self.pos.min(self.s.len())..].starts_with(b"**") {
                return Ok(v);
            } else if self.eat(b'*') {
                v *= self.power(p, depth)?;
            } else if self.eat(b'/') {
                let d = self.power(p, depth)?;
                if d == 0.0 {
                    return Err(ExprError::DivisionByZero);
                }
                v /= d;
            } else if self.eat_word(b"MOD") {
                let d = self.power(p, depth)?;
                if d == 0.0 {
                    return Err(ExprError::ModByZero);
                }
                // RS274 MOD is the non-negative remainder.
                v = v.rem_euclid(d.abs());
            } else {
                return Ok(v);
            }
        }
    }

    fn power(&mut self, p: &Params, depth: u32) -> Result<f64, ExprError> {
        let mut v = self.real_value_depth(p, depth + 1)?;
        while self.eat_word(b"**") {
            let e = self.real_value_depth(p, depth + 1)?;
            v = v.powf(e);
        }
        if !v.is_finite() {
            return Err(ExprError::NotFinite);
        }
        Ok(v)
    }
}

fn domain(a: f64, lo: f64, hi: f64, f: &'static str) -> Result<f64, ExprError> {
    if a < lo || a > hi {
        Err(ExprError::Domain { f, a })
    } else {
        Ok(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(s: &str, p: &Params) -> Result<f64, ExprError> {
        let mut c = Cursor::new(s.as_bytes());
        let v = c.real_value(p)?;
        assert!(c.at_end(), "left over: {}", &s[c.pos..]);
        Ok(v)
    }

    #[test]
    fn errors_are_values_with_linuxcnc_style_messages() {
        let p = Params::default();
        let e = |t: &str| eval(t, &p).unwrap_err();
        assert_eq!(e("[1/0]"), ExprError::DivisionByZero);
        assert_eq!(e("[1/0]").to_string(), "division by zero");
        assert_eq!(e("SQRT[-1]").to_string(), "SQRT of -1: out of its domain");
        assert_eq!(e("#6000").to_string(), "parameter number 6000 out of range 1..5602");
        assert_eq!(
            e("#<nope>").to_string(),
            "named parameter #<nope> is used before it is set"
        );
        assert_eq!(e("LN[0]").to_string(), "LN of 0: not positive");
    }

    #[test]
    fn evaluates_rs274_expressions() {
        let mut p = Params::default();
        p.set(&ParamRef::Num(1), 3.0);
        p.set(&ParamRef::Named(b"Z_SAFE".to_vec()), 5.0);
        let cases = [
            ("[1+2*3]", 7.0),
            ("[2**3*2]", 16.0),
            ("[[1+2]*3]", 9.0),
            ("#1", 3.0),
            ("[#1*#<Z_SAFE>]", 15.0),
            ("-#1", -3.0),
            ("SIN[30]", 0.5),
            ("ATAN[1]/[1]", 45.0),
            ("[7MOD3]", 1.0),
            ("[-7MOD3]", 2.0),
            ("[1LT2]", 1.0),
            ("[1GT2OR1]", 1.0),
            ("[FIX[2.7]+FUP[2.1]+ROUND[2.5]]", 8.0),
            ("##1", 0.0),
            ("EXISTS[#<Z_SAFE>]", 1.0),
            ("EXISTS[#<NOPE>]", 0.0),
            ("[SQRT[16]/2]", 2.0),
            ("--#1", 3.0),
            ("[-+-2]", 2.0),
        ];
        for (s, want) in cases {
            let got = eval(s, &p).unwrap_or_else(|e| panic!("{s}: {e}"));
            assert!((got - want).abs() < 1e-12, "{s}: {got} != {want}");
        }
    }

    #[test]
    fn numbers_parse_exactly_like_the_standard_library() {
        let p = Params::default();
        let texts = [
            "0",
            "-0",
            "1.",
            ".5",
            "+2.25",
            "-1.5319380",
            "0.000001",
            "123456789.123456789",
            "99999999999999999999.5",
            "0.1",
            "3.14159265358979323846",
            "1e",
            "007",
            "-.0001",
        ];
        for t in texts {
            let mut c = Cursor::new(t.as_bytes());
            let got = c.real_value(&p).unwrap();
            let digits: String = t.chars().take_while(|c| !c.is_ascii_alphabetic()).collect();
            let want: f64 = digits.trim_start_matches('+').parse().unwrap();
            assert_eq!(got.to_bits(), want.to_bits(), "{t}");
        }
        let mut state = 88172645463325252u64;
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let t = format!("{:.*}", (state % 9) as usize, (state >> 11) as f64 / 1e6 - 4e6);
            let got = Cursor::new(t.as_bytes()).real_value(&p).unwrap();
            assert_eq!(got.to_bits(), t.parse::<f64>().unwrap().to_bits(), "{t}");
        }
    }

    #[test]
    fn named_parameters_are_local_unless_they_start_with_underscore() {
        let mut p = Params::default();
        let local = ParamRef::Named(b"DEPTH".to_vec());
        let global = ParamRef::Named(b"_DEPTH".to_vec());
        p.set(&local, 99.0);
        p.set(&global, 1.0);
        p.push_frame();
        assert!(p.get(&local).is_err(), "a callee does not see its caller's locals");
        p.set(&local, 5.0);
        p.set(&global, 2.0);
        assert_eq!(p.get(&local), Ok(5.0));
        p.pop_frame();
        assert_eq!(p.get(&local), Ok(99.0));
        assert_eq!(p.get(&global), Ok(2.0));
    }

    #[test]
    fn rejects_bad_expressions_without_panicking() {
        let p = Params::default();
        for s in [
            "[1+", "[1/0]", "#<nope>", "#0", "#99999", "SQRT[-1]", "FOO[1]", "[1]]", "#<", "ATAN[1]",
        ] {
            let mut c = Cursor::new(s.as_bytes());
            let r = c.real_value(&p);
            assert!(r.is_err() || !c.at_end(), "{s} should fail");
        }
        let deep = "[".repeat(10_000);
        assert!(Cursor::new(deep.as_bytes()).real_value(&p).is_err());
    }
}
