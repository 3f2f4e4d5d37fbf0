use super::*;

fn circle_pts(r: f64, n: usize, turns: f64) -> Vec<P2> {
    (0..=n)
        .map(|i| {
            let a = TAU * turns * i as f64 / n as f64;
            P2::new(r * a.cos(), r * a.sin())
        })
        .collect()
}

#[test]
fn end_tangents_are_exact_on_a_circle() {
    let pts = circle_pts(3.0, 40, 0.3);
    let t = tangents(&pts);
    for (p, u) in [(pts[0], t[0]), (pts[40], t[40])] {
        let exact = V2::new(-p.y, p.x) / 3.0;
        assert!((u - exact).norm() < 1e-12, "{u:?} vs {exact:?}");
    }
}

#[test]
fn a_closed_circle_is_two_arcs_and_an_open_arc_one() {
    for tol in [1e-3, 1e-6] {
        let closed = circle_pts(5.0, 720, 1.0);
        let f = fit_points(&closed, tol, 0.0, false);
        assert!(f.len() <= 2, "{} pieces", f.len());
        assert!(point_deviation(&f, &closed) <= tol);
        let open = circle_pts(5.0, 300, 0.6);
        let f = fit_points(&open, tol, 0.0, false);
        assert_eq!(f.len(), 1);
        assert!(point_deviation(&f, &open) <= tol);
        assert!((f[0].end().xy() - open[300]).norm() < 1e-12);
    }
}

#[test]
fn a_sharp_corner_is_kept() {
    // A line into a half circle, turning 90° at the origin.
    let mut pts: Vec<P2> = (0..=30).map(|i| P2::new(-3.0 + 0.1 * i as f64, 0.0)).collect();
    pts.extend((1..=47).map(|i| {
        let a = std::f64::consts::PI * (1.0 - i as f64 / 47.0);
        P2::new(1.5 + 1.5 * a.cos(), 1.5 * a.sin())
    }));
    let f = fit_points(&pts, 1e-4, 0.0, false);
    assert_eq!(f.len(), 2, "{f:?}");
    assert!(matches!(f[0], Segment::Line(_)) && matches!(f[1], Segment::Arc(_)));
    assert!((f[0].end().xy() - P2::origin()).norm() < 1e-12);
    // A coarse polygon of a circle turns evenly: no corners.
    assert!(corners(&circle_pts(1.0, 12, 1.0)).is_empty());
}

#[test]
fn probes_and_the_grid_measure_exactly() {
    // Arcs of every size and sense, lines; points all round.
    let mut fit = Vec::new();
    for k in 0..40 {
        let a0 = k as f64 * 0.7;
        let sweep = 0.1 + (k as f64 * 0.37) % 6.0;
        let c = P3::new((k % 7) as f64, (k % 5) as f64, 0.0);
        let r = 0.2 + (k % 3) as f64;
        let at = |a: f64| P3::new(c.x + r * a.cos(), c.y + r * a.sin(), 0.0);
        let ccw = k % 2 == 0;
        let end = if ccw { a0 + sweep } else { a0 - sweep };
        fit.push(Segment::Arc(Arc3::new(c, at(a0), at(end), ccw, Plane::Xy, 0).unwrap()));
        fit.push(Segment::line(at(end), P3::new(c.x - 1.0, c.y + 0.5, 0.0)));
    }
    let pts: Vec<P2> = (0..500)
        .map(|i| {
            P2::new(
                (i as f64 * 0.618).fract() * 9.0 - 1.0,
                (i as f64 * 0.414).fract() * 7.0 - 1.0,
            )
        })
        .collect();
    for p in &pts {
        for e in &fit {
            let (a, b) = (Probe::new(e).dist(p), dist_to_elem(p, e));
            assert!((a - b).abs() <= 1e-12 * (1.0 + b), "{a} vs {b} for {e:?}");
        }
    }
    let brute = pts
        .iter()
        .map(|p| fit.iter().map(|e| dist_to_elem(p, e)).fold(f64::INFINITY, f64::min))
        .fold(0.0, f64::max);
    assert!((point_deviation(&fit, &pts) - brute).abs() < 1e-12);
    let poly_brute = fit
        .iter()
        .flat_map(|e| (0..=8).map(move |k| e.point_at_length(e.length() * k as f64 / 8.0).xy()))
        .map(|q| dist_to_polyline(&q, &pts))
        .fold(brute, f64::max);
    assert!((max_deviation(&fit, &pts, 8) - poly_brute).abs() < 1e-12);
}

