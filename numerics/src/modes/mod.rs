//! The generalized eigenproblem K φ = λ M φ on the free DOFs: the lowest modes, rigid ones set
//! apart, every elastic mode checked (residual, M-orthonormality, finiteness).
//!
//! Solvers behind one trait: [`block::BlockKrylov`] (block shift-invert Krylov–Schur on a sparse
//! Cholesky factor, the default for real meshes), [`arpack::Arpack`] (single-vector shift-invert
//! Lanczos on the same factor: the reference path and test oracle), [`dense::Dense`] (a full
//! generalized eigen-solve, for tiny problems and as an oracle) and `slepc::Distributed` (SLEPc
//! over the MPI ranks, feature `slepc`; the MPI job around it in [`mpi_job`]).

pub mod arpack;
pub mod block;
pub mod dense;
pub mod derivatives;
#[cfg(feature = "slepc")]
pub mod mpi_job;
#[cfg(not(feature = "slepc"))]
#[path = "mpi_job_off.rs"]
pub mod mpi_job;
#[cfg(feature = "slepc")]
pub mod slepc;
pub mod trial;
pub mod warm;

use crate::fem::Dofs;
use crate::linsolve::{Cholesky, FactorError, nested_dissection, sym_matmul};
use faer::sparse::SymbolicSparseColMat;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use rayon::prelude::*;
use std::time::Instant;

/// K and M on the free DOFs (lower triangles on one pattern).
pub struct EigenProblem<'a> {
    /// Shared pattern.
    pub pattern: &'a SymbolicSparseColMat<usize>,
    /// Values of K.
    pub k: &'a [f64],
    /// Values of M.
    pub m: &'a [f64],
}

impl<'a> EigenProblem<'a> {
    /// The problem of an assembled space.
    pub fn of(system: &'a crate::fem::Assembled) -> Self {
        EigenProblem {
            pattern: &system.pattern,
            k: &system.k,
            m: &system.m,
        }
    }

    /// Unknowns.
    pub fn size(&self) -> usize {
        self.pattern.nrows()
    }

    /// The scales of its diagonals.
    pub fn scales(&self) -> Scales {
        let (cp, ri) = (self.pattern.col_ptr(), self.pattern.row_idx());
        Scales::of_diagonal(
            self.size(),
            (0..self.size()).filter_map(|j| (cp[j]..cp[j + 1]).find(|&k| ri[k] == j).map(|k| (self.k[k], self.m[k]))),
        )
    }
}

/// What the mode selection and checks need to know of K and M besides the solver: sums over
/// their diagonals (of the whole problem, or of one MPI rank's rows, then reduced).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    /// Unknowns.
    pub size: usize,
    /// Σ K_jj.
    pub diag_k: f64,
    /// Σ M_jj.
    pub diag_m: f64,
    /// max K_jj / M_jj.
    pub max_ratio: f64,
}

impl Scales {
    /// The scales of `size` unknowns from their diagonal entries (K_jj, M_jj) (all of them, or a
    /// part to be reduced with the other parts by sum, sum, max).
    pub fn of_diagonal(size: usize, diagonal: impl Iterator<Item = (f64, f64)>) -> Scales {
        let mut s = Scales {
            size,
            diag_k: 0.0,
            diag_m: 0.0,
            max_ratio: 0.0,
        };
        for (k, m) in diagonal {
            s.diag_k += k;
            s.diag_m += m;
            s.max_ratio = s.max_ratio.max(k / m);
        }
        s
    }

    /// mean(diag K) / mean(diag M): the squared angular frequency of the mesh scale, used to
    /// make shifts and thresholds independent of units.
    pub fn stiffness(&self) -> f64 {
        self.diag_k / self.diag_m
    }

    /// mean(diag M): about ‖Mx‖/‖x‖ for a smooth x.
    pub fn mass(&self) -> f64 {
        self.diag_m / self.size.max(1) as f64
    }

    /// An upper estimate of λ_max: 10 × the largest diagonal ratio K_jj / M_jj (the consistent
    /// mass spreads a node's mass over its neighbours, so the ratio alone underestimates it).
    pub fn lambda_max_estimate(&self) -> f64 {
        10.0 * self.max_ratio
    }
}

/// The lowest eigenpairs a solver found.
pub struct Spectrum {
    /// Eigenvalues, ascending.
    pub values: Vec<f64>,
    /// Column-major `n × values.len()`.
    pub vectors: Vec<f64>,
    /// Seconds spent factorising.
    pub factorize_s: f64,
    /// Seconds spent iterating.
    pub eigensolve_s: f64,
    /// What the solver keeps of its factor of K − σM, when it made one.
    pub factored: Option<Factored>,
    /// The checks, when the solver made them where the vectors live (SLEPc, on every rank):
    /// then `vectors` are already M-normalised.
    pub checked: Option<Checked>,
}

/// Mode checks a solver made itself, for every pair it returned (in its order).
pub struct Checked {
    /// ‖Kφ − λMφ‖ / ‖Kφ‖ per pair.
    pub residuals: Vec<f64>,
    /// ΦᵀMΦ, column-major, square.
    pub gram: Vec<f64>,
}

