//! Block shift-invert Krylov–Schur (thick-restart block Lanczos in the M inner product).
//!
//! The operator is T = (K − σM)⁻¹M, M-self-adjoint, whose largest eigenvalues θ = 1/(λ − σ)
//! are the wanted λ. Each step solves with a block of `block` right-hand sides: the sparse
//! triangular solves are memory-bound, and one pass over the factor serves the whole block
//! (docs/benchmarks.md: 3.6× less time per vector at 8). Everything else is dense BLAS-3 on
//! both cores: the basis V is kept with W = MV, so M-inner products are plain GEMMs, with full
//! re-orthogonalisation (classical Gram–Schmidt twice) and SVQB block orthonormalisation.
//! When the basis is full it restarts thick: the best Ritz vectors are kept (Krylov–Schur),
//! so converged ones stay converged without explicit locking.
//!
//! The Ritz residual ‖T x − θ x‖_M is ‖B y‖ (B the coupling of the next block) and a pair is
//! accepted when it is ≤ tol·θ — ARPACK's criterion, so both paths promise the same; the mode
//! checks and the Sturm count after it do not trust either.

use super::dense::self_adjoint_eigen_qr;
use super::{EigenProblem, EigenSolver, ModesError, Spectrum};
use crate::linsolve::{Cholesky, sym_matmul};
use crate::tall;
use faer::{Accum, Mat, MatMut, MatRef};
use std::time::Instant;

/// Block Krylov–Schur with a METIS-ordered sparse Cholesky factor of K − σM.
pub struct BlockKrylov<'g> {
    /// K and M.
    pub problem: &'g EigenProblem<'g>,
    /// Fill-reducing ordering of the free DOFs (new→old, old→new).
    pub ordering: &'g (Vec<usize>, Vec<usize>),
    /// Relative tolerance on the Ritz residuals (as ARPACK's `tol`; never below round-off).
    pub tol: f64,
    /// Right-hand sides per solve.
    pub block: usize,
}

/// Vectors in the basis for `nev` wanted pairs and blocks of `b`.
fn basis_size(nev: usize, b: usize) -> usize {
    (3 * nev).max(nev + 4 * b).div_ceil(b) * b
}

impl BlockKrylov<'_> {
    /// Bytes of the basis and its M-image for `n` unknowns and `nev` pairs: what the block
    /// solver holds in place of ARPACK's Krylov vectors (about 3× as many).
    pub fn basis_bytes(n: usize, nev: usize, b: usize) -> usize {
        2 * (basis_size(nev, b) + b) * n * std::mem::size_of::<f64>()
    }
}

/// Restarts before giving up (each restart keeps the best half of the basis).
const MAX_RESTARTS: usize = 300;

/// SVQB runs a second pass unless the Gram matrix of the block had a condition number below
/// this (its orthonormality error is ~ε·κ): on the mould κ was 1.3–7 for every block.
const SVQB_ONCE: f64 = 1e2;

/// A block direction whose M-norm² after orthogonalisation is below this fraction of what it
/// was before lies in the basis already (an invariant subspace): it is replaced by a random one.
const DEFLATION: f64 = 1e-24;

