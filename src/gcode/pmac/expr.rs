//! PMAC variables (P, Q, M, I) and expressions: the variable store and the
//! evaluator of `{data}` and `(expression)` text.

use super::GcodeError;
use super::lexer::Cursor;

/// Highest variable number of each kind (P, Q, M, I) on a Turbo PMAC.
pub(super) const VAR_MAX: u32 = 8191;
const VAR_SLOTS: usize = VAR_MAX as usize + 1;
/// Deepest nesting of parentheses, functions and unary signs in one
/// expression; deeper text is refused instead of overflowing the stack.
const MAX_DEPTH: u32 = 64;

/// The four PMAC variable families.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum VarKind {
    P,
    Q,
    M,
    I,
}

impl VarKind {
    pub(super) fn from_letter(c: u8) -> Option<VarKind> {
        match c.to_ascii_uppercase() {
            b'P' => Some(VarKind::P),
            b'Q' => Some(VarKind::Q),
            b'M' => Some(VarKind::M),
            b'I' => Some(VarKind::I),
            _ => None,
        }
    }

    pub(super) fn letter(self) -> char {
        match self {
            VarKind::P => 'P',
            VarKind::Q => 'Q',
            VarKind::M => 'M',
            VarKind::I => 'I',
        }
    }
}

/// One controller variable, such as `M33` or `P400`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Var {
    pub(super) kind: VarKind,
    pub(super) index: u32,
}

impl Var {
    /// Index into the interpreter's variable store.
    fn slot(self) -> usize {
        self.kind as usize * VAR_SLOTS + self.index as usize
    }

    /// Parse a configured name such as `M33` (any case, spaces around).
    pub(super) fn parse(name: &str) -> Option<Var> {
        let b = name.trim().as_bytes();
        let (&first, digits) = b.split_first()?;
        let kind = VarKind::from_letter(first)?;
        if digits.is_empty() || digits.len() > 5 || !digits.iter().all(u8::is_ascii_digit) {
            return None;
        }
        let index = digits.iter().fold(0u32, |n, d| n * 10 + u32::from(d - b'0'));
        (index <= VAR_MAX).then_some(Var { kind, index })
    }

    pub(super) fn name(self) -> String {
        format!("{}{}", self.kind.letter(), self.index)
    }
}

/// Expression functions (PMAC's set). `ATAN2` is matched as `ATAN` + `2`.
#[derive(Debug, Clone, Copy)]
enum Func {
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Atan2,
    Ln,
    Exp,
    Sqrt,
    Abs,
    Int,
}

/// PMAC bit-by-bit operators work on the integer and fractional bits of
/// their operands; 32 fractional bits in an `i128` reproduce that for any
/// value a program can sensibly hold.
fn bitwise(a: f64, b: f64, op: u8) -> f64 {
    const SCALE: f64 = 4_294_967_296.0;
    if !(a.abs() < 1e18 && b.abs() < 1e18) {
        return f64::NAN;
    }
    let x = (a * SCALE).floor() as i128;
    let y = (b * SCALE).floor() as i128;
    let r = match op {
        b'&' => x & y,
        b'|' => x | y,
        _ => x ^ y,
    };
    r as f64 / SCALE
}

/// Variables per page of the store.
const PAGE: usize = 256;

/// The controller's variables as assigned so far (P, Q, M and I,
/// 0..=8191 each); unset ones read 0, as after a controller reset.
///
/// Stored in pages of 256 allocated on first assignment: a program uses a
/// handful of variables, and the emulator starts an interpreter for every
/// run command, which with one flat array of all 32,768 meant zeroing
/// 256 KB each time (a tenth of the fuzzer's time on PMAC input).
pub(super) struct Vars {
    pages: Vec<Option<Box<[f64; PAGE]>>>,
}

impl Vars {
    pub(super) fn new() -> Self {
        Vars {
            pages: (0..(4 * VAR_SLOTS).div_ceil(PAGE)).map(|_| None).collect(),
        }
    }

    pub(super) fn get(&self, v: Var) -> f64 {
        let k = v.slot();
        match self.pages.get(k / PAGE) {
            Some(Some(page)) => page[k % PAGE],
            _ => 0.0,
        }
    }

    pub(super) fn set(&mut self, v: Var, value: f64) {
        let k = v.slot();
        let Some(page) = self.pages.get_mut(k / PAGE) else {
            return;
        };
        if page.is_none() && value.to_bits() == 0 {
            return; // +0 is what an unset variable reads
        }
        page.get_or_insert_with(|| Box::new([0.0; PAGE]))[k % PAGE] = value;
    }

