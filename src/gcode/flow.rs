//! O-word control flow of the ISO reader, as LinuxCNC runs it: `sub` /
//! `call` (also from files on the subroutine path), `if`, `while`, `do`,
//! `repeat`, `break`, `continue` and `return`. A structure's lines are
//! held from its opening line to its closing line, then run.

use super::*;

/// Lines of a control structure read so far, from its opening line.
pub(super) struct Capture {
    pub(super) label: Vec<u8>,
    pub(super) opener: OKeyword,
    pub(super) lines: Vec<(u64, String)>,
}

/// How a block of lines finished.
#[derive(Debug, PartialEq)]
pub(super) enum Flow {
    Normal,
    Return,
    Break(Vec<u8>),
    Continue(Vec<u8>),
}

/// Deepest subroutine nesting (LinuxCNC allows 10 levels of call).
pub(super) const MAX_CALL_DEPTH: u32 = 64;

/// The keyword that closes a structure opened by `opener`.
pub(super) fn closer_of(opener: OKeyword) -> Option<OKeyword> {
    Some(match opener {
        OKeyword::Sub => OKeyword::EndSub,
        OKeyword::While => OKeyword::EndWhile,
        OKeyword::Do => OKeyword::While,
        OKeyword::If => OKeyword::EndIf,
        OKeyword::Repeat => OKeyword::EndRepeat,
        _ => return None,
    })
}

pub(super) fn label_text(l: &[u8]) -> String {
    String::from_utf8_lossy(l).to_lowercase()
}

impl IsoInterpreter {
    /// The O-word of the normalised line, if it is an O-word line (after an
    /// optional block delete and N word).
    pub(super) fn oline(&self, lineno: u64) -> Result<Option<OLine>, GcodeError> {
        let mut c = Cursor::new(&self.norm);
        if c.peek() == Some(b'/') {
            c.pos += 1;
        }
        if c.peek() == Some(b'N') {
            c.pos += 1;
            if c.number().is_err() {
                return Ok(None);
            }
        }
        if c.peek() != Some(b'O') {
            return Ok(None);
        }
        let mut ol = oword::parse(&self.norm[c.pos..]).map_err(|e| GcodeError::at(lineno, e))?;
        ol.rest += c.pos;
        Ok(Some(ol))
    }

    /// Normalise `text` and evaluate the expression after its O keyword.
    pub(super) fn o_value(&mut self, text: &str, lineno: u64) -> Result<Option<f64>, GcodeError> {
        self.normalise(text.as_bytes(), lineno)?;
        let ol = self
            .oline(lineno)?
            .ok_or_else(|| GcodeError::at(lineno, "expected an O-word line"))?;
        if ol.rest >= self.norm.len() {
            return Ok(None);
        }
        let mut c = Cursor::new(&self.norm[ol.rest..]);
        let v = c.real_value(&self.params).map_err(|e| GcodeError::at(lineno, e))?;
        if !c.at_end() {
            return Err(GcodeError::at(lineno, "unexpected text after the O-word expression"));
        }
        Ok(Some(v))
    }

    pub(super) fn o_condition(&mut self, line: &(u64, String)) -> Result<bool, GcodeError> {
        let v = self
            .o_value(&line.1, line.0)?
            .ok_or_else(|| GcodeError::at(line.0, "this O-word needs a condition in [ ]"))?;
        Ok(v != 0.0)
    }

    pub(super) fn count_iteration(&mut self, lineno: u64) -> Result<(), GcodeError> {
        self.iterations += 1;
        if self.iterations > self.max_iterations {
            return Err(GcodeError::at(
                lineno,
                format!(
                    "more than {} loop iterations: is this loop endless?",
                    self.max_iterations
                ),
            ));
        }
        Ok(())
    }

    /// Index of the next line after `from` that is an O-word with `label`
    /// and one of `keywords`.
    pub(super) fn find_o(
        &mut self,
        lines: &[(u64, String)],
        from: usize,
        label: &[u8],
        keywords: &[OKeyword],
    ) -> Result<Option<(usize, OKeyword)>, GcodeError> {
        for (k, (ln, text)) in lines.iter().enumerate().skip(from + 1) {
            self.normalise(text.as_bytes(), *ln)?;
            if let Some(ol) = self.oline(*ln)?
                && ol.label == label
                && keywords.contains(&ol.keyword)
            {
                return Ok(Some((k, ol.keyword)));
            }
        }
        Ok(None)
    }

