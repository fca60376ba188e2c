//! SLEPc Krylov–Schur in shift-invert with a MUMPS factorisation (or Jacobi–Davidson with
//! GAMG), over every MPI rank: an [`EigenSolver`] whose K and M live on the ranks.
//!
//! For each space rank 0 splits the part into one compact region per rank (METIS), numbers the
//! free DOFs rank by rank so that each rank's rows are its region's DOFs
//! ([`crate::fem::share::Numbering`]), and sends every rank its share of the mesh: the elements
//! touching its rows. Each rank, rank 0 included, assembles only its rows; all factor, iterate
//! and check the modes together (residuals and M-inner products are computed on each rank's
//! rows); only the eigenvectors come back, to rank 0. So rank 0 never holds the whole K and M
//! (unless a later stage needs them: the error estimate, static correction, VOI transfers), and
//! every rank's memory is its share of the matrices, the factor and the Krylov vectors, falling
//! with the number of ranks; rank 0 holds in addition the mesh and the basis. The other ranks
//! wait in [`super::mpi_job::serve`] for rank 0's messages.

use super::mpi_job::{HEADER, IN_SOLVE, header, message, with_token};
use super::{EigenSolver, ModesError, Scales, SolvedOnRanks, SolverChoice, Spectrum};
use crate::fem::Dofs;
use crate::fem::Moments;
use crate::fem::share::{Numbering, Share};
use crate::material::Material;
use crate::tet_mesh::Mesh;
use std::sync::atomic::Ordering::SeqCst;
use ves_slepc::{Method, Operators, Slepc};

/// [`super::solve_on_ranks`]: solves K φ = λ M φ of `mesh` (its material; supports in `dofs`, `rigid` rigid motions left) with
/// SLEPc over every MPI rank: rank 0 calls this while the others are in
/// [`super::mpi_job::serve`]. The `count` lowest elastic modes come back checked (by the ranks,
/// where the vectors live), with the part's mass moments.
pub fn solve(
    mesh: &Mesh,
    dofs: &Dofs,
    material: Material,
    rigid: usize,
    count: usize,
    choice: SolverChoice,
) -> Result<SolvedOnRanks, ModesError> {
    with_token(|token| {
        // Refused before the ranks assemble anything.
        super::eigenpairs_wanted(dofs.free_count(), count, rigid)?;
        let t0 = std::time::Instant::now();
        let (solver, scales, moments) = Distributed::assemble(token, mesh, dofs, material, choice)?;
        let assemble_s = t0.elapsed().as_secs_f64();
        let petsc_options = std::env::var_os("PETSC_OPTIONS").is_some();
        let modes = super::select(&scales, rigid, count, &solver, None, None)
            .map_err(|e| super::blame_petsc_options(e, petsc_options));
        solver.release()?;
        Ok(SolvedOnRanks {
            modes: modes?,
            moments,
            assemble_s,
        })
    })
}

/// SLEPc over the MPI ranks, on operators the ranks assembled (each its rows).
pub struct Distributed<'t> {
    token: &'t Slepc,
    ops: Operators,
    /// The rank-by-rank numbering of the free DOFs (to put the eigenvectors back in the DOFs' own).
    numbering: Numbering,
    tol: f64,
    method: Method,
}

impl EigenSolver for Distributed<'_> {
    /// Rank 0's side of one eigen-solve on the assembled operators: the other ranks are told σ
    /// and the rest, then all solve together; the pairs come back ascending with their checks.
    fn lowest(&self, nev: usize, sigma: f64) -> Result<Spectrum, ModesError> {
        IN_SOLVE.store(true, SeqCst);
        let words = [
            nev as u64,
            sigma.to_bits(),
            self.tol.to_bits(),
            u64::from(self.method == Method::Iterative),
        ];
        for r in 1..self.token.size() {
            self.token
                .send(r, &header(message::SOLVE, &words))
                .map_err(slepc_error)?;
        }
        let e = self
            .token
            .lowest_eigenpairs(&self.ops, nev, sigma, self.tol, self.method)
            .map_err(slepc_error)?;
        IN_SOLVE.store(false, SeqCst);
        tracing::debug!(iterations = e.iterations, errors = ?e.relative_errors, "SLEPc converged");
        // Ascending (nearest a target below the spectrum is already ascending; make sure).
        let mut order: Vec<usize> = (0..e.values.len()).collect();
        order.sort_by(|&a, &b| e.values[a].total_cmp(&e.values[b]));
        let n = self.ops.size();
        let k = order.len();
        // Usually in order already: then the gathered vectors are kept, not copied (n × nev).
        let mut vectors = if order.iter().enumerate().all(|(i, &o)| i == o) {
            e.vectors
        } else {
            order
                .iter()
                .flat_map(|&i| e.vectors[i * n..(i + 1) * n].iter().copied())
                .collect()
        };
        // Rows back from the ranks' numbering to the DOFs' own.
        self.numbering.restore(&mut vectors);
        Ok(Spectrum {
            values: order.iter().map(|&i| e.values[i]).collect(),
            vectors,
            factorize_s: e.setup_s,
            eigensolve_s: e.solve_s,
            factored: None,
            checked: Some(super::Checked {
                residuals: order.iter().map(|&i| e.residuals[i]).collect(),
                gram: (0..k * k).map(|x| e.gram[order[x / k] * k + order[x % k]]).collect(),
            }),
        })
    }
}