    /// `{data}` after a word: a constant or a parenthesised expression, with
    /// an optional sign.
    pub(super) fn data(&self, cur: &mut Cursor, word: &str, lineno: u64) -> Result<f64, GcodeError> {
        cur.skip_ws();
        let neg = if cur.eat(b'-') {
            true
        } else {
            cur.eat(b'+');
            false
        };
        let v = match cur.peek() {
            Some(b'(') => {
                cur.i += 1;
                let v = self.expr(cur, 1, lineno)?;
                cur.skip_ws();
                if !cur.eat(b')') {
                    return Err(GcodeError::at(lineno, "expression without closing ')'"));
                }
                v
            }
            Some(b'$') => {
                cur.i += 1;
                cur.hex()
                    .ok_or_else(|| GcodeError::at(lineno, "bad hexadecimal constant after '$'"))?
            }
            _ => cur.number().ok_or_else(|| {
                GcodeError::at(
                    lineno,
                    format!("{word} needs a value (a number or a parenthesised expression)"),
                )
            })?,
        };
        let v = if neg { -v } else { v };
        if !v.is_finite() {
            return Err(GcodeError::at(
                lineno,
                format!("value of {word} is not a finite number"),
            ));
        }
        Ok(v)
    }

    /// expr := term (('+' | '-' | '|' | '^') term)*
    pub(super) fn expr(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        let mut v = self.term(cur, depth, lineno)?;
        loop {
            cur.skip_ws();
            let Some(op @ (b'+' | b'-' | b'|' | b'^')) = cur.peek() else {
                return Ok(v);
            };
            cur.i += 1;
            let r = self.term(cur, depth, lineno)?;
            v = match op {
                b'+' => v + r,
                b'-' => v - r,
                _ => bitwise(v, r, op),
            };
        }
    }

    /// term := unary (('*' | '/' | '%' | '&') unary)*
    pub(super) fn term(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        let mut v = self.unary(cur, depth, lineno)?;
        loop {
            cur.skip_ws();
            let Some(op @ (b'*' | b'/' | b'%' | b'&')) = cur.peek() else {
                return Ok(v);
            };
            cur.i += 1;
            let r = self.unary(cur, depth, lineno)?;
            v = match op {
                b'*' => v * r,
                b'/' => v / r,
                // Remainder with the divisor's sign for positive divisors
                // (unconfirmed for negative ones on a controller).
                b'%' => {
                    if r > 0.0 {
                        v.rem_euclid(r)
                    } else {
                        v % r
                    }
                }
                _ => bitwise(v, r, op),
            };
        }
    }

    pub(super) fn unary(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        if depth > MAX_DEPTH {
            return Err(GcodeError::at(lineno, "expression nested too deeply"));
        }
        cur.skip_ws();
        if cur.eat(b'-') {
            return Ok(-self.unary(cur, depth + 1, lineno)?);
        }
        if cur.eat(b'+') {
            return self.unary(cur, depth + 1, lineno);
        }
        self.primary(cur, depth, lineno)
    }

