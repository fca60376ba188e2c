//! Sparse symmetric matrices on the shared pattern: products, and the Cholesky factorisation of
//! K − σM with a METIS nested-dissection ordering (on 3D elasticity it factors several times
//! faster than AMD, see DEPENDENCIES.md).

use crate::fem::Dofs;
use crate::fem::assembly::NodeGraph;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};

/// y = A x for a symmetric A stored as its lower triangle.
pub fn sym_matvec(pattern: &SymbolicSparseColMat<usize>, values: &[f64], x: &[f64], y: &mut [f64]) {
    y.fill(0.0);
    let (cp, ri) = (pattern.col_ptr(), pattern.row_idx());
    for j in 0..x.len() {
        let xj = x[j];
        let mut acc = 0.0;
        for k in cp[j]..cp[j + 1] {
            let (i, a) = (ri[k], values[k]);
            y[i] += a * xj;
            if i != j {
                acc += a * x[i];
            }
        }
        y[j] += acc;
    }
}

/// Y = A X for `x.len() / n` column-major vectors (A symmetric, lower triangle), reading A once
/// per group of [`GROUP`] vectors instead of once per vector (the products are memory-bound),
/// groups in parallel.
pub fn sym_matmul(pattern: &SymbolicSparseColMat<usize>, values: &[f64], x: &[f64], y: &mut [f64]) {
    use rayon::prelude::*;
    let n = pattern.nrows();
    y.par_chunks_mut(GROUP * n)
        .zip(x.par_chunks(GROUP * n))
        .for_each(|(y, x)| {
            if x.len() == GROUP * n {
                sym_matmul_group(pattern, values, x, y);
            } else {
                for (y, x) in y.chunks_mut(n).zip(x.chunks(n)) {
                    sym_matvec(pattern, values, x, y);
                }
            }
        });
}

/// Vectors per pass over the matrix in [`sym_matmul`].
const GROUP: usize = 4;

/// [`sym_matmul`] for exactly [`GROUP`] vectors: interleaved so each stored entry serves all.
fn sym_matmul_group(pattern: &SymbolicSparseColMat<usize>, values: &[f64], x: &[f64], y: &mut [f64]) {
    let n = pattern.nrows();
    let mut xi = vec![[0.0f64; GROUP]; n];
    for (c, col) in x.chunks(n).enumerate() {
        for (row, v) in xi.iter_mut().zip(col) {
            row[c] = *v;
        }
    }
    let mut yi = vec![[0.0f64; GROUP]; n];
    let (cp, ri) = (pattern.col_ptr(), pattern.row_idx());
    for j in 0..n {
        let xj = xi[j];
        let mut acc = [0.0; GROUP];
        for k in cp[j]..cp[j + 1] {
            let (i, a) = (ri[k], values[k]);
            let yr = &mut yi[i];
            for c in 0..GROUP {
                yr[c] += a * xj[c];
            }
            if i != j {
                let xr = &xi[i];
                for c in 0..GROUP {
                    acc[c] += a * xr[c];
                }
            }
        }
        for c in 0..GROUP {
            yi[j][c] += acc[c];
        }
    }
    for (c, col) in y.chunks_mut(n).enumerate() {
        for (v, row) in col.iter_mut().zip(&yi) {
            *v = row[c];
        }
    }
}

/// The factorisation failed.
#[derive(Debug, thiserror::Error)]
pub enum FactorError {
    /// K − σM is not positive definite in floating point.
    #[error(
        "K − σM is not positive definite (σ = {sigma:.3e}): the model may be a mechanism or the material data extreme; \
         check supports and units"
    )]
    NotPositiveDefinite {
        /// The shift used.
        sigma: f64,
    },
    /// Symbolic analysis failed (out of memory or index overflow).
    #[error("sparse Cholesky analysis failed: {0}")]
    Symbolic(String),
    /// The factor would not fit in memory (refused before it was allocated).
    #[error(
        "{0}: coarsen the mesh (mesh.size × {coarser:.2} or more: a 3D factor grows about as size⁻⁴) or free memory",
        coarser = .0.coarsening()
    )]
    Memory(crate::memory::OutOfMemory),
}