impl<'t> Distributed<'t> {
    /// Rank 0's side of the assembly: the free DOFs numbered rank by rank (one compact region of
    /// the part each), every other rank (waiting in [`super::mpi_job::serve`]) sent its share of
    /// the mesh, one rank at a time (rank 0 never holds more than its own and one other share),
    /// then all assemble their rows together ([`build`]). Also the scales of K and M and the
    /// part's mass moments, summed over the ranks.
    fn assemble(
        token: &'t Slepc,
        mesh: &Mesh,
        dofs: &Dofs,
        material: Material,
        choice: SolverChoice,
    ) -> Result<(Self, Scales, Moments), ModesError> {
        let method = if choice == SolverChoice::SlepcIterative {
            Method::Iterative
        } else {
            Method::ShiftInvert
        };
        IN_SOLVE.store(true, SeqCst);
        let (n, size) = (dofs.free_count(), token.size());
        let numbering = if size > 1 {
            let graph = crate::fem::assembly::node_graph(mesh, &[]);
            Numbering::from_parts(dofs, &crate::linsolve::node_parts(&graph, dofs, size), size)
        } else {
            Numbering::single(dofs)
        };
        let mut parts = crate::fem::share::partition(mesh, &numbering);
        let frame = (method == Method::Iterative).then(|| crate::rigid_motions::frame(&mesh.nodes));
        let (c, l) = frame.unwrap_or(([0.0; 3], 0.0));
        let numbers = [material.young, material.poisson, material.density, c[0], c[1], c[2], l];
        let range = |r: usize| (numbering.bounds[r], numbering.bounds[r + 1]);
        for (r, part) in parts.iter_mut().enumerate().skip(1) {
            let (elements, owned) = std::mem::take(part);
            let s = Share::of(mesh, &numbering, elements, owned);
            send_share(token, r, n, range(r), &s, &numbers, frame.is_some()).map_err(slepc_error)?;
        }
        let (elements, owned) = std::mem::take(&mut parts[0]);
        drop(parts);
        let own = Share::of(mesh, &numbering, elements, owned);
        let (ops, scales, moments) =
            build(token, n, range(0), &own, material, frame).map_err(|e| ModesError::Rank(format!("{e:#}")))?;
        IN_SOLVE.store(false, SeqCst);
        let tol = super::slepc_tolerance(choice, scales.mass());
        let solver = Distributed {
            token,
            ops,
            numbering,
            tol,
            method,
        };
        Ok((solver, scales, moments))
    }

    /// The solves are done: the other ranks free their operators (they wait for a message). A
    /// failed solve may have left them in a collective call instead: then only
    /// [`super::mpi_job::finish`] can end them, and nothing is sent.
    fn release(self) -> Result<(), ModesError> {
        if !IN_SOLVE.load(SeqCst) {
            for r in 1..self.token.size() {
                self.token
                    .send(r, &header(message::RELEASE, &[]))
                    .map_err(slepc_error)?;
            }
        }
        Ok(())
    }
}

/// Sends rank `r` its share of the mesh (the header, then E, ν, ρ and the rigid-motion frame,
/// then the arrays).
fn send_share(
    token: &Slepc,
    r: usize,
    n: usize,
    (lo, hi): (usize, usize),
    s: &Share,
    numbers: &[f64; 7],
    frame: bool,
) -> Result<(), ves_slepc::PetscError> {
    let words = [
        n as u64,
        lo as u64,
        hi as u64,
        (s.xyz.len() / 3) as u64,
        s.tets.len() as u64,
        s.elements.len() as u64,
        s.owned as u64,
        u64::from(s.kind.order()),
        s.vertex_count as u64,
        u64::from(frame),
    ];
    token.send(r, &header(message::ASSEMBLE, &words))?;
    token.send(r, numbers)?;
    token.send(r, &s.xyz)?;
    token.send(r, &s.free)?;
    token.send(r, &s.tets)?;
    token.send(r, &s.elements)
}

