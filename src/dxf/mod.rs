//! DXF import: from an ASCII or binary DXF file (R12 and older to current)
//! to exact lines and arcs in millimetres, ready for chaining.
//!
//! - [`reader`]: the streaming group-code tokenizer (ASCII and binary).
//! - [`entities`]: one entity's tags to a typed [`entities::EntityShape`].
//! - [`ocs`]: affine maps and the Object Coordinate System.
//! - [`expand`]: blocks, inserts, units and transforms applied; curves fitted.
//! - [`curves`]: ellipses and splines as biarcs within a tolerance.
//! - [`units`]: `$INSUNITS` and unit names.
//! - [`chain`]: joining segments into oriented, repaired chains.
//! - [`svg`]: a preview of the chains.
//! - [`transform`]: the user's move / rotate / scale / mirror / patterns.
//! - [`summary`]: the stderr report.
//!
//! The file is read once, front to back; ENTITIES are expanded as they are
//! read (from the first SPLINE on, in batches whose splines are fitted on
//! the thread pool: `batch.rs`), so memory holds the block definitions and
//! the output geometry but never the whole file. See docs/dxf.md.
#![warn(missing_docs)]

mod batch;
pub mod chain;
pub mod curves;
pub mod entities;
pub mod expand;
pub mod ocs;
mod place;
pub mod reader;
pub mod summary;
pub mod svg;
pub mod tokens;
pub mod transform;
pub mod units;

use entities::{EntityShape, Read, Scratch};
use expand::{BlockDef, Expander, Sink};
use ocs::Affine;
use reader::{DxfError, Reader};
use std::collections::{BTreeMap, HashMap};
use std::io::BufRead;

/// What to import and how.
#[derive(Debug, Clone)]
pub struct ImportOptions {
    /// Fitting tolerance for splines and ellipses (mm).
    pub arc_tol: f64,
    /// Layers to keep; empty keeps all.
    pub layers: Vec<String>,
    /// Millimetres per drawing unit, overriding `$INSUNITS`.
    pub units_mm: Option<f64>,
    /// User transforms (in mm), one per copy of the drawing; empty means
    /// one untransformed copy.
    pub copies: Vec<Affine>,
    /// Give up when the drawing expands to more segments than this (block
    /// bombs: arrays of inserts of arrays...).
    pub max_segments: usize,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            arc_tol: 0.001,
            layers: Vec::new(),
            units_mm: None,
            copies: Vec::new(),
            max_segments: expand::MAX_SEGMENTS,
        }
    }
}

/// Where the unit scale came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UnitSource {
    /// `$INSUNITS` with this code.
    Header(i64),
    /// `--units`.
    Option,
    /// Neither: millimetres assumed.
    Assumed,
}

/// The drawing as geometry, with what was counted on the way.
#[derive(Debug)]
pub struct Import {
    /// The geometry in millimetres (segments, points, layers) and what
    /// the expansion counted and warned about.
    pub sink: Sink,
    /// Entity types not turned into geometry, with counts.
    pub skipped: BTreeMap<String, u64>,
    /// Millimetres per drawing unit, as applied.
    pub unit_mm: f64,
    /// Where `unit_mm` came from.
    pub unit_source: UnitSource,
    /// `$ACADVER` (such as `AC1015`), when the header states it.
    pub version: Option<String>,
    /// The file was a binary DXF.
    pub binary: bool,
}

#[derive(PartialEq)]
enum Section {
    None,
    Header,
    Blocks,
    Entities,
    Other,
}