impl From<crate::memory::OutOfMemory> for FactorError {
    fn from(e: crate::memory::OutOfMemory) -> Self {
        FactorError::Memory(e)
    }
}

/// The factor's values and the factorisation's scratch, each allocated only after
/// [`crate::memory::ensure_fits`] said both fit (and fallibly: never an abort).
fn factor_storage(symbolic: &SymbolicCholesky<usize>, req: StackReq) -> Result<(Vec<f64>, MemBuffer), FactorError> {
    let what = format!("the sparse factor of K − σM ({} values)", symbolic.len_val());
    let bytes = 8 * symbolic.len_val() as u64 + req.size_bytes() as u64;
    crate::memory::ensure_fits(&what, bytes)?;
    let l = crate::memory::try_zeros::<f64>(&what, symbolic.len_val())?;
    let stack = MemBuffer::try_new(req).map_err(|_| crate::memory::OutOfMemory {
        what,
        needed: bytes,
        available: crate::memory::headroom_bytes().unwrap_or(0),
    })?;
    Ok((l, stack))
}

/// The node graph as METIS takes it: full symmetric adjacency without self loops (CSR).
fn adjacency(graph: &NodeGraph) -> (Vec<i32>, Vec<i32>) {
    let n = graph.col_ptr.len() - 1;
    let mut deg = vec![0i32; n];
    for j in 0..n {
        for &i in &graph.rows[graph.col_ptr[j]..graph.col_ptr[j + 1]] {
            if i as usize != j {
                deg[i as usize] += 1;
                deg[j] += 1;
            }
        }
    }
    let mut xadj = vec![0i32; n + 1];
    for i in 0..n {
        xadj[i + 1] = xadj[i] + deg[i];
    }
    let mut fill = xadj.clone();
    let mut adj = vec![0i32; xadj[n] as usize];
    for j in 0..n {
        for &i in &graph.rows[graph.col_ptr[j]..graph.col_ptr[j + 1]] {
            let i = i as usize;
            if i != j {
                adj[fill[i] as usize] = j as i32;
                fill[i] += 1;
                adj[fill[j] as usize] = i as i32;
                fill[j] += 1;
            }
        }
    }
    (xadj, adj)
}

/// The nodes split into `parts` compact pieces of about equal free DOFs (METIS k-way on the
/// node graph, each node weighted by its free DOFs): the part of each node. For MPI ranks,
/// whose rows of K and M are then the DOFs of one region of the part, not a stripe of the
/// numbering (gmsh numbers the corner vertices first: a stripe held every element).
pub fn node_parts(graph: &NodeGraph, dofs: &Dofs, parts: usize) -> Vec<u32> {
    let n = graph.col_ptr.len() - 1;
    if parts <= 1 || n <= parts {
        return (0..n).map(|i| (i * parts.max(1) / n.max(1)) as u32).collect();
    }
    let (xadj, adj) = adjacency(graph);
    // Fully supported nodes weigh 1, not 0 (METIS needs positive weights; the imbalance is
    // negligible).
    let weight: Vec<i32> = (0..n)
        .map(|i| (0..3).filter(|&c| dofs.free_of[3 * i + c] != u32::MAX).count().max(1) as i32)
        .collect();
    let graph = ves_metis::Graph {
        offsets: &xadj,
        adjacency: &adj,
    };
    // On failure, stripes of the numbering: correct, only less local.
    ves_metis::partition(&graph, &weight, parts).unwrap_or_else(|| (0..n).map(|i| (i * parts / n) as u32).collect())
}

/// Where fill-reducing orderings are kept between runs, keyed by the node graph (CSR `xadj`,
/// `adj`): the mesh cache keeps them beside its meshes and installs itself with
/// [`keep_orderings_in`] (the solvers know nothing of meshing).
pub trait OrderingStore: Send + Sync {
    /// The graph's key in the store (a hash of it), or None when the store is off: computed
    /// once per ordering, for the lookup and the store that may follow.
    fn key(&self, xadj: &[i32], adj: &[i32]) -> Option<u64>;
    /// The node ordering stored under `key`: a permutation of `0..n`, else None.
    fn lookup(&self, key: u64, n: usize) -> Option<Vec<i32>>;
    /// Keeps `order` under `key`.
    fn store(&self, key: u64, order: &[i32]);
}

