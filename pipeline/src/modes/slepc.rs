//! SLEPc Krylov–Schur in shift-invert with a MUMPS factorisation (or Jacobi–Davidson with
//! GAMG), over every MPI rank (`ves precompute --solver slepc`, alone or under `mpirun -n N`).
//!
//! Under MPI rank 0 runs the pipeline (meshing, checks of the scene, writing) and the other
//! ranks only [`serve`] its eigen-solves. For each space rank 0 splits the part into one compact
//! region per rank (METIS), numbers the free DOFs rank by rank so that each rank's rows are its
//! region's DOFs ([`crate::fem::share::Numbering`]), and sends every rank its share of the
//! mesh: the elements touching its rows. Each rank, rank 0 included, assembles only its rows; all
//! factor, iterate and check the modes together (residuals and M-inner products are computed on
//! each rank's rows); only the eigenvectors come back, to rank 0. So rank 0 never holds the whole
//! K and M (unless a later stage needs them: the error estimate, static correction, VOI
//! transfers), and every rank's memory is its share of the matrices, the factor and the Krylov
//! vectors, falling with the number of ranks; rank 0 holds in addition the mesh and the basis.

use super::{Modes, ModesError, SolverChoice};
use crate::fem::Moments;
#[cfg(feature = "slepc")]
use crate::fem::share::Numbering;
use crate::mesh::Mesh;
use crate::supports::Dofs;

#[cfg(feature = "slepc")]
thread_local! {
    static TOKEN: std::cell::RefCell<Option<ves_ffi::slepc::Slepc>> = const { std::cell::RefCell::new(None) };
}

#[cfg(not(feature = "slepc"))]
fn not_built() -> ModesError {
    ModesError::Slepc(
        "this ves was built without SLEPc: install libslepc-real-dev and build with `--features slepc`".into(),
    )
}

/// SLEPc initialised on this thread for the life of the guard (MPI too; finalised on drop).
pub struct SlepcGuard(());

impl SlepcGuard {
    /// Initialises SLEPc and MPI (once per process).
    pub fn init() -> Result<SlepcGuard, ModesError> {
        #[cfg(feature = "slepc")]
        {
            let token = ves_ffi::slepc::Slepc::init().map_err(|e| ModesError::Slepc(e.to_string()))?;
            TOKEN.with(|t| *t.borrow_mut() = Some(token));
            Ok(SlepcGuard(()))
        }
        #[cfg(not(feature = "slepc"))]
        Err(not_built())
    }
}

impl Drop for SlepcGuard {
    fn drop(&mut self) {
        #[cfg(feature = "slepc")]
        TOKEN.with(|t| drop(t.borrow_mut().take()));
    }
}

/// This process's MPI rank (0 without SLEPc).
pub fn rank() -> usize {
    #[cfg(feature = "slepc")]
    {
        TOKEN.with(|t| t.borrow().as_ref().map_or(0, |s| s.rank()))
    }
    #[cfg(not(feature = "slepc"))]
    0
}

/// Number of MPI ranks (1 without SLEPc).
pub fn ranks() -> usize {
    #[cfg(feature = "slepc")]
    {
        TOKEN.with(|t| t.borrow().as_ref().map_or(1, |s| s.size()))
    }
    #[cfg(not(feature = "slepc"))]
    1
}

/// Whether an error has been made every rank's by [`agree`] (then no rank waits for another,
/// and the job ends cleanly).
#[cfg(feature = "slepc")]
static AGREED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Longest error message [`agree`] passes between ranks, bytes (longer ones are cut).
#[cfg(feature = "slepc")]
const MESSAGE_BYTES: usize = 2048;