impl EigenSolver for BlockKrylov<'_> {
    fn lowest(&self, nev: usize, sigma: f64) -> Result<Spectrum, ModesError> {
        let problem = self.problem;
        let n = problem.size();
        let b = self.block.max(1);
        // Basis size: three times the wanted count and at least four blocks beyond it, in
        // blocks (on the mould, 30 modes: 64 took 15 restarts and 304 solves, 96 four and 232,
        // 128 two and 224 for 33 % more memory).
        let m = basis_size(nev, b);
        if m + 2 * b > n {
            // Too small to block: ARPACK does it as well.
            return super::arpack::Arpack {
                problem,
                ordering: self.ordering,
                tol: self.tol,
            }
            .lowest(nev, sigma);
        }
        let t = Instant::now();
        let chol = super::factor_shifted(problem, self.ordering, sigma)?;
        let factorize_s = t.elapsed().as_secs_f64();
        // The Krylov basis and its K − σM images: the largest allocation after the factor.
        crate::memory::ensure_fits("the block Krylov basis", 16 * (n * (m + b)) as u64)
            .map_err(crate::linsolve::FactorError::from)?;
        let t = Instant::now();
        let mut s = State::new(problem, n, m, b);
        s.start(&chol)?;
        let mut restarts = 0;
        let mut solves = b;
        let (theta, y) = loop {
            s.expand(&chol)?;
            solves += b;
            if s.k < nev {
                continue;
            }
            let Ritz { theta, y, residuals } = s.ritz()?;
            // Round-off bounds a Ritz residual by about ε·θ_max (θ_max: a rigid mode's, which can
            // be 1e2–1e6 × an elastic one's at σ < 0): a tolerance below that is never met.
            let floor = 64.0 * f64::EPSILON * theta[0].abs();
            let done = (0..nev).all(|i| residuals[i] <= (self.tol * theta[i].abs()).max(floor));
            if done {
                break (theta, y);
            }
            if s.k + b > m {
                restarts += 1;
                if restarts > MAX_RESTARTS {
                    let worst = (0..nev).map(|i| residuals[i] / theta[i].abs()).fold(0.0, f64::max);
                    return Err(ModesError::Block(format!(
                        "no convergence after {MAX_RESTARTS} restarts (worst relative Ritz residual {worst:.1e}); \
                         run with --solver arpack"
                    )));
                }
                s.restart(&theta, &y, (nev + m) / 2);
            }
        };
        let [solve_s, mass_s, orthogonalize_s] = s.seconds;
        tracing::debug!(
            restarts,
            solves,
            block = b,
            basis = m,
            solve_s,
            mass_s,
            orthogonalize_s,
            total_s = t.elapsed().as_secs_f64(),
            "block Krylov–Schur converged"
        );
        // λ = σ + 1/θ; θ descending is λ ascending.
        let values: Vec<f64> = theta[..nev].iter().map(|t| sigma + 1.0 / t).collect();
        let mut x = Mat::<f64>::zeros(n, nev);
        tall::times(x.as_mut(), Accum::Replace, s.v_ref(0, s.k), y.subcols(0, nev), 1.0);
        let mut vectors = Vec::with_capacity(n * nev);
        for j in 0..nev {
            vectors.extend_from_slice(x.col_as_slice(j));
        }
        Ok(Spectrum {
            values,
            vectors,
            factorize_s,
            eigensolve_s: t.elapsed().as_secs_f64(),
            factored: Some(super::Factored::of(chol, sigma)),
            checked: None,
        })
    }
}

/// Ritz pairs of the expanded basis, θ descending: the vectors are V y.
struct Ritz {
    theta: Vec<f64>,
    y: Mat<f64>,
    /// ‖T x − θ x‖_M = ‖B y‖.
    residuals: Vec<f64>,
}

/// The Krylov–Schur state: basis V (column-major, stride n) with W = MV, the projected matrix
/// H, `k` expanded vectors and the next block at columns k..k+b; `capacity` + b columns (the
/// expansion runs while k + b ≤ capacity and writes the new block after the next one).
struct State<'p> {
    problem: &'p EigenProblem<'p>,
    n: usize,
    b: usize,
    v: Vec<f64>,
    w: Vec<f64>,
    /// H on the expanded vectors plus the coupling B of the next block (rows k..k+b).
    h: Mat<f64>,
    k: usize,
    /// `k` right after the last thick restart (0 before any): the kept Ritz vectors end here.
    restarted_at: usize,
    rng: u64,
    /// Seconds in the solves, the M products, the Gram–Schmidt and SVQB GEMMs (for the log).
    seconds: [f64; 3],
}

impl<'p> State<'p> {
    fn new(problem: &'p EigenProblem<'p>, n: usize, capacity: usize, b: usize) -> Self {
        State {
            problem,
            n,
            b,
            v: vec![0.0; n * (capacity + b)],
            w: vec![0.0; n * (capacity + b)],
            h: Mat::zeros(capacity + b, capacity + b),
            k: 0,
            restarted_at: 0,
            rng: 0x9E37_79B9_7F4A_7C15,
            seconds: [0.0; 3],
        }
    }

