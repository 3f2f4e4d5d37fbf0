//! Tests of what a PMAC download file holds besides motion programs:
//! on-line assignments and commands, PLC buffers, `#define` and
//! `#include`, and assignments held for a bare program.

use super::tests::{assert_pt, moves, p, pmac_opts, read, read_err};
use super::*;
use crate::gcode::read_str;

/// Read with fresh options; the records and the notes left.
fn read_noted(text: &str, opts: ReadOptions) -> (Vec<Record>, Vec<(u64, String)>) {
    let (_, recs) = read_str(text, &opts).unwrap_or_else(|e| panic!("unexpected error: {e}\n{text}"));
    (recs, opts.notes.take())
}

#[test]
fn online_assignments_are_applied_and_ranges_cover_every_variable() {
    let text = "CLOSE\nP10=2.5 Q(3+4)=P10*2\nI5213,3,100=10 P20..22=7\nM33=1\n\
                OPEN PROG 1 CLEAR\nLINEAR X(P10) Y(Q7) Z(P22+I5413) F(P21)\nCLOSE\n";
    let (recs, notes) = read_noted(text, pmac_opts());
    let m = moves(&recs);
    assert_eq!(recs.len(), 1, "on-line assignments make no records: {recs:?}");
    assert_pt(&m[0].to, &p(2.5, 5.0, 17.0));
    assert_eq!(m[0].feed, Some(7.0));
    // M33 = 1 on-line: the program starts with the shutter open.
    assert!(m[0].beam);
    assert!(m[0].beam_switch.is_none());
    // Only the I-variables are noted (P/Q/M are applied silently).
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].1.contains("I5213..I5413 (3 variables, step 100) = 10"),
        "{notes:?}"
    );
    // Out-of-range ranges and unevaluable values are noted, not applied.
    let (_, notes) = read_noted("I8190,5,1=1\nP1=$(X)\nQ(P1)=\nOPEN PROG 1\nCLOSE\n", pmac_opts());
    assert_eq!(notes.len(), 3, "{notes:?}");
    assert!(notes[0].1.contains("runs past I8191"), "{notes:?}");
    assert!(notes[1].1.contains("template macro"), "{notes:?}");
    // A count of 20 digits: refused at once (it used to overflow the last
    // variable's number round to a small one and loop, the pmac_read fuzz
    // target found).
    let (_, n2) = read_noted("I888,57777777777777777777,1=4\nOPEN PROG 1\nCLOSE\n", pmac_opts());
    assert!(n2[0].1.contains("runs past I8191"), "{n2:?}");
    assert!(notes[2].1.contains("not applied"), "{notes:?}");
}

#[test]
fn online_definitions_addressing_and_buffer_commands_are_noted() {
    let text = "CLOSE\nUNDEFINE ALL\n&1 #1->1000X #2->1000Y\nM1->Y:$78800,0,1 M2->*\n#3J/ &2B1R J9\n\
                DEFINE LOOKAHEAD 50,10 DEL GAT ENABLE PLC 3\nP1 SAVE\nWhoKnows = 3\n\
                OPEN PROG 1\nLINEAR X1 F1\nCLOSE\n";
    let (recs, notes) = read_noted(text, pmac_opts());
    assert_eq!(moves(&recs).len(), 1);
    let texts: Vec<&str> = notes.iter().map(|n| n.1.as_str()).collect();
    let want = [
        (2, "UNDEFINE ALL: on-line buffer"),
        (3, "#1->1000X: motor axis definition"),
        (3, "#2->1000Y: motor axis definition"),
        (4, "M1->Y:$78800,0,1: M-variable definition"),
        (4, "M2->*: M-variable definition"),
        (5, "#3J/: motor command"),
        (5, "J9: on-line command"),
        (6, "DEFINE LOOKAHEAD 50,10: on-line buffer"),
        (6, "ENABLE PLC 3: on-line buffer"),
        (7, "P1: query"),
        (7, "SAVE: on-line buffer"),
        (8, "'WhoKnows = 3': not an on-line command"),
    ];
    assert_eq!(notes.len(), want.len(), "{texts:#?}");
    for ((line, text), (l, t)) in notes.iter().zip(want) {
        assert_eq!(*line, l, "{text}");
        assert!(text.starts_with(t), "{text} does not start with {t}");
    }
}

#[test]
fn a_file_of_plcs_only_reads_as_no_motion_with_notes() {
    let text = "// Power PMAC style\nOPEN PLC 18\n  X=Motor[3].ActPos // comment\nCLOSE\n\
                open plc 19\n  #define Gap Q82\n  Gap = 1;\nclose\nOPEN FORWARD\nCLEAR\nQ7=1\nCLOSE\n";
    let (recs, notes) = read_noted(text, pmac_opts());
    assert!(recs.is_empty(), "{recs:?}");
    let texts: Vec<&str> = notes.iter().map(|n| n.1.as_str()).collect();
    assert_eq!(notes.len(), 4, "{texts:#?}");
    assert!(texts[0].starts_with("OPEN PLC 18: PLC program skipped"));
    assert!(texts[1].starts_with("OPEN PLC 19: PLC program skipped"));
    assert!(texts[2].starts_with("OPEN FORWARD: kinematic subroutine skipped"));
    assert_eq!(notes[3].0, 12);
    assert!(texts[3].starts_with("no motion program"));
}

