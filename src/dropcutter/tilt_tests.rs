//! The tilt search against the gouge check's own answers: turned tools
//! clear the trough of the gouge tests and still touch their contact, and
//! eased turns keep the part clear while the axis turns gradually.

use super::*;
use crate::cutter::Cutter;
use crate::dropcutter::DropCutter;
use crate::dropcutter::gouge::GougeRule;
use crate::dropcutter::gouge::tests::{inside_tool, on_corpus_passes, samples, trough_pass};
use crate::geometry::V3;

/// A search in degrees (max, step) with a ramp in mm.
fn search(max_deg: f64, step_deg: f64, ramp: f64) -> TiltSearch {
    TiltSearch {
        max: max_deg.to_radians(),
        step: step_deg.to_radians(),
        ramp,
        both: true,
    }
}

/// The tests' 5-axis job along `xy`: lead 5 degrees, 6 mm of tool
/// checked; its orientation, contacts and unchecked locations.
fn lead_5_job(dc: &DropCutter, xy: &[crate::geometry::P2]) -> (FiveAxis, Vec<Vec<Contact>>, Vec<Vec<Location>>) {
    let fa = FiveAxis {
        lead: 5f64.to_radians(),
        tilt: 0.0,
        axis_length: 6.0,
    };
    (fa, FiveAxis::contacts(dc, xy), fa.pass(dc, xy).unwrap())
}

#[test]
fn tilting_clears_the_trough_with_the_tool_still_on_its_contact() {
    let (mesh, xy) = trough_pass();
    let points = samples(&mesh, 8);
    for cutter in [
        Cutter::Flat { radius: 0.6 },
        Cutter::Torus {
            radius: 0.8,
            corner: 0.2,
        },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let gc = GougeCheck::new(&dc);
        let (fa, contacts, raw) = lead_5_job(&dc, &xy);
        // No turn allowed: exactly the lift.
        let mut lifted = raw.clone();
        let lift_report = gc.check(&mut lifted, 6.0, GougeRule::Lift);
        let mut none = raw.clone();
        let (r0, t0, _) = gc
            .check_tilting(&fa, &contacts, &mut none, &search(0.0, 5.0, 0.0), Placement::Tangent)
            .unwrap();
        assert_eq!((r0, none.clone()), (lift_report, lifted.clone()));
        assert_eq!((t0.tilted, t0.lifted), (0, lift_report.gouging));
        // Turns up to 30 degrees in steps of 5.
        let mut turned = raw.clone();
        let (report, tilt, _) = gc
            .check_tilting(&fa, &contacts, &mut turned, &search(30.0, 5.0, 0.0), Placement::Tangent)
            .unwrap();
        assert_eq!(report, lift_report, "the same gouges found");
        assert_eq!(tilt.tilted + tilt.lifted, report.gouging);
        assert!(tilt.tilted > report.gouging / 2, "{cutter:?}: {tilt:?}");
        assert!(tilt.largest_turn <= 30f64.to_radians() + 1e-12);
        let steps = tilt.largest_turn / 5f64.to_radians();
        assert!((steps - steps.round()).abs() < 1e-9);
        for ((t, l), c) in turned
            .iter()
            .flatten()
            .zip(lifted.iter().flatten())
            .zip(contacts.iter().flatten())
        {
            let a = (t.axis_point - t.cl).normalize();
            assert!(gc.clearance(t.cl, a, 6.0) <= GOUGE_TOL);
            if t == l {
                continue;
            }
            // A turned tool still touches the part: lowered along its axis
            // by 1e-3 mm it is 1e-3 mm deep.
            let lower = gc.clearance(t.cl - a * 1e-3, a, 6.0);
            assert!((lower - 1e-3).abs() < 1e-9, "{lower}");
            // ... at its contact: the contact point lies on the tool's
            // underside (the flat bottom, or the corner's tube).
            let (r, rc) = (cutter.radius(), cutter.corner_radius());
            let d = c.cc - t.cl;
            let h = d.dot(&a);
            let w = d - a * h;
            let on_bottom = h.abs() < 1e-9 && w.norm() <= r - rc + 1e-9;
            let on_tube = rc > 0.0 && {
                let ring = t.cl + a * rc + w.normalize() * (r - rc);
                ((c.cc - ring).norm() - rc).abs() < 1e-9 && h <= rc + 1e-9
            };
            assert!(
                on_bottom || on_tube,
                "{cutter:?}: contact {:?} off the tool at {:?}",
                c.cc,
                t.cl
            );
            for &p in &points {
                assert!(!inside_tool(cutter, t.cl, a, 6.0, p, 1e-7), "{p:?}");
            }
        }
    }
}