    fn v_ref(&self, from: usize, cols: usize) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.v[from * self.n..(from + cols) * self.n], self.n, cols)
    }

    /// A deterministic pseudo-random number in [−1, 1) (splitmix64): runs are reproducible.
    fn random(&mut self) -> f64 {
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The first block: random vectors put in the range of (K − σM)⁻¹, M-orthonormal. A raw
    /// random vector carries every mesh-scale component; left in the basis they come back in
    /// the Ritz vectors amplified by λ_max in the residual (ARPACK's dgetv0 does the same:
    /// cantilever, max residual 1.4e-8 from a raw start).
    fn start(&mut self, chol: &Cholesky) -> Result<(), ModesError> {
        let (n, b) = (self.n, self.b);
        for i in 0..n * b {
            self.v[i] = self.random();
        }
        chol.solve_many_in_place(&mut self.v[..n * b], b);
        self.orthonormalize(0, b, 0)?;
        Ok(())
    }

    /// T applied to the next block, orthogonalised against the basis; H gains a block column.
    fn expand(&mut self, chol: &Cholesky) -> Result<(), ModesError> {
        let (n, b, k) = (self.n, self.b, self.k);
        let new = &mut self.v[(k + b) * n..(k + 2 * b) * n];
        new.copy_from_slice(&self.w[k * n..(k + b) * n]);
        let t = Instant::now();
        // Two halves on two threads: one thread alone does not use all the memory bandwidth
        // (mould: 1.00 s against 1.17 s for 232 solves).
        if b >= 2 {
            let (x, y) = new.split_at_mut((b / 2) * n);
            rayon::join(
                || chol.solve_many_in_place(x, b / 2),
                || chol.solve_many_in_place(y, b - b / 2),
            );
        } else {
            chol.solve_many_in_place(new, b);
        }
        self.seconds[0] += t.elapsed().as_secs_f64();
        if new.iter().any(|x| !x.is_finite()) {
            return Err(ModesError::Block("non-finite value in a solve".into()));
        }
        // In exact arithmetic T V_p couples only to the block before it and to itself (block
        // Lanczos), and right after a restart to the kept Ritz vectors as well: the first
        // Gram–Schmidt pass needs no more; the second, over the whole basis, takes off what
        // round-off left along the rest.
        let local = if k > self.restarted_at { k - b } else { 0 };
        let (c, r) = self.orthonormalize(k + b, b, local)?;
        // T V_p = V c + Q r: column block p of H, and r couples the new block.
        for j in 0..b {
            for i in 0..k + b {
                self.h[(i, k + j)] = c[(i, j)];
            }
            for i in 0..b {
                self.h[(k + b + i, k + j)] = r[(i, j)];
            }
        }
        self.k += b;
        Ok(())
    }

    /// M-orthonormalises columns `from..from+width` of V against columns 0..from and among
    /// themselves (W updated): returns the Gram–Schmidt coefficients c (from × width) and the
    /// triangle-like factor r (width × width) with Z = V c + Q r. The first Gram–Schmidt pass
    /// runs against columns `local..from` only (see [`State::expand`]), the second against all.
    fn orthonormalize(&mut self, from: usize, width: usize, local: usize) -> Result<(Mat<f64>, Mat<f64>), ModesError> {
        let n = self.n;
        let t = Instant::now();
        let mut c = Mat::<f64>::zeros(from, width);
        if from > 0 {
            for lo in [local, 0] {
                let (basis, z) = self.v.split_at_mut(from * n);
                let z = MatMut::from_column_major_slice_mut(&mut z[..width * n], n, width);
                let wb = MatRef::from_column_major_slice(&self.w[lo * n..from * n], n, from - lo);
                let vb = MatRef::from_column_major_slice(&basis[lo * n..], n, from - lo);
                let d = tall::t_times(wb, z.as_ref());
                tall::times(z, Accum::Add, vb, d.as_ref(), -1.0);
                let mut part = c.subrows_mut(lo, from - lo);
                part += &d;
            }
        }
        self.seconds[2] += t.elapsed().as_secs_f64();
        self.apply_m(from, width);
        let t = Instant::now();
        // The squared M-norms before orthogonalisation (‖z‖² = ‖c‖² + ‖z − Vc‖², V being
        // M-orthonormal): the reference for deflation.
        let mut before = 0.0f64;
        // SVQB twice: G = ZᵀMZ = U S Uᵀ, Q = Z U S^{-1/2}, r = S^{1/2} Uᵀ.
        let mut r = Mat::<f64>::identity(width, width);
        for pass in 0..2 {
            let z = MatRef::from_column_major_slice(&self.v[from * n..(from + width) * n], n, width);
            let mz = MatRef::from_column_major_slice(&self.w[from * n..(from + width) * n], n, width);
            let g = tall::t_times(z, mz);
            let g = Mat::from_fn(width, width, |i, j| 0.5 * (g[(i, j)] + g[(j, i)]));
            if pass == 0 {
                before = (0..width)
                    .map(|j| g[(j, j)] + (0..from).map(|i| c[(i, j)].powi(2)).sum::<f64>())
                    .fold(0.0, f64::max);
            }
            // A symmetric eigen-solve of a small finite matrix: its failure is reported, never
            // worked around.
            let (s, u) = self_adjoint_eigen_qr(g.as_ref())?;
            // Directions that vanished (the block met an invariant subspace) go last, replaced
            // by random ones below; r has zero rows for them.
            let good: Vec<usize> = (0..width)
                .rev()
                .filter(|&i| s[i] > DEFLATION * before.max(f64::MIN_POSITIVE))
                .collect();
            let mut scale = Mat::<f64>::zeros(width, width);
            let mut step = Mat::<f64>::zeros(width, width);
            for (col, &i) in good.iter().enumerate() {
                let root = s[i].sqrt();
                for row in 0..width {
                    scale[(row, col)] = u[(row, i)] / root;
                    step[(col, row)] = u[(row, i)] * root;
                }
            }
            let q = z * scale.as_ref();
            let mq = mz * scale.as_ref();
            for j in 0..width {
                self.v[(from + j) * n..(from + j + 1) * n].copy_from_slice(q.col_as_slice(j));
                self.w[(from + j) * n..(from + j + 1) * n].copy_from_slice(mq.col_as_slice(j));
            }
            r = &step * &r;
            if good.len() < width {
                let g = good.len();
                self.randomize(from + g, width - g);
                // The replacements are orthogonal to everything before them, good ones included.
                self.orthonormalize(from + g, width - g, 0)?;
            } else if s.iter().fold(0.0f64, |a, &x| a.max(x))
                <= SVQB_ONCE * s.iter().fold(f64::INFINITY, |a, &x| a.min(x))
            {
                // A well-conditioned block is orthonormal to ~ε·κ(G) after one pass.
                break;
            }
        }
        self.seconds[2] += t.elapsed().as_secs_f64();
        Ok((c, r))
    }

    /// Random columns.
    fn randomize(&mut self, from: usize, width: usize) {
        let n = self.n;
        for i in from * n..(from + width) * n {
            self.v[i] = self.random();
        }
    }

    /// W = M V on columns from..from+width (one column per thread).
    fn apply_m(&mut self, from: usize, width: usize) {
        let n = self.n;
        let p = self.problem;
        let t = Instant::now();
        sym_matmul(
            p.pattern,
            p.m,
            &self.v[from * n..(from + width) * n],
            &mut self.w[from * n..(from + width) * n],
        );
        self.seconds[1] += t.elapsed().as_secs_f64();
    }

    /// Ritz pairs of the expanded basis, θ descending, with their residual norms ‖B y‖.
    fn ritz(&self) -> Result<Ritz, ModesError> {
        let (k, b) = (self.k, self.b);
        let hs = Mat::from_fn(k, k, |i, j| 0.5 * (self.h[(i, j)] + self.h[(j, i)]));
        let (s, u) = self_adjoint_eigen_qr(hs.as_ref())?;
        let order: Vec<usize> = (0..k).rev().collect();
        let theta: Vec<f64> = order.iter().map(|&i| s[i]).collect();
        let y = Mat::from_fn(k, k, |i, j| u[(i, order[j])]);
        let coupling = self.h.submatrix(k, 0, b, k);
        let by = coupling * &y;
        let residuals = (0..k)
            .map(|j| (0..b).map(|i| by[(i, j)].powi(2)).sum::<f64>().sqrt())
            .collect();
        Ok(Ritz { theta, y, residuals })
    }

    /// Thick restart: keeps the `keep` best Ritz vectors and the next block.
    fn restart(&mut self, theta: &[f64], y: &Mat<f64>, keep: usize) {
        let (n, b, k) = (self.n, self.b, self.k);
        let keep = keep.min(k);
        let yk = y.subcols(0, keep);
        for buf in [&mut self.v, &mut self.w] {
            let old = MatRef::from_column_major_slice(&buf[..k * n], n, k);
            let mut kept = Mat::<f64>::zeros(n, keep);
            tall::times(kept.as_mut(), Accum::Replace, old, yk, 1.0);
            for j in 0..keep {
                buf[j * n..(j + 1) * n].copy_from_slice(kept.col_as_slice(j));
            }
            buf.copy_within(k * n..(k + b) * n, keep * n);
        }
        let coupling = self.h.submatrix(k, 0, b, k) * yk;
        self.h.fill(0.0);
        for j in 0..keep {
            self.h[(j, j)] = theta[j];
            for i in 0..b {
                self.h[(keep + i, j)] = coupling[(i, j)];
            }
        }
        self.k = keep;
        self.restarted_at = keep;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::Dofs;
    use crate::linsolve::{nested_dissection, sym_matvec};
    use crate::modes::Model as Discretized;
    use crate::modes::dense::Dense;
    use crate::tet_mesh::Mesh;
    use faer::sparse::SymbolicSparseColMat;

    fn beam(clamped: bool) -> Discretized {
        let mesh = Mesh::structured_box([16, 2, 2], 0.05, crate::fem::element::Kind::Tet4, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [clamped && p[0] < 1e-12; 3]).collect();
        Discretized::assemble(
            mesh,
            Dofs::from_mask(&mask),
            crate::material::Material::elastic(2e11, 0.3, 7800.0),
        )
        .expect("assembles")
    }

    /// ‖Φ_refᵀ M φ‖ for each found φ: 1 when φ lies in the reference subspace (which also holds
    /// for the beam's double eigenvalues, where single vectors are not unique).
    fn in_subspace(p: &EigenProblem<'_>, reference: &[f64], found: &[f64]) -> Vec<f64> {
        let n = p.size();
        let mut mx = vec![0.0; n];
        found
            .chunks(n)
            .map(|phi| {
                sym_matvec(p.pattern, p.m, phi, &mut mx);
                let norm: f64 = phi.iter().zip(&mx).map(|(a, b)| a * b).sum::<f64>().sqrt();
                reference
                    .chunks(n)
                    .map(|r| (r.iter().zip(&mx).map(|(a, b)| a * b).sum::<f64>() / norm).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect()
    }

    /// Clamped beam (432 unknowns, double eigenvalues from its square section): the lowest 8
    /// equal ARPACK's to 1e-12 and the dense solver's to 1e-9, subspaces to 1e-8, with blocks of
    /// 8 and of 3 (an uneven split between the two solving threads).
    #[test]
    fn block_krylov_schur_equals_the_dense_solve_on_a_clamped_beam() {
        let d = beam(true);
        let p = EigenProblem::of(&d.system);
        let dense = Dense(&p).lowest(10, 0.0).expect("dense");
        let ordering = nested_dissection(&d.system.graph, &d.dofs);
        let arpack = crate::modes::arpack::Arpack {
            problem: &p,
            ordering: &ordering,
            tol: 1e-12,
        }
        .lowest(8, 0.0)
        .expect("ARPACK");
        for block in [8, 3] {
            let s = BlockKrylov {
                problem: &p,
                ordering: &ordering,
                tol: 1e-12,
                block,
            }
            .lowest(8, 0.0)
            .expect("block");
            // The dense solve is the less accurate of the two oracles (ε·λ_max: 1.6e-10 off
            // ARPACK on mode 2, where ARPACK and this solver agree to 2e-16).
            for ((a, b), c) in s.values.iter().zip(&arpack.values).zip(&dense.values) {
                assert!((a - b).abs() <= 1e-12 * b, "block {block}: {a} vs ARPACK {b}");
                assert!((a - c).abs() <= 1e-9 * c, "block {block}: {a} vs dense {c}");
            }
            for (j, c) in in_subspace(&p, &dense.vectors, &s.vectors).iter().enumerate() {
                assert!(
                    (c - 1.0).abs() < 1e-8,
                    "block {block}, mode {j}: {c} of it in the dense subspace"
                );
            }
        }
    }

    /// A free beam: six rigid modes at σ < 0 set apart, the elastic ones equal the dense solve.
    #[test]
    fn block_krylov_schur_separates_the_rigid_modes_of_a_free_beam() {
        let d = beam(false);
        let p = EigenProblem::of(&d.system);
        let ordering = nested_dissection(&d.system.graph, &d.dofs);
        let block = BlockKrylov {
            problem: &p,
            ordering: &ordering,
            tol: 1e-12,
            block: 8,
        };
        let found = crate::modes::compute(&p, &d.dofs, 6, 6, &block).expect("block");
        let dense = crate::modes::compute(&p, &d.dofs, 6, 6, &Dense(&p)).expect("dense");
        assert_eq!(found.rigid_dropped, 6);
        for (a, b) in found.eigenvalues.iter().zip(&dense.eigenvalues) {
            assert!((a - b).abs() <= 1e-9 * b, "{a} vs dense {b}");
        }
        assert!(found.residuals.iter().all(|r| *r < 1e-8), "{:?}", found.residuals);
        assert!(found.orthonormality_error < 1e-10);
    }

    /// K = diag(1, 2, 3, 1, 2, 3, …), M = I: a block of 8 spans an invariant subspace after
    /// three steps and must restart its directions at random instead of dividing by zero; the
    /// five lowest are all 1, M-orthonormal, with exact residuals.
    #[test]
    fn a_block_that_meets_an_invariant_subspace_is_replaced_not_divided_by_zero() {
        let n = 300;
        let pattern = SymbolicSparseColMat::new_checked(n, n, (0..=n).collect(), None, (0..n).collect());
        let k: Vec<f64> = (0..n).map(|i| (1 + i % 3) as f64).collect();
        let m = vec![1.0; n];
        let p = EigenProblem {
            pattern: &pattern,
            k: &k,
            m: &m,
        };
        let ordering = ((0..n).collect(), (0..n).collect());
        let s = BlockKrylov {
            problem: &p,
            ordering: &ordering,
            tol: 1e-12,
            block: 8,
        }
        .lowest(5, 0.0)
        .expect("block");
        assert!(s.values.iter().all(|v| (v - 1.0).abs() < 1e-12), "{:?}", s.values);
        for a in 0..5 {
            let x = &s.vectors[a * n..(a + 1) * n];
            assert!(x.iter().all(|v| v.is_finite()));
            // Only the λ = 1 components (i % 3 == 0) may be non-zero.
            let off: f64 = x
                .iter()
                .enumerate()
                .filter(|(i, _)| i % 3 != 0)
                .map(|(_, v)| v * v)
                .sum();
            assert!(off < 1e-20, "mode {a}: {off:e} outside the eigenspace");
            for b in 0..=a {
                let y = &s.vectors[b * n..(b + 1) * n];
                let dot: f64 = x.iter().zip(y).map(|(p, q)| p * q).sum();
                assert!(
                    (dot - if a == b { 1.0 } else { 0.0 }).abs() < 1e-12,
                    "({a}, {b}): {dot}"
                );
            }
        }
    }
}