/// A serving rank's side of [`message::ASSEMBLE`] (header `h`): receives its share of the mesh
/// and assembles its rows with every other rank ([`build`]).
pub(super) fn assemble_share(token: &Slepc, h: &[u64]) -> anyhow::Result<Operators> {
    debug_assert_eq!(h.len(), HEADER);
    let (n, lo, hi) = (h[1] as usize, h[2] as usize, h[3] as usize);
    let (nodes, tets, elements) = (h[4] as usize, h[5] as usize, h[6] as usize);
    let numbers: Vec<f64> = token.receive(0, 7)?;
    let kind = u32::try_from(h[8])
        .ok()
        .and_then(crate::fem::element::Kind::of_order)
        .ok_or_else(|| anyhow::anyhow!("rank 0 sent element order {}, which this ves does not know", h[8]))?;
    let share = Share {
        owned: h[7] as usize,
        kind,
        vertex_count: h[9] as usize,
        xyz: token.receive(0, 3 * nodes)?,
        free: token.receive(0, 3 * nodes)?,
        tets: token.receive(0, tets)?,
        elements: token.receive(0, elements)?,
    };
    let material = Material::elastic(numbers[0], numbers[1], numbers[2]);
    let frame = (h[10] == 1).then(|| ([numbers[3], numbers[4], numbers[5]], numbers[6]));
    Ok(build(token, n, (lo, hi), &share, material, frame)?.0)
}

/// Near-null vectors per unknown of the iterative method (the rigid-body motions).
const NEAR_NULL: usize = 6;

/// Every rank's side of the assembly (collective): its rows of K and M from its share (with the
/// rigid motions in `frame` as near-null space, for the iterative method), an error on any rank
/// made every rank's, the scales and mass moments summed over the ranks, and the operators.
fn build(
    token: &Slepc,
    n: usize,
    (lo, hi): (usize, usize),
    share: &crate::fem::share::Share,
    material: Material,
    frame: Option<([f64; 3], f64)>,
) -> anyhow::Result<(Operators, Scales, Moments)> {
    let (rows, moments) = super::mpi_job::agree(rows_of(share, material, frame, lo, hi))?;

    let local = Scales::of_diagonal(
        n,
        (0..hi - lo).filter_map(|r| {
            let span = rows.row_ptr[r] as usize..rows.row_ptr[r + 1] as usize;
            span.clone()
                .find(|&e| rows.cols[e] as usize == lo + r)
                .map(|e| (rows.k[e], rows.m[e]))
        }),
    );
    let mut sums = [0.0; 15];
    sums[0] = local.diag_k;
    sums[1] = local.diag_m;
    sums[2..].copy_from_slice(&moments.to_array());
    token.sum_over_ranks(&mut sums)?;
    let mut ratio = [local.max_ratio];
    token.max_over_ranks(&mut ratio)?;
    let scales = Scales {
        size: n,
        diag_k: sums[0],
        diag_m: sums[1],
        max_ratio: ratio[0],
    };
    let moments = Moments::from_array(sums[2..].try_into().unwrap_or(&[0.0; 13]));
    let ops = token.operators(n, rows)?;
    // The share's assembly and the rows are freed now, but malloc keeps their pages (measured
    // on the 556k mould: 0.3–0.5 GB per rank): given back before MUMPS takes its own.
    crate::memory::release_free_memory();
    tracing::debug!(
        rank = token.rank(),
        rows = hi - lo,
        rss_gb = crate::memory::rss_bytes() as f64 / 1e9,
        "operators assembled"
    );
    Ok((ops, scales, moments))
}

/// This rank's rows `lo..hi` of K and M from its share, and the moments of the elements it owns.
fn rows_of(
    share: &crate::fem::share::Share,
    material: Material,
    frame: Option<([f64; 3], f64)>,
    lo: usize,
    hi: usize,
) -> anyhow::Result<(ves_slepc::LocalRows, Moments)> {
    let (a, global, moments, mesh, dofs) = share.assemble(&material)?;
    let pair = ves_slepc::SymmetricPair {
        n: global.len(),
        col_ptr: a.pattern.col_ptr(),
        row_idx: a.pattern.row_idx(),
        k: &a.k,
        m: &a.m,
    };
    let mut rows = ves_slepc::LocalRows::from_lower(&pair, &global, lo, hi);
    drop(a);
    if let Some(r) = (0..hi - lo).find(|&r| rows.row_ptr[r + 1] == rows.row_ptr[r]) {
        anyhow::bail!(
            "unknown {} belongs to no element of this rank's share of the mesh (a node outside every tet): remesh",
            lo + r
        );
    }
    if let Some(frame) = frame {
        let motions = crate::rigid_motions::on_free_dofs_in(&mesh.nodes, &dofs, frame);
        rows.near_null = vec![0.0; NEAR_NULL * (hi - lo)];
        for (k, &g) in global.iter().enumerate() {
            let g = g as usize;
            if (lo..hi).contains(&g) {
                rows.near_null[NEAR_NULL * (g - lo)..NEAR_NULL * (g - lo + 1)]
                    .copy_from_slice(&motions[NEAR_NULL * k..NEAR_NULL * (k + 1)]);
            }
        }
        rows.near_null_count = NEAR_NULL;
    }
    Ok((rows, moments))
}

fn slepc_error(e: ves_slepc::PetscError) -> ModesError {
    ModesError::Slepc(e.to_string())
}