#[test]
fn eased_turns_keep_the_part_clear_and_shrink_the_jumps() {
    // A pass across the trough, sampled finely so a turned stretch has
    // neighbours within a ramp of a millimetre.
    let (mesh, _) = trough_pass();
    let xy: Vec<crate::geometry::P2> = (0..=96)
        .map(|i| crate::geometry::P2::new(-1.0, -1.6 + 3.2 * i as f64 / 96.0))
        .collect();
    let points = samples(&mesh, 8);
    let cutter = Cutter::Flat { radius: 0.6 };
    let dc = DropCutter::new(&mesh, cutter).unwrap();
    let gc = GougeCheck::new(&dc);
    let (fa, contacts, raw) = lead_5_job(&dc, &xy);
    let mut sharp = raw.clone();
    let (r_sharp, t_sharp, _) = gc
        .check_tilting(&fa, &contacts, &mut sharp, &search(30.0, 5.0, 0.0), Placement::Tangent)
        .unwrap();
    let mut eased = raw.clone();
    let (r_eased, t_eased, _) = gc
        .check_tilting(&fa, &contacts, &mut eased, &search(30.0, 5.0, 1.0), Placement::Tangent)
        .unwrap();
    assert_eq!(r_sharp, r_eased, "the same gouges found");
    // Chosen along the pass, the turns keep one way across the trough: the
    // axis changes by a step at most even without easing (25 degrees when
    // each location took the first turn that cleared it: +15, -10, +15).
    assert!(
        t_sharp.largest_jump <= 5f64.to_radians() + 1e-9,
        "sharp {:.2} deg",
        t_sharp.largest_jump.to_degrees()
    );
    assert!(t_sharp.tilted > 0 && t_sharp.eased == 0, "{t_sharp:?}");
    assert!(t_eased.eased > 0, "{t_eased:?}");
    // Every turned location needed its turn or is within the ramp; no
    // location gouges, none lies deeper in the part than the sharp search
    // allowed (every sampled point of the part outside every tool).
    assert!(
        t_eased.largest_jump < t_sharp.largest_jump,
        "eased {:.2} deg, sharp {:.2} deg",
        t_eased.largest_jump.to_degrees(),
        t_sharp.largest_jump.to_degrees()
    );
    // The jumps, measured here from the locations themselves: the angle
    // between consecutive tool axes, against the same from the sharp run.
    let angles = |run: &[Vec<Location>]| -> f64 {
        let axes: Vec<V3> = run
            .iter()
            .flatten()
            .map(|l| (l.axis_point - l.cl).normalize())
            .collect();
        axes.windows(2)
            .map(|w| w[0].dot(&w[1]).clamp(-1.0, 1.0).acos())
            .fold(0.0, f64::max)
    };
    assert!(angles(&eased) < angles(&sharp), "{} {}", angles(&eased), angles(&sharp));
    let mut changed = 0;
    for ((e, s), c) in eased
        .iter()
        .flatten()
        .zip(sharp.iter().flatten())
        .zip(contacts.iter().flatten())
    {
        let a = (e.axis_point - e.cl).normalize();
        assert!(gc.clearance(e.cl, a, 6.0) <= GOUGE_TOL);
        for &p in &points {
            assert!(!inside_tool(cutter, e.cl, a, 6.0, p, 1e-7), "{p:?}");
        }
        if e != s {
            changed += 1;
            // An eased or re-turned tool still touches its contact: on the
            // flat bottom's rim or face.
            let d = c.cc - e.cl;
            assert!(d.dot(&a).abs() < 1e-9 && (d - a * d.dot(&a)).norm() <= 0.6 + 1e-9);
        }
    }
    assert!(changed >= t_eased.eased, "{changed} {t_eased:?}");
    // No turned location farther than the ramp from one that needed it:
    // with a ramp shorter than the spacing, nothing is eased.
    let mut short = raw.clone();
    let (_, t_short, _) = gc
        .check_tilting(&fa, &contacts, &mut short, &search(30.0, 5.0, 1e-3), Placement::Tangent)
        .unwrap();
    assert_eq!((t_short.eased, &short), (0, &sharp));
}

