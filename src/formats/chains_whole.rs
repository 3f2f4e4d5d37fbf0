//! Reading a whole chains stream on every core. Contouring, pocketing and
//! gsim's per-chain report need every chain before they start, so nothing
//! is lost by holding the text;
//! parsing JSON is then the largest serial cost, so the text is cut at line
//! boundaries into chunks that the streaming reader parses in parallel.
//! Errors keep the line numbers of the whole stream.

use crate::formats::FormatError;
use crate::formats::chains::ChainsReader;
use crate::model::chain::{Chain, ChainsHeader};
use rayon::prelude::*;
use std::io::BufRead;

/// Bytes per parallel chunk: large enough to amortise the per-chunk
/// header parse, small enough to balance across cores.
const CHUNK: usize = 1 << 20;

/// Read a `microcam.chains/1` stream: the header and every chain, in order.
pub fn read_chains(mut input: impl BufRead) -> Result<(ChainsHeader, Vec<Chain>), FormatError> {
    let mut text = String::new();
    input
        .read_to_string(&mut text)
        .map_err(|e| FormatError::Io { line: 0, source: e })?;
    // The header is the first non-blank line; its validation is the reader's.
    let mut line_no = 0u64;
    let mut rest = text.as_str();
    let header_line = loop {
        let (line, tail) = rest.split_once('\n').unwrap_or((rest, ""));
        line_no += 1;
        rest = tail;
        if !line.trim().is_empty() || tail.is_empty() {
            break line;
        }
    };
    let header = ChainsReader::new(header_line.as_bytes())
        .map_err(|e| renumber(e, line_no - 1))?
        .header()
        .clone();
    // Chunks of whole lines, each with the stream line number of its first line.
    let mut chunks: Vec<(u64, &str)> = Vec::new();
    let mut first = line_no + 1;
    while !rest.is_empty() {
        let cut = if rest.len() <= CHUNK {
            rest.len()
        } else {
            rest[CHUNK..].find('\n').map_or(rest.len(), |i| CHUNK + i + 1)
        };
        let (chunk, tail) = rest.split_at(cut);
        chunks.push((first, chunk));
        first += chunk.bytes().filter(|&b| b == b'\n').count() as u64;
        rest = tail;
    }
    let parsed: Vec<Result<Vec<Chain>, FormatError>> = chunks
        .par_iter()
        .map(|&(first, chunk)| {
            let mut buf = String::with_capacity(header_line.len() + 1 + chunk.len());
            buf.push_str(header_line);
            buf.push('\n');
            buf.push_str(chunk);
            // In `buf` the chunk's first line is line 2.
            let reader = ChainsReader::new(buf.as_bytes()).map_err(|e| renumber(e, first - 2))?;
            reader
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| renumber(e, first - 2))
        })
        .collect();
    let mut chains = Vec::new();
    for p in parsed {
        chains.extend(p?);
    }
    Ok((header, chains))
}

fn renumber(e: FormatError, offset: u64) -> FormatError {
    match e {
        FormatError::Invalid { line, msg } => FormatError::Invalid {
            line: line + offset,
            msg,
        },
        FormatError::Io { line, source } => FormatError::Io {
            line: line + offset,
            source,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain_line(id: usize) -> String {
        format!(
            "{{\"id\":{id},\"closed\":false,\"segments\":[{{\"type\":\"line\",\"start\":[{id},0],\"end\":[{id},1]}}]}}\n"
        )
    }

    #[test]
    fn parallel_read_equals_the_streaming_reader_and_keeps_line_numbers() {
        let mut text = String::from("\n{\"schema\":\"microcam.chains/1\",\"units\":\"mm\"}\n");
        for i in 0..60_000 {
            text.push_str(&chain_line(i));
            if i % 7 == 0 {
                text.push('\n');
            }
        }
        let (_, got) = read_chains(text.as_bytes()).unwrap();
        let want: Vec<Chain> = ChainsReader::new(text.as_bytes())
            .unwrap()
            .map(|c| c.unwrap())
            .collect();
        assert_eq!(got, want);
        // A bad record deep in a later chunk reports its line in the stream.
        let bad = text.clone() + "{\"id\":1}\n";
        let want_line = ChainsReader::new(bad.as_bytes())
            .unwrap()
            .find_map(|c| c.err())
            .unwrap()
            .line();
        let e = read_chains(bad.as_bytes()).unwrap_err();
        assert_eq!(e.line(), want_line);
        assert!(e.to_string().contains("needs 'closed'"), "{e}");
        let e = read_chains("{\"schema\":\"microcam.toolpath/1\"}\n".as_bytes()).unwrap_err();
        assert!(e.to_string().contains("unknown schema"), "{e}");
    }
}