#[test]
fn degenerate_input_does_not_panic() {
    let p = |x: f64, y: f64| P2::new(x, y);
    assert!(fit_points(&[], 1e-3, 0.0, false).is_empty());
    assert!(fit_points(&[p(1.0, 1.0)], 1e-3, 0.0, true).is_empty());
    assert!(fit_points(&[p(1.0, 1.0), p(1.0, 1.0)], 1e-3, 0.0, false).is_empty());
    let col = [p(0.0, 0.0), p(1.0, 1.0), p(1.0, 1.0), p(2.0, 2.0), p(3.0, 3.0)];
    let f = fit_points(&col, 1e-4, 0.0, false);
    assert_eq!(f.len(), 1, "{f:?}");
    let back = [p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1e-9), p(1.0, 0.0)];
    for polyline in [false, true] {
        let f = fit_points(&back, 1e-4, 0.0, polyline);
        assert!(point_deviation(&f, &back) <= 1e-4);
    }
}

#[test]
fn biarcs_join_tangentially_and_hit_both_ends() {
    for (t0, t1) in [(0.3f64, -1.2f64), (0.0, 0.0), (1.0, 2.5), (-0.7, 0.9)] {
        let (p0, p1) = (P2::new(0.0, 0.0), P2::new(2.0, 0.5));
        let (u0, u1) = (V2::new(t0.cos(), t0.sin()), V2::new(t1.cos(), t1.sin()));
        let f = biarc(p0, u0, p1, u1, 0.0);
        assert!((f[0].start().xy() - p0).norm() < 1e-12);
        assert!((f.last().unwrap().end().xy() - p1).norm() < 1e-9);
        assert!((f[0].start_tangent().xy() - u0).norm() < 1e-9);
        assert!((f.last().unwrap().end_tangent().xy() - u1).norm() < 1e-6, "{t0} {t1}");
        for w in f.windows(2) {
            assert!(w[0].end_tangent().dot(&w[1].start_tangent()) > 1.0 - 1e-9);
        }
    }
}

#[test]
fn sampled_points_fit_far_fewer_blocks() {
    // Coarse samples of a sine: as points (not a polyline) they fit in
    // a handful of biarcs, every point within tol.
    let pts: Vec<P2> = (0..=126)
        .map(|i| P2::new(i as f64 * 0.05, (i as f64 * 0.05).sin()))
        .collect();
    let f = fit_points(&pts, 1e-4, 0.0, false);
    assert!(point_deviation(&f, &pts) <= 1e-4);
    assert!(f.len() * 2 < pts.len(), "{} pieces", f.len());
}

#[test]
fn a_sine_fits_within_tolerance_in_fewer_blocks() {
    let pts: Vec<P2> = (0..=400)
        .map(|i| {
            let x = i as f64 * 0.025;
            P2::new(x, x.sin())
        })
        .collect();
    for tol in [1e-3, 1e-4] {
        let f = fit_points(&pts, tol, 0.0, true);
        let dev = max_deviation(&f, &pts, 64);
        assert!(dev <= tol * 1.0001, "deviation {dev} > {tol}");
        assert!(f.len() * 4 < pts.len(), "{} pieces for {} points", f.len(), pts.len());
        for w in f.windows(2) {
            assert!((w[0].end() - w[1].start()).norm() < 1e-9);
            assert!(w[0].end_tangent().dot(&w[1].start_tangent()) > (0.5f64).to_radians().cos());
        }
    }
}

