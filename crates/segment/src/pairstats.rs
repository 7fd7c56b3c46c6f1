//! One pass over the frames: every marker pair's distance mean and standard deviation.

use mocap_io::Trajectories;
use rayon::prelude::*;

/// Distance statistics of every marker pair over the frames where both are visible.
///
/// Stored as full symmetric `n × n` row-major matrices (n = markers); the diagonal is zero.
#[derive(Clone, Debug)]
pub(crate) struct PairStats {
    /// Number of markers.
    pub n: usize,
    /// Frames in which each marker is visible.
    pub visible: Vec<usize>,
    /// Frames in which both markers of a pair are visible.
    pub overlap: Vec<usize>,
    /// Mean distance over the co-visible frames, mm (NaN when never co-visible).
    pub mean: Vec<f64>,
    /// Population standard deviation ρ of the distance over the co-visible frames, mm.
    pub std: Vec<f64>,
}

impl PairStats {
    /// Index of the pair (i, j) in the flat matrices.
    #[inline]
    pub fn at(&self, i: usize, j: usize) -> usize {
        i * self.n + j
    }

    /// Whether the two tracks are never seen in one frame (pieces of one marker may be).
    #[inline]
    pub fn apart(&self, i: usize, j: usize) -> bool {
        self.overlap[self.at(i, j)] == 0
    }

    /// ρ of a pair in mm, or `None` when it was seen together in fewer than `min_overlap` frames.
    #[inline]
    pub fn rho(&self, i: usize, j: usize, min_overlap: usize) -> Option<f64> {
        let k = self.at(i, j);
        (i != j && self.overlap[k] >= min_overlap).then_some(self.std[k])
    }
}

/// Sums of one pair, shifted by its first co-visible distance so that the variance does not
/// cancel catastrophically (distances ~10³ mm, standard deviations ~10⁻² mm).
#[derive(Clone, Copy, Default)]
struct PairSums {
    count: usize,
    shift: f64,
    sum: f64,
    sum_sq: f64,
}

/// Lanes of the manually unrolled frame loop: fixed, so the summation order (and the
/// output bytes) do not depend on the machine, while the compiler may vectorise.
const LANES: usize = 4;

/// Computes [`PairStats`] in one pass; rows (first marker) run in parallel, each row serially.
pub(crate) fn pair_stats(traj: &Trajectories) -> PairStats {
    let n = traj.markers();
    let frames = traj.frames();
    // Marker-major, coordinate-split copy: a pair's loop then streams two short arrays
    // (≈ 3 × 8 × frames bytes each) instead of the whole frame-major capture per row.
    let mut soa = vec![f64::NAN; 3 * n * frames];
    for (f, frame) in traj.positions().chunks_exact(n.max(1)).enumerate() {
        for (m, p) in frame.iter().enumerate() {
            if mocap_io::is_present(*p) {
                for (c, v) in p.iter().enumerate() {
                    soa[(m * 3 + c) * frames + f] = *v;
                }
            }
        }
    }
    let coords = |m: usize, c: usize| &soa[(m * 3 + c) * frames..(m * 3 + c + 1) * frames];
    let visible: Vec<usize> = (0..n)
        .map(|m| coords(m, 0).iter().filter(|x| !x.is_nan()).count())
        .collect();

    let rows: Vec<Vec<PairSums>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (xi, yi, zi) = (coords(i, 0), coords(i, 1), coords(i, 2));
            (i + 1..n)
                .map(|j| pair_sums(xi, yi, zi, coords(j, 0), coords(j, 1), coords(j, 2)))
                .collect()
        })
        .collect();

    let mut stats = PairStats {
        n,
        visible,
        overlap: vec![0; n * n],
        mean: vec![f64::NAN; n * n],
        std: vec![f64::NAN; n * n],
    };
    for i in 0..n {
        stats.mean[i * n + i] = 0.0;
        stats.std[i * n + i] = 0.0;
    }
    for (i, row) in rows.iter().enumerate() {
        for (off, s) in row.iter().enumerate() {
            let j = i + 1 + off;
            let (mean, std) = if s.count == 0 {
                (f64::NAN, f64::NAN)
            } else {
                let c = s.count as f64;
                let m = s.sum / c;
                let var = (s.sum_sq / c - m * m).max(0.0);
                (s.shift + m, var.sqrt())
            };
            for (a, b) in [(i, j), (j, i)] {
                stats.overlap[a * n + b] = s.count;
                stats.mean[a * n + b] = mean;
                stats.std[a * n + b] = std;
            }
        }
    }
    stats
}

/// Shifted sums of one pair's distance over the frames where both markers are visible.
fn pair_sums(xi: &[f64], yi: &[f64], zi: &[f64], xj: &[f64], yj: &[f64], zj: &[f64]) -> PairSums {
    let dist = |f: usize| {
        let (dx, dy, dz) = (xi[f] - xj[f], yi[f] - yj[f], zi[f] - zj[f]);
        (dx * dx + dy * dy + dz * dz).sqrt()
    };
    let frames = xi.len();
    let Some(shift) = (0..frames).map(dist).find(|d| !d.is_nan()) else {
        return PairSums::default();
    };
    let mut count = [0usize; LANES];
    let mut sum = [0.0f64; LANES];
    let mut sum_sq = [0.0f64; LANES];
    let full = frames / LANES * LANES;
    let mut f = 0;
    while f < full {
        for l in 0..LANES {
            let d = dist(f + l);
            // A missing sample is NaN in one coordinate array, so its distance is NaN.
            let ok = !d.is_nan();
            let e = if ok { d - shift } else { 0.0 };
            count[l] += usize::from(ok);
            sum[l] += e;
            sum_sq[l] += e * e;
        }
        f += LANES;
    }
    for g in full..frames {
        let d = dist(g);
        if !d.is_nan() {
            let e = d - shift;
            count[0] += 1;
            sum[0] += e;
            sum_sq[0] += e * e;
        }
    }
    PairSums {
        count: count.iter().sum(),
        shift,
        sum: sum.iter().sum(),
        sum_sq: sum_sq.iter().sum(),
    }
}
