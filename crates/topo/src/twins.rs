//! Twins hang on one parent: a segment the spanning tree hung on a segment built like
//! itself is moved to that segment's parent.
//!
//! Two like limbs on one body meet it close together (two clavicles on the sternum, two
//! coxae on a hexapod's body), so each fits a centre with the other about as well as with
//! the body, and the costs alone can hang one on the other. The tree then shows it: Y hangs
//! on X, and what hangs below Y is what hangs below X besides Y, bone for bone (the same
//! branching, bone lengths alike). A body part is built like its mirror image, not like the
//! segment it hangs from, so where the pair of Y with X's parent P is also a fair joint
//! (`twin_cost_ratio`), Y is moved to P. Twins are limbs: chains of at least two bones
//! below the two segments (one bone of a like length is a coin toss), and not a segment
//! carrying several branches (rather a body cut in pieces).
//!
//! Where one of X and Y is posed through their very joint (two markers and the centre as
//! the other carries it: `PairFit::posed_through`), that edge is cheap by construction,
//! and Y's pair with P is weighed against the larger of it and X's own joint with P: a
//! twin hung on P costs about what its twin's joint there does.
//!
//! A leaf hung on one twin that fits a centre with the other twin and with their parent
//! about as well (`twin_leaf_cost_ratio`) sits where the twins meet the parent, not on
//! one twin's far side (where a hand or a paw hangs, away from the mirror limb): it moves
//! to the parent (a head the tree hung on a clavicle). A leaf posed through its joint with
//! the twin (two markers and that joint's centre) has that pair cheap by construction, so
//! its other pairs cannot be weighed against it: it moves when the parent's centre held its
//! markers next best, nearly as well (`twin_leaf_anchor_ratio`,
//! `PairFit::next_best_anchor`). Such leaves are set aside when twins are compared, since
//! one twin carries them and the other does not.

use jointfit::{JointKind, PairFits};

use crate::Params;

/// A tree edge as the spanning tree accepts it: (segment a, segment b, pair index, cost).
pub(crate) type Edge = (usize, usize, usize, f64);

/// What hangs below a segment, as its tree shows it: the branching (a canonical nested
/// string, children in a fixed order) and every bone's length in that order (mm: from the
/// joint the segment is entered by to each child's joint, in the segment's frame).
#[derive(Debug)]
struct Branch {
    shape: String,
    lengths: Vec<f64>,
}