/// What a solve keeps of its factor of K − σM.
pub enum Factored {
    /// The symbolic analysis (ordering and structure), for the Sturm count's factorisation of
    /// the same pattern (METIS and the analysis not redone): σ ≠ 0, the numbers are of no
    /// further use.
    Symbolic(SymbolicCholesky<usize>),
    /// The whole factor at σ = 0, K's own (a held part): the stages after the solve that solve
    /// with K (static correction, load cases, influence coefficients, the felt check) take it
    /// instead of factorising K again (0.43 s on the ribplate's 49k unknowns).
    Stiffness(Cholesky),
}

impl Factored {
    /// Keeps the whole factor when it is K's (σ = 0), else its symbolic analysis.
    pub fn of(chol: Cholesky, sigma: f64) -> Factored {
        if sigma == 0.0 {
            Factored::Stiffness(chol)
        } else {
            Factored::Symbolic(chol.into_symbolic())
        }
    }

    /// Its symbolic analysis only (the numbers' memory released).
    pub fn symbolic_only(self) -> Factored {
        match self {
            Factored::Stiffness(c) => Factored::Symbolic(c.into_symbolic()),
            s => s,
        }
    }

    /// K's factor, when this is one.
    pub fn stiffness(&self) -> Option<&Cholesky> {
        match self {
            Factored::Stiffness(c) => Some(c),
            Factored::Symbolic(_) => None,
        }
    }

    /// The symbolic analysis.
    pub fn symbolic(&self) -> &SymbolicCholesky<usize> {
        match self {
            Factored::Symbolic(s) => s,
            Factored::Stiffness(c) => c.symbolic(),
        }
    }
}

/// Analyses and factorises K − σM (the shift-invert operator of ARPACK and the block solver).
fn factor_shifted(
    problem: &EigenProblem<'_>,
    ordering: &(Vec<usize>, Vec<usize>),
    sigma: f64,
) -> Result<crate::linsolve::Cholesky, FactorError> {
    use crate::linsolve::Cholesky;
    let shifted: Vec<f64> = problem.k.iter().zip(problem.m).map(|(k, m)| k - sigma * m).collect();
    let t0 = std::time::Instant::now();
    let symbolic = Cholesky::analyse(problem.pattern, ordering)?;
    tracing::debug!(seconds = t0.elapsed().as_secs_f64(), "analysed");
    Cholesky::factor(symbolic, problem.pattern, &shifted, sigma)
}

/// A generalized symmetric eigen-solver on one problem (its K and M here, or on the MPI ranks).
pub trait EigenSolver {
    /// The `nev` eigenpairs nearest `sigma` (below the spectrum, so the lowest).
    fn lowest(&self, nev: usize, sigma: f64) -> Result<Spectrum, ModesError>;
}

/// Why no basis could be computed.
#[derive(Debug, thiserror::Error)]
pub enum ModesError {
    /// The factorisation failed.
    #[error(transparent)]
    Factor(#[from] FactorError),
    /// ARPACK failed.
    #[error(transparent)]
    Arpack(#[from] ves_arpack::ArpackError),
    /// Too few unknowns for the modes asked.
    #[error(
        "the mesh has {unknowns} free unknowns, too few for {wanted} modes (+{rigid} rigid); refine the mesh or ask fewer modes"
    )]
    TooFewUnknowns {
        /// Free DOFs.
        unknowns: usize,
        /// Elastic modes asked.
        wanted: usize,
        /// Rigid modes expected.
        rigid: usize,
    },
    /// The rigid modes could not be told apart from the elastic ones.
    #[error(
        "expected {rigid} rigid modes but the spectrum does not separate them (eigenvalues {values:?}); \
         the part may be in several pieces or be a mechanism: check the geometry and supports"
    )]
    RigidSeparation {
        /// Expected rigid count.
        rigid: usize,
        /// The lowest eigenvalues found.
        values: Vec<f64>,
    },
    /// SLEPc/PETSc failed or is not available.
    #[error("SLEPc: {0}")]
    Slepc(String),
    /// Assembling an MPI rank's share of the problem failed (on that rank; the message says
    /// which when it is not rank 0).
    #[error("{0}")]
    Rank(String),
    /// The block Krylov–Schur solver failed.
    #[error("block eigen-solver: {0}")]
    Block(String),
    /// A dense decomposition failed.
    #[error("dense eigen-solve failed: {0}")]
    Dense(String),
    /// A computed mode failed its checks.
    #[error(
        "mode {mode} failed its check: {what}; the basis is not trustworthy (try a finer mesh or report this case)"
    )]
    Check {
        /// Index of the elastic mode.
        mode: usize,
        /// What failed.
        what: String,
    },
}

/// Elastic modes on the free DOFs, with their quality.
pub struct Modes {
    /// λ = ω², ascending.
    pub eigenvalues: Vec<f64>,
    /// Column-major `free × r`, M-orthonormal.
    pub vectors: Vec<f64>,
    /// Rigid modes found and dropped.
    pub rigid_dropped: usize,
    /// ‖Kφ − λMφ‖ / ‖Kφ‖ per mode.
    pub residuals: Vec<f64>,
    /// max |ΦᵀMΦ − I|.
    pub orthonormality_error: f64,
    /// The shift used.
    pub sigma: f64,
    /// Seconds spent factorising.
    pub factorize_s: f64,
    /// Seconds spent iterating.
    pub eigensolve_s: f64,
    /// What the solve kept of its factor of K − σM ([`Factored`]).
    pub factored: Option<Factored>,
}