#[test]
fn ease_offers_the_largest_neighbouring_turn_scaled_by_distance() {
    // Five contacts a millimetre apart on a line; the middle one turned
    // 10 degrees of tilt. A 2.5 mm ramp offers 6 deg at 1 mm and 2 deg
    // at 2 mm; `place` records the offers and accepts all but the last
    // location's.
    let contacts: Vec<Contact> = (0..5)
        .map(|i| Contact {
            cc: crate::geometry::P3::new(i as f64, 0.0, 0.0),
            normal: V3::z(),
            facet: V3::z(),
            feed: V3::x(),
        })
        .collect();
    let at = |x: f64| Location {
        cl: crate::geometry::P3::new(x, 0.0, 0.0),
        axis_point: crate::geometry::P3::new(x, 0.0, 1.0),
    };
    let ten = 10f64.to_radians();
    let own: Vec<(f64, Outcome)> = (0..5)
        .map(|i| {
            if i == 2 {
                (0.1, Outcome::Tilted(at(2.0), [0.0, ten]))
            } else if i == 1 {
                // Its own smaller tilt gives way to the 6 degree offer.
                (0.05, Outcome::Tilted(at(1.0), [0.0, 3f64.to_radians()]))
            } else if i == 3 {
                // And its own lead: the larger offer is taken whichever
                // way it turns.
                (0.05, Outcome::Tilted(at(3.0), [3f64.to_radians(), 0.0]))
            } else {
                (0.0, Outcome::Clear)
            }
        })
        .collect();
    let out = ease(own, &contacts, 2.5, |c, t| {
        (c.cc.x < 4.0).then(|| at(c.cc.x + 100.0 * t[1]))
    });
    let turns: Vec<[f64; 2]> = out.iter().map(|(_, o)| o.turn()).collect();
    let deg = |t: [f64; 2]| [t[0].to_degrees(), t[1].to_degrees()];
    let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9;
    assert!(close(deg(turns[0]), [0.0, 2.0]), "{:?}", deg(turns[0]));
    assert!(close(deg(turns[1]), [0.0, 6.0]), "{:?}", deg(turns[1]));
    assert!(close(deg(turns[2]), [0.0, 10.0]));
    assert!(close(deg(turns[3]), [0.0, 6.0]), "{:?}", deg(turns[3]));
    // The last offer (2 deg) was refused by `place`: it stays clear.
    assert_eq!(out[4].1, Outcome::Clear);
    assert!(matches!(out[0].1, Outcome::Eased(..)));
    assert!(
        matches!(out[1].1, Outcome::Tilted(..)),
        "a gouging location stays tilted"
    );
    // The depths are the locations' own, whatever they were turned to.
    assert_eq!(
        out.iter().map(|o| o.0).collect::<Vec<_>>(),
        vec![0.0, 0.05, 0.1, 0.05, 0.0]
    );
    // No ramp: nothing changes.
    let own2 = out.clone();
    assert_eq!(ease(own2.clone(), &contacts, 0.0, |_, _| None), own2);
}

#[test]
fn the_envelope_of_offers_is_the_best_of_every_pair() {
    // Random passes: contacts at random spacings on a line, some turned by
    // whole steps in one of the four ways. The offers found by the
    // per-size passes equal a search over every (turned, location) pair.
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let step = 5f64.to_radians();
    for case in 0..200 {
        let n = 1 + (rnd() * 60.0) as usize;
        let ramp = 0.05 + rnd() * 3.0;
        let mut x = 0.0;
        let contacts: Vec<Contact> = (0..n)
            .map(|_| {
                x += rnd() * 0.4;
                Contact {
                    cc: crate::geometry::P3::new(x, 0.0, 0.0),
                    normal: V3::z(),
                    facet: V3::z(),
                    feed: V3::x(),
                }
            })
            .collect();
        let at = |c: &Contact| Location {
            cl: c.cc,
            axis_point: c.cc + V3::z(),
        };
        let own: Vec<(f64, Outcome)> = contacts
            .iter()
            .map(|c| {
                if rnd() < 0.3 {
                    let a = step * (1 + (rnd() * 6.0) as usize) as f64;
                    let ways = [
                        [0., 1.],
                        [0., -1.],
                        [1., 0.],
                        [-1., 0.],
                        [1., 1.],
                        [1., -1.],
                        [-1., 1.],
                        [-1., -1.],
                    ];
                    let w = ways[(rnd() * 8.0) as usize];
                    let t = [w[0] * a, w[1] * a];
                    (0.1, Outcome::Tilted(at(c), t))
                } else {
                    (0.0, Outcome::Clear)
                }
            })
            .collect();
        let s: Vec<f64> = contacts.iter().map(|c| c.cc.x).collect();
        let mut expect: Vec<[f64; 2]> = own.iter().map(|(_, o)| o.turn()).collect();
        for j in 0..n {
            let mut best = size(expect[j]);
            for i in 0..n {
                let Outcome::Tilted(_, t) = own[i].1 else { continue };
                let d = (s[j] - s[i]).abs();
                if d < ramp {
                    let w = 1.0 - d / ramp;
                    let cand = [t[0] * w, t[1] * w];
                    if size(cand) > best {
                        best = size(cand);
                        expect[j] = cand;
                    }
                }
            }
        }
        let got = ease(own, &contacts, ramp, |c, _| Some(at(c)));
        for (j, ((_, o), e)) in got.iter().zip(&expect).enumerate() {
            let t = o.turn();
            assert!(
                (t[0] - e[0]).abs() < 1e-12 && (t[1] - e[1]).abs() < 1e-12,
                "case {case}, location {j}: {t:?} against {e:?}"
            );
        }
    }
}