static ORDERINGS: std::sync::OnceLock<&'static dyn OrderingStore> = std::sync::OnceLock::new();

/// Orderings are looked up in and stored to `store` from now on (the first call wins).
pub fn keep_orderings_in(store: &'static dyn OrderingStore) {
    let _ = ORDERINGS.set(store);
}

/// Fill-reducing ordering of the free DOFs: METIS nested dissection of the node graph,
/// each node's free DOFs kept together. Returns (new→old, old→new).
pub fn nested_dissection(graph: &NodeGraph, dofs: &Dofs) -> (Vec<usize>, Vec<usize>) {
    let t0 = std::time::Instant::now();
    let n = graph.col_ptr.len() - 1;
    let (xadj, adj) = adjacency(graph);
    let mut node_order: Vec<i32> = (0..n as i32).collect();
    let store = ORDERINGS.get().and_then(|s| Some((*s, s.key(&xadj, &adj)?)));
    let cached = store.and_then(|(s, k)| s.lookup(k, n)).filter(|o| o.len() == n);
    let was_cached = cached.is_some();
    if let Some(order) = cached {
        node_order = order;
    } else if n > 1 && !adj.is_empty() {
        let graph = ves_metis::Graph {
            offsets: &xadj,
            adjacency: &adj,
        };
        // On failure the natural order is kept: slower, never wrong.
        if let Some(perm) = ves_metis::nested_dissection(&graph) {
            node_order = perm;
            if let Some((s, k)) = store {
                s.store(k, &node_order);
            }
        }
    }
    let mut fwd = Vec::with_capacity(dofs.free_count());
    for &node in &node_order {
        for c in 0..3 {
            let f = dofs.free_of[3 * node as usize + c];
            if f != u32::MAX {
                fwd.push(f as usize);
            }
        }
    }
    let mut inv = vec![0usize; fwd.len()];
    for (new, &old) in fwd.iter().enumerate() {
        inv[old] = new;
    }
    tracing::debug!(cached = was_cached, seconds = t0.elapsed().as_secs_f64(), "ordered");
    (fwd, inv)
}

/// K's factor: `given` when an earlier stage made it on the same K, else made into `own`
/// (which then holds it as long as the caller needs it).
pub fn given_or_made<'a>(
    system: &crate::fem::Assembled,
    dofs: &Dofs,
    given: Option<&'a Cholesky>,
    own: &'a mut Option<Cholesky>,
) -> Result<&'a Cholesky, FactorError> {
    match given {
        Some(c) => Ok(c),
        None => Ok(own.insert(factor_stiffness(system, dofs)?)),
    }
}

/// Factorises the stiffness K of a supported part (METIS ordering).
pub fn factor_stiffness(system: &crate::fem::Assembled, dofs: &Dofs) -> Result<Cholesky, FactorError> {
    Cholesky::factor(analyse(system, dofs)?, &system.pattern, &system.k, 0.0)
}

/// The symbolic analysis of a system's pattern in its METIS ordering.
pub fn analyse(system: &crate::fem::Assembled, dofs: &Dofs) -> Result<SymbolicCholesky<usize>, FactorError> {
    Cholesky::analyse(&system.pattern, &nested_dissection(&system.graph, dofs))
}

/// Sparse Cholesky factor of a symmetric positive definite matrix.
pub struct Cholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    stack: MemBuffer,
    par: Par,
}

impl Cholesky {
    /// Symbolic analysis of `pattern` with the given ordering (new→old, old→new).
    pub fn analyse(
        pattern: &SymbolicSparseColMat<usize>,
        ordering: &(Vec<usize>, Vec<usize>),
    ) -> Result<SymbolicCholesky<usize>, FactorError> {
        let perm = PermRef::new_checked(&ordering.0, &ordering.1, pattern.nrows());
        factorize_symbolic_cholesky(
            pattern.as_ref(),
            Side::Lower,
            SymmetricOrdering::Custom(perm),
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| FactorError::Symbolic(format!("{e:?}")))
    }