impl Modes {
    /// Releases the memory of the solve's factor of K, keeping its symbolic analysis.
    pub fn release_factor(&mut self) {
        self.factored = self.factored.take().map(Factored::symbolic_only);
    }

    /// Keeps the solve's factor of K for the stages after the solve only where memory is
    /// plentiful: twice its size (it, and a factor of the same size made beside it, such as
    /// the Sturm count's) at most a quarter of what is left. Kept, it raises a run's peak
    /// while the stages between the solve and its last use run (the error estimate's coarser
    /// solves); at scale it is released and made again when needed, as before.
    pub fn release_factor_unless_plentiful(&mut self) {
        if let Some(c) = self.factored.as_ref().and_then(Factored::stiffness) {
            let both = 2 * 8 * c.factor_len() as u64;
            if crate::memory::headroom_bytes().is_none_or(|free| both > free / 4) {
                tracing::debug!("K's factor released after the solve: memory is not plentiful");
                self.release_factor();
            }
        }
    }

    /// Keeps the lowest `r` modes.
    pub fn truncate(&mut self, r: usize) {
        let old = self.eigenvalues.len();
        if r >= old {
            return;
        }
        let n = self.vectors.len() / old.max(1);
        self.eigenvalues.truncate(r);
        self.vectors.truncate(r * n);
        self.residuals.truncate(r);
    }

