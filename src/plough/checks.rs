//! Closed-form checks of the simulation: a full-immersion slot against the
//! crescent D × s and its analytic thin part, half immersion on both
//! sides, an arc, a cutter leaving the stock, and dexel against exact.

use super::*;
use crate::model::toolpath::{ArcData, Motion};

fn mv(kind: MotionKind, x: f64, y: f64, feed: Option<f64>) -> Record {
    Record::Move(Motion::bare(kind, P3::new(x, y, 0.0), feed))
}

fn params(stock: [f64; 4], res: f64, method: Method) -> Params {
    Params {
        stock_mm: stock,
        resolution_mm: res,
        diameter_mm: 0.794,
        teeth: 2,
        h_min_mm: 0.0024,
        accuracy_mm: 0.001,
        scale: 10.0,
        rpm: Some(60_000.0),
        method,
        max_memory_mib: 512.0,
        max_steps: super::DEFAULT_MAX_STEPS,
    }
}

/// Run `moves` (feeds in mm/s) from `start`.
fn run(p: Params, start: (f64, f64), moves: &[Record]) -> Plough {
    let mut pl = Plough::new(p, FeedUnit::MmPerS, P3::new(start.0, start.1, 0.0)).unwrap();
    for m in moves {
        pl.add(m).unwrap();
    }
    pl
}

