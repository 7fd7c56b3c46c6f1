//! The crate's only faer calls: the symmetric eigen-decomposition of the normalised affinity.

use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self, ComputeEigenvectors};
use faer::{Mat, Par};

/// Eigenvalues in descending order and their unit eigenvectors.
pub(crate) struct Spectrum {
    /// Eigenvalues, largest first.
    pub values: Vec<f64>,
    /// Eigenvectors as columns matching `values`, row-major `n × n`: entry (row r, column c) at `r * n + c`.
    pub vectors: Vec<f64>,
}

/// Eigen-decomposition of the symmetric row-major `n × n` matrix `a`.
///
/// Runs sequentially (`Par::Seq`): the matrices are small (markers²) and the result must
/// not depend on thread scheduling.
pub(crate) fn symmetric_eigen(a: &[f64], n: usize) -> Result<Spectrum, String> {
    let m = Mat::<f64>::from_fn(n, n, |r, c| a[r * n + c]);
    let mut u = Mat::<f64>::zeros(n, n);
    let mut s = Diag::<f64>::zeros(n);
    let par = Par::Seq;
    let scratch =
        evd::self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::Yes, par, Default::default());
    evd::self_adjoint_evd(
        m.as_ref(),
        s.as_mut(),
        Some(u.as_mut()),
        par,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    )
    .map_err(|e| format!("{e:?}"))?;
    // faer sorts ascending; we want the top of the spectrum first.
    let values: Vec<f64> = (0..n).rev().map(|c| s[c]).collect();
    let mut vectors = vec![0.0; n * n];
    for (dst, src) in (0..n).rev().enumerate() {
        for r in 0..n {
            vectors[r * n + dst] = u[(r, src)];
        }
    }
    Ok(Spectrum { values, vectors })
}