/// A location's search outcome with these turns (degrees: lead, tilt)
/// clearing it; the locations are placeholders (the choice reads the
/// turns only).
fn turns(ts: &[[f64; 2]]) -> (f64, Found) {
    let l = Location {
        cl: crate::geometry::P3::origin(),
        axis_point: crate::geometry::P3::new(0.0, 0.0, 1.0),
    };
    let f = Found::Turns(ts.iter().map(|t| (l, [t[0].to_radians(), t[1].to_radians()])).collect());
    (1.0, f)
}

/// The turns chosen, in degrees (0 for clear and lifted locations).
fn chosen(found: Vec<(f64, Found)>) -> Vec<[f64; 2]> {
    choose_along(found)
        .iter()
        .map(|(_, o)| {
            let t = o.turn();
            [t[0].to_degrees().round(), t[1].to_degrees().round()]
        })
        .collect()
}

#[test]
fn the_pass_keeps_one_way_where_a_location_offers_both() {
    let clear = || (0.0, Found::Clear);
    // A stretch needing +15 of lead whose middle also clears with -10:
    // +15 throughout, not a swing of 25 degrees each way.
    let got = chosen(vec![
        clear(),
        turns(&[[15.0, 0.0]]),
        turns(&[[-10.0, 0.0], [15.0, 0.0]]),
        turns(&[[15.0, 0.0]]),
        clear(),
    ]);
    assert_eq!(got, [[0.0, 0.0], [15.0, 0.0], [15.0, 0.0], [15.0, 0.0], [0.0, 0.0]]);
    // Either way serves every location: the search's order decides (tilt
    // +, the first tried), the same way throughout.
    let both = || turns(&[[0.0, 5.0], [0.0, -5.0]]);
    assert_eq!(chosen(vec![both(), both(), both()]), [[0.0, 5.0]; 3]);
    // One location can only go one way: its neighbours follow it.
    let got = chosen(vec![both(), turns(&[[0.0, -5.0]]), both()]);
    assert_eq!(got, [[0.0, -5.0]; 3]);
    // A turn much larger than needed is not worth a small change saved:
    // the size counts, at half the weight of a change.
    let got = chosen(vec![clear(), turns(&[[5.0, 0.0], [30.0, 0.0]]), clear()]);
    assert_eq!(got[1], [5.0, 0.0]);
    // Lifted locations count as no turn; an empty pass is empty.
    let got = chosen(vec![
        turns(&[[10.0, 0.0]]),
        (2.0, Found::Lifted(0.1)),
        turns(&[[10.0, 0.0]]),
    ]);
    assert_eq!(got, [[10.0, 0.0], [0.0, 0.0], [10.0, 0.0]]);
    assert!(chosen(Vec::new()).is_empty());
}

#[test]
fn on_every_corpus_mesh_the_tilt_search_leaves_no_gouge() {
    // Passes across each corpus mesh with the axis along the facets'
    // normals: after the search (turns chosen along each pass, eased, the
    // rest lifted) every location clears the part, and no turn taken goes
    // past the reach.
    let mut checked = 0;
    let mut turned = 0;
    let ran = on_corpus_passes(|f, gc, size, fa, xy| {
        let dc = gc.drop_cutter();
        let contacts = FiveAxis::contacts(dc, xy);
        let Ok(mut runs) = fa.pass(dc, xy) else { return };
        let (_, report, _) = gc
            .check_tilting(
                fa,
                &contacts,
                &mut runs,
                &search(30.0, 5.0, 0.1 * size),
                Placement::Tangent,
            )
            .unwrap();
        assert!(report.largest_turn <= 30f64.to_radians() + 1e-12, "{f:?}: {report:?}");
        turned += report.tilted;
        for l in runs.iter().flatten() {
            let a = (l.axis_point - l.cl).normalize();
            assert!(
                gc.clearance(l.cl, a, fa.axis_length) <= GOUGE_TOL * size.max(1.0),
                "{f:?}: {l:?} cuts into the part"
            );
            checked += 1;
        }
    });
    if ran.is_none() {
        crate::corpus::skip("corpus_meshes_tilt_search_clears_them");
        return;
    }
    crate::corpus::record("corpus_meshes_tilt_search_clears_them", checked);
    assert!(checked > 100, "{checked}");
    println!("{checked} locations on the corpus meshes, {turned} turned to clear them");
}