/// Read a whole DXF file (ASCII or binary, sniffed) into geometry in
/// millimetres with every copy of [`ImportOptions::copies`] applied. Fails
/// on a malformed or truncated file, and on a drawing that expands past
/// [`ImportOptions::max_segments`] or beyond [`expand::MAX_COORD`].
pub fn import(input: Box<dyn BufRead>, opts: &ImportOptions) -> Result<Import, DxfError> {
    let mut r = Reader::new(input)?;
    let binary = r.is_binary();
    let (mut events, rx) = place::channel();
    #[cfg(test)]
    let unbatched = batch::unbatched();
    let (parsed, placed) = std::thread::scope(|s| {
        let placer = s.spawn(move || {
            #[cfg(test)]
            batch::set_unbatched(unbatched);
            place::place(rx, opts)
        });
        let parsed = parse(&mut r, opts, &mut events);
        // The placer ends at the End or Error event, or when the channel
        // closes (the parser stopped because the placer had).
        drop(events);
        let placed = placer.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
        (parsed, placed)
    });
    let mut sink = placed?;
    // Give back the growth slack of the geometry array before chaining
    // starts allocating (a shrink of a large block is a remap, not a copy).
    sink.segments.shrink_to_fit();
    let (unit_mm, unit_source) = unit_of(opts, parsed.insunits);
    Ok(Import {
        sink,
        skipped: parsed.skipped,
        unit_mm,
        unit_source,
        version: parsed.version,
        binary,
    })
}

/// Why the parser stopped before the end of the file.
enum Halt {
    /// The file is bad here: sent on to the placer as the last event.
    Error(DxfError),
    /// The placer stopped first (its own error is the import's).
    Stopped(place::Stopped),
}

impl From<DxfError> for Halt {
    fn from(e: DxfError) -> Halt {
        Halt::Error(e)
    }
}

impl From<place::Stopped> for Halt {
    fn from(s: place::Stopped) -> Halt {
        Halt::Stopped(s)
    }
}

/// What only the parser sees: the header's variables and the entities
/// it skipped.
#[derive(Default)]
struct Parsed {
    skipped: BTreeMap<String, u64>,
    insunits: Option<i64>,
    version: Option<String>,
}

/// The entity state machine over the whole file: sections, header
/// variables, block definitions and top-level entities, sent to the
/// placer in file order. Ends with [`place::Event::End`] or
/// [`place::Event::Error`], or early when the placer has stopped.
fn parse(r: &mut Reader, opts: &ImportOptions, events: &mut place::Events) -> Parsed {
    let mut parsed = Parsed::default();
    let mut scratch = Scratch::default();
    let mut section = Section::None;
    let mut tops_sent = false;
    let mut seen_anything = false;
    let mut saw_eof = false;
    // The current `0` tag's text, in one buffer reused for every entity.
    let mut tag = String::new();
    let mut read = |events: &mut place::Events| -> Result<(), Halt> {
        while let Some(code) = r.next_tag()? {
            seen_anything = true;
            if code == 9 && section == Section::Header {
                let var = r.text().trim().to_string();
                if var == "$INSUNITS" || var == "$ACADVER" {
                    match r.next_tag()? {
                        Some(70) if var == "$INSUNITS" => parsed.insunits = Some(r.int()),
                        Some(1) if var == "$ACADVER" => parsed.version = Some(r.text().trim().to_string()),
                        Some(_) => r.unread(),
                        None => break,
                    }
                }
                continue;
            }
            if code != 0 {
                continue;
            }
            tag.clear();
            tag.push_str(r.text().trim());
            if matches!(tag.as_str(), "SECTION" | "ENDSEC" | "EOF") {
                events.send(place::Event::SectionBoundary)?;
            }
            match tag.as_str() {
                "SECTION" => {
                    section = match r.next_tag()? {
                        Some(2) => match r.text().trim() {
                            "HEADER" => Section::Header,
                            "BLOCKS" => Section::Blocks,
                            "ENTITIES" => Section::Entities,
                            _ => Section::Other,
                        },
                        Some(c) => {
                            return Err(DxfError::at(
                                r.pos,
                                format!("SECTION must be followed by group code 2 (its name), found {c}"),
                            )
                            .into());
                        }
                        None => return Err(DxfError::at(r.pos, "file ends after SECTION: truncated file?").into()),
                    };
                    continue;
                }
                "ENDSEC" => {
                    section = Section::None;
                    continue;
                }
                "EOF" => {
                    saw_eof = true;
                    break;
                }
                _ => {}
            }
            match section {
                Section::Blocks if tag == "BLOCK" => {
                    let (name, block) = read_block(r, &mut scratch, &mut parsed.skipped)?;
                    events.send(place::Event::Block(name, block))?;
                }
                // Entities outside any section: some minimal writers omit the
                // SECTION lines altogether.
                Section::Entities | Section::None => {
                    if !tops_sent {
                        tops_sent = true;
                        events.send(place::Event::Tops(top_transforms(opts, parsed.insunits)))?;
                    }
                    match entities::read_entity(&tag, r, &mut scratch)? {
                        Read::Skipped(k) => *parsed.skipped.entry(k).or_default() += 1,
                        Read::Entity(e) => events.send(place::Event::Entity(e))?,
                    }
                }
                _ => {}
            }
        }
        events.send(place::Event::SectionBoundary)?;
        Ok(())
    };
    let last = match read(events) {
        Err(Halt::Stopped(place::Stopped)) => return parsed,
        Err(Halt::Error(e)) => place::Event::Error(e),
        Ok(()) if !seen_anything => {
            place::Event::Error(DxfError::at(reader::Pos::Line(1), "empty input: not a DXF file"))
        }
        // Every writer ends with 0/EOF; its absence means the file was cut.
        Ok(()) if !saw_eof => {
            place::Event::Error(DxfError::at(r.pos, "file ends without the EOF marker: truncated file?"))
        }
        Ok(()) => place::Event::End,
    };
    // A failed send means the placer stopped first, with its own error.
    let _ = events.send(last);
    parsed
}