/// Noisy samples, deterministic: a circle with radial noise far above
/// the tolerance (a measured part) and a random walk across a line.
fn noisy(n: usize, walk: bool) -> Vec<P2> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..n)
        .map(|i| {
            if walk {
                P2::new(i as f64 * 0.01, 0.1 * rnd())
            } else {
                let a = TAU * i as f64 / n as f64;
                let r = 6.35 + 4e-3 * rnd();
                P2::new(r * a.cos(), r * a.sin())
            }
        })
        .collect()
}

#[test]
fn noisy_points_cost_near_linear_work() {
    // The fit and both checks, as `pathgen arcfit --report` runs them:
    // distance evaluations per point stay bounded (about log n) from
    // 10k to 40k points, where the old checks grew with n.
    for walk in [false, true] {
        let mut per_point = Vec::new();
        for n in [10_000, 40_000] {
            let pts = noisy(n, walk);
            let w0 = work_done();
            let f = fit_points(&pts, 1e-3, 0.0, false);
            let dev_pts = point_deviation(&f, &pts);
            let dev_poly = max_deviation(&f, &pts, 256);
            let w = (work_done() - w0) as f64 / n as f64;
            assert!(dev_pts <= 1e-3, "{dev_pts}");
            // No excursion far from the points (noise of 0.1 mm at most).
            assert!(dev_poly < 1.0, "the fit swings {dev_poly} mm off the points");
            eprintln!(
                "walk {walk} n {n}: {w:.0} distance evaluations per point, {} pieces",
                f.len()
            );
            per_point.push(w);
        }
        assert!(per_point[1] < 1.5 * per_point[0], "work per point grew {per_point:?}");
    }
}

/// `deviation_within` gives `max_deviation`'s verdict on every fit, at
/// every limit: below, at and above the exact deviation, and on fits that
/// stray from the points, that miss them or have no pieces at all.
#[test]
fn the_early_verdict_is_the_measured_one() {
    let mut rnd = crate::geometry::test_rng::unit_rng(0x2545_f491_4f6c_dd1d);
    let mut checked = [0usize; 2];
    for case in 0..400 {
        // Every tenth large enough for the grid (delegated to max_deviation).
        let n = if case % 10 == 0 {
            300
        } else {
            2 + (rnd() * 60.0) as usize
        };
        let noise = [0.0, 1e-4, 1e-2][case % 3];
        // Points on a wavy curve, with noise; the fit is the package's own
        // (polyline mode), a fit of other points, or none.
        let pts: Vec<P2> = (0..n)
            .map(|i| {
                let x = i as f64 * 0.1;
                P2::new(
                    x + noise * rnd(),
                    (x * (1.0 + case as f64 * 0.01)).sin() + noise * rnd(),
                )
            })
            .collect();
        let fit = match case % 4 {
            3 => Vec::new(),
            2 => fit_points(
                &pts.iter().map(|p| p + V2::new(0.0, 0.003)).collect::<Vec<_>>(),
                1e-3,
                0.0,
                true,
            ),
            _ => fit_points(&pts, [1e-4, 1e-3, 1e-2][case % 3], 0.0, true),
        };
        let samples = [1, 8, 32][case % 3];
        let exact = max_deviation(&fit, &pts, samples);
        let mut limits = vec![0.0, 1e-4, 1e-3, 1e-2, 1.0, f64::NAN];
        if exact.is_finite() {
            limits.extend([exact, exact * (1.0 - 1e-12), exact * (1.0 + 1e-12)]);
        }
        for limit in limits {
            let want = exact <= limit;
            assert_eq!(
                deviation_within(&fit, &pts, samples, limit),
                want,
                "case {case}, limit {limit}, exact {exact}"
            );
            checked[usize::from(want)] += 1;
        }
    }
    // Both verdicts, many times.
    assert!(checked[0] > 500 && checked[1] > 500, "{checked:?}");
}