/// A step that may fail on some ranks and not others (reading the scene, checking the output),
/// made collective: every rank passes its own result of the same step, and if any rank failed,
/// every rank returns the error of the lowest failing rank (its message, prefixed with the rank
/// when it is not rank 0), so that all ranks stop together and rank 0 alone reports it. Without
/// MPI (or on one rank) the result is returned as it is. Collective: every rank must call it at
/// the same point.
pub fn agree<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    #[cfg(feature = "slepc")]
    {
        if ranks() <= 1 {
            return result;
        }
        let me = rank();
        let failed = result.is_err();
        let reduced = TOKEN.with(|t| -> Result<Option<String>, ves_ffi::slepc::PetscError> {
            let guard = t.borrow();
            let Some(mpi) = guard.as_ref() else {
                return Ok(None);
            };
            let mut first = [if failed { me as i32 } else { i32::MAX }];
            mpi.min_over_ranks(&mut first)?;
            if first[0] == i32::MAX {
                return Ok(None);
            }
            // The failing rank's message, one byte per int, summed with everyone else's zeros.
            let mut text = vec![0i32; MESSAGE_BYTES];
            if let (true, Err(e)) = (first[0] as usize == me, &result) {
                let message = format!("{e:#}");
                let mut end = message.len().min(MESSAGE_BYTES);
                while !message.is_char_boundary(end) {
                    end -= 1;
                }
                for (slot, byte) in text.iter_mut().zip(message[..end].bytes()) {
                    *slot = byte as i32;
                }
            }
            mpi.sum_over_ranks(&mut text)?;
            let bytes: Vec<u8> = text.iter().take_while(|&&b| b != 0).map(|&b| b as u8).collect();
            let message = String::from_utf8_lossy(&bytes).into_owned();
            Ok(Some(if first[0] == 0 {
                message
            } else {
                format!("MPI rank {}: {message}", first[0])
            }))
        });
        match reduced {
            Ok(None) => result,
            Ok(Some(message)) => {
                AGREED.store(true, std::sync::atomic::Ordering::SeqCst);
                Err(anyhow::anyhow!(message))
            }
            // MPI itself failed: no agreement is possible; [`finish`] aborts the job.
            Err(e) => Err(anyhow::anyhow!("{e}")),
        }
    }
    #[cfg(not(feature = "slepc"))]
    result
}

/// The end of a command under MPI: an error that [`agree`] did not make every rank's may have
/// left other ranks waiting in a collective call, so it is printed here (with its rank) and the
/// whole job is ended (`MPI_Abort`, exit status 1 on every rank). Anything else is returned.
/// Call it before the [`SlepcGuard`] is dropped (finalising MPI would wait for the stuck ranks).
pub fn finish<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    #[cfg(feature = "slepc")]
    if let Err(e) = &result
        && ranks() > 1
        && !AGREED.load(std::sync::atomic::Ordering::SeqCst)
    {
        eprintln!("error: MPI rank {} of {}: {e:#}; ending every rank", rank(), ranks());
        TOKEN.with(|t| {
            if let Some(mpi) = t.borrow().as_ref() {
                mpi.abort(1)
            }
        });
    }
    result
}

/// The result of [`solve`].
pub struct Solved {
    /// The modes, checked.
    pub modes: Modes,
    /// Mass and moments of the whole part (each rank's elements, summed).
    pub moments: Moments,
    /// Seconds the ranks spent partitioning and assembling.
    pub assemble_s: f64,
}

/// Solves K φ = λ M φ of `mesh` (E, ν, ρ; supports in `dofs`, `rigid` rigid motions left) with
/// SLEPc over every MPI rank: rank 0 calls this while the others are in [`serve`]. The `count`
/// lowest elastic modes come back checked, with the part's mass moments.
pub fn solve(
    mesh: &Mesh,
    dofs: &Dofs,
    material: (f64, f64, f64),
    rigid: usize,
    count: usize,
    choice: SolverChoice,
) -> Result<Solved, ModesError> {
    #[cfg(feature = "slepc")]
    {
        use std::sync::atomic::Ordering::SeqCst;
        TOKEN.with(|t| {
            let t = t.borrow();
            let token = t
                .as_ref()
                .ok_or_else(|| ModesError::Slepc("SLEPc is not initialised (SlepcGuard::init)".into()))?;
            // Refused before the ranks assemble anything.
            super::eigenpairs_wanted(dofs.free_count(), count, rigid)?;
            let t0 = std::time::Instant::now();
            let method = method_of(choice);
            IN_SOLVE.store(true, SeqCst);
            let (ops, scales, moments, numbering) = assemble(token, mesh, dofs, material, method)?;
            IN_SOLVE.store(false, SeqCst);
            let assemble_s = t0.elapsed().as_secs_f64();
            let tol = super::slepc_tolerance(choice, scales.mass());
            let petsc_options = std::env::var_os("PETSC_OPTIONS").is_some();
            let modes = super::select(
                &scales,
                rigid,
                count,
                |nev, sigma| lowest(token, &ops, &numbering, nev, sigma, tol, method),
                None,
            )
            .map_err(|e| super::blame_petsc_options(e, petsc_options));
            // A failed solve may have left the other ranks in a collective call: then only
            // `finish` can end them. Otherwise they wait for a message: free their matrices.
            if !IN_SOLVE.load(SeqCst) {
                for r in 1..token.size() {
                    token.send(r, &header(message::RELEASE, &[])).map_err(slepc_error)?;
                }
            }
            Ok(Solved {
                modes: modes?,
                moments,
                assemble_s,
            })
        })
    }
    #[cfg(not(feature = "slepc"))]
    {
        let _ = (mesh, dofs, material, rigid, count, choice);
        Err(not_built())
    }
}