    /// Numeric factorisation of A (lower triangle on `pattern`); `sigma` is only for the message.
    pub fn factor(
        symbolic: SymbolicCholesky<usize>,
        pattern: &SymbolicSparseColMat<usize>,
        values: &[f64],
        sigma: f64,
    ) -> Result<Cholesky, FactorError> {
        let par = Par::rayon(0);
        let a = SparseColMatRef::new(pattern.as_ref(), values);
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let (mut l, mut stack) = factor_storage(&symbolic, req)?;
        symbolic
            .factorize_numeric_llt(
                &mut l,
                a,
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut stack),
                Default::default(),
            )
            .map_err(|_| FactorError::NotPositiveDefinite { sigma })?;
        tracing::debug!(factor_values = l.len(), "factorised");
        // One right-hand side: a parallel solve only adds synchronisation.
        Ok(Cholesky {
            symbolic,
            values: l,
            stack,
            par: Par::Seq,
        })
    }

    /// The symbolic analysis (ordering and structure), for another factorisation of a matrix
    /// with the same pattern.
    pub fn into_symbolic(self) -> SymbolicCholesky<usize> {
        self.symbolic
    }

    /// The symbolic analysis (ordering and structure).
    pub fn symbolic(&self) -> &SymbolicCholesky<usize> {
        &self.symbolic
    }

    /// Parallelism of later solves (sequential by default).
    pub fn set_parallelism(&mut self, par: Par) {
        self.par = par;
    }

    /// Where free DOF `dof` (`u32::MAX`: none) falls in the factor's elimination order.
    pub fn position(&self, dof: u32) -> Option<usize> {
        if dof == u32::MAX {
            return None;
        }
        let d = dof as usize;
        match self.symbolic.perm() {
            Some(p) => p.arrays().1.get(d).copied(),
            None => Some(d),
        }
    }

    /// Number of stored values of L (a measure of fill).
    pub fn factor_len(&self) -> usize {
        self.values.len()
    }

    /// X ← A⁻¹ X for `nrhs` column-major right-hand sides (the factor is read once). Takes its
    /// own scratch, so several threads can solve with one factor.
    pub fn solve_many_in_place(&self, x: &mut [f64], nrhs: usize) {
        let n = x.len() / nrhs;
        let mut stack = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(nrhs, self.par));
        let llt = LltRef::<usize, f64>::new(&self.symbolic, &self.values);
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, n, nrhs),
            self.par,
            MemStack::new(&mut stack),
        );
    }

    /// Bᵀ A⁻¹ B for `k` right-hand sides B given by their nonzero `entries` (row, column,
    /// value; repeated ones add), few to a column (a contact patch's weights): Y = L⁻¹ P B by a
    /// forward solve that skips every supernode no right-hand side reaches yet (a local load
    /// reaches only its path up the elimination tree), then YᵀY, summed supernode by supernode
    /// as each block of Y is final. No backward solve. None when the factor is simplicial (a
    /// small problem: the caller solves in full) or an entry is out of range.
    pub fn local_gram(&self, entries: &[(usize, usize, f64)], k: usize) -> Option<faer::Mat<f64>> {
        use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
        let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw() else {
            return None;
        };
        let n = symbolic.nrows();
        if entries.iter().any(|&(i, j, _)| i >= n || j >= k) {
            return None;
        }
        let llt = SupernodalLltRef::<usize, f64>::new(symbolic, &self.values);
        let mut x = faer::Mat::<f64>::zeros(n, k);
        let inv = self.symbolic.perm().map(|p| p.arrays().1);
        for &(old, j, v) in entries {
            x[(inv.map_or(old, |inv| inv[old]), j)] += v;
        }
        let mut gram = faer::Mat::<f64>::zeros(k, k);
        for s in 0..symbolic.n_supernodes() {
            let node = llt.supernode(s);
            let l = node.val();
            let size = l.ncols();
            let start = node.start();
            if (0..k).all(|j| (start..start + size).all(|i| x[(i, j)] == 0.0)) {
                continue;
            }
            let (l_top, l_bot) = l.split_at_row(size);
            let mut top = x.as_mut().subrows_mut(start, size);
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(l_top, top.as_mut(), Par::Seq);
            faer::linalg::matmul::matmul(
                gram.as_mut(),
                faer::Accum::Add,
                top.as_ref().transpose(),
                top.as_ref(),
                1.0,
                Par::Seq,
            );
            let below = l_bot * top.as_ref();
            for j in 0..k {
                for (idx, &i) in node.pattern().iter().enumerate() {
                    x[(i, j)] -= below[(idx, j)];
                }
            }
        }
        Some(gram)
    }

    /// x ← A⁻¹ x.
    pub fn solve_in_place(&mut self, x: &mut [f64]) {
        let n = x.len();
        let llt = LltRef::<usize, f64>::new(&self.symbolic, &self.values);
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, n, 1),
            self.par,
            MemStack::new(&mut self.stack),
        );
    }
}

