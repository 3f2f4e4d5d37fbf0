use super::*;
use crate::pmac::upload_plan::UploadPlan;
use std::path::Path;

#[test]
fn split_budget_fills_ninety_percent_at_most_the_limit_less_the_marker() {
    assert_eq!(split_budget(10_000, None), 9_000 - MARKER_WORDS);
    assert_eq!(split_budget(10_000, Some(5_000)), 5_000 - MARKER_WORDS);
    assert_eq!(split_budget(10_000, Some(50_000)), 9_000 - MARKER_WORDS);
    assert_eq!(split_budget(-5, None), 0);
    assert_eq!(split_budget(4, Some(4)), 0);
}

#[test]
fn dry_run_files_are_wrapped_buffers_or_bare_rotary_chunks() {
    let mut text = String::from("G21 G90\n");
    for i in 1..=40 {
        text.push_str(&format!("G1 X{i} F10\n"));
    }
    let job = UploadPlan::read(&text, &Names::default()).unwrap();
    let budget = dry_run_budget(Mode::Split, Some(60), 16).unwrap();
    assert_eq!(budget, Some(60 - MARKER_WORDS));
    let (files, plan) = dry_run(&job, Mode::Split, budget, 3, "P401").unwrap();
    assert!(files.len() > 1, "{}", files.len());
    assert_eq!(plan["chunks"].as_array().unwrap().len(), files.len());
    for (i, f) in files.iter().enumerate() {
        assert_eq!(f.name, plan_file_name(i + 1));
        assert!(
            f.text.starts_with("CLOSE\nDELETE GATHER\nOPEN PROG 3 CLEAR\n"),
            "{}",
            f.text
        );
        assert!(
            f.text.ends_with(&format!("DWELL0\nP401={}\nCLOSE\n", i + 1)),
            "{}",
            f.text
        );
    }
    let (rot, _) = dry_run(&job, Mode::Rotary, Some(16), 3, "P401").unwrap();
    assert!(
        rot.iter()
            .all(|f| !f.text.contains("OPEN PROG") && !f.text.contains("P401="))
    );
    assert!(dry_run_budget(Mode::Split, None, 16).is_err());
    assert_eq!(dry_run_budget(Mode::Program, None, 16), Ok(None));
    assert!(is_stale_plan_file("chunk-005.pmac", 4));
    assert!(!is_stale_plan_file("chunk-004.pmac", 4));
    assert!(is_stale_plan_file("chunk-000.pmac", 4));
    assert!(is_stale_plan_file("chunk-5.pmac", 4));
    assert!(is_stale_plan_file("chunk-3.pmac", 4));
    assert!(!is_stale_plan_file("plan.json", 4));
}

#[test]
fn resume_is_refused_for_another_input_or_mode() {
    let s = State::new("abc".into(), Mode::Split, 5);
    assert!(s.session >= 1 && s.session <= 1_000_000_000);
    let p = Path::new("st.json");
    assert!(s.check_resume("abc", Mode::Split, p).is_ok());
    assert!(
        s.check_resume("abd", Mode::Split, p)
            .unwrap_err()
            .to_string()
            .contains("another program")
    );
    assert!(
        s.check_resume("abc", Mode::Rotary, p)
            .unwrap_err()
            .to_string()
            .contains("split mode")
    );
    let mut done = s.clone();
    done.next_move = 6;
    let v = SendSummary::finished(&done).to_json(true);
    assert_eq!(v["ok"], true);
    assert_eq!(v["final_counter"], 5);
    assert_eq!(v["mode"], "split");
}

#[test]
fn a_state_file_that_names_no_place_in_its_job_is_refused() {
    let mut good = State::new("abc".into(), Mode::Rotary, 5);
    good.next_move = 3;
    good.resume_at = Some([1.0, 2.0, 0.0]);
    good.budget = Some(900);
    let text = serde_json::to_string(&good).unwrap();
    assert_eq!(State::from_json(&text, "st.json").unwrap(), good);
    let finished = State {
        next_move: 6,
        resume_at: None,
        ..good.clone()
    };
    assert!(State::from_json(&serde_json::to_string(&finished).unwrap(), "st.json").is_ok());
    let cases: [(&str, State); 6] = [
        (
            "layout version 1",
            State {
                version: 1,
                ..good.clone()
            },
        ),
        (
            "next move 0",
            State {
                next_move: 0,
                ..good.clone()
            },
        ),
        (
            "next move 7",
            State {
                next_move: 7,
                ..good.clone()
            },
        ),
        (
            "finished job",
            State {
                next_move: 6,
                ..good.clone()
            },
        ),
        (
            "session number 0",
            State {
                session: 0,
                ..good.clone()
            },
        ),
        (
            "word budget 0",
            State {
                budget: Some(0),
                ..good.clone()
            },
        ),
    ];
    for (why, s) in cases {
        let e = State::from_json(&serde_json::to_string(&s).unwrap(), "st.json").unwrap_err();
        let m = e.to_string();
        assert!(m.contains("st.json") && m.contains(why), "{why}: {m}");
    }
    // Cut short, and a resume point of 1e999 (out of range for a double:
    // refused as a number or as a point that is not finite).
    assert!(State::from_json(&text[..text.len() / 2], "st.json").is_err());
    let inf = text.replace("[1.0,2.0,0.0]", "[1e999,2.0,0.0]");
    assert_ne!(inf, text);
    assert!(State::from_json(&inf, "st.json").is_err());
}
