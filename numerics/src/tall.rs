//! Dense products of tall matrices (n rows ≫ columns: a basis of vectors of the mesh's size),
//! parallel over blocks of rows with rayon.
//!
//! Why not `Par::rayon` inside faer's own GEMM: it synchronises its threads with spinning
//! barriers, so one thread descheduled by any other load (a compiler, the viewer's haptic and
//! drawing threads, a browser) stalls the others at every barrier. Measured on the mould
//! (63k unknowns, 30 modes, 2 cores, a `nice 19` compiler beside it): the eigen-solver's
//! Gram–Schmidt took 8.4 s on both cores against 0.79 s on one. Blocks of rows are
//! independent here: a late block delays only itself, and idle threads take the next one.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// Rows per block: large enough that each block's product is efficient, small enough that two
/// cores share the work evenly.
const ROWS: usize = 4096;

/// aᵀ b for tall a (n × p) and b (n × q): the sum of the blocks' products.
pub fn t_times(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    assert_eq!(a.nrows(), b.nrows(), "aᵀb needs the same rows");
    if a.nrows() <= ROWS {
        let mut out = Mat::zeros(a.ncols(), b.ncols());
        matmul(out.as_mut(), Accum::Replace, a.transpose(), b, 1.0, Par::Seq);
        return out;
    }
    let mid = a.nrows() / 2;
    let (a0, a1) = a.split_at_row(mid);
    let (b0, b1) = b.split_at_row(mid);
    let (mut x, y) = rayon::join(|| t_times(a0, b0), || t_times(a1, b1));
    x += &y;
    x
}

/// out ← alpha a s (`Accum::Replace`) or out ← out + alpha a s (`Accum::Add`), for tall a
/// (n × p) and small s (p × q): each block of rows on its own.
pub fn times(out: MatMut<'_, f64>, accum: Accum, a: MatRef<'_, f64>, s: MatRef<'_, f64>, alpha: f64) {
    assert_eq!(out.nrows(), a.nrows(), "a s needs out and a with the same rows");
    if a.nrows() <= ROWS {
        matmul(out, accum, a, s, alpha, Par::Seq);
        return;
    }
    let mid = a.nrows() / 2;
    let (o0, o1) = out.split_at_row_mut(mid);
    let (a0, a1) = a.split_at_row(mid);
    rayon::join(|| times(o0, accum, a0, s, alpha), || times(o1, accum, a1, s, alpha));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both products against faer's own sequential GEMM, on sizes that split unevenly.
    #[test]
    fn blocked_products_equal_one_gemm() {
        let (n, p, q) = (3 * ROWS + 17, 7, 5);
        let a = Mat::<f64>::from_fn(n, p, |i, j| ((i * 31 + j * 7) % 101) as f64 / 101.0 - 0.5);
        let b = Mat::<f64>::from_fn(n, q, |i, j| ((i * 13 + j * 29) % 97) as f64 / 97.0 - 0.5);
        let s = Mat::<f64>::from_fn(p, q, |i, j| (i as f64 + 1.0) / (j as f64 + 2.0));
        let mut want = Mat::<f64>::zeros(p, q);
        matmul(want.as_mut(), Accum::Replace, a.transpose(), b.as_ref(), 1.0, Par::Seq);
        let got = t_times(a.as_ref(), b.as_ref());
        assert!((&got - &want).norm_max() <= 1e-9 * want.norm_max(), "aᵀb");

        let mut want = b.clone();
        matmul(want.as_mut(), Accum::Add, a.as_ref(), s.as_ref(), -2.0, Par::Seq);
        let mut got = b.clone();
        times(got.as_mut(), Accum::Add, a.as_ref(), s.as_ref(), -2.0);
        assert_eq!((&got - &want).norm_max(), 0.0, "b − 2 a s, block by block");
        let mut got = Mat::<f64>::zeros(n, q);
        times(got.as_mut(), Accum::Replace, a.as_ref(), s.as_ref(), 1.0);
        let mut want = Mat::<f64>::zeros(n, q);
        matmul(want.as_mut(), Accum::Replace, a.as_ref(), s.as_ref(), 1.0, Par::Seq);
        assert_eq!((&got - &want).norm_max(), 0.0, "a s");
    }
}
