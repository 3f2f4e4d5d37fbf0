//! Any toolpath input a tool accepts: toolpath JSON Lines or G-code of
//! either dialect, told apart by the first non-blank byte (`{` is JSON).
#![warn(missing_docs)]

use crate::cli::{CliError, Input};
use crate::formats::toolpath::ToolpathReader;
use crate::gcode::{Dialect, ProgramReader, ReadOptions};
use crate::model::toolpath::{Header, Record};
use std::io::BufRead;

/// What the input turned out to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceKind {
    /// `microcam.toolpath/1` JSON Lines.
    Toolpath,
    /// G-code text, in the dialect the reader settled on.
    Gcode(Dialect),
}

/// A stream of toolpath records with its header, from either kind of input.
pub struct ToolpathSource {
    /// The toolpath header: read from a JSON input; for G-code, the
    /// dialect's feed unit and the file name as the source.
    pub header: Header,
    /// What the input turned out to be.
    pub kind: SourceKind,
    name: String,
    inner: Inner,
}

enum Inner {
    Json(ToolpathReader<Box<dyn BufRead>>),
    Gcode(ProgramReader<Box<dyn BufRead>>),
}

impl ToolpathSource {
    /// Open `input`; `opts` applies when it is G-code.
    pub fn open(mut input: Input, opts: &ReadOptions) -> Result<Self, CliError> {
        let name = input.name.clone();
        let is_json = {
            let buf = input
                .reader
                .fill_buf()
                .map_err(|e| CliError::input(format!("{name}: {e}")))?;
            buf.iter().find(|c| !c.is_ascii_whitespace()) == Some(&b'{')
        };
        if is_json {
            let r = ToolpathReader::new(input.reader).map_err(|e| CliError::in_file(&name, e))?;
            Ok(ToolpathSource {
                header: r.header().clone(),
                kind: SourceKind::Toolpath,
                name,
                inner: Inner::Json(r),
            })
        } else {
            let mut opts = opts.clone();
            if name != "<stdin>" && opts.source_path.is_none() {
                // PMAC #include names are relative to the including file.
                opts.source_path = Some(std::path::PathBuf::from(&name));
            }
            let r = ProgramReader::new(input.reader, &opts).map_err(|e| CliError::in_file(&name, e))?;
            let d = r.dialect();
            Ok(ToolpathSource {
                header: Header {
                    feed_unit: d.feed_unit(),
                    source: if name == "<stdin>" { None } else { Some(name.clone()) },
                },
                kind: SourceKind::Gcode(d),
                name,
                inner: Inner::Gcode(r),
            })
        }
    }

    /// The input's name for messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Append up to `max` records to `out`; fewer only at the end of the
    /// input. What the iterator yields, in batches: the G-code reader
    /// moves its records straight into `out` (see
    /// [`ProgramReader::next_batch`]).
    pub fn next_batch(&mut self, out: &mut Vec<Record>, max: usize) -> Result<(), CliError> {
        let name = &self.name;
        match &mut self.inner {
            Inner::Gcode(r) => r.next_batch(out, max).map_err(|e| CliError::in_file(name, e)),
            Inner::Json(r) => {
                while out.len() < max {
                    match r.next() {
                        Some(Ok(x)) => out.push(x),
                        Some(Err(e)) => return Err(CliError::in_file(name, e)),
                        None => break,
                    }
                }
                Ok(())
            }
        }
    }
}

impl Iterator for ToolpathSource {
    type Item = Result<Record, CliError>;
    fn next(&mut self) -> Option<Self::Item> {
        let name = &self.name;
        match &mut self.inner {
            Inner::Json(r) => r.next().map(|x| x.map_err(|e| CliError::in_file(name, e))),
            Inner::Gcode(r) => r.next().map(|x| x.map_err(|e| CliError::in_file(name, e))),
        }
    }
}
