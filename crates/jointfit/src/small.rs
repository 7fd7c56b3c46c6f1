//! Allocation-free symmetric eigen-decomposition of tiny matrices (3×3, 4×4, 6×6).
//!
//! Cyclic Jacobi rotations: a handful of sweeps reach machine precision for these sizes,
//! and the eigenvectors come out orthonormal even when eigenvalues are (nearly) repeated,
//! which matters for hinge and rigid pairs where the normal equations are singular.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

/// Eigenvalues (descending) and eigenvectors (`vectors[k]` belongs to `values[k]`) of a
/// symmetric `N×N` matrix; only the lower triangle of `a` is read.
pub(crate) fn sym_eigen<const N: usize>(a: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut m = a;
    for i in 0..N {
        for j in (i + 1)..N {
            m[i][j] = m[j][i];
        }
    }
    let mut v = [[0.0; N]; N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let scale: f64 = m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    if scale > 0.0 && scale.is_finite() {
        for _sweep in 0..60 {
            let off: f64 = (0..N)
                .flat_map(|i| ((i + 1)..N).map(move |j| (i, j)))
                .map(|(i, j)| m[i][j] * m[i][j])
                .sum();
            if off.sqrt() <= 1e-17 * scale {
                break;
            }
            for p in 0..N {
                for q in (p + 1)..N {
                    let apq = m[p][q];
                    if apq == 0.0 {
                        continue;
                    }
                    // Rotation angle that zeroes m[p][q] (Golub & Van Loan, sym.schur2).
                    let theta = (m[q][q] - m[p][p]) / (2.0 * apq);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let t = if theta == 0.0 { 1.0 } else { t };
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for k in 0..N {
                        let mkp = m[k][p];
                        let mkq = m[k][q];
                        m[k][p] = c * mkp - s * mkq;
                        m[k][q] = s * mkp + c * mkq;
                    }
                    for k in 0..N {
                        let mpk = m[p][k];
                        let mqk = m[q][k];
                        m[p][k] = c * mpk - s * mqk;
                        m[q][k] = s * mpk + c * mqk;
                    }
                    for row in v.iter_mut() {
                        let vp = row[p];
                        let vq = row[q];
                        row[p] = c * vp - s * vq;
                        row[q] = s * vp + c * vq;
                    }
                }
            }
        }
    }
    // Sort descending; columns of `v` are eigenvectors, return them as rows.
    let mut order = [0usize; N];
    for (i, o) in order.iter_mut().enumerate() {
        *o = i;
    }
    order.sort_by(|&i, &j| m[j][j].total_cmp(&m[i][i]));
    let mut values = [0.0; N];
    let mut vectors = [[0.0; N]; N];
    for (k, &i) in order.iter().enumerate() {
        values[k] = m[i][i];
        for r in 0..N {
            vectors[k][r] = v[r][i];
        }
    }
    (values, vectors)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_reconstructs_matrix() {
        let a = [
            [4.0, 1.0, -2.0, 0.5],
            [1.0, 3.0, 0.0, 0.2],
            [-2.0, 0.0, 5.0, 1.0],
            [0.5, 0.2, 1.0, -1.0],
        ];
        let (vals, vecs) = sym_eigen(a);
        assert!(vals.windows(2).all(|w| w[0] >= w[1]));
        for i in 0..4 {
            for j in 0..4 {
                let r: f64 = (0..4).map(|k| vals[k] * vecs[k][i] * vecs[k][j]).sum();
                assert!((r - a[i][j]).abs() < 1e-12, "{i} {j}: {r} vs {}", a[i][j]);
                let d: f64 = (0..4).map(|k| vecs[i][k] * vecs[j][k]).sum();
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((d - e).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn eigen_handles_repeated_and_zero() {
        let (vals, _) = sym_eigen([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0]]);
        assert_eq!(vals, [2.0, 2.0, 0.0]);
        let (vals, _) = sym_eigen([[0.0; 6]; 6]);
        assert_eq!(vals, [0.0; 6]);
    }
}