/// A floor with two walls 5 mm tall meeting in a corner: faces at x = 0.8
/// (ahead of a pass along +X) and at y = 0.8 (to its left).
fn corner() -> crate::mesh::Mesh {
    use crate::mesh::Triangle;
    let mut tris = Vec::new();
    let mut quad = |a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]| {
        let [a, b, c, d] = [a, b, c, d].map(|p| crate::geometry::P3::new(p[0], p[1], p[2]));
        tris.push(Triangle::new(a, b, c));
        tris.push(Triangle::new(a, c, d));
    };
    quad([-3.0, -3.0, 0.0], [0.8, -3.0, 0.0], [0.8, 0.8, 0.0], [-3.0, 0.8, 0.0]);
    quad([0.8, -3.0, 0.0], [0.8, 0.8, 0.0], [0.8, 0.8, 5.0], [0.8, -3.0, 5.0]);
    quad([-3.0, 0.8, 0.0], [-3.0, 0.8, 5.0], [0.8, 0.8, 5.0], [0.8, 0.8, 0.0]);
    crate::mesh::Mesh::from_triangles(&tris)
}

#[test]
fn both_angles_turn_only_where_one_angle_cannot_clear() {
    let mesh = corner();
    let xy: Vec<crate::geometry::P2> = (0..=16)
        .map(|i| crate::geometry::P2::new(-1.5 + 0.1 * i as f64, 0.1))
        .collect();
    let mut some_both = false;
    for cutter in [
        Cutter::Flat { radius: 0.6 },
        Cutter::Torus {
            radius: 0.6,
            corner: 0.2,
        },
    ] {
        for (lead, tilt) in [(5.0f64, 3.0f64), (5.0, -3.0), (-5.0, 3.0), (-5.0, -3.0)] {
            let dc = DropCutter::new(&mesh, cutter).unwrap();
            let gc = GougeCheck::new(&dc);
            let fa = FiveAxis {
                lead: lead.to_radians(),
                tilt: tilt.to_radians(),
                axis_length: 6.0,
            };
            let (contacts, raw) = (FiveAxis::contacts(&dc, &xy), fa.pass(&dc, &xy).unwrap());
            let run = |both: bool| {
                let mut runs = raw.clone();
                let s = TiltSearch {
                    both,
                    ..search(30.0, 5.0, 0.0)
                };
                let (report, tilt, _) = gc
                    .check_tilting(&fa, &contacts, &mut runs, &s, Placement::Tangent)
                    .unwrap();
                (report, tilt, runs)
            };
            let (r1, one, runs1) = run(false);
            let (r2, two, runs2) = run(true);
            assert_eq!(r1, r2, "the same gouges found");
            assert_eq!(one.both, 0);
            // The locations one angle clears are turned by one angle still; of
            // those it could not, some now turn both, the rest are lifted.
            assert_eq!(two.tilted - two.both, one.tilted, "{cutter:?}");
            assert_eq!(two.both + two.lifted, one.lifted, "{cutter:?}");
            some_both |= two.both > 0;
            // No turn goes past the reach (each angle within 30 degrees, so
            // the axis within about 42 of where it was asked), and every
            // location clears the part.
            let axis = |l: &Location| (l.axis_point - l.cl).normalize();
            for (a, r) in runs2.iter().flatten().zip(raw.iter().flatten()) {
                assert!(gc.clearance(a.cl, axis(a), 6.0) <= GOUGE_TOL);
                assert!(axis(a).angle(&axis(r)) <= 42.5f64.to_radians(), "{a:?}");
            }
            assert_eq!(runs1.len(), runs2.len());
            // Leaning into the corner (lead -5, tilt -3): turning one angle
            // away from one wall leaves the tool on the other; both clear.
            if (lead, tilt) == (-5.0, -3.0) {
                assert!(
                    one.lifted > 0 && two.lifted == 0 && two.both == one.lifted,
                    "{cutter:?}: {two:?}"
                );
            }
        }
    }
    assert!(some_both, "the trough should have locations one angle cannot clear");
}