/// Negative pivots of A = LDLᵀ (A symmetric, lower triangle on `pattern`, `symbolic` its
/// analysis, e.g. the one of the Cholesky factor of the shift-invert solve: same pattern): by
/// Sylvester's law of inertia, the number of negative eigenvalues of A. For A = K − σM (M
/// positive definite) it is the number of generalized eigenvalues below σ — a Sturm count that
/// proves no eigenvalue below σ was skipped. `Err` when a pivot is exactly zero (σ is an
/// eigenvalue to machine precision: move it).
pub fn negative_pivots(
    symbolic: &SymbolicCholesky<usize>,
    pattern: &SymbolicSparseColMat<usize>,
    values: &[f64],
) -> Result<usize, FactorError> {
    let par = Par::rayon(0);
    let a = SparseColMatRef::new(pattern.as_ref(), values);
    let (mut l, mut stack) = factor_storage(
        symbolic,
        symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
    )?;
    symbolic
        .factorize_numeric_ldlt(
            &mut l,
            a,
            Side::Lower,
            // No regularization: the signs of D are the answer.
            LdltRegularization::default(),
            par,
            MemStack::new(&mut stack),
            Default::default(),
        )
        .map_err(|e| FactorError::Symbolic(format!("LDLᵀ for the Sturm count: {e:?}")))?;
    // D sits on the diagonal of L's storage (L has a unit diagonal, not stored).
    let negative = match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let (cp, ri) = (s.col_ptr(), s.row_idx());
            (0..s.nrows())
                .filter(|&j| {
                    let first = cp[j];
                    debug_assert_eq!(ri[first], j, "diagonal first in each column");
                    l[first] < 0.0
                })
                .count()
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            let (begin, end) = (s.supernode_begin(), s.supernode_end());
            let (rows_ptr, val_ptr) = (s.col_ptr_for_row_idx(), s.col_ptr_for_val());
            (0..s.n_supernodes())
                .map(|k| {
                    let ncols = end[k] - begin[k];
                    let nrows = ncols + (rows_ptr[k + 1] - rows_ptr[k]);
                    let block = &l[val_ptr[k]..val_ptr[k + 1]];
                    (0..ncols).filter(|&c| block[c * nrows + c] < 0.0).count()
                })
                .sum()
        }
    };
    Ok(negative)
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::linalg::SupernodalThreshold;

    /// The grouped product equals one product per vector (7 vectors: a group of 4 and 3 left).
    #[test]
    fn grouped_products_equal_single_ones() {
        let mesh = crate::tet_mesh::Mesh::structured_box([3, 2, 2], 0.02, crate::fem::element::Kind::Tet4, |_, p| p);
        let mask = vec![false; 3 * mesh.nodes.len()];
        let dofs = crate::fem::Dofs::from_mask(&mask);
        let d = crate::modes::Model::assemble(mesh, dofs, crate::material::Material::elastic(2e11, 0.3, 7800.0))
            .expect("assembles");
        let n = d.system.pattern.nrows();
        let x: Vec<f64> = (0..7 * n).map(|i| ((i * 37 % 101) as f64 - 50.0) / 7.0).collect();
        let mut grouped = vec![0.0; 7 * n];
        sym_matmul(&d.system.pattern, &d.system.k, &x, &mut grouped);
        let mut single = vec![0.0; n];
        for c in 0..7 {
            sym_matvec(&d.system.pattern, &d.system.k, &x[c * n..(c + 1) * n], &mut single);
            for (a, b) in grouped[c * n..(c + 1) * n].iter().zip(&single) {
                assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "vector {c}: {a} vs {b}");
            }
        }
    }

    /// Bᵀ K⁻¹ B from the forward solve that skips unreached supernodes equals the one from full
    /// solves, for right-hand sides local to a few nodes (a patch's) and for a dense one, on a
    /// factor that is supernodal (asserted: a simplicial one would leave nothing tested).
    #[test]
    fn the_local_gram_equals_full_solves() {
        let mesh = crate::tet_mesh::Mesh::structured_box([12, 6, 6], 0.01, crate::fem::element::Kind::Tet4, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-9; 3]).collect();
        let dofs = crate::fem::Dofs::from_mask(&mask);
        let d = crate::modes::Model::assemble(mesh, dofs, crate::material::Material::elastic(2e11, 0.3, 7800.0))
            .expect("assembles");
        let chol = factor_stiffness(&d.system, &d.dofs).expect("factors");
        let n = d.dofs.free_count();
        // Six columns touching three nodes each, spread over the part, and one dense column.
        let k = 7;
        let mut b = vec![0.0; n * k];
        for j in 0..6 {
            for t in 0..3 {
                b[j * n + (j * 997 + t * 31) % n] = 1.0 + 0.25 * t as f64 - 0.1 * j as f64;
            }
        }
        for (i, v) in b[6 * n..].iter_mut().enumerate() {
            *v = ((i * 37 % 101) as f64 - 50.0) / 50.0;
        }
        let entries: Vec<(usize, usize, f64)> = (0..k)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .filter(|&(i, j)| b[j * n + i] != 0.0)
            .map(|(i, j)| (i, j, b[j * n + i]))
            .collect();
        let g = chol.local_gram(&entries, k).expect("a supernodal factor");
        let mut x = b.clone();
        chol.solve_many_in_place(&mut x, k);
        let want = |p: usize, q: usize| -> f64 { (0..n).map(|i| b[p * n + i] * x[q * n + i]).sum() };
        for p in 0..k {
            for q in 0..k {
                let scale = (want(p, p) * want(q, q)).sqrt();
                assert!(scale > 0.0);
                assert!(
                    (g[(p, q)] - want(p, q)).abs() <= 1e-10 * scale,
                    "({p}, {q}): {} against {}",
                    g[(p, q)],
                    want(p, q)
                );
            }
        }
    }

    /// The Sturm count equals the number of generalized eigenvalues below σ from a dense
    /// solve, for shifts between every pair of the lowest ones, through both of faer's factor
    /// layouts (simplicial and supernodal).
    #[test]
    fn negative_pivots_count_the_eigenvalues_below_the_shift() {
        use crate::modes::EigenSolver;
        let mesh = crate::tet_mesh::Mesh::structured_box([4, 1, 1], 0.02, crate::fem::element::Kind::Tet4, |_, p| p);
        // Clamped at x = 0.
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-9; 3]).collect();
        let dofs = crate::fem::Dofs::from_mask(&mask);
        let d = crate::modes::Model::assemble(mesh, dofs, crate::material::Material::elastic(2e11, 0.3, 7800.0))
            .expect("assembles");
        let problem = crate::modes::EigenProblem::of(&d.system);
        let dense = crate::modes::dense::Dense(&problem)
            .lowest(9, 0.0)
            .expect("dense")
            .values;
        let ordering = nested_dissection(&d.system.graph, &d.dofs);
        for threshold in [
            SupernodalThreshold::FORCE_SIMPLICIAL,
            SupernodalThreshold::FORCE_SUPERNODAL,
        ] {
            for k in 0..8 {
                let sigma = 0.5 * (dense[k] + dense[k + 1]);
                let shifted: Vec<f64> = d.system.k.iter().zip(&d.system.m).map(|(a, b)| a - sigma * b).collect();
                let params = CholeskySymbolicParams {
                    supernodal_flop_ratio_threshold: threshold,
                    ..Default::default()
                };
                let perm = PermRef::new_checked(&ordering.0, &ordering.1, d.system.pattern.nrows());
                let symbolic = factorize_symbolic_cholesky(
                    d.system.pattern.as_ref(),
                    Side::Lower,
                    SymmetricOrdering::Custom(perm),
                    params,
                )
                .unwrap();
                let n = negative_pivots(&symbolic, &d.system.pattern, &shifted).unwrap();
                assert_eq!(n, k + 1, "σ between λ{} and λ{}", k + 1, k + 2);
            }
        }
    }
}
