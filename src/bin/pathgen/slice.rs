//! `pathgen slice` (planar sections of a mesh as chains) and `pathgen
//! mesh-info` (the topology report as JSON). Included from pathgen.rs.

use clap::{Args as ClapArgs, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::formats::chains::ChainsWriter;
use microcam::mesh::topology::{Prepared, prepare};
use microcam::mesh::{Format, LoadedMesh, ReadOptions, Units, read_bytes};
use microcam::model::chain::ChainsHeader;
use microcam::progress::{self, Meter, Show};
use microcam::slice::{self, SliceOptions};
use std::io::{Read, Write};
use std::path::PathBuf;

pub const SLICE_EXAMPLES: &str = "\
Examples:
  pathgen slice part.stl --z-step 0.01 > sections.jsonl      every 10 um from the top down
  pathgen slice part.stl --z-step 0.05 --from bottom --arc-tol 0.0005
  pathgen slice part.obj --levels 0.5,1,1.5 --units inch
  cat part.stl | pathgen slice --levels 2.0

Sections are closed chains (microcam.chains/1) with Z on every point, one
chain per loop: outer boundaries counter-clockwise (layer \"outer\"), holes
clockwise (layer \"hole\"), levels in order. The mesh is welded
(--weld-tol) and repaired first; repairs and joined gaps are warned on
stderr. A vertex exactly at a level counts as below it (the section just
above the plane): a level at a flat bottom gives its outline, at a flat
top nothing. Method: Bayesteh (2013), planar sections of a model filled
by the beam level by level. Exit status: 0 ok, 1 failure, 2 bad usage or
bad input (malformed mesh: the line or byte offset is named).";

pub const INFO_EXAMPLES: &str = "\
Examples:
  pathgen mesh-info part.stl               topology before and after repair
  pathgen mesh-info --units inch part.obj

Prints one JSON object: the file's format, groups and reader notes, what
welding did, the topology (triangles, vertices, edges, boundary and
non-manifold edges, degenerate and duplicate triangles, inconsistent edges,
parts, watertight, volume_mm3 when closed, area_mm2, bbox_mm) before and
after the repairs, and the repairs done. Exit status: 0 ok, 1 failure, 2
bad usage or bad input.";

/// Length unit of the mesh file (STL carries none).
#[derive(Clone, Copy, ValueEnum)]
pub enum UnitsArg {
    Mm,
    Inch,
    Um,
}

/// Mesh file format, when neither the extension nor the content tells.
#[derive(Clone, Copy, ValueEnum)]
pub enum FormatArg {
    Stl,
    Obj,
}

/// Where --z-step levels start.
#[derive(Clone, Copy, ValueEnum, PartialEq)]
pub enum From {
    /// One step below the top, downwards.
    Top,
    /// At the bottom, upwards.
    Bottom,
}

/// Reading a mesh: the options slice and mesh-info share.
#[derive(ClapArgs)]
pub struct MeshInput {
    /// STL (ASCII or binary) or OBJ file; '-' or none for stdin.
    file: Option<PathBuf>,
    /// Unit of the file's coordinates.
    #[arg(long, value_enum, default_value = "mm")]
    units: UnitsArg,
    /// Format, when the extension and content do not tell.
    #[arg(long, value_enum)]
    format: Option<FormatArg>,
    /// Vertices closer than this are welded into one (mm).
    #[arg(long, default_value_t = 1e-6)]
    weld_tol: f64,
}

#[derive(ClapArgs)]
pub struct SliceArgs {
    #[command(flatten)]
    input: MeshInput,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
    /// Distance between levels (mm).
    #[arg(long, conflicts_with = "levels")]
    z_step: Option<f64>,
    /// Where --z-step starts.
    #[arg(long, value_enum, default_value = "top")]
    from: From,
    /// Explicit levels, comma-separated (mm).
    #[arg(long, value_delimiter = ',')]
    levels: Vec<f64>,
    /// Open ends of the section closer than this are joined, with a warning (mm).
    #[arg(long, default_value_t = 1e-3)]
    join_tol: f64,
    /// Fit arcs through the section points within this (mm); 0 keeps polygons.
    #[arg(long, default_value_t = 0.0)]
    arc_tol: f64,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

#[derive(ClapArgs)]
pub struct MeshInfoArgs {
    #[command(flatten)]
    input: MeshInput,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn load(inp: &MeshInput) -> Result<(String, LoadedMesh, Prepared), CliError> {
    if !(inp.weld_tol >= 0.0 && inp.weld_tol.is_finite()) {
        return Err(CliError::input(format!(
            "--weld-tol must be >= 0, got {}",
            inp.weld_tol
        )));
    }
    let mut input = cli::open_input(inp.file.as_deref())?;
    let name = input.name.clone();
    let mut bytes = Vec::new();
    input
        .reader
        .read_to_end(&mut bytes)
        .map_err(|e| CliError::failure(format!("{name}: {e}")))?;
    let ext = inp
        .file
        .as_deref()
        .and_then(|p| p.extension())
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let format = match inp.format {
        Some(FormatArg::Stl) => Some(Format::Stl),
        Some(FormatArg::Obj) => Some(Format::Obj),
        None => match ext.as_deref() {
            Some("stl") => Some(Format::Stl),
            Some("obj") => Some(Format::Obj),
            _ => None,
        },
    };
    let units = match inp.units {
        UnitsArg::Mm => Units::Mm,
        UnitsArg::Inch => Units::Inch,
        UnitsArg::Um => Units::Um,
    };
    let m = read_bytes(&bytes, &ReadOptions { units, format }).map_err(|e| CliError::in_file(&name, e))?;
    let p = prepare(&m.mesh, inp.weld_tol);
    Ok((name, m, p))
}

pub fn slice_cmd(a: SliceArgs) -> Result<(), CliError> {
    if !(a.join_tol >= 0.0 && a.join_tol.is_finite() && a.arc_tol >= 0.0 && a.arc_tol.is_finite()) {
        return Err(CliError::input("--join-tol and --arc-tol must be finite and >= 0"));
    }
    let levels: Vec<f64> = if let Some(step) = a.z_step {
        if !(step > 0.0 && step.is_finite()) {
            return Err(CliError::input(format!("--z-step must be > 0, got {step}")));
        }
        Vec::new()
    } else if a.levels.is_empty() {
        return Err(CliError::input("give --z-step or --levels"));
    } else if a.levels.iter().any(|z| !z.is_finite()) {
        return Err(CliError::input("--levels must be finite numbers"));
    } else {
        a.levels.clone()
    };
    let (name, _m, p) = load(&a.input)?;
    for r in &p.repairs {
        microcam::diag!("pathgen: slice: {name}: repaired: {r}");
    }
    if !p.after.watertight {
        microcam::diag!(
            "pathgen: slice: {name}: warning: the mesh is not watertight ({} boundary, {} non-manifold edges): sections may have gaps",
            p.after.boundary_edges,
            p.after.non_manifold_edges
        );
    }
    let levels = match a.z_step {
        Some(step) => {
            let b = p.mesh.bbox();
            let n = ((b.max.z - b.min.z) / step).floor();
            if n > 1e6 {
                return Err(CliError::input(format!(
                    "--z-step {step} gives {n} levels (more than 1,000,000)"
                )));
            }
            slice::step_levels(b.min.z, b.max.z, step, a.from == From::Top)
        }
        None => levels,
    };
    let opts = SliceOptions {
        join_tol: a.join_tol,
        arc_tol: (a.arc_tol > 0.0).then_some(a.arc_tol),
        ..Default::default()
    };
    use rayon::prelude::*;
    let meter = Meter::start(
        "pathgen",
        "slicing levels",
        levels.len() as u64,
        Show::from_flags(a.quiet, false),
    );
    let sections: Vec<_> = levels
        .par_iter()
        .map(|&z| {
            let s = slice::section(&p.mesh, z, &opts);
            progress::advance(1);
            s
        })
        .collect();
    meter.finish();
    for s in &sections {
        for w in &s.warnings {
            microcam::diag!("pathgen: slice: {name}: z {}: warning: {w}", s.z);
        }
    }
    let chains: Vec<_> = sections
        .par_iter()
        .map(|s| slice::to_chains(std::slice::from_ref(s), opts.arc_tol, 0))
        .collect();
    let mut out = Output::new(a.output.as_deref());
    let mut w = ChainsWriter::new(&mut out);
    w.header(&ChainsHeader { source: Some(name) })?;
    for (id, mut c) in (1..).zip(chains.into_iter().flatten()) {
        c.id = id;
        w.chain(&c)?;
    }
    w.finish()?;
    out.commit()
}

pub fn mesh_info_cmd(a: MeshInfoArgs) -> Result<(), CliError> {
    let (name, m, p) = load(&a.input)?;
    if p.weld.vertices_in >= 3 && p.weld.vertices_out < 3 {
        return Err(CliError::input(format!(
            "{name}: --weld-tol {} mm joins all {} corners into {}: no triangle is left to report on",
            a.input.weld_tol, p.weld.vertices_in, p.weld.vertices_out
        )));
    }
    #[derive(serde::Serialize)]
    struct GroupInfo<'a> {
        name: &'a str,
        triangles: usize,
    }
    #[derive(serde::Serialize)]
    struct Info<'a> {
        schema: &'static str,
        file: &'a str,
        format: &'a str,
        groups: Vec<GroupInfo<'a>>,
        notes: &'a [String],
        weld_tol_mm: f64,
        weld: microcam::mesh::weld::WeldReport,
        topology: &'a microcam::mesh::topology::TopologyReport,
        repairs: &'a [String],
        repaired: &'a microcam::mesh::topology::TopologyReport,
    }
    let j = Info {
        schema: "microcam.mesh-info/1",
        file: &name,
        format: &m.format,
        groups: m
            .groups
            .iter()
            .map(|g| GroupInfo {
                name: &g.name,
                triangles: g.triangles.len(),
            })
            .collect(),
        notes: &m.notes,
        weld_tol_mm: a.input.weld_tol,
        weld: p.weld,
        topology: &p.before,
        repairs: &p.repairs,
        repaired: &p.after,
    };
    let mut out = Output::new(a.output.as_deref());
    writeln!(
        out,
        "{}",
        serde_json::to_string(&j).map_err(|e| CliError::failure(e.to_string()))?
    )?;
    out.commit()
}
