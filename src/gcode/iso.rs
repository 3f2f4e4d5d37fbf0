//! ISO/RS274 interpreter (being written).

use super::{GcodeError, LineInterpreter, ReadOptions};
use crate::model::toolpath::Record;
use std::collections::VecDeque;

pub struct IsoInterpreter {}

impl IsoInterpreter {
    pub fn new(_opts: &ReadOptions) -> Self {
        IsoInterpreter {}
    }
}

impl LineInterpreter for IsoInterpreter {
    fn line(&mut self, _text: &str, lineno: u64, _out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        Err(GcodeError::at(lineno, "ISO reading is not available yet"))
    }
    fn finish(&mut self, _lineno: u64, _out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        Ok(())
    }
    fn ended(&self) -> bool {
        false
    }
}