/// Euclidean distance, mm.
fn distance(p: [f64; 3], q: [f64; 3]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// The branch below `node`, entered at `entry` (its parent joint's centre, in `node`'s
/// frame), not descending into `blocked` neighbours.
fn branch(
    node: usize,
    entry: [f64; 3],
    blocked: &[usize],
    neighbours: &[Vec<(usize, usize)>],
    edges: &[Edge],
    fits: &PairFits,
) -> Branch {
    let mut children: Vec<(String, f64, Vec<f64>)> = neighbours[node]
        .iter()
        .filter(|(c, _)| !blocked.contains(c))
        .map(|&(c, e)| {
            let pair = &fits.pairs[edges[e].2];
            let below = branch(c, pair.centre_in(c), &[node], neighbours, edges, fits);
            (
                below.shape,
                distance(pair.centre_in(node), entry),
                below.lengths,
            )
        })
        .collect();
    children.sort_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
    let mut shape = String::from("(");
    let mut lengths = Vec::new();
    for (child_shape, length, below) in children {
        shape.push_str(&child_shape);
        lengths.push(length);
        lengths.extend(below);
    }
    shape.push(')');
    Branch { shape, lengths }
}

/// Where `leaf` is posed through the joint `pair` (its edge to a twin) and the twins'
/// parent `p` held its markers next best, within `twin_leaf_anchor_ratio` × that joint's
/// radial residual: the ratio. Such an edge is cheap by construction, so the leaf's other
/// pairs cannot be weighed against its cost.
fn parent_holds_leaf(
    fits: &PairFits,
    pair: usize,
    leaf: usize,
    p: usize,
    params: &Params,
) -> Option<f64> {
    let fit = &fits.pairs[pair];
    let (next, ratio) = fit.next_best_anchor?;
    (fit.posed_through == Some(leaf) && next == p && ratio < params.twin_leaf_anchor_ratio)
        .then_some(ratio)
}

/// The pair (a, b)'s index and its cost over `cost` when that is finite and at most `bound`.
fn fair_pair(fits: &PairFits, a: usize, b: usize, cost: f64, bound: f64) -> Option<(usize, f64)> {
    let i = fits.pair_index(a, b)?;
    let ratio = fits.pairs[i].cost / cost;
    (ratio.is_finite() && ratio <= bound).then_some((i, ratio))
}

/// What a twin Y's pair with X's parent is weighed against: Y's edge to X, the cost of the
/// pair the move replaces; but where one of X and Y is posed through that very joint its
/// cost is low by construction (a two-marker clavicle posed through the other clavicle
/// keeps its centre there by its own fit), and a twin hung on the parent costs about what
/// X's own joint with the parent does: the larger of the two.
fn twin_scale(fits: &PairFits, pair: usize, cost: f64, parent_cost: f64) -> f64 {
    if fits.pairs[pair].posed_through.is_some() && parent_cost.is_finite() {
        cost.max(parent_cost)
    } else {
        cost
    }
}

/// Fewest bones below a twin: one bone of a like length is a coin toss in a random tree
/// (random-hard-s40070: two segments with one child each, bones of 501 and 592 mm).
const MIN_BONES: usize = 2;

/// Whether two branches are built alike: the same chain (one child per segment: a limb; a
/// segment carrying several branches like another is rather a body cut in pieces, as a
/// hexapod's body split with its coxae), at least [`MIN_BONES`] bones, and every bone
/// within `tolerance` × the longer of the two.
fn alike(x: &Branch, y: &Branch, tolerance: f64) -> bool {
    x.shape == y.shape
        && !x.shape.contains(")(")
        && x.lengths.len() >= MIN_BONES
        && x.lengths
            .iter()
            .zip(&y.lengths)
            .all(|(&a, &b)| a.is_finite() && b.is_finite() && (a - b).abs() <= tolerance * a.max(b))
}

/// Moves each segment Y that the tree hangs on a twin X to X's parent P (see the module
/// docs), best first (the move whose new pair costs least against the edge it replaces),
/// each segment at most once; an edge `fixed` marks (`topo.joints`) stays. Gives a note per
/// move.
pub(crate) fn hang_twins_on_one_parent(
    edges: &mut [Edge],
    fixed: &[bool],
    fits: &PairFits,
    n: usize,
    params: &Params,
) -> Vec<String> {
    let mut notes = Vec::new();
    if params.twin_cost_ratio <= 0.0 {
        return notes;
    }
    let mut moved = vec![false; n];
    loop {
        let neighbours = tree_neighbours(edges, n);
        // (new cost over the replaced edge's, edge, Y, P, the new pair's index)
        let mut best: Option<(f64, usize, usize, usize, usize)> = None;
        for (e, &(a, b, pair, cost)) in edges.iter().enumerate() {
            // A rigid pair is one body split in two, not a limb on its twin; a fixed edge
            // is the user's (`topo.joints`).
            if fixed[e] || fits.pairs[pair].tree_kind() == JointKind::Rigid {
                continue;
            }
            for (x, y) in [(a, b), (b, a)] {
                if moved[y] {
                    continue;
                }
                for &(p, pe) in &neighbours[x] {
                    if p == y {
                        continue;
                    }
                    let scale = twin_scale(fits, pair, cost, edges[pe].3);
                    let Some((pi, ratio)) = fair_pair(fits, p, y, scale, params.twin_cost_ratio)
                    else {
                        continue;
                    };
                    let py = &fits.pairs[pi];
                    let below_y = branch(y, py.centre_in(y), &[x], &neighbours, edges, fits);
                    let px = &fits.pairs[edges[pe].2];
                    let mut blocked = vec![p, y];
                    blocked.extend(shared_leaves(x, p, y, &neighbours, edges, fits, params));
                    let below_x = branch(x, px.centre_in(x), &blocked, &neighbours, edges, fits);
                    if !alike(&below_x, &below_y, params.twin_length_tolerance) {
                        continue;
                    }
                    let key = (ratio, e, y, p, pi);
                    if best.is_none_or(|b| (key.0, key.1, key.2, key.3) < (b.0, b.1, b.2, b.3)) {
                        best = Some(key);
                    }
                }
            }
        }
        let Some((ratio, e, y, p, pi)) = best else {
            break;
        };
        let x = if edges[e].0 == y {
            edges[e].1
        } else {
            edges[e].0
        };
        let against = match fits.pairs[edges[e].2].posed_through {
            Some(s) => format!(
                "the larger of its pair with {x} (low by construction: segment {s} is posed \
                 through it) and {x}'s with {p}"
            ),
            None => format!("its pair with {x}"),
        };
        notes.push(format!(
            "segment {y} hung on segment {p}, not on {x}: what hangs below {y} is built like \
             what else hangs below {x} (twins on one parent), and its pair with {p} costs \
             {ratio:.2} × {against} (topo.twin_cost_ratio)"
        ));
        edges[e] = (p.min(y), p.max(y), pi, fits.pairs[pi].cost);
        moved[y] = true;
    }
    notes
}

/// The leaves hung on `x` (nothing below them) that fit a centre with `p` and with `y`
/// too, each pair within `twin_leaf_cost_ratio` × the leaf's edge to `x`, or that are
/// posed through their edge to `x` with `p` next best ([`parent_holds_leaf`]).
fn shared_leaves(
    x: usize,
    p: usize,
    y: usize,
    neighbours: &[Vec<(usize, usize)>],
    edges: &[Edge],
    fits: &PairFits,
    params: &Params,
) -> Vec<usize> {
    if params.twin_leaf_cost_ratio <= 0.0 {
        return Vec::new();
    }
    let fair = |leaf: usize, other: usize, cost: f64| {
        fair_pair(fits, leaf, other, cost, params.twin_leaf_cost_ratio).is_some()
    };
    neighbours[x]
        .iter()
        .filter(|&&(l, e)| {
            l != p
                && l != y
                && neighbours[l].len() == 1
                && ((fair(l, p, edges[e].3) && fair(l, y, edges[e].3))
                    || parent_holds_leaf(fits, edges[e].2, l, p, params).is_some())
        })
        .map(|&(l, _)| l)
        .collect()
}

/// Moves each leaf L hung on one of two twins X, Y (siblings on P, built alike: see the
/// module docs) to P when L fits a centre with P and with Y about as well as with X
/// (`twin_leaf_cost_ratio`): a segment hung on a limb sits at the limb's far side, away
/// from its mirror twin; one that fits both twins alike sits where they meet their
/// parent (a head between the clavicles). No edge among X, Y, P and L may be rigid (a
/// rigid pair is one body split in two, not a limb), and an edge `fixed` marks
/// (`topo.joints`) stays. Best first, each leaf at most once. Gives a note per move.
pub(crate) fn hang_shared_leaves_on_the_twins_parent(
    edges: &mut [Edge],
    fixed: &[bool],
    fits: &PairFits,
    n: usize,
    params: &Params,
) -> Vec<String> {
    let mut notes = Vec::new();
    if params.twin_leaf_cost_ratio <= 0.0 || params.twin_cost_ratio <= 0.0 {
        return notes;
    }
    let rigid = |edges: &[Edge], e: usize| fits.pairs[edges[e].2].tree_kind() == JointKind::Rigid;
    let mut moved = vec![false; n];
    loop {
        let neighbours = tree_neighbours(edges, n);
        // (new cost over the replaced edge's, or the anchor ratio, edge, leaf, P, the new
        // pair's index, Y, whether the anchor ratio moved it)
        let mut best: Option<(f64, usize, usize, usize, usize, usize, bool)> = None;
        for (e, &(a, b, _, cost)) in edges.iter().enumerate() {
            if fixed[e] || rigid(edges, e) {
                continue;
            }
            for (x, l) in [(a, b), (b, a)] {
                if moved[l] || neighbours[l].len() != 1 {
                    continue;
                }
                for &(p, pe) in &neighbours[x] {
                    if p == l || rigid(edges, pe) {
                        continue;
                    }
                    let bound = params.twin_leaf_cost_ratio;
                    let held = parent_holds_leaf(fits, edges[e].2, l, p, params);
                    let Some((pi, ratio, by_anchor)) = fair_pair(fits, p, l, cost, bound)
                        .map(|(pi, ratio)| (pi, ratio, false))
                        .or_else(|| Some((fits.pair_index(p, l)?, held?, true)))
                    else {
                        continue;
                    };
                    for &(y, ye) in &neighbours[p] {
                        if y == x || rigid(edges, ye) {
                            continue;
                        }
                        if held.is_none() && fair_pair(fits, y, l, cost, bound).is_none() {
                            continue;
                        }
                        let below = |s: usize, t: usize, se: usize| {
                            let mut blocked = vec![p];
                            blocked.extend(shared_leaves(
                                s,
                                p,
                                t,
                                &neighbours,
                                edges,
                                fits,
                                params,
                            ));
                            let entry = fits.pairs[edges[se].2].centre_in(s);
                            branch(s, entry, &blocked, &neighbours, edges, fits)
                        };
                        if !alike(
                            &below(x, y, pe),
                            &below(y, x, ye),
                            params.twin_length_tolerance,
                        ) {
                            continue;
                        }
                        let key = (ratio, e, l, p, pi, y, by_anchor);
                        if best.is_none_or(|b| (key.0, key.1, key.2, key.3) < (b.0, b.1, b.2, b.3))
                        {
                            best = Some(key);
                        }
                    }
                }
            }
        }
        let Some((ratio, e, l, p, pi, y, by_anchor)) = best else {
            break;
        };
        let x = if edges[e].0 == l {
            edges[e].1
        } else {
            edges[e].0
        };
        notes.push(if by_anchor {
            format!(
                "segment {l} hung on segment {p}, not on {x}: it is posed through its joint \
                 with {x} ({y}'s twin), and {p}'s centre holds its markers next best, \
                 {ratio:.2} × that joint's radial residual (topo.twin_leaf_anchor_ratio), so \
                 it sits where the twins meet {p}"
            )
        } else {
            format!(
                "segment {l} hung on segment {p}, not on {x}: it fits a centre with {x}'s twin \
                 {y} and with {p} about as well (its pair with {p} costs {ratio:.2} × its pair \
                 with {x}; topo.twin_leaf_cost_ratio), so it sits where the twins meet {p}"
            )
        });
        edges[e] = (p.min(l), p.max(l), pi, fits.pairs[pi].cost);
        moved[l] = true;
    }
    notes
}

/// Each segment's tree neighbours, (neighbour, edge index), in a fixed order.
fn tree_neighbours(edges: &[Edge], n: usize) -> Vec<Vec<(usize, usize)>> {
    let mut neighbours: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (e, &(a, b, _, _)) in edges.iter().enumerate() {
        neighbours[a].push((b, e));
        neighbours[b].push((a, e));
    }
    for list in &mut neighbours {
        list.sort_unstable();
    }
    neighbours
}