/// The slot's crescent seen from the new centre, step `s` along +X:
/// chip area and the part thinner than `h_min`, by fine quadrature of the
/// closed-form radial extent ρ(θ) = −s cos θ + sqrt(r² − s² sin² θ).
fn crescent(r: f64, s: f64, h_min: f64) -> (f64, f64) {
    let n = 2_000_000;
    let (mut chip, mut plough) = (0.0, 0.0);
    for k in 0..n {
        let th = (k as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
        let rho = -s * th.cos() + (r * r - s * s * th.sin().powi(2)).sqrt();
        if rho < r {
            let a = 0.5 * (r * r - rho * rho);
            chip += a;
            if r - rho < h_min {
                plough += a;
            }
        }
    }
    let d = std::f64::consts::TAU / n as f64;
    (chip * d, plough * d)
}

/// Mean chip and ploughing area over steps whose x lies in `[xa, xb]`.
fn mean_between(pl: &Plough, xa: f64, xb: f64, exact: bool) -> (f64, f64, usize) {
    let v: Vec<_> = pl.steps.iter().filter(|s| s.x_mm >= xa && s.x_mm <= xb).collect();
    let pick = |s: &Step| {
        if exact {
            s.exact_mm2.unwrap()
        } else {
            (s.chip_mm2, s.plough_mm2)
        }
    };
    let n = v.len() as f64;
    (
        v.iter().map(|s| pick(s).0).sum::<f64>() / n,
        v.iter().map(|s| pick(s).1).sum::<f64>() / n,
        v.len(),
    )
}

#[test]
fn full_slot_removes_the_crescent_and_its_thin_part() {
    // 2 mm/s at 60,000 rpm, 2 teeth: 1 µm per tooth, steps of 10 µm.
    let p = params([0.0, 0.0, 3.0, 2.0], 0.794 / 100.0, Method::Both);
    let moves = [mv(MotionKind::Line, 2.5, 1.0, Some(2.0))];
    let pl = run(p, (0.5, 1.0), &moves);
    let (r, s) = (0.397, 0.01);
    assert_eq!(pl.steps.len(), 201);
    let (want_chip, want_plough) = crescent(r, s, 0.0024);
    assert!((want_chip - 0.794 * s).abs() < 1e-4 * want_chip);
    // Steady state: past the plunge disc.
    let (chip, plough, n) = mean_between(&pl, 1.0, 2.5, false);
    assert!(n > 100);
    assert!(
        (chip - 0.794 * s).abs() < 0.01 * 0.794 * s,
        "dexel chip {chip} vs {}",
        0.794 * s
    );
    // The ploughing band is about 12 R long on each horn; the dexel sees
    // its edge to about R.
    assert!(
        (plough - want_plough).abs() < 0.06 * want_plough,
        "dexel plough {plough} vs {want_plough}"
    );
    let (echip, eplough, _) = mean_between(&pl, 1.0, 2.5, true);
    assert!(
        (echip - want_chip).abs() < 1e-3 * want_chip,
        "exact chip {echip} vs {want_chip}"
    );
    assert!(
        (eplough - want_plough).abs() < 0.01 * want_plough,
        "exact plough {eplough} vs {want_plough}"
    );
}

#[test]
fn finer_dexels_find_the_thin_part_closer() {
    let (_, want) = crescent(0.397, 0.01, 0.0024);
    let p = params([0.0, 0.0, 3.0, 2.0], 0.794 / 200.0, Method::Dexel);
    let pl = run(p, (0.5, 1.0), &[mv(MotionKind::Line, 2.5, 1.0, Some(2.0))]);
    let (_, plough, _) = mean_between(&pl, 1.0, 2.5, false);
    assert!((plough - want).abs() < 0.02 * want, "{plough} vs {want}");
}

#[test]
fn half_immersion_cuts_half_the_crescent_on_either_side() {
    // The stock's lower edge on the path: only the upper half of the
    // disc meets material. Moving +X with the material on the left
    // (y > path) and moving −X with it on the right are the two sides
    // (down and up milling for a clockwise spindle).
    let (r, s) = (0.397, 0.01);
    let (want_chip, want_plough) = crescent(r, s, 0.0024);
    for (from, to) in [(0.5, 2.5), (2.5, 0.5)] {
        let p = params([0.0, 1.0, 3.0, 2.5], 0.794 / 100.0, Method::Both);
        let pl = run(p, (from, 1.0), &[mv(MotionKind::Line, to, 1.0, Some(2.0))]);
        let (chip, plough, _) = mean_between(&pl, 1.0, 2.0, false);
        assert!((chip - 0.5 * want_chip).abs() < 0.01 * want_chip, "{chip}");
        // One horn of the crescent.
        assert!((plough - 0.5 * want_plough).abs() < 0.05 * want_plough, "{plough}");
        let (echip, eplough, _) = mean_between(&pl, 1.0, 2.0, true);
        assert!((echip - 0.5 * want_chip).abs() < 2e-3 * want_chip, "{echip}");
        assert!((eplough - 0.5 * want_plough).abs() < 0.01 * want_plough, "{eplough}");
    }
}

#[test]
fn an_arc_slot_cuts_its_crescent() {
    // A full-immersion circular slot of radius 1 mm: the cutter centre
    // advances s per step along the arc, so each step removes about D × s.
    let p = params([0.0, 0.0, 4.0, 4.0], 0.794 / 100.0, Method::Both);
    let arc = MotionKind::Arc(ArcData {
        center: P3::new(2.0, 2.0, 0.0),
        ccw: true,
        plane: Plane::Xy,
        extra_turns: 0,
    });
    let pl = run(p, (3.0, 2.0), &[mv(arc, 1.0, 2.0, Some(2.0))]);
    let steps = &pl.steps[60..pl.steps.len()];
    let step_len = std::f64::consts::PI / (pl.steps.len() - 1) as f64;
    let chip = steps.iter().map(|s| s.chip_mm2).sum::<f64>() / steps.len() as f64;
    let exact = steps.iter().map(|s| s.exact_mm2.unwrap().0).sum::<f64>() / steps.len() as f64;
    let want = 0.794 * step_len;
    assert!((chip - want).abs() < 0.01 * want, "{chip} vs {want}");
    assert!((exact - want).abs() < 2e-3 * want, "{exact} vs {want}");
    // The path ends on the arc's end point, a half turn later.
    let last = pl.steps.last().unwrap();
    assert!((last.x_mm - 1.0).abs() < 1e-9 && (last.path_mm - std::f64::consts::PI).abs() < 1e-9);
}

#[test]
fn a_cutter_leaving_the_stock_cuts_less_and_then_nothing() {
    // Slot towards the right edge at x = 2 and beyond: once the cutter's
    // front passes the edge the chip splits into two pieces, each with two
    // thin ends, then vanishes when the cutter is out.
    let p = params([0.0, 0.0, 2.0, 2.0], 0.794 / 100.0, Method::Both);
    let pl = run(p, (0.6, 1.0), &[mv(MotionKind::Line, 2.6, 1.0, Some(2.0))]);
    let at = |x: f64| {
        let s = pl
            .steps
            .iter()
            .min_by(|a, b| (a.x_mm - x).abs().total_cmp(&(b.x_mm - x).abs()))
            .unwrap();
        let (c, p) = s.exact_mm2.unwrap();
        (s.chip_mm2, s.plough_mm2, c, p)
    };
    let (full, fplough, efull, efplough) = at(1.2);
    let (part, pplough, epart, epplough) = at(1.7);
    assert!(part < 0.8 * full && part > 0.2 * full, "{part} vs {full}");
    assert!((part - epart).abs() < 0.02 * epart, "{part} vs {epart}");
    // The same two horns plus two thin ends at the edge, on a smaller
    // chip: more ploughing, and a larger share of the chip.
    assert!(epplough > efplough, "{epplough} vs {efplough}");
    assert!(pplough / part > fplough / full, "{pplough}/{part} vs {fplough}/{full}");
    assert!(epplough / epart > efplough / efull);
    let (none, _, enone, _) = at(2.45);
    assert_eq!((none, enone), (0.0, 0.0));
}

#[test]
fn dexel_error_shrinks_with_resolution() {
    let arc = MotionKind::Arc(ArcData {
        center: P3::new(1.5, 1.5, 0.0),
        ccw: false,
        plane: Plane::Xy,
        extra_turns: 0,
    });
    let moves = [
        mv(MotionKind::Line, 1.5, 1.0, Some(1.0)),
        mv(arc, 1.5, 2.0, Some(1.0)),
        mv(MotionKind::Line, 2.4, 1.6, Some(1.0)),
    ];
    let mut errs = Vec::new();
    for res in [0.04, 0.02, 0.01] {
        let pl = run(params([0.0, 0.0, 3.0, 3.0], res, Method::Both), (0.8, 1.0), &moves);
        let (mut d, mut e) = (0.0, 0.0);
        for s in &pl.steps {
            let (c, _) = s.exact_mm2.unwrap();
            d += (s.chip_mm2 - c).abs();
            e += c;
        }
        errs.push(d / e);
    }
    assert!(errs[0] > errs[1] && errs[1] > errs[2], "{errs:?}");
}

#[test]
fn bad_parameters_are_refused() {
    let base = params([0.0, 0.0, 3.0, 2.0], 0.01, Method::Dexel);
    let mut p = base.clone();
    p.diameter_mm = 2.5;
    assert!(matches!(
        Plough::new(p, FeedUnit::MmPerS, P3::origin()),
        Err(PloughError::ToolTooLarge { .. })
    ));
    let mut p = base.clone();
    p.resolution_mm = 1e-8;
    assert!(matches!(
        Plough::new(p, FeedUnit::MmPerS, P3::origin()),
        Err(PloughError::Memory { .. })
    ));
    let mut p = base;
    p.rpm = None;
    let mut pl = Plough::new(p, FeedUnit::MmPerS, P3::new(1.0, 1.0, 0.0)).unwrap();
    let e = pl.add(&mv(MotionKind::Line, 2.0, 1.0, Some(1.0))).unwrap_err();
    assert!(e.to_string().contains("spindle speed"), "{e}");
}

#[test]
fn a_run_past_the_step_cap_is_refused_before_its_work() {
    // F120 mm/min is 101 steps of 10 µm on this 1 mm move: a cap of 50
    // refuses the move before any of its steps is cut.
    let mut p = params([0.0, 0.0, 3.0, 2.0], 0.01, Method::Dexel);
    p.max_steps = 50;
    let mut pl = Plough::new(p, FeedUnit::MmPerMin, P3::new(1.0, 1.0, 0.0)).unwrap();
    let e = pl.add(&mv(MotionKind::Line, 2.0, 1.0, Some(120.0))).unwrap_err();
    assert!(e.to_string().contains("--max-steps"), "{e}");
    assert!(pl.steps.is_empty(), "{} steps cut before the refusal", pl.steps.len());
}

#[test]
fn feed_per_tooth_follows_the_feed_unit() {
    // ISO programs give mm/min: F120 is 2 mm/s, steps of 10 µm.
    let p = params([0.0, 0.0, 3.0, 2.0], 0.01, Method::Dexel);
    let mut pl = Plough::new(p, FeedUnit::MmPerMin, P3::new(1.0, 1.0, 0.0)).unwrap();
    pl.add(&mv(MotionKind::Line, 2.0, 1.0, Some(120.0))).unwrap();
    assert_eq!(pl.steps.len(), 101);
}
