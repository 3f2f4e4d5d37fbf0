//! The graph walk: pieces joined at their nodes into chains, open chains
//! from the nodes of degree other than two first, then the cycles; each
//! chain's pieces snapped onto its nodes and its repairs gathered.

use super::assign;
use super::repair::{remove_duplicates, snap, zero_length_and_collinear};
use super::{ChainReport, Chains, Item, Notes, REPORT_GAP, Work, push_num};
use rayon::prelude::*;

/// Chain the pieces of one layer (`w`, whose first piece is number `base`
/// of the drawing) into `out`.
pub(super) fn chain_layer(
    w: &mut [Work],
    base: u32,
    layer: u32,
    tol: f64,
    report: &mut ChainReport,
    out: &mut Chains,
    repairs_out: &mut Vec<(u32, Vec<String>)>,
) {
    let mut notes = Notes::default();
    // 1. Zero-length pieces, collinear overlaps.
    zero_length_and_collinear(w, &mut notes, tol, report);
    crate::progress::lap("chain: zero length, collinear");

    // 2. End points to nodes.
    let nodes = assign::assign(w, tol);
    let (ends, n_nodes) = (&nodes.ends, nodes.len());
    crate::progress::lap("chain: nodes");

    // 3. Duplicates between the same pair of nodes, and the nodes'
    // adjacency lists of the pieces left.
    let (start_idx, adj) = remove_duplicates(w, ends, n_nodes, &mut notes, tol, report);
    crate::progress::lap("chain: duplicates");

    // 4. Walk the graph: open chains from nodes of degree != 2, then cycles.
    let degree = |n: u32| start_idx[n as usize + 1] - start_idx[n as usize];
    let mut used = vec![false; w.len()];
    // Each walk fills `run` (reused) and is turned into a chain at once:
    // no list of all runs is ever held.
    let walk = |first_node: u32, first: usize, used: &mut Vec<bool>, run: &mut Vec<(usize, bool)>| -> u32 {
        run.clear();
        let mut cur = first_node;
        let mut s = first;
        loop {
            used[s] = true;
            let (a, b) = ends[s];
            let fwd = a == cur;
            let next = if fwd { b } else { a };
            run.push((s, fwd));
            cur = next;
            if cur == first_node || degree(cur) != 2 {
                break;
            }
            let lo = start_idx[cur as usize] as usize;
            let hi = start_idx[cur as usize + 1] as usize;
            match adj[lo..hi].iter().find(|&&t| !used[t as usize]) {
                Some(&t) => s = t as usize,
                None => break,
            }
        }
        cur
    };
    // Which nodes closed a gap worth a note, read twice per piece by the
    // walk: a byte per node, made on the pool, instead of the node's gap
    // looked up through the sides of the clustering.
    let gappy: Vec<bool> = (0..n_nodes as u32)
        .into_par_iter()
        .with_min_len(1 << 12)
        .map(|n| nodes.gap(n) > REPORT_GAP)
        .collect();
    let mut run: Vec<(usize, bool)> = Vec::new();
    // Each walked piece's direction of travel: the pieces are snapped onto
    // their nodes after the walk, on the pool (the walk never reads a
    // piece's geometry).
    let mut forward = vec![false; w.len()];
    // Each chain's repair notes and the nodes where it closed a gap; the
    // gaps' messages are formatted after the walk, on the pool.
    let mut chain_repairs: Vec<(u32, Vec<String>, Vec<u32>)> = Vec::new();
    let mut emit = |run: &[(usize, bool)], first: u32, last: u32| {
        let start = out.seq.len() as u32;
        let mut repairs: Vec<String> = Vec::new();
        let mut order = u32::MAX;
        let mut gap_nodes: Vec<u32> = Vec::new();
        for &(i, fwd) in run {
            order = order.min(w[i].order);
            let (a, b) = ends[i];
            let (na, nb) = if fwd { (a, b) } else { (b, a) };
            forward[i] = fwd;
            out.seq.push(base + i as u32);
            if !notes.is_empty()
                && let Some(mut v) = notes.remove(&i)
            {
                repairs.append(&mut v);
            }
            for n in [na, nb] {
                if gappy[n as usize] && !gap_nodes.contains(&n) {
                    gap_nodes.push(n);
                }
            }
        }
        for &n in &gap_nodes {
            report.gaps_closed += 1;
            report.max_gap = report.max_gap.max(nodes.gap(n));
        }
        if !repairs.is_empty() || !gap_nodes.is_empty() {
            chain_repairs.push((out.items.len() as u32, repairs, gap_nodes));
        }
        out.items.push(Item {
            start,
            len: out.seq.len() as u32 - start,
            order,
            layer,
            closed: first == last,
            reversed: false,
        });
    };
    for n in 0..n_nodes as u32 {
        if degree(n) == 2 {
            continue;
        }
        let lo = start_idx[n as usize] as usize;
        let hi = start_idx[n as usize + 1] as usize;
        for &s in &adj[lo..hi] {
            let s = s as usize;
            if !used[s] {
                let last = walk(n, s, &mut used, &mut run);
                emit(&run, n, last);
            }
        }
    }
    // What is left unused and alive are the cycles. `used` first: it is
    // dense, and the 88-byte pieces are read only for the few it leaves.
    for i in 0..w.len() {
        if !used[i] && w[i].alive {
            let last = walk(ends[i].0, i, &mut used, &mut run);
            emit(&run, ends[i].0, last);
        }
    }
    crate::progress::lap("chain: walk");
    chain_repairs.par_iter_mut().for_each(|(_, repairs, gap_nodes)| {
        for &n in gap_nodes.iter() {
            let p = nodes.rep(n);
            // Pieces pushed in place: `format!` and three number strings
            // cost about half a microsecond a note.
            let mut note = String::with_capacity(48);
            note.push_str("gap of ");
            push_num(&mut note, nodes.gap(n));
            note.push_str(" mm closed at [");
            push_num(&mut note, p.x);
            note.push_str(", ");
            push_num(&mut note, p.y);
            note.push(']');
            repairs.push(note);
        }
    });
    repairs_out.extend(chain_repairs.into_iter().map(|(k, repairs, _)| (k, repairs)));
    // Snapped in place, turned to the direction of travel.
    w.par_iter_mut().enumerate().for_each(|(i, x)| {
        if used[i] {
            let (a, b) = ends[i];
            let (na, nb, seg) = if forward[i] {
                (a, b, x.seg)
            } else {
                (b, a, x.seg.reversed())
            };
            x.seg = snap(&seg, nodes.rep(na), nodes.rep(nb));
        }
    });
    // The layer's graph is some 20 MB in a handful of arrays: unmapping
    // them took 1.5 ms of this thread on the mix benchmark. A worker does
    // it while the next layer, or the orientation, goes on.
    rayon::spawn(move || drop((nodes, start_idx, adj, used, forward, gappy)));
    crate::progress::lap("chain: notes and snap");
}
