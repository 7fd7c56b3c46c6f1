//! Rigid cliques (local-fitting paper, Sect. 3.1): sets of markers whose every pair keeps
//! its distance within the tolerance, taken greedily biggest first.

use crate::pairstats::PairStats;
use crate::rigidity::{move_markers, normalise};

/// Bron–Kerbosch calls allowed per clique search; rigid-body graphs need a few hundred,
/// the cap only bounds pathological tolerances (the best clique found so far is used).
const SEARCH_BUDGET: usize = 200_000;

/// Greedy partition of `nodes` into rigid cliques under `tol` (mm), then markers left alone
/// join the clique they are rigid with (RMS ρ ≤ `tol`), if any.
pub(crate) fn rigid_cliques(
    stats: &PairStats,
    nodes: &[usize],
    tol: f64,
    min_overlap: usize,
) -> Vec<Vec<usize>> {
    let n = nodes.len();
    let rho = |a: usize, b: usize| stats.rho(nodes[a], nodes[b], min_overlap);
    let adjacent: Vec<Vec<bool>> = (0..n)
        .map(|a| {
            (0..n)
                .map(|b| a != b && rho(a, b).is_some_and(|r| r <= tol))
                .collect()
        })
        .collect();
    let mut remaining: Vec<usize> = (0..n).collect();
    let mut clusters = Vec::new();
    while !remaining.is_empty() {
        let mut search = Search {
            adjacent: &adjacent,
            rho: &rho,
            best: Vec::new(),
            best_mean: f64::INFINITY,
            budget: SEARCH_BUDGET,
        };
        search.expand(&mut Vec::new(), remaining.clone(), Vec::new());
        let clique = if search.best.is_empty() {
            vec![remaining[0]]
        } else {
            search.best
        };
        remaining.retain(|v| !clique.contains(v));
        clusters.push(clique.into_iter().map(|v| nodes[v]).collect::<Vec<_>>());
    }
    normalise(&mut clusters);
    // Markers that fit no clique of their own (all singletons) may still be rigid with a clique.
    let mut singles_done = false;
    for _ in 0..4 {
        if singles_done {
            break;
        }
        singles_done = !move_markers(&mut clusters, stats, tol, min_overlap);
        clusters.retain(|c| !c.is_empty());
    }
    normalise(&mut clusters);
    clusters
}

/// Maximum-clique search state: the best clique so far (largest, then lowest mean ρ, then
/// lexicographically smallest), and the remaining call budget.
struct Search<'a, F: Fn(usize, usize) -> Option<f64>> {
    adjacent: &'a [Vec<bool>],
    rho: &'a F,
    best: Vec<usize>,
    best_mean: f64,
    budget: usize,
}

impl<F: Fn(usize, usize) -> Option<f64>> Search<'_, F> {
    /// Bron–Kerbosch with pivoting over candidate set `p` and excluded set `x`.
    fn expand(&mut self, r: &mut Vec<usize>, mut p: Vec<usize>, mut x: Vec<usize>) {
        if self.budget == 0 {
            return;
        }
        self.budget -= 1;
        if r.len() + p.len() < self.best.len() {
            return;
        }
        if p.is_empty() {
            if x.is_empty() {
                self.offer(r);
            }
            return;
        }
        let adj = self.adjacent;
        let pivot = p
            .iter()
            .chain(&x)
            .copied()
            .max_by_key(|&u| {
                (
                    p.iter().filter(|&&v| adj[u][v]).count(),
                    std::cmp::Reverse(u),
                )
            })
            .unwrap_or(p[0]);
        let candidates: Vec<usize> = p.iter().copied().filter(|&v| !adj[pivot][v]).collect();
        for v in candidates {
            r.push(v);
            let np = p.iter().copied().filter(|&w| adj[v][w]).collect();
            let nx = x.iter().copied().filter(|&w| adj[v][w]).collect();
            self.expand(r, np, nx);
            r.pop();
            p.retain(|&w| w != v);
            x.push(v);
        }
    }

    fn offer(&mut self, r: &[usize]) {
        let mut clique = r.to_vec();
        clique.sort_unstable();
        let (mut sum, mut count) = (0.0, 0usize);
        for (i, &a) in clique.iter().enumerate() {
            for &b in &clique[i + 1..] {
                if let Some(v) = (self.rho)(a, b) {
                    sum += v;
                    count += 1;
                }
            }
        }
        let mean = if count > 0 { sum / count as f64 } else { 0.0 };
        let better = clique.len() > self.best.len()
            || (clique.len() == self.best.len()
                && (mean < self.best_mean || (mean == self.best_mean && clique < self.best)));
        if better {
            self.best = clique;
            self.best_mean = mean;
        }
    }
}