fn expander<'a>(blocks: &'a HashMap<String, BlockDef>, opts: &'a ImportOptions) -> Expander<'a> {
    Expander {
        blocks,
        arc_tol: opts.arc_tol,
        layers: &opts.layers,
        max_segments: opts.max_segments,
    }
}

/// Expand every entity the batches hold (they hold some only once `tops`
/// is set, at the first entity).
fn finish(
    batches: &mut batch::Batches,
    blocks: &HashMap<String, BlockDef>,
    tops: &Option<Vec<Affine>>,
    sink: &mut Sink,
    opts: &ImportOptions,
) -> Result<(), DxfError> {
    batches.finish(&mut batch::Expansion {
        x: &expander(blocks, opts),
        tops: tops.as_deref().unwrap_or(&[]),
        sink,
        after: |sink: &mut Sink, pos| stopped(sink, pos, opts.max_segments),
    })
}

/// The error that stopped the expansion of the top-level entity at `top`,
/// if any.
fn stopped(sink: &mut Sink, top: reader::Pos, max: usize) -> Result<(), DxfError> {
    if let Some((pos, msg)) = sink.bad.take() {
        if pos == top {
            return Err(DxfError::at(pos, msg));
        }
        return Err(DxfError::at(pos, format!("{msg}, as placed by the INSERT at {top}")));
    }
    if sink.overflow {
        return Err(DxfError::at(
            top,
            format!(
                "this entity expands the drawing past {max} segments or entities (blocks inserted in arrays of arrays?)"
            ),
        ));
    }
    Ok(())
}

fn unit_of(opts: &ImportOptions, insunits: Option<i64>) -> (f64, UnitSource) {
    if let Some(u) = opts.units_mm {
        return (u, UnitSource::Option);
    }
    match insunits.and_then(|c| units::insunits_mm(c).map(|mm| (mm, c))) {
        Some((mm, c)) => (mm, UnitSource::Header(c)),
        None => (1.0, UnitSource::Assumed),
    }
}

fn top_transforms(opts: &ImportOptions, insunits: Option<i64>) -> Vec<Affine> {
    let (mm, _) = unit_of(opts, insunits);
    let unit = Affine::scale(mm, mm, mm);
    if opts.copies.is_empty() {
        vec![unit]
    } else {
        opts.copies.iter().map(|c| c.then_after(&unit)).collect()
    }
}