    pub(super) fn must_find(
        &mut self,
        lines: &[(u64, String)],
        from: usize,
        label: &[u8],
        kw: OKeyword,
    ) -> Result<usize, GcodeError> {
        self.find_o(lines, from, label, &[kw])?.map(|(k, _)| k).ok_or_else(|| {
            GcodeError::at(
                lines[from].0,
                format!("o{} has no matching {kw:?}", label_text(label)).to_lowercase(),
            )
        })
    }

    /// Run a block of lines with O-word control flow.
    pub(super) fn exec_block(
        &mut self,
        lines: &[(u64, String)],
        out: &mut VecDeque<Record>,
        depth: u32,
    ) -> Result<Flow, GcodeError> {
        let mut pc = 0;
        while pc < lines.len() {
            if self.ended {
                return Ok(Flow::Normal);
            }
            let (ln, text) = (lines[pc].0, &lines[pc].1);
            self.normalise(text.as_bytes(), ln)?;
            if self.norm.is_empty() || self.norm[0] == b'%' {
                pc += 1;
                continue;
            }
            let Some(ol) = self.oline(ln)? else {
                let mut b = Block::new();
                self.parse_block(&mut b, ln)?;
                self.execute(&b, ln, out)?;
                pc += 1;
                continue;
            };
            let label = ol.label.clone();
            match ol.keyword {
                OKeyword::Sub => {
                    let end = self.must_find(lines, pc, &label, OKeyword::EndSub)?;
                    self.subs.insert(label, Rc::new(lines[pc + 1..end].to_vec()));
                    pc = end + 1;
                }
                OKeyword::Call => {
                    self.call(&ol, ln, out, depth)?;
                    pc += 1;
                }
                OKeyword::If => {
                    let mut marks = vec![(pc, OKeyword::If)];
                    loop {
                        let last = marks.last().map_or(pc, |m| m.0);
                        match self.find_o(
                            lines,
                            last,
                            &label,
                            &[OKeyword::ElseIf, OKeyword::Else, OKeyword::EndIf],
                        )? {
                            Some((k, OKeyword::EndIf)) => {
                                marks.push((k, OKeyword::EndIf));
                                break;
                            }
                            Some(m) => marks.push(m),
                            None => {
                                return Err(GcodeError::at(ln, format!("o{} if has no endif", label_text(&label))));
                            }
                        }
                    }
                    let end = marks.last().map_or(pc, |m| m.0);
                    for w in marks.windows(2) {
                        let (k, kw) = w[0];
                        let take = kw == OKeyword::Else || self.o_condition(&lines[k])?;
                        if take {
                            let flow = self.exec_block(&lines[k + 1..w[1].0], out, depth)?;
                            if flow != Flow::Normal {
                                return Ok(flow);
                            }
                            break;
                        }
                    }
                    pc = end + 1;
                }
                OKeyword::While => {
                    let end = self.must_find(lines, pc, &label, OKeyword::EndWhile)?;
                    while self.o_condition(&lines[pc])? {
                        self.count_iteration(ln)?;
                        match self.exec_block(&lines[pc + 1..end], out, depth)? {
                            Flow::Break(l) if l == label => break,
                            Flow::Normal => {}
                            Flow::Continue(l) if l == label => {}
                            other => return Ok(other),
                        }
                        if self.ended {
                            break;
                        }
                    }
                    pc = end + 1;
                }
                OKeyword::Do => {
                    let end = self.must_find(lines, pc, &label, OKeyword::While)?;
                    loop {
                        self.count_iteration(ln)?;
                        match self.exec_block(&lines[pc + 1..end], out, depth)? {
                            Flow::Break(l) if l == label => break,
                            Flow::Normal => {}
                            Flow::Continue(l) if l == label => {}
                            other => return Ok(other),
                        }
                        if self.ended || !self.o_condition(&lines[end])? {
                            break;
                        }
                    }
                    pc = end + 1;
                }
                OKeyword::Repeat => {
                    let n = self
                        .o_value(text, ln)?
                        .ok_or_else(|| GcodeError::at(ln, "repeat needs a count in [ ]"))?;
                    let end = self.must_find(lines, pc, &label, OKeyword::EndRepeat)?;
                    let mut i = 0.0;
                    while i < n.round() {
                        self.count_iteration(ln)?;
                        match self.exec_block(&lines[pc + 1..end], out, depth)? {
                            Flow::Break(l) if l == label => break,
                            Flow::Normal => {}
                            Flow::Continue(l) if l == label => {}
                            other => return Ok(other),
                        }
                        if self.ended {
                            break;
                        }
                        i += 1.0;
                    }
                    pc = end + 1;
                }
                OKeyword::Break => return Ok(Flow::Break(label)),
                OKeyword::Continue => return Ok(Flow::Continue(label)),
                OKeyword::Return | OKeyword::EndSub => {
                    if depth == 0 {
                        return Err(GcodeError::at(ln, "return/endsub outside a subroutine"));
                    }
                    if let Some(v) = self.o_value(text, ln)? {
                        self.params.set(&ParamRef::Named(b"_VALUE".to_vec()), v);
                    }
                    return Ok(Flow::Return);
                }
                kw => {
                    return Err(GcodeError::at(
                        ln,
                        format!("o{} {kw:?} without its opening line", label_text(&label)).to_lowercase(),
                    ));
                }
            }
        }
        Ok(Flow::Normal)
    }