    /// Frequencies in Hz.
    pub fn frequencies_hz(&self) -> Vec<f64> {
        self.eigenvalues
            .iter()
            .map(|l| l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect()
    }
}

/// A mode is rejected when its relative residual exceeds this.
pub const MAX_RESIDUAL: f64 = 1e-6;

/// The relative residual (as the mode checks measure it) the iterative SLEPc method aims at.
const ITERATIVE_RESIDUAL: f64 = 1e-7;

/// Right-hand sides per solve of the block solver: at 8 a solve costs 3.6× less per vector
/// than one at a time, beyond it the gain flattens while the Krylov space needs more vectors.
const BLOCK: usize = 8;

/// `--solver auto` leaves the block solver for ARPACK when its basis would take more than this
/// (e.g. 1.5M unknowns and 60 modes: 4.5 GB): ARPACK needs ~3× less for its vectors, at ~2× the
/// time.
const AUTO_BLOCK_BYTES: usize = 4 << 30;

/// Computes `count` elastic modes, dropping the `rigid` rigid ones the supports leave.
pub fn compute(
    problem: &EigenProblem<'_>,
    dofs: &Dofs,
    rigid: usize,
    count: usize,
    solver: &dyn EigenSolver,
) -> Result<Modes, ModesError> {
    compute_bounded(problem, dofs, rigid, count, solver, None)
}

/// [`compute`] with an upper bound of the first elastic eigenvalue, when one is known
/// ([`trial::first_elastic_bound`]): a part with rigid motions is solved at a shift just below
/// it rather than one from the mesh's stiffness scale.
pub fn compute_bounded(
    problem: &EigenProblem<'_>,
    dofs: &Dofs,
    rigid: usize,
    count: usize,
    solver: &dyn EigenSolver,
    first_elastic: Option<f64>,
) -> Result<Modes, ModesError> {
    debug_assert_eq!(problem.size(), dofs.free_count());
    select(&problem.scales(), rigid, count, solver, Some(problem), first_elastic)
}

/// The eigenpairs to ask a solver for `count` elastic modes with `rigid` rigid ones, if `n`
/// unknowns have room for them.
fn eigenpairs_wanted(n: usize, count: usize, rigid: usize) -> Result<usize, ModesError> {
    if count + rigid + 1 >= n {
        return Err(ModesError::TooFewUnknowns {
            unknowns: n,
            wanted: count,
            rigid,
        });
    }
    Ok(count + rigid)
}

/// The lowest `count` elastic modes from a solver (`lowest(nev, sigma)`), the `rigid` rigid ones
/// dropped, each checked: by the solver itself ([`Spectrum::checked`]) or here against the
/// whole `problem`. Steps: [`shifted_spectrum`] → [`drop_rigid`] → [`checked_residuals`] →
/// [`accept_residuals`].
pub fn select(
    scales: &Scales,
    rigid: usize,
    count: usize,
    solver: &dyn EigenSolver,
    problem: Option<&EigenProblem<'_>>,
    first_elastic: Option<f64>,
) -> Result<Modes, ModesError> {
    let nev = eigenpairs_wanted(scales.size, count, rigid)?;
    let (mut spectrum, sigma) = shifted_spectrum(scales, rigid, nev, solver, first_elastic, problem)?;
    let t = Instant::now();
    let (eigenvalues, mut vectors) = drop_rigid(&mut spectrum, rigid, scales.size)?;
    let (residuals, orthonormality_error) =
        checked_residuals(&mut spectrum, rigid, problem, &mut vectors, &eigenvalues)?;
    accept_residuals(&residuals, &eigenvalues, scales.lambda_max_estimate())?;
    Ok(Modes {
        eigenvalues,
        vectors,
        rigid_dropped: rigid,
        residuals,
        orthonormality_error,
        sigma,
        factorize_s: spectrum.factorize_s,
        eigensolve_s: spectrum.eigensolve_s + t.elapsed().as_secs_f64(),
        factored: spectrum.factored,
    })
}

/// The `nev` lowest eigenpairs from the solver, and the shift they were found with. A
/// supported part: σ = 0 (K is SPD; shift-invert on K⁻¹M). With rigid modes K is singular, so
/// σ < 0: at −λ̃₁/100 where an upper bound λ̃₁ of the first elastic eigenvalue is given, but
/// never farther below than 10⁻⁶ of the mesh's stiffness scale; then, if that lands below
/// −λ₁/100 (thin or soft parts, where λ₁/λ_max can be 1e-10 and the low modes crowd together
/// as seen from σ; a bound above λ₁), again at σ = −λ₁/100 — unless
/// the pairs found are already as good as that solve would make them ([`settled`]: the corpus
/// cast housing's, to 1e-9 in frequency, at a third of the time).
fn shifted_spectrum(
    scales: &Scales,
    rigid: usize,
    nev: usize,
    solver: &dyn EigenSolver,
    first_elastic: Option<f64>,
    problem: Option<&EigenProblem<'_>>,
) -> Result<(Spectrum, f64), ModesError> {
    let far = -1e-6 * scales.stiffness();
    let mut sigma = match (rigid, first_elastic) {
        (0, _) => 0.0,
        // Never nearer than the second solve's −λ₁/100 (λ̃₁ ≥ λ₁): under stiff springs a shift
        // nearer zero factorises K − σM too ill-conditioned (a sliding face's mode 5 came out
        // at a residual of 1.8e-6 at −λ̃₁/200).
        (_, Some(bound)) => far.max(-0.01 * bound),
        (_, None) => far,
    };
    let mut spectrum = solver.lowest(nev, sigma)?;
    if let Some(&l1) = spectrum
        .values
        .get(rigid)
        .filter(|&&l1| rigid > 0 && l1 > 0.0 && -sigma > 0.01 * l1)
        .filter(|_| !problem.is_some_and(|p| settled(p, &spectrum, rigid, scales.lambda_max_estimate())))
    {
        sigma = -0.01 * l1;
        let again = solver.lowest(nev, sigma)?;
        spectrum = Spectrum {
            factorize_s: spectrum.factorize_s + again.factorize_s,
            eigensolve_s: spectrum.eigensolve_s + again.eigensolve_s,
            ..again
        };
    }
    Ok((spectrum, sigma))
}

/// Whether the pairs of a spectrum found at a shift far below the first elastic eigenvalue are
/// as good as a solve nearer it would make them: the rigid ones clearly apart, and each elastic
/// pair's residual against the whole problem at most 1e-8 or its round-off floor ε·λ_max/λ.
/// Far below, the wanted pairs crowd together as the solver sees them; a pair it took for
/// converged could mix two modes, and its residual shows that.
fn settled(problem: &EigenProblem<'_>, spectrum: &Spectrum, rigid: usize, lambda_max: f64) -> bool {
    let n = problem.size();
    if spectrum.values.len() <= rigid || spectrum.vectors.len() != n * spectrum.values.len() {
        return false;
    }
    if rigid_apart(&spectrum.values, rigid).is_err() {
        return false;
    }
    let values = &spectrum.values[rigid..];
    let mut vectors = spectrum.vectors[rigid * n..].to_vec();
    let (residuals, _) = check(problem, &mut vectors, values);
    residuals
        .iter()
        .zip(values)
        .all(|(&r, &l)| l > 0.0 && r <= (1e-2 * MAX_RESIDUAL).max(f64::EPSILON * lambda_max / l))
}

/// Refuses a spectrum (ascending) whose first elastic value is not clearly above its `rigid`
/// rigid ones (1000× the largest of them, and positive).
fn rigid_apart(vals: &[f64], rigid: usize) -> Result<(), ModesError> {
    if rigid == 0 {
        return Ok(());
    }
    let rigid_max = vals[..rigid].iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let first_elastic = vals[rigid];
    if first_elastic.is_nan() || first_elastic <= 1e3 * rigid_max || first_elastic <= 0.0 {
        return Err(ModesError::RigidSeparation {
            rigid,
            values: vals[..(rigid + 2).min(vals.len())].to_vec(),
        });
    }
    Ok(())
}

/// The elastic eigenvalues and vectors (the rigid modes' vectors dropped in place: no second
/// copy of the basis), once the rigid ones are clearly apart from the first elastic one and
/// every elastic pair is finite and positive.
fn drop_rigid(spectrum: &mut Spectrum, rigid: usize, n: usize) -> Result<(Vec<f64>, Vec<f64>), ModesError> {
    let vals = &spectrum.values;
    rigid_apart(vals, rigid)?;
    let eigenvalues: Vec<f64> = vals[rigid..].to_vec();
    let mut vectors = std::mem::take(&mut spectrum.vectors);
    vectors.drain(..rigid * n);
    for (j, &lam) in eigenvalues.iter().enumerate() {
        if !(lam > 0.0 && lam.is_finite()) || vectors[j * n..(j + 1) * n].iter().any(|v| !v.is_finite()) {
            return Err(ModesError::Check {
                mode: j,
                what: format!("eigenvalue {lam:e} or its vector is not finite and positive"),
            });
        }
    }
    Ok((eigenvalues, vectors))
}

/// Each elastic mode's relative residual and the largest |ΦᵀMΦ − I|: the solver's own checks
/// when it made them (where the vectors live, for distributed solvers), or made here against
/// the whole problem (which also M-normalises the vectors).
fn checked_residuals(
    spectrum: &mut Spectrum,
    rigid: usize,
    problem: Option<&EigenProblem<'_>>,
    vectors: &mut [f64],
    eigenvalues: &[f64],
) -> Result<(Vec<f64>, f64), ModesError> {
    let r = eigenvalues.len();
    match spectrum.checked.take() {
        Some(c) => {
            let nev = c.residuals.len();
            let mut worst = 0.0f64;
            for a in 0..r {
                for b in 0..=a {
                    let target = if a == b { 1.0 } else { 0.0 };
                    worst = worst.max((c.gram[(rigid + a) * nev + rigid + b] - target).abs());
                }
            }
            Ok((c.residuals[rigid..].to_vec(), worst))
        }
        None => {
            let problem = problem.ok_or_else(|| ModesError::Check {
                mode: 0,
                what: "the solver made no checks and K, M are not at hand".into(),
            })?;
            Ok(check(problem, vectors, eigenvalues))
        }
    }
}

/// Refuses a mode whose residual is above both 1e-6 and the round-off floor. Double precision
/// cannot promise better than about ε·λ_max/λ relative to ‖Kφ‖ (the backward error of the
/// solves): on meshes of flat elements (thin plates) that bound exceeds 1e-6 for the lowest
/// modes, which is then said.
fn accept_residuals(residuals: &[f64], eigenvalues: &[f64], lambda_max: f64) -> Result<(), ModesError> {
    for (j, (&rel, &lam)) in residuals.iter().zip(eigenvalues).enumerate() {
        let floor = f64::EPSILON * lambda_max / lam;
        let limit = MAX_RESIDUAL.max(floor);
        if rel.is_nan() || rel > limit {
            return Err(ModesError::Check {
                mode: j,
                what: format!("relative residual {rel:.2e} > {limit:.1e} (round-off floor {floor:.1e})"),
            });
        }
        if rel > MAX_RESIDUAL {
            tracing::warn!(
                mode = j,
                residual = rel,
                floor,
                "residual above 1e-6 because λ_max/λ = {:.1e}: the mesh has very flat or very small elements",
                lambda_max / lam
            );
        }
    }
    Ok(())
}

/// M-normalises the modes (column-major, n × r) and checks them against the whole problem:
/// each one's ‖Kφ − λMφ‖ / ‖Kφ‖, and max |ΦᵀMΦ − I|. The products for all modes at once (each
/// pass over K or M serves several vectors), the columns in parallel.
fn check(problem: &EigenProblem<'_>, vectors: &mut [f64], eigenvalues: &[f64]) -> (Vec<f64>, f64) {
    let (n, r) = (problem.size(), eigenvalues.len());
    let mut m_phi = vec![0.0; n * r];
    sym_matmul(problem.pattern, problem.m, vectors, &mut m_phi);
    vectors
        .par_chunks_mut(n)
        .zip(m_phi.par_chunks_mut(n))
        .for_each(|(phi, mx)| {
            let norm = phi.iter().zip(mx.iter()).map(|(a, b)| a * b).sum::<f64>().sqrt();
            phi.iter_mut().for_each(|v| *v /= norm);
            mx.iter_mut().for_each(|v| *v /= norm);
        });
    let mut k_phi = vec![0.0; n * r];
    sym_matmul(problem.pattern, problem.k, vectors, &mut k_phi);
    let residuals: Vec<f64> = k_phi
        .par_chunks(n)
        .zip(m_phi.par_chunks(n))
        .zip(eigenvalues)
        .map(|((kx, mx), &lam)| {
            let residual = kx
                .iter()
                .zip(mx)
                .map(|(k, m)| (k - lam * m).powi(2))
                .sum::<f64>()
                .sqrt();
            residual / kx.iter().map(|k| k * k).sum::<f64>().sqrt()
        })
        .collect();
    drop(k_phi);
    let gram = crate::tall::t_times(
        faer::MatRef::from_column_major_slice(vectors, n, r),
        faer::MatRef::from_column_major_slice(&m_phi, n, r),
    );
    let mut orthonormality_error = 0.0f64;
    for a in 0..r {
        for b in 0..=a {
            let target = if a == b { 1.0 } else { 0.0 };
            orthonormality_error = orthonormality_error.max((gram[(a, b)] - target).abs());
        }
    }
    (residuals, orthonormality_error)
}

/// A Sturm count at the top of the spectrum found: how many eigenvalues lie below σ, from the
/// inertia of K − σM (LDLᵀ), against how many were found there (rigid + elastic modes).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct SturmCount {
    /// The shift: the highest eigenvalue found, raised by [`STURM_MARGIN`].
    pub sigma: f64,
    /// Eigenvalues of the discrete problem below σ (negative pivots of K − σM).
    pub below: usize,
    /// Modes found below σ (the rigid ones dropped included).
    pub found: usize,
    /// Of those, rigid modes.
    pub rigid: usize,
    /// Seconds the count took (one more factorisation).
    pub seconds: f64,
}