#[cfg(feature = "slepc")]
fn slepc_error(e: ves_ffi::slepc::PetscError) -> ModesError {
    ModesError::Slepc(e.to_string())
}

/// The SLEPc method of a solver choice.
#[cfg(feature = "slepc")]
fn method_of(choice: SolverChoice) -> ves_ffi::slepc::Method {
    if choice == SolverChoice::SlepcIterative {
        ves_ffi::slepc::Method::Iterative
    } else {
        ves_ffi::slepc::Method::ShiftInvert
    }
}

/// What rank 0 tells the other ranks (the first word of a [`HEADER`]-word message).
#[cfg(feature = "slepc")]
mod message {
    /// The pipeline is done: return.
    pub const STOP: u64 = 0;
    /// An eigen-solve on the operators assembled last: nev, σ, tolerance, method.
    pub const SOLVE: u64 = 1;
    /// Rank 0 failed outside a solve (and says why itself): return that error.
    pub const FAIL: u64 = 2;
    /// A share of a new problem follows: assemble its rows (the operators of the solves after).
    pub const ASSEMBLE: u64 = 3;
    /// The problem's solves are done: free its operators.
    pub const RELEASE: u64 = 4;
}

/// Words of a message header: its kind, then the kind's numbers.
#[cfg(feature = "slepc")]
const HEADER: usize = 12;

#[cfg(feature = "slepc")]
fn header(kind: u64, words: &[u64]) -> [u64; HEADER] {
    let mut h = [0; HEADER];
    h[0] = kind;
    h[1..=words.len()].copy_from_slice(words);
    h
}

/// Near-null vectors per unknown of the iterative method (the rigid-body motions).
#[cfg(feature = "slepc")]
const NEAR_NULL: usize = 6;

/// True while rank 0 is in a step every rank takes part in: an error then may leave the others
/// in a collective call, so it must end the job ([`finish`]) rather than be told to them.
#[cfg(feature = "slepc")]
static IN_SOLVE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Rank 0's side of the assembly: the free DOFs numbered rank by rank (one compact region of the
/// part each), every other rank (waiting in [`serve`]) sent its share of the mesh, one rank at a
/// time (rank 0 never holds more than its own and one other share), then all assemble their rows
/// together ([`build`]). Also the numbering (to put the eigenvectors back into the DOFs' own).
#[cfg(feature = "slepc")]
fn assemble(
    token: &ves_ffi::slepc::Slepc,
    mesh: &Mesh,
    dofs: &Dofs,
    material: (f64, f64, f64),
    method: ves_ffi::slepc::Method,
) -> Result<(ves_ffi::slepc::Operators, super::Scales, Moments, Numbering), ModesError> {
    use crate::fem::share::{Share, partition};
    let (n, size) = (dofs.free_count(), token.size());
    let numbering = if size > 1 {
        let graph = crate::fem::assembly::node_graph(mesh);
        Numbering::from_parts(dofs, &crate::linsolve::node_parts(&graph, dofs, size), size)
    } else {
        Numbering::single(dofs)
    };
    let mut parts = partition(mesh, &numbering);
    let frame = (method == ves_ffi::slepc::Method::Iterative).then(|| crate::rigid_motions::frame(&mesh.nodes));
    let (c, l) = frame.unwrap_or(([0.0; 3], 0.0));
    let numbers = [material.0, material.1, material.2, c[0], c[1], c[2], l];
    let range = |r: usize| (numbering.bounds[r], numbering.bounds[r + 1]);
    for (r, part) in parts.iter_mut().enumerate().skip(1) {
        let (elements, owned) = std::mem::take(part);
        let s = Share::of(mesh, &numbering, elements, owned);
        let words = [
            n as u64,
            range(r).0 as u64,
            range(r).1 as u64,
            (s.xyz.len() / 3) as u64,
            s.tets.len() as u64,
            s.elements.len() as u64,
            s.owned as u64,
            s.order as u64,
            s.vertex_count as u64,
            u64::from(frame.is_some()),
        ];
        let sent = token
            .send(r, &header(message::ASSEMBLE, &words))
            .and_then(|_| token.send(r, &numbers))
            .and_then(|_| token.send(r, &s.xyz))
            .and_then(|_| token.send(r, &s.free))
            .and_then(|_| token.send(r, &s.tets))
            .and_then(|_| token.send(r, &s.elements));
        sent.map_err(slepc_error)?;
    }
    let (elements, owned) = std::mem::take(&mut parts[0]);
    drop(parts);
    let own = Share::of(mesh, &numbering, elements, owned);
    let (ops, scales, moments) =
        build(token, n, range(0), &own, material, frame).map_err(|e| ModesError::Rank(format!("{e:#}")))?;
    Ok((ops, scales, moments, numbering))
}