/// A BLOCK definition up to ENDBLK.
fn read_block(
    r: &mut Reader,
    scratch: &mut Scratch,
    skipped: &mut BTreeMap<String, u64>,
) -> Result<(String, BlockDef), DxfError> {
    let start = r.pos;
    let mut name = String::new();
    let mut base = crate::geometry::P3::origin();
    while let Some(code) = r.next_tag()? {
        match code {
            0 => {
                r.unread();
                break;
            }
            2 => name = r.text().trim().to_uppercase(),
            10 => base.x = r.float(),
            20 => base.y = r.float(),
            30 => base.z = r.float(),
            _ => {}
        }
    }
    let mut block = BlockDef {
        base,
        entities: Vec::new(),
    };
    loop {
        match r.next_tag()? {
            None => {
                return Err(DxfError::at(
                    start,
                    format!("BLOCK '{name}' has no ENDBLK: truncated file?"),
                ));
            }
            Some(0) => {}
            Some(c) => {
                return Err(DxfError::at(
                    r.pos,
                    format!("unexpected group code {c} in BLOCK '{name}'"),
                ));
            }
        }
        let tag = r.text().trim().to_string();
        match tag.as_str() {
            "ENDBLK" => {
                // Its own tags (handle, layer) mean nothing to us.
                while let Some(c) = r.next_tag()? {
                    if c == 0 {
                        r.unread();
                        break;
                    }
                }
                break;
            }
            "ENDSEC" | "EOF" => {
                return Err(DxfError::at(
                    r.pos,
                    format!("BLOCK '{name}' ends with {tag} instead of ENDBLK"),
                ));
            }
            _ => match entities::read_entity(&tag, r, scratch)? {
                Read::Skipped(k) => *skipped.entry(k).or_default() += 1,
                Read::Entity(mut e) => {
                    if let EntityShape::Insert(ins) = &mut e.shape {
                        ins.block = ins.block.to_uppercase();
                    }
                    block.entities.push(e);
                }
            },
        }
    }
    Ok((name, block))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn run(text: &str, opts: &ImportOptions) -> Result<Import, DxfError> {
        import(Box::new(Cursor::new(text.as_bytes().to_vec())), opts)
    }

    #[test]
    fn inch_header_scales_and_blocks_insert() {
        let t = "0\nSECTION\n2\nHEADER\n9\n$INSUNITS\n70\n1\n0\nENDSEC\n\
                 0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n2\nb1\n10\n0\n20\n0\n0\nLINE\n10\n0\n20\n0\n11\n1\n21\n0\n0\nENDBLK\n0\nENDSEC\n\
                 0\nSECTION\n2\nENTITIES\n0\nINSERT\n2\nB1\n10\n1\n20\n0\n0\nTEXT\n1\nhi\n0\nENDSEC\n0\nEOF\n";
        let imp = run(t, &ImportOptions::default()).unwrap();
        assert_eq!(imp.unit_source, UnitSource::Header(1));
        assert_eq!(imp.sink.segments.len(), 1);
        let (s, _) = imp.sink.segments[0];
        assert!((s.end().x - 50.8).abs() < 1e-12);
        assert_eq!(imp.skipped.get("TEXT"), Some(&1));
    }

    #[test]
    fn units_option_wins_and_missing_header_is_assumed() {
        let t = "0\nSECTION\n2\nENTITIES\n0\nLINE\n10\n0\n20\n0\n11\n1\n21\n0\n0\nENDSEC\n0\nEOF\n";
        let imp = run(t, &ImportOptions::default()).unwrap();
        assert_eq!(imp.unit_source, UnitSource::Assumed);
        let o = ImportOptions {
            units_mm: Some(10.0),
            ..Default::default()
        };
        let imp = run(t, &o).unwrap();
        assert_eq!(imp.sink.segments[0].0.end().x, 10.0);
    }

    #[test]
    fn layer_filter() {
        let t = "0\nSECTION\n2\nENTITIES\n0\nLINE\n8\nA\n10\n0\n20\n0\n11\n1\n21\n0\n0\nLINE\n8\nB\n10\n0\n20\n0\n11\n1\n21\n0\n0\nENDSEC\n0\nEOF\n";
        let o = ImportOptions {
            layers: vec!["B".into()],
            ..Default::default()
        };
        let imp = run(t, &o).unwrap();
        assert_eq!(imp.sink.segments.len(), 1);
        assert_eq!(imp.sink.layers, vec!["B".to_string()]);
    }

    #[test]
    fn block_bombs_stop_with_a_located_error() {
        let t = "0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n2\nA\n0\nLINE\n10\n0\n20\n0\n11\n1\n21\n0\n0\nENDBLK\n\
                 0\nBLOCK\n2\nB\n0\nINSERT\n2\nA\n70\n1000\n71\n1000\n44\n2\n45\n2\n0\nENDBLK\n0\nENDSEC\n\
                 0\nSECTION\n2\nENTITIES\n0\nLINE\n10\n0\n20\n0\n11\n1\n21\n0\n\
                 0\nINSERT\n2\nB\n70\n100\n71\n100\n44\n3000\n45\n3000\n0\nENDSEC\n0\nEOF\n";
        let o = ImportOptions {
            max_segments: 10_000,
            ..Default::default()
        };
        let e = run(t, &o).unwrap_err().to_string();
        assert!(e.starts_with("line 55:") && e.contains("10000 segments"), "{e}");
    }

    /// The placer runs behind the parser: an entity past the bound must
    /// still be the error reported when the parser has gone on to a
    /// syntax error twenty thousand entities later (the placer stops, the
    /// parser's sends fail and it stops too), and a syntax error after a
    /// long run of good entities is reported once every one of them is
    /// placed.
    #[test]
    fn errors_come_in_file_order_across_the_pipeline() {
        let line = "0\nLINE\n8\nL\n10\n0\n20\n0\n11\n1\n21\n0\n";
        let mut t = String::from("0\nSECTION\n2\nENTITIES\n");
        t.push_str(&line.repeat(20_000));
        // The value line of the 20,001st entity's group 10.
        let bad = 4 + 12 * 20_000 + 4;
        t.push_str("0\nLINE\n10\nnot-a-number\n0\nENDSEC\n0\nEOF\n");
        let o = ImportOptions {
            max_segments: 40,
            ..Default::default()
        };
        // The 41st entity (its `0` on line 4 + 12 * 40 + 1) passes the bound.
        let e = run(&t, &o).unwrap_err().to_string();
        assert!(e.starts_with("line 485:") && e.contains("40 segments"), "{e}");
        let e = run(&t, &ImportOptions::default()).unwrap_err().to_string();
        assert!(e.starts_with(&format!("line {bad}:")), "{e}");
        // And a good ending: every entity placed, in order.
        let good = t.replace("0\nLINE\n10\nnot-a-number\n", "");
        let imp = run(&good, &ImportOptions::default()).unwrap();
        assert_eq!(imp.sink.segments.len(), 20_000);
        assert!(imp.sink.segments.iter().all(|(s, _)| s.end().x == 1.0));
    }

    /// A cubic spline through a zigzag of `n` control points, the file's
    /// last entity (its `0`/`SPLINE` on line 5).
    fn zigzag_spline(n: usize) -> String {
        let mut t = String::from("0\nSECTION\n2\nENTITIES\n0\nSPLINE\n71\n3\n");
        for i in 0..n {
            t += &format!("10\n{}\n20\n{}\n30\n0\n", i, (i % 2) as f64 * 3.0);
        }
        t + "0\nENDSEC\n0\nEOF\n"
    }

    #[test]
    fn a_curve_past_the_bound_stops_its_fit_and_names_itself() {
        let t = zigzag_spline(60);
        let all = run(&t, &ImportOptions::default()).unwrap();
        let pieces = all.sink.segments.len();
        assert!(pieces > 200, "{pieces}");
        // Within the bound: the same pieces, bound or not.
        let o = ImportOptions {
            max_segments: pieces,
            ..Default::default()
        };
        assert_eq!(run(&t, &o).unwrap().sink.segments, all.sink.segments);
        // One short: the spline, though the last entity, is named as the
        // one that takes the drawing past the bound (the check used to run
        // only before each entity, so the last one went through).
        let o = ImportOptions {
            max_segments: pieces - 1,
            ..Default::default()
        };
        let e = run(&t, &o).unwrap_err().to_string();
        assert!(e.starts_with("line 5:") && e.contains("past"), "{e}");
    }

    #[test]
    fn truncated_block_and_empty_input() {
        let t = "0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n2\nX\n0\nLINE\n10\n0\n";
        let e = run(t, &ImportOptions::default()).unwrap_err().to_string();
        assert!(e.contains("line"), "{e}");
        assert!(run("", &ImportOptions::default()).is_err());
    }
}

#[cfg(test)]
mod hostile_tests;