impl SturmCount {
    /// True when no eigenvalue below σ was skipped.
    pub fn complete(&self) -> bool {
        self.below == self.found
    }
}

/// σ = λ_r · (1 + STURM_MARGIN): above the last mode found by far more than its error (residuals
/// ≤ 1e-8), close enough that a skipped mode just above it would still be caught unless it
/// coincides with it to 1e-6.
pub const STURM_MARGIN: f64 = 1e-6;

/// Counts the eigenvalues below the highest mode found (see [`SturmCount`]); `None` without
/// modes. Proves that the solver skipped none below it.
pub fn sturm_count(
    system: &crate::fem::Assembled,
    dofs: &crate::fem::Dofs,
    modes: &Modes,
) -> Result<Option<SturmCount>, ModesError> {
    let Some(&top) = modes.eigenvalues.last() else {
        return Ok(None);
    };
    let t = Instant::now();
    let sigma = top * (1.0 + STURM_MARGIN);
    let shifted: Vec<f64> = system.k.iter().zip(&system.m).map(|(k, m)| k - sigma * m).collect();
    let analysed;
    let symbolic = match &modes.factored {
        Some(f) => f.symbolic(),
        None => {
            analysed = crate::linsolve::analyse(system, dofs)?;
            &analysed
        }
    };
    let below = crate::linsolve::negative_pivots(symbolic, &system.pattern, &shifted)?;
    Ok(Some(SturmCount {
        sigma,
        below,
        found: modes.rigid_dropped + modes.eigenvalues.len(),
        rigid: modes.rigid_dropped,
        seconds: t.elapsed().as_secs_f64(),
    }))
}