/// Every rank's side of the assembly (collective): its rows of K and M from its share (with the
/// rigid motions in `frame` as near-null space, for the iterative method), an error on any rank
/// made every rank's, the scales and mass moments summed over the ranks, and the operators.
#[cfg(feature = "slepc")]
fn build(
    token: &ves_ffi::slepc::Slepc,
    n: usize,
    (lo, hi): (usize, usize),
    share: &crate::fem::share::Share,
    material: (f64, f64, f64),
    frame: Option<([f64; 3], f64)>,
) -> anyhow::Result<(ves_ffi::slepc::Operators, super::Scales, Moments)> {
    let (rows, moments) = agree(rows_of(share, material, frame, lo, hi))?;

    let local = super::Scales::of_diagonal(
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
    let scales = super::Scales {
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
#[cfg(feature = "slepc")]
fn rows_of(
    share: &crate::fem::share::Share,
    material: (f64, f64, f64),
    frame: Option<([f64; 3], f64)>,
    lo: usize,
    hi: usize,
) -> anyhow::Result<(ves_ffi::slepc::LocalRows, Moments)> {
    let (a, global, moments, mesh, dofs) = share.assemble(material)?;
    let pair = ves_ffi::slepc::SymmetricPair {
        n: global.len(),
        col_ptr: a.pattern.col_ptr(),
        row_idx: a.pattern.row_idx(),
        k: &a.k,
        m: &a.m,
    };
    let mut rows = ves_ffi::slepc::LocalRows::from_lower(&pair, &global, lo, hi);
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

/// Rank 0's side of one eigen-solve on the assembled operators: the other ranks are told σ and
/// the rest, then all solve together; the pairs come back ascending with their checks.
#[cfg(feature = "slepc")]
fn lowest(
    token: &ves_ffi::slepc::Slepc,
    ops: &ves_ffi::slepc::Operators,
    numbering: &Numbering,
    nev: usize,
    sigma: f64,
    tol: f64,
    method: ves_ffi::slepc::Method,
) -> Result<super::Spectrum, ModesError> {
    use std::sync::atomic::Ordering::SeqCst;
    IN_SOLVE.store(true, SeqCst);
    let words = [
        nev as u64,
        sigma.to_bits(),
        tol.to_bits(),
        u64::from(method == ves_ffi::slepc::Method::Iterative),
    ];
    for r in 1..token.size() {
        token.send(r, &header(message::SOLVE, &words)).map_err(slepc_error)?;
    }
    let e = token
        .lowest_eigenpairs(ops, nev, sigma, tol, method)
        .map_err(slepc_error)?;
    IN_SOLVE.store(false, SeqCst);
    tracing::debug!(iterations = e.iterations, errors = ?e.relative_errors, "SLEPc converged");
    // Ascending (nearest a target below the spectrum is already ascending; make sure).
    let mut order: Vec<usize> = (0..e.values.len()).collect();
    order.sort_by(|&a, &b| e.values[a].total_cmp(&e.values[b]));
    let n = ops.size();
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
    numbering.restore(&mut vectors);
    Ok(super::Spectrum {
        values: order.iter().map(|&i| e.values[i]).collect(),
        vectors,
        factorize_s: e.setup_s,
        eigensolve_s: e.solve_s,
        symbolic: None,
        checked: Some(super::Checked {
            residuals: order.iter().map(|&i| e.residuals[i]).collect(),
            gram: (0..k * k).map(|x| e.gram[order[x / k] * k + order[x % k]]).collect(),
        }),
    })
}

/// The life of ranks 1.. under MPI: assemble each problem rank 0 sends a share of and take part
/// in its eigen-solves, until rank 0 says the pipeline is done (Ok) or failed (an error that rank
/// 0 reports: nothing to print here).
pub fn serve() -> anyhow::Result<()> {
    #[cfg(feature = "slepc")]
    {
        TOKEN.with(|t| -> anyhow::Result<()> {
            let guard = t.borrow();
            let token = guard
                .as_ref()
                .ok_or_else(|| anyhow::anyhow!("SLEPc is not initialised (SlepcGuard::init)"))?;
            let mut ops = None;
            loop {
                let h: Vec<u64> = token.receive(0, HEADER)?;
                match h[0] {
                    message::STOP => return Ok(()),
                    message::FAIL => {
                        AGREED.store(true, std::sync::atomic::Ordering::SeqCst);
                        anyhow::bail!("rank 0 failed");
                    }
                    message::RELEASE => ops = None,
                    message::ASSEMBLE => {
                        // The last problem's matrices go before this one's are built.
                        drop(ops.take());
                        let (n, lo, hi) = (h[1] as usize, h[2] as usize, h[3] as usize);
                        let (nodes, tets, elements) = (h[4] as usize, h[5] as usize, h[6] as usize);
                        let numbers: Vec<f64> = token.receive(0, 7)?;
                        let share = crate::fem::share::Share {
                            owned: h[7] as usize,
                            order: h[8] as u8,
                            vertex_count: h[9] as usize,
                            xyz: token.receive(0, 3 * nodes)?,
                            free: token.receive(0, 3 * nodes)?,
                            tets: token.receive(0, tets)?,
                            elements: token.receive(0, elements)?,
                        };
                        let material = (numbers[0], numbers[1], numbers[2]);
                        let frame = (h[10] == 1).then(|| ([numbers[3], numbers[4], numbers[5]], numbers[6]));
                        ops = Some(build(token, n, (lo, hi), &share, material, frame)?.0);
                    }
                    message::SOLVE => {
                        let o = ops
                            .as_ref()
                            .ok_or_else(|| anyhow::anyhow!("rank 0 asked for a solve before an assembly"))?;
                        let method = if h[4] == 1 {
                            ves_ffi::slepc::Method::Iterative
                        } else {
                            ves_ffi::slepc::Method::ShiftInvert
                        };
                        let (nev, sigma, tol) = (h[1] as usize, f64::from_bits(h[2]), f64::from_bits(h[3]));
                        token.lowest_eigenpairs(o, nev, sigma, tol, method)?;
                    }
                    other => anyhow::bail!("rank 0 sent message kind {other}, which this ves does not know"),
                }
            }
        })
    }
    #[cfg(not(feature = "slepc"))]
    Err(not_built().into())
}

/// Rank 0's end of the pipeline under MPI: tells the ranks in [`serve`] to return, with the
/// pipeline's outcome (an error is then every rank's, reported once by rank 0). An error inside
/// a solve is left to [`finish`], which ends the job.
pub fn release<T>(result: anyhow::Result<T>) -> anyhow::Result<T> {
    #[cfg(feature = "slepc")]
    {
        use std::sync::atomic::Ordering::SeqCst;
        if ranks() <= 1 || rank() != 0 || IN_SOLVE.load(SeqCst) {
            return result;
        }
        let kind = if result.is_ok() { message::STOP } else { message::FAIL };
        let told = TOKEN.with(|t| -> Result<(), ves_ffi::slepc::PetscError> {
            if let Some(token) = t.borrow().as_ref() {
                for r in 1..token.size() {
                    token.send(r, &header(kind, &[]))?;
                }
            }
            Ok(())
        });
        match told {
            Ok(()) => {
                if result.is_err() {
                    AGREED.store(true, SeqCst);
                }
                result
            }
            Err(e) => Err(anyhow::anyhow!("{e}")),
        }
    }
    #[cfg(not(feature = "slepc"))]
    result
}