    /// `O<label> call [a] [b] ...`: arguments go to #1, #2 ..., which are
    /// local to the call (restored after it), as in LinuxCNC.
    pub(super) fn call(
        &mut self,
        ol: &OLine,
        lineno: u64,
        out: &mut VecDeque<Record>,
        depth: u32,
    ) -> Result<(), GcodeError> {
        if depth >= MAX_CALL_DEPTH {
            return Err(GcodeError::at(
                lineno,
                format!("subroutine calls nested deeper than {MAX_CALL_DEPTH}"),
            ));
        }
        // The arguments first: reading a subroutine file reuses the line buffer.
        let mut args = Vec::new();
        let mut c = Cursor::new(&self.norm[ol.rest..]);
        while !c.at_end() {
            if args.len() >= 30 {
                return Err(GcodeError::at(lineno, "more than 30 subroutine arguments"));
            }
            args.push(c.real_value(&self.params).map_err(|e| GcodeError::at(lineno, e))?);
        }
        if !self.subs.contains_key(&ol.label) {
            self.load_sub_file(&ol.label, lineno, out, depth)?;
        }
        let body = self.subs.get(&ol.label).cloned().ok_or_else(|| {
            GcodeError::at(
                lineno,
                format!(
                    "o{} is called before its definition (define subroutines before calling them, or give the folder of {}.ngc with --subroutine-path)",
                    label_text(&ol.label),
                    label_text(&ol.label)
                ),
            )
        })?;
        let saved: Vec<f64> = (1..=30)
            .map(|i| self.params.get(&ParamRef::Num(i)).unwrap_or(0.0))
            .collect();
        for i in 1..=30 {
            self.params
                .set(&ParamRef::Num(i), args.get(i - 1).copied().unwrap_or(0.0));
        }
        self.params.push_frame();
        let flow = self.exec_block(&body, out, depth + 1);
        self.params.pop_frame();
        for (i, v) in saved.into_iter().enumerate() {
            self.params.set(&ParamRef::Num(i + 1), v);
        }
        match flow? {
            Flow::Normal | Flow::Return => Ok(()),
            Flow::Break(l) | Flow::Continue(l) => Err(GcodeError::at(
                lineno,
                format!("break/continue o{} escaped its subroutine", label_text(&l)),
            )),
        }
    }

    /// Define subroutine `label` from `label.ngc` in the first folder of
    /// the subroutine path that has it, as LinuxCNC does: the file's lines
    /// are run (they hold the `sub ... endsub`), so the definition exists
    /// after. Nothing when no folder has the file.
    pub(super) fn load_sub_file(
        &mut self,
        label: &[u8],
        lineno: u64,
        out: &mut VecDeque<Record>,
        depth: u32,
    ) -> Result<(), GcodeError> {
        let name = format!("{}.ngc", label_text(label));
        let Some(path) = self.sub_path.iter().map(|d| d.join(&name)).find(|p| p.is_file()) else {
            return Ok(());
        };
        let text = std::fs::read(&path).map_err(|e| GcodeError::Io {
            line: lineno,
            source: e,
        })?;
        let lines: Vec<(u64, String)> = String::from_utf8_lossy(&text)
            .lines()
            .enumerate()
            .map(|(k, l)| (k as u64 + 1, l.trim_end_matches('\r').to_string()))
            .collect();
        self.exec_block(&lines, out, depth + 1)
            .map_err(|e| GcodeError::at(lineno, format!("in {}: {e}", path.display())))?;
        Ok(())
    }
}