/// Which eigen-solver to use (named on the command line and in a page's compute by
/// [`SolverChoice::name`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// Dense for tiny problems (≤ 500 unknowns), the block Krylov–Schur solver otherwise, ARPACK
    /// when the block solver's basis would exceed 4 GiB.
    Auto,
    /// ARPACK shift-invert with a sparse Cholesky factor.
    Arpack,
    /// Block Krylov–Schur shift-invert with the same factor (8 right-hand sides per solve).
    Block,
    /// Dense generalized eigen-solve (small meshes only).
    Dense,
    /// SLEPc Krylov–Schur, shift-invert with MUMPS, on every MPI rank (run under `mpirun`).
    Slepc,
    /// SLEPc Jacobi–Davidson preconditioned by algebraic multigrid (GAMG with the rigid-body
    /// near-null space), on every MPI rank: no factorisation, for parts whose factor does not fit.
    SlepcIterative,
}

impl SolverChoice {
    /// Every choice, in the order the command line lists them.
    pub const ALL: [SolverChoice; 6] = [
        SolverChoice::Auto,
        SolverChoice::Arpack,
        SolverChoice::Block,
        SolverChoice::Dense,
        SolverChoice::Slepc,
        SolverChoice::SlepcIterative,
    ];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SolverChoice::Auto => "auto",
            SolverChoice::Arpack => "arpack",
            SolverChoice::Block => "block",
            SolverChoice::Dense => "dense",
            SolverChoice::Slepc => "slepc",
            SolverChoice::SlepcIterative => "slepc-iterative",
        }
    }

    /// One line on what it does (the command line's help).
    pub fn about(self) -> &'static str {
        match self {
            SolverChoice::Auto => {
                "Dense for tiny problems (≤ 500 unknowns), the block Krylov–Schur solver otherwise, ARPACK when the block solver's basis would exceed 4 GiB"
            }
            SolverChoice::Arpack => "ARPACK shift-invert with a sparse Cholesky factor",
            SolverChoice::Block => {
                "Block Krylov–Schur shift-invert with the same factor (8 right-hand sides per solve)"
            }
            SolverChoice::Dense => "Dense generalized eigen-solve (small meshes only)",
            SolverChoice::Slepc => {
                "SLEPc Krylov–Schur, shift-invert with MUMPS, on every MPI rank (run under `mpirun`)"
            }
            SolverChoice::SlepcIterative => {
                "SLEPc Jacobi–Davidson preconditioned by algebraic multigrid (GAMG with the rigid-body near-null space), on every MPI rank: no factorisation, for parts whose factor does not fit"
            }
        }
    }

    /// Whether this solver runs in SLEPc (MPI initialised; under `mpirun`, rank 0 leads).
    pub fn is_slepc(self) -> bool {
        matches!(self, SolverChoice::Slepc | SolverChoice::SlepcIterative)
    }
}

/// A name that is no [`SolverChoice`]'s.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("no eigen-solver named {name:?}; choose one of {}", SolverChoice::ALL.map(SolverChoice::name).join(", "))]
pub struct UnknownSolver {
    /// The name given.
    pub name: String,
}

impl std::str::FromStr for SolverChoice {
    type Err = UnknownSolver;

    /// By [`SolverChoice::name`], in any case.
    fn from_str(s: &str) -> Result<Self, UnknownSolver> {
        SolverChoice::ALL
            .into_iter()
            .find(|c| c.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| UnknownSolver { name: s.to_string() })
    }
}