    pub(super) fn primary(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        let Some(c) = cur.peek() else {
            return Err(GcodeError::at(lineno, "expression ends where a value is expected"));
        };
        if c == b'(' {
            cur.i += 1;
            let v = self.expr(cur, depth + 1, lineno)?;
            cur.skip_ws();
            if !cur.eat(b')') {
                return Err(GcodeError::at(lineno, "expression without closing ')'"));
            }
            return Ok(v);
        }
        if c == b'$' {
            cur.i += 1;
            return cur
                .hex()
                .ok_or_else(|| GcodeError::at(lineno, "bad hexadecimal constant after '$'"));
        }
        if c.is_ascii_digit() || c == b'.' {
            return cur
                .number()
                .ok_or_else(|| GcodeError::at(lineno, format!("bad number '{}'", cur.snippet(cur.i))));
        }
        if !c.is_ascii_alphabetic() {
            return Err(GcodeError::at(
                lineno,
                format!("expected a value in the expression, found '{}'", cur.snippet(cur.i)),
            ));
        }
        let start = cur.i;
        let end = cur.letters_end(start);
        let run = cur.b.get(start..end).unwrap_or(&[]);
        cur.i = end;
        if let [letter] = run
            && let Some(kind) = VarKind::from_letter(*letter)
        {
            cur.skip_ws();
            let index = if cur.peek() == Some(b'(') {
                cur.i += 1;
                let v = self.expr(cur, depth + 1, lineno)?;
                cur.skip_ws();
                if !cur.eat(b')') {
                    return Err(GcodeError::at(lineno, "expression without closing ')'"));
                }
                if !(v >= 0.0 && v < f64::from(VAR_MAX + 1)) {
                    return Err(GcodeError::at(
                        lineno,
                        format!("variable {}({v}) is out of range", kind.letter()),
                    ));
                }
                v as u64
            } else {
                cur.uint()
                    .ok_or_else(|| GcodeError::at(lineno, format!("variable {} needs a number", kind.letter())))?
            };
            if index > u64::from(VAR_MAX) {
                return Err(GcodeError::at(
                    lineno,
                    format!("variable {}{index} is out of range (0 to {VAR_MAX})", kind.letter()),
                ));
            }
            return Ok(self.get(Var {
                kind,
                index: index as u32,
            }));
        }
        let is = |s: &str| run.eq_ignore_ascii_case(s.as_bytes());
        let func = if is("SIN") {
            Func::Sin
        } else if is("COS") {
            Func::Cos
        } else if is("TAN") {
            Func::Tan
        } else if is("ASIN") {
            Func::Asin
        } else if is("ACOS") {
            Func::Acos
        } else if is("ATAN") {
            if cur.eat(b'2') { Func::Atan2 } else { Func::Atan }
        } else if is("LN") {
            Func::Ln
        } else if is("EXP") {
            Func::Exp
        } else if is("SQRT") {
            Func::Sqrt
        } else if is("ABS") {
            Func::Abs
        } else if is("INT") {
            Func::Int
        } else {
            return Err(GcodeError::at(
                lineno,
                format!("unknown function or variable '{}' in expression", cur.snippet(start)),
            ));
        };
        cur.skip_ws();
        if !cur.eat(b'(') {
            return Err(GcodeError::at(
                lineno,
                format!("function '{}' needs its argument in parentheses", cur.snippet(start)),
            ));
        }
        let a = self.expr(cur, depth + 1, lineno)?;
        cur.skip_ws();
        if !cur.eat(b')') {
            return Err(GcodeError::at(lineno, "expression without closing ')'"));
        }
        // Angles in degrees, as on a controller with I15 = 0 (the default).
        Ok(match func {
            Func::Sin => a.to_radians().sin(),
            Func::Cos => a.to_radians().cos(),
            Func::Tan => a.to_radians().tan(),
            Func::Asin => a.asin().to_degrees(),
            Func::Acos => a.acos().to_degrees(),
            Func::Atan => a.atan().to_degrees(),
            // PMAC's ATAN2 takes the cosine argument from Q0.
            Func::Atan2 => a
                .atan2(self.get(Var {
                    kind: VarKind::Q,
                    index: 0,
                }))
                .to_degrees(),
            Func::Ln => a.ln(),
            Func::Exp => a.exp(),
            Func::Sqrt => a.sqrt(),
            Func::Abs => a.abs(),
            // Truncation towards minus infinity, per the Turbo PMAC manual.
            Func::Int => a.floor(),
        })
    }
}

#[cfg(test)]
mod vars_tests {
    use super::*;

    #[test]
    fn unset_variables_read_zero_and_assignments_stick_in_every_family() {
        let mut vars = Vars::new();
        let all = [VarKind::P, VarKind::Q, VarKind::M, VarKind::I]
            .into_iter()
            .flat_map(|kind| [0, 1, 255, 256, 4000, VAR_MAX].map(|index| Var { kind, index }));
        for v in all.clone() {
            assert_eq!(vars.get(v).to_bits(), 0.0f64.to_bits());
        }
        for (k, v) in all.clone().enumerate() {
            vars.set(v, k as f64 + 0.5);
        }
        for (k, v) in all.enumerate() {
            assert_eq!(vars.get(v), k as f64 + 0.5, "{}", v.name());
        }
        // A negative zero is a value, not "unset".
        let m7 = Var {
            kind: VarKind::M,
            index: 7000,
        };
        vars.set(m7, -0.0);
        assert_eq!(vars.get(m7).to_bits(), (-0.0f64).to_bits());
        vars.set(m7, 0.0);
        assert_eq!(vars.get(m7).to_bits(), 0.0f64.to_bits());
    }
}
