//! dxf2chains on hostile drawings (issue 18), end to end: exit status 2
//! naming the file and line, nothing on stdout, done within seconds; the
//! self-inserting block drawn once with a warning.

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Instant;

fn run(text: &str) -> (i32, String, String) {
    let t = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_dxf2chains"))
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(text.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(t.elapsed().as_secs() < 20, "took {:?}", t.elapsed());
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn entities(body: &str) -> String {
    format!("0\nSECTION\n2\nENTITIES\n{body}0\nENDSEC\n0\nEOF\n")
}

#[test]
fn far_coordinates_exit_2_with_the_line() {
    for v in ["1e308", "-1e308", "1.7976931348623157e308", "2e9"] {
        let t = entities(&format!(
            "0\nLINE\n10\n0\n20\n0\n11\n{v}\n21\n0\n0\nLINE\n10\n{v}\n20\n0\n11\n0\n21\n1\n0\nLINE\n10\n0\n20\n1\n11\n0\n21\n0\n"
        ));
        let (code, out, err) = run(&t);
        assert_eq!(code, 2, "{v}: {err}");
        assert!(out.is_empty());
        assert!(err.contains("<stdin>:5:") && err.contains("beyond"), "{v}: {err}");
    }
    let spline =
        entities("0\nSPLINE\n70\n8\n71\n3\n10\n0\n20\n0\n10\n1e20\n20\n1\n10\n-1e20\n20\n3\n10\n5\n20\n1e20\n");
    let (code, _, err) = run(&spline);
    assert_eq!(code, 2, "{err}");
    let ellipse = entities("0\nELLIPSE\n10\n0\n20\n0\n11\n1e20\n21\n0\n40\n1e-12\n41\n0\n42\n6.283185307179586\n");
    let (code, _, err) = run(&ellipse);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn self_insert_warns_and_draws_once() {
    let t = "0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n2\nA\n10\n0\n20\n0\n0\nLINE\n10\n0\n20\n0\n11\n1\n21\n0\n\
             0\nINSERT\n2\nA\n10\n1\n20\n0\n0\nENDBLK\n0\nENDSEC\n"
        .to_string()
        + &entities("0\nINSERT\n2\nA\n10\n0\n20\n0\n");
    let (code, out, err) = run(&t);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("inserts itself (A -> A)"), "{err}");
    // The header line and one chain of one line.
    assert_eq!(out.lines().count(), 2, "{out}");
}