/// What an eigen-solve needs of one space (a `problem::Discretized` lends it): the mesh and
/// material too, from which SLEPc's ranks assemble their own rows.
#[derive(Clone, Copy)]
pub struct Space<'a> {
    /// The mesh.
    pub mesh: &'a crate::tet_mesh::Mesh,
    /// DOF numbering (the supports).
    pub dofs: &'a Dofs,
    /// K, M and the node graph.
    pub system: &'a crate::fem::Assembled,
    /// The material.
    pub material: crate::material::Material,
    /// Rigid motions the supports leave free.
    pub rigid: usize,
}

/// A space's model in one piece (mesh, DOFs, material, K and M): what a caller without a scene
/// (a test, a library user with its own mesh) assembles and solves.
pub struct Model {
    /// The mesh.
    pub mesh: crate::tet_mesh::Mesh,
    /// DOF numbering (the supports).
    pub dofs: Dofs,
    /// K, M and the node graph.
    pub system: crate::fem::Assembled,
    /// The material.
    pub material: crate::material::Material,
    /// Rigid motions the supports leave free.
    pub rigid: usize,
}

impl Model {
    /// Assembles K and M of `mesh` with `material`, supported as `dofs` says.
    pub fn assemble(
        mesh: crate::tet_mesh::Mesh,
        dofs: Dofs,
        material: crate::material::Material,
    ) -> Result<Model, crate::fem::assembly::AssemblyError> {
        Self::assemble_with(mesh, dofs, material, &[])
    }

    /// [`Model::assemble`] with surface springs holding the part too.
    pub fn assemble_with(
        mesh: crate::tet_mesh::Mesh,
        dofs: Dofs,
        material: crate::material::Material,
        springs: &[crate::fem::springs::NodeSpring],
    ) -> Result<Model, crate::fem::assembly::AssemblyError> {
        let mut system = crate::fem::assembly::assemble_with(&mesh, &material, &dofs, springs)?;
        system.mass.free = crate::rigid_motions::free_motions(&mesh.nodes, &dofs, springs, system.mass.center);
        let rigid = system.mass.free.count();
        Ok(Model {
            mesh,
            dofs,
            system,
            material,
            rigid,
        })
    }

    /// What the eigen-solvers take of it.
    pub fn space(&self) -> Space<'_> {
        Space {
            mesh: &self.mesh,
            dofs: &self.dofs,
            system: &self.system,
            material: self.material,
            rigid: self.rigid,
        }
    }
}

/// Solves the eigenproblem of a space; also the seconds spent before the solver (the
/// fill-reducing ordering, or under SLEPc the ranks' assembly of their rows).
pub fn solve(d: Space<'_>, count: usize, choice: SolverChoice) -> Result<(Modes, f64), ModesError> {
    let t = Instant::now();
    if choice.is_slepc() {
        return on_ranks(d, count, choice);
    }
    let problem = EigenProblem::of(d.system);
    let dense = match choice {
        SolverChoice::Dense => true,
        SolverChoice::Arpack | SolverChoice::Block | SolverChoice::Slepc | SolverChoice::SlepcIterative => false,
        SolverChoice::Auto => problem.size() <= 500,
    };
    let ordering;
    let solver: Box<dyn EigenSolver> = if dense {
        Box::new(dense::Dense(&problem))
    } else if choice == SolverChoice::Block
        || (choice == SolverChoice::Auto
            && block::BlockKrylov::basis_bytes(problem.size(), count + d.rigid, BLOCK) <= AUTO_BLOCK_BYTES)
    {
        ordering = nested_dissection(&d.system.graph, d.dofs);
        // Tighter than ARPACK's 1e-12: at 1e-12 the mode checks measured 2e-10 on the mould and
        // 1.7e-9 on a 323k-unknown mesh (ARPACK: 2e-12, 1.2e-11); 1e-14 gave 8.7e-12 on the
        // mould for 7 % more solves.
        Box::new(block::BlockKrylov {
            problem: &problem,
            ordering: &ordering,
            tol: 1e-14,
            block: BLOCK,
        })
    } else {
        ordering = nested_dissection(&d.system.graph, d.dofs);
        Box::new(arpack::Arpack {
            problem: &problem,
            ordering: &ordering,
            tol: 1e-12,
        })
    };
    let first_elastic = (d.rigid > 0)
        .then(|| trial::first_elastic_bound(&problem, d.dofs, &d.mesh.nodes, d.rigid))
        .flatten();
    let ordering_s = t.elapsed().as_secs_f64();
    let modes = compute_bounded(&problem, d.dofs, d.rigid, count, solver.as_ref(), first_elastic)?;
    tracing::debug!(
        bound = first_elastic,
        first = modes.eigenvalues.first().copied(),
        "first elastic eigenvalue: bound and solved"
    );
    Ok((modes, ordering_s))
}

/// SLEPc over the MPI ranks, which assemble their own rows from the mesh (rank 0's whole K and M
/// are not sent); also the seconds of that assembly.
fn on_ranks(d: Space<'_>, count: usize, choice: SolverChoice) -> Result<(Modes, f64), ModesError> {
    let s = solve_on_ranks(d.mesh, d.dofs, d.material, d.rigid, count, choice)?;
    Ok((s.modes, s.assemble_s))
}

