//! Largest eigenpair of a symmetric 4 × 4 matrix: Horn's quaternion method for the rigid
//! fits every stage runs once per frame (mocap-io's stitching of pieces, segment's fit
//! residuals and joint test, jointfit's poses), so it is shared from here, the crate they
//! all build on, and kept allocation-free and fast.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

/// Horn's symmetric 4 × 4 matrix of the cross-covariance `s[a][b] = Σ reference_a ·
/// observed_b`: its largest eigenvector is the quaternion (w, x, y, z) of the best
/// rotation, its largest eigenvalue Σ observed · (R reference) at that rotation.
pub fn horn_matrix(s: [[f64; 3]; 3]) -> [[f64; 4]; 4] {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ]
}

/// Rotation matrix (row-major) of a unit quaternion (w, x, y, z).
pub fn rotation_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            w * w - x * x + y * y - z * z,
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w - x * x - y * y + z * z,
        ],
    ]
}

/// Determinant of a 3 × 3 matrix.
pub fn det3(j: &[[f64; 3]; 3]) -> f64 {
    j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1])
        - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0])
}

/// Cyclic Jacobi on a symmetric 4 × 4 matrix (allocation-free): the matrix brought to
/// diagonal form, and with `VECTORS` the accumulated rotations (eigenvectors in columns);
/// without, the rotations are not accumulated (an eigenvalue alone is cheaper).
fn jacobi4<const VECTORS: bool>(mut m: [[f64; 4]; 4]) -> ([[f64; 4]; 4], [[f64; 4]; 4]) {
    let mut v = [[0.0; 4]; 4];
    (0..4).for_each(|i| v[i][i] = 1.0);
    for _ in 0..30 {
        let off: f64 = (0..4)
            .flat_map(|r| (r + 1..4).map(move |c| (r, c)))
            .map(|(r, c)| m[r][c] * m[r][c])
            .sum();
        let diag: f64 = (0..4).map(|r| m[r][r] * m[r][r]).sum();
        if off <= 1e-24 * diag.max(1e-300) {
            break;
        }
        for p in 0..4 {
            for q in p + 1..4 {
                if m[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                let t = if theta == 0.0 {
                    1.0
                } else {
                    theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
                };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in m.iter_mut() {
                    let (mkp, mkq) = (row[p], row[q]);
                    row[p] = c * mkp - s * mkq;
                    row[q] = s * mkp + c * mkq;
                }
                let (rp, rq) = (m[p], m[q]);
                for k in 0..4 {
                    m[p][k] = c * rp[k] - s * rq[k];
                    m[q][k] = s * rp[k] + c * rq[k];
                }
                if VECTORS {
                    for row in v.iter_mut() {
                        let (vp, vq) = (row[p], row[q]);
                        row[p] = c * vp - s * vq;
                        row[q] = s * vp + c * vq;
                    }
                }
            }
        }
    }
    (m, v)
}

/// Largest eigenvalue of a symmetric 4 × 4 matrix (allocation-free).
///
/// Newton's method on the characteristic polynomial from above, as Theobald's QCP does for
/// Horn's matrix: every root is real, so from any bound above the largest root the
/// iterates fall monotonically onto it, in a handful of steps from the Frobenius norm
/// (a tenth of the cost of Jacobi sweeps; this runs once per frame per fit). Where the
/// iteration stalls (a repeated largest root converges only linearly) Jacobi decides.
pub fn largest_eigenvalue4(m: [[f64; 4]; 4]) -> f64 {
    largest_eigenvalue4_below(m, f64::INFINITY)
}

/// [`largest_eigenvalue4`] given a bound `upper` at or above the largest eigenvalue: Newton
/// starts there where it is below the Frobenius norm. For Horn's matrix of centred point
/// sets P and Q, (|P|² + |Q|²) / 2 is such a bound (QCP's start): it exceeds the root by
/// half the fit's residual sum of squares, so for a good fit Newton starts next to it.
pub fn largest_eigenvalue4_below(m: [[f64; 4]; 4], upper: f64) -> f64 {
    largest_root4(m, upper).unwrap_or_else(|| {
        let (d, _) = jacobi4::<false>(m);
        (0..4).map(|r| d[r][r]).fold(f64::NEG_INFINITY, f64::max)
    })
}

/// The unit vector spanning the null space of a symmetric 4 × 4 matrix of rank 3: its
/// adjugate's largest column (cofactors: 3 × 3 minors); `None` when that column is too
/// short to trust (rank below 3, or not singular to rounding).
fn null_vector4(a: &[[f64; 4]; 4]) -> Option<[f64; 4]> {
    let minor = |skip_row: usize, skip_col: usize| {
        let mut m = [[0.0; 3]; 3];
        for (r, i) in (0..4).filter(|&i| i != skip_row).enumerate() {
            for (c, j) in (0..4).filter(|&j| j != skip_col).enumerate() {
                m[r][c] = a[i][j];
            }
        }
        det3(&m)
    };
    let mut best = ([0.0; 4], 0.0);
    for j in 0..4 {
        let mut col = [0.0; 4];
        for (i, v) in col.iter_mut().enumerate() {
            let sign = if (i + j) % 2 == 0 { 1.0 } else { -1.0 };
            *v = sign * minor(j, i);
        }
        let norm2: f64 = col.iter().map(|x| x * x).sum();
        if norm2 > best.1 {
            best = (col, norm2);
        }
    }
    // A rank-3 matrix has an adjugate column of the order of its three non-zero
    // eigenvalues' product; compare with the cube of its scale.
    let scale2: f64 = a.iter().flatten().map(|x| x * x).sum();
    let (col, norm2) = best;
    if !(norm2.is_finite() && norm2 > 1e-16 * scale2 * scale2 * scale2) {
        return None;
    }
    let norm = norm2.sqrt();
    Some(col.map(|x| x / norm))
}

/// Newton iterations before [`largest_root4`] gives up.
const NEWTON_STEPS: usize = 30;

/// The largest root of the characteristic polynomial of symmetric `m` by Newton's method
/// from the Frobenius norm or `upper`, whichever is less (both at or above the root);
/// `None` if it has not converged within [`NEWTON_STEPS`].
fn largest_root4(m: [[f64; 4]; 4], upper: f64) -> Option<f64> {
    // Power sums p_k = tr(mᵏ) (m symmetric: tr(m²) and tr(m⁴) are squared Frobenius
    // norms), then Newton's identities for λ⁴ + c3 λ³ + c2 λ² + c1 λ + c0.
    let mut sq = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in i..4 {
            let v = (0..4).map(|k| m[i][k] * m[k][j]).sum();
            sq[i][j] = v;
            sq[j][i] = v;
        }
    }
    let p1 = m[0][0] + m[1][1] + m[2][2] + m[3][3];
    let p2 = sq[0][0] + sq[1][1] + sq[2][2] + sq[3][3];
    let (mut p3, mut p4) = (0.0, 0.0);
    for i in 0..4 {
        for j in 0..4 {
            p3 += m[i][j] * sq[i][j];
            p4 += sq[i][j] * sq[i][j];
        }
    }
    let c3 = -p1;
    let c2 = -(p2 + c3 * p1) / 2.0;
    let c1 = -(p3 + c3 * p2 + c2 * p1) / 3.0;
    let c0 = -(p4 + c3 * p3 + c2 * p2 + c1 * p1) / 4.0;
    let scale = m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    if !scale.is_finite() {
        return None;
    }
    if scale == 0.0 {
        return Some(0.0);
    }
    // Rounding in the coefficients moves a root by about ε·scale⁴ / P'(root): below this
    // slope (a nearly repeated largest root) that is not good to 1e-12 of the scale.
    let min_slope = 1e-4 * scale * scale * scale;
    let mut x = scale.min(upper);
    for _ in 0..NEWTON_STEPS {
        let p = (((x + c3) * x + c2) * x + c1) * x + c0;
        let dp = ((4.0 * x + 3.0 * c3) * x + 2.0 * c2) * x + c1;
        if dp < min_slope {
            return None;
        }
        if p <= 0.0 {
            // At (or by rounding just past) the root.
            return Some(x);
        }
        let step = p / dp;
        x -= step;
        if step <= 1e-15 * scale {
            return Some(x);
        }
    }
    None
}