#[test]
fn defines_substitute_in_programs_and_online_commands() {
    let text = "#define STATE Q69\n#define FAST F(SPEED*2)\n#define SPEED 5\nCLOSE\nSTATE = 3\n\
                OPEN PROG 11\nCLEAR\nLINEAR X(STATE) FAST\n#undefine STATE\nCLOSE\n";
    let (recs, notes) = read_noted(text, pmac_opts());
    let m = moves(&recs);
    assert_eq!(recs.len(), 1, "{recs:?}");
    assert_pt(&m[0].to, &p(3.0, 0.0, 0.0));
    assert_eq!(m[0].feed, Some(10.0));
    assert!(notes.is_empty(), "{notes:?}");
    // A bare program with defines, and an undefined name after #undefine.
    let (recs, _) = read_noted("#define GO LINEAR X1 F2\nGO\n", pmac_opts());
    assert_eq!(moves(&recs).len(), 1);
    let (line, msg) = read_err("#define GO X1\n#undef GO\nLINEAR F1\nGO\n");
    assert_eq!(line, 4);
    assert!(msg.contains("unknown word 'GO'"), "{msg}");
    // Malformed directives and runaway nesting are errors on their line.
    assert_eq!(read_err("LINEAR F1\n#define\n").0, 2);
    let mut deep = String::new();
    for k in 0..40 {
        deep.push_str(&format!("#define N{k} N{}\n", k + 1));
    }
    deep.push_str("LINEAR X1 F1 N0\n");
    let (line, msg) = read_err(&deep);
    assert_eq!(line, 41);
    assert!(msg.contains("deeper than"), "{msg}");
}

#[test]
fn includes_are_relative_to_the_including_file_and_errors_name_both_lines() {
    let d = tempfile::tempdir().unwrap();
    let sub = d.path().join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    std::fs::write(
        sub.join("defs.pmc"),
        "; header\n#define SPEED 4\n#include \"more.pmc\"\n",
    )
    .unwrap();
    std::fs::write(sub.join("more.pmc"), "#define TARGET X2\n").unwrap();
    std::fs::write(sub.join("bad.pmc"), "\n\nLINEAR X1 FOO3\n").unwrap();
    std::fs::write(sub.join("loop.pmc"), "#include \"loop2.pmc\"\n").unwrap();
    std::fs::write(sub.join("loop2.pmc"), "#include \"loop.pmc\"\n").unwrap();
    let main = d.path().join("main.pmc");
    let with = |text: &str| {
        std::fs::write(&main, text).unwrap();
        let opts = ReadOptions {
            source_path: Some(main.clone()),
            ..pmac_opts()
        };
        read_str(text, &opts)
    };
    let (_, recs) = with("#include \"sub/defs.pmc\"\nOPEN PROG 1\nLINEAR TARGET F(SPEED)\nCLOSE\n").unwrap();
    assert_eq!(moves(&recs)[0].feed, Some(4.0));
    assert_pt(&moves(&recs)[0].to, &p(2.0, 0.0, 0.0));
    // An error inside an included file names the include line and its own.
    let e = with("OPEN PROG 1\n#include \"sub/bad.pmc\"\nCLOSE\n").unwrap_err();
    assert_eq!(e.line(), 2);
    assert!(e.to_string().contains("bad.pmc:3: unknown word 'FOO3'"), "{e}");
    // A missing file, a cycle.
    let e = with("CLOSE\n#include \"nope.pmc\"\n").unwrap_err();
    assert_eq!(e.line(), 2);
    assert!(e.to_string().contains("#include \"nope.pmc\": cannot read"), "{e}");
    let e = with("#include \"sub/loop.pmc\"\n").unwrap_err();
    assert_eq!(e.line(), 1);
    let msg = e.to_string();
    assert!(msg.contains("a cycle") && msg.contains("loop2.pmc:1:"), "{msg}");
    // Self-inclusion of the program's own file.
    let e = with("#include \"main.pmc\"\n").unwrap_err();
    assert!(e.to_string().contains("a cycle"), "{e}");
}

#[test]
fn held_assignments_belong_to_a_bare_program_when_motion_follows() {
    // No OPEN: the assignments are the program's first lines (records).
    let recs = read("P1=2\nQ5=P1+1\nLINEAR X(Q5) F1\n");
    assert_eq!(recs.len(), 3, "{recs:?}");
    assert_eq!(recs[0].block(), Some(1));
    assert_pt(&moves(&recs)[0].to, &p(3.0, 0.0, 0.0));
    // Assignments only: still a bare program.
    assert_eq!(read("P1=2\n").len(), 1);
    // An unknown name in a bare program is an error on its line.
    let (line, msg) = read_err("Speed = 3\nLINEAR X1 F1\n");
    assert_eq!(line, 1);
    assert!(msg.contains("unknown word"), "{msg}");
}