/// The result of [`solve_on_ranks`].
pub struct SolvedOnRanks {
    /// The modes, checked.
    pub modes: Modes,
    /// Mass and moments of the whole part (each rank's elements, summed).
    pub moments: crate::fem::Moments,
    /// Seconds the ranks spent partitioning and assembling.
    pub assemble_s: f64,
}

/// Solves K φ = λ M φ of `mesh` (E, ν, ρ; supports in `dofs`, `rigid` rigid motions left) with
/// SLEPc over every MPI rank, each assembling its own rows: rank 0 calls this while the others
/// are in [`mpi_job::serve`]. The `count` lowest elastic modes come back checked, with the
/// part's mass moments. An error in a ves built without the `slepc` feature.
pub fn solve_on_ranks(
    mesh: &crate::tet_mesh::Mesh,
    dofs: &Dofs,
    material: crate::material::Material,
    rigid: usize,
    count: usize,
    choice: SolverChoice,
) -> Result<SolvedOnRanks, ModesError> {
    #[cfg(feature = "slepc")]
    {
        slepc::solve(mesh, dofs, material, rigid, count, choice)
    }
    #[cfg(not(feature = "slepc"))]
    {
        let _ = (mesh, dofs, material, rigid, count, choice);
        Err(mpi_job::not_built())
    }
}

/// SLEPc's tolerance for a method, given the problem's mean(diag M).
pub fn slepc_tolerance(choice: SolverChoice, mass_scale: f64) -> f64 {
    if choice == SolverChoice::SlepcIterative {
        // SLEPc's relative error ‖Kx − λMx‖/(|λ|‖x‖) is the mode checks' ‖Kx − λMx‖/‖Kx‖ times
        // ‖Mx‖/‖x‖ ≈ mean(diag M): aim at 1e-7 by the checks' measure (they ask 1e-6). A fixed
        // tolerance fails one way or the other: 1e-9 left the P1 mould's mode 16 at 1.13e-6,
        // and at 1e-10 the cantilever converged nothing in 10,000 iterations (Jacobi–Davidson's
        // explicit residuals stall).
        (ITERATIVE_RESIDUAL * mass_scale).clamp(1e-13, 1e-8)
    } else {
        1e-12
    }
}

/// A failed mode check under SLEPc with `PETSC_OPTIONS` set names it: an approximate factor
/// there (measured: MUMPS block low-rank with CNTL(7) = 1e-8 left residuals of 1e-5 on the P2
/// mould) or a loose tolerance fails the checks, and no mesh change would help.
#[cfg_attr(not(feature = "slepc"), allow(dead_code))]
pub(crate) fn blame_petsc_options(e: ModesError, petsc_options: bool) -> ModesError {
    match e {
        ModesError::Check { mode, what } if petsc_options => ModesError::Check {
            mode,
            what: format!(
                "{what}; PETSC_OPTIONS is set, and an approximate factor there (MUMPS block low-rank) or a loose \
                 tolerance gives such residuals: run without it"
            ),
        },
        e => e,
    }
}

#[cfg(test)]
mod tests {
    use super::Model as Discretized;
    use super::*;
    use crate::tet_mesh::Mesh;

    #[test]
    fn a_failed_check_under_petsc_options_names_them() {
        let check = || ModesError::Check {
            mode: 0,
            what: "relative residual 1.27e-5 > 1.0e-6".into(),
        };
        let with = blame_petsc_options(check(), true).to_string();
        assert!(with.contains("1.27e-5") && with.contains("PETSC_OPTIONS"), "{with}");
        let without = blame_petsc_options(check(), false).to_string();
        assert!(!without.contains("PETSC_OPTIONS"), "{without}");
        let other = blame_petsc_options(ModesError::Block("x".into()), true).to_string();
        assert!(!other.contains("PETSC_OPTIONS"), "{other}");
    }

    /// The count agrees with what ARPACK found on a clamped beam, and catches a mode taken out
    /// of the middle of the spectrum (as a solver that skipped one would leave it).
    #[test]
    fn the_sturm_count_proves_completeness_and_catches_a_skipped_mode() {
        let mesh = Mesh::structured_box([16, 2, 2], 0.05, crate::fem::element::Kind::Tet4, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-12; 3]).collect();
        let d = Discretized::assemble(
            mesh,
            Dofs::from_mask(&mask),
            crate::material::Material::elastic(2e11, 0.3, 7800.0),
        )
        .expect("assembles");
        let (mut m, _) = solve(d.space(), 8, SolverChoice::Arpack).expect("solves");
        let s = sturm_count(&d.system, &d.dofs, &m).unwrap().unwrap();
        assert!(s.complete() && s.below == 8, "{s:?}");
        // Skip mode 4: the top is unchanged, so 8 eigenvalues still lie below σ, 7 were "found".
        let n = m.vectors.len() / 8;
        m.eigenvalues.remove(3);
        m.vectors.drain(3 * n..4 * n);
        let s = sturm_count(&d.system, &d.dofs, &m).unwrap().unwrap();
        assert!(!s.complete() && s.below == 8 && s.found == 7, "{s:?}");
    }
}