/// Largest eigenvalue of a symmetric 4 × 4 matrix and its unit eigenvector (allocation-free).
///
/// The eigenvalue as [`largest_eigenvalue4`] finds it; the eigenvector is the largest
/// column of the adjugate of m − λI, which spans its null space when λ is a simple root (the
/// slope test in `largest_root4` guarantees that). Otherwise cyclic Jacobi with
/// accumulated rotations.
pub fn largest_eigenpair4(m: [[f64; 4]; 4]) -> (f64, [f64; 4]) {
    if let Some(lambda) = largest_root4(m, f64::INFINITY) {
        let mut a = m;
        (0..4).for_each(|i| a[i][i] -= lambda);
        if let Some(v) = null_vector4(&a) {
            return (lambda, v);
        }
    }
    let (d, v) = jacobi4::<true>(m);
    let best = (0..4).fold(0, |b, i| if d[i][i] > d[b][b] { i } else { b });
    (
        d[best][best],
        [v[0][best], v[1][best], v[2][best], v[3][best]],
    )
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::{
        horn_matrix, jacobi4, largest_eigenpair4, largest_eigenvalue4, largest_eigenvalue4_below,
        largest_root4,
    };

    /// The Newton eigenvalue agrees with Jacobi's to rounding on random symmetric matrices
    /// and on Horn matrices of rigid, noisy, planar and collinear marker sets (the last two
    /// with repeated eigenvalues), so fit residuals (norms − 2λ) keep their digits.
    #[test]
    fn newton_eigenvalue_matches_jacobi() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let jacobi = |m: [[f64; 4]; 4]| {
            let (d, _) = jacobi4::<false>(m);
            (0..4).map(|r| d[r][r]).fold(f64::NEG_INFINITY, f64::max)
        };
        let mut matrices = Vec::new();
        for _ in 0..200 {
            let mut m = [[0.0; 4]; 4];
            for (i, j) in (0..4).flat_map(|i| (0..=i).map(move |j| (i, j))) {
                let v = rng.random_range(-100.0..100.0);
                m[i][j] = v;
                m[j][i] = v;
            }
            // No bound known but the norm.
            matrices.push((m, f64::INFINITY));
        }
        for shape in 0..3 {
            for _ in 0..200 {
                // Markers: general, planar (z = 0) or collinear (on x), a rotation, noise.
                let k = rng.random_range(3..7);
                let angle: f64 = rng.random_range(-3.0..3.0);
                let (c, s) = (angle.cos(), angle.sin());
                let noise = if rng.random_bool(0.5) { 0.0 } else { 1.0 };
                let mut cov = [[0.0; 3]; 3];
                // Σ |p|² + |q|²: twice a bound on the largest eigenvalue (QCP's start).
                let mut norms = 0.0;
                for _ in 0..k {
                    let mut p = [0.0; 3];
                    for (i, v) in p.iter_mut().enumerate() {
                        let free = shape == 0 || (shape == 1 && i < 2) || i == 0;
                        if free {
                            *v = rng.random_range(-200.0..200.0);
                        }
                    }
                    let q = [
                        c * p[0] - s * p[1] + noise * rng.random_range(-1.0..1.0),
                        s * p[0] + c * p[1] + noise * rng.random_range(-1.0..1.0),
                        p[2] + noise * rng.random_range(-1.0..1.0),
                    ];
                    for r in 0..3 {
                        for col in 0..3 {
                            cov[r][col] += p[r] * q[col];
                        }
                        norms += p[r] * p[r] + q[r] * q[r];
                    }
                }
                matrices.push((horn_matrix(cov), norms / 2.0));
            }
        }
        let mut newton = 0;
        for (m, upper) in matrices {
            let scale = m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
            let slow = jacobi(m);
            for fast in [largest_eigenvalue4(m), largest_eigenvalue4_below(m, upper)] {
                assert!(
                    (fast - slow).abs() <= 1e-11 * scale.max(1.0),
                    "{fast} vs {slow} (scale {scale}, bound {upper}) for {m:?}"
                );
            }
            newton += usize::from(largest_root4(m, upper).is_some());
        }
        // The fast path is the common one; Jacobi only settles repeated roots.
        assert!(newton >= 600, "Newton converged on {newton} of 800");
    }

    /// The eigenvector belongs to the largest eigenvalue: m v = λ v to rounding, unit length.
    #[test]
    fn eigenpair_satisfies_its_equation() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for _ in 0..500 {
            let mut cov = [[0.0; 3]; 3];
            for row in cov.iter_mut() {
                for v in row.iter_mut() {
                    *v = rng.random_range(-1000.0..1000.0);
                }
            }
            let m = horn_matrix(cov);
            let (lambda, v) = largest_eigenpair4(m);
            let scale = m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
            // The largest: no eigenvalue Jacobi finds is above it.
            let (d, _) = jacobi4::<false>(m);
            assert!((0..4).all(|r| d[r][r] <= lambda + 1e-11 * scale));
            assert!((v.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-12);
            for (i, row) in m.iter().enumerate() {
                let mv: f64 = row.iter().zip(&v).map(|(a, b)| a * b).sum();
                assert!(
                    (mv - lambda * v[i]).abs() <= 1e-9 * scale,
                    "{mv} vs {}",
                    lambda * v[i]
                );
            }
        }
    }
}
