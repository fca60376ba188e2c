//! Parallel assembly of K and M on one shared sparsity pattern (free DOFs, lower triangle).
//!
//! The pattern is built once at node level (3×3 blocks) from the connectivity; each thread
//! accumulates its share of the elements into its own block arrays, which are then summed and
//! expanded to DOF level with the supported DOFs removed.

use super::element::{self, BadJacobian, Kind, Lame, Shape, tet4::Tet4, tet10::Tet10};
use crate::fem::Dofs;
use crate::material::Material;
use crate::tet_mesh::Mesh;
use faer::sparse::SymbolicSparseColMat;
use rayon::prelude::*;

/// Mass, centre of mass and inertia tensor of the meshed part.
#[derive(Clone, Copy, Debug, Default)]
pub struct MassProperties {
    /// kg.
    pub mass: f64,
    /// m.
    pub center: [f64; 3],
    /// kg·m², about the centre of mass.
    pub inertia: [[f64; 3]; 3],
    /// The rigid motions the supports leave free, as twists about the centre of mass: all six
    /// as assembled, set from the supports by whoever knows them
    /// (`rigid_motions::free_motions`).
    pub free: ves_format::FreeMotions,
}

/// Node-level lower-triangular block pattern (CSC over nodes).
#[derive(Clone, Debug)]
pub struct NodeGraph {
    /// Start of each node column in `rows`.
    pub col_ptr: Vec<usize>,
    /// Row nodes ≥ column node, ascending within a column.
    pub rows: Vec<u32>,
}

impl NodeGraph {
    fn block(&self, row: u32, col: u32) -> usize {
        let (s, e) = (self.col_ptr[col as usize], self.col_ptr[col as usize + 1]);
        // The pattern was built from these very elements: the block exists.
        s + self.rows[s..e]
            .binary_search(&row)
            .unwrap_or_else(|_| unreachable!("block ({row},{col}) missing from pattern"))
    }
}

/// Assembled stiffness and mass on the free DOFs.
pub struct Assembled {
    /// Lower triangle (with diagonal) of the free-DOF matrices, shared by K and M.
    pub pattern: SymbolicSparseColMat<usize>,
    /// Values of K on `pattern`.
    pub k: Vec<f64>,
    /// Values of M on `pattern`.
    pub m: Vec<f64>,
    /// Node adjacency (for fill-reducing orderings).
    pub graph: NodeGraph,
    /// Mass properties of the whole part.
    pub mass: MassProperties,
}

/// An element with a non-positive Jacobian was met.
#[derive(Debug, thiserror::Error)]
#[error(
    "element {element} near ({:.6}, {:.6}, {:.6}) m is degenerate or inverted (det J = {det:.3e}); \
     remesh with a different size or repair the geometry there", at[0], at[1], at[2]
)]
pub struct AssemblyError {
    /// Element index.
    pub element: usize,
    /// Its centroid.
    pub at: [f64; 3],
    /// The offending Jacobian determinant.
    pub det: f64,
}

/// The node-level lower-triangular pattern of the mesh's connectivity and of `springs`.
pub fn node_graph(mesh: &Mesh, springs: &[super::springs::NodeSpring]) -> NodeGraph {
    let p = mesh.nodes_per_tet();
    let mut keys: Vec<u64> = mesh
        .tets
        .par_chunks_exact(p)
        .flat_map_iter(|t| {
            t.iter().flat_map(move |&a| {
                t.iter()
                    .filter(move |&&b| a >= b)
                    .map(move |&b| ((b as u64) << 32) | a as u64)
            })
        })
        .collect();
    // Springs mostly couple the nodes of one surface triangle, which share a tet; a located
    // bearing's couples nodes around its ring, which do not.
    keys.extend(springs.iter().map(|sp| ((sp.b as u64) << 32) | sp.a as u64));
    keys.par_sort_unstable();
    keys.dedup();
    let n = mesh.nodes.len();
    let mut col_ptr = vec![0usize; n + 1];
    for &k in &keys {
        col_ptr[(k >> 32) as usize + 1] += 1;
    }
    for i in 0..n {
        col_ptr[i + 1] += col_ptr[i];
    }
    let rows = keys.iter().map(|&k| k as u32).collect();
    NodeGraph { col_ptr, rows }
}

/// Mass and its first and second moments (about the origin) of a set of elements: what
/// shares of a mesh sum (over threads, over MPI ranks) before [`Moments::properties`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moments {
    /// ∫ρ, kg.
    pub mass: f64,
    /// ∫ρ r, kg·m.
    pub first: [f64; 3],
    /// ∫ρ r rᵀ, kg·m².
    pub second: [[f64; 3]; 3],
}

impl Moments {
    /// Adds another set's moments.
    pub fn add(&mut self, o: &Moments) {
        self.mass += o.mass;
        for r in 0..3 {
            self.first[r] += o.first[r];
            for c in 0..3 {
                self.second[r][c] += o.second[r][c];
            }
        }
    }

    /// The 13 numbers, flat (to be summed over MPI ranks).
    pub fn to_array(&self) -> [f64; 13] {
        let mut a = [0.0; 13];
        a[0] = self.mass;
        a[1..4].copy_from_slice(&self.first);
        for r in 0..3 {
            a[4 + 3 * r..7 + 3 * r].copy_from_slice(&self.second[r]);
        }
        a
    }

    /// [`Moments::to_array`] back.
    pub fn from_array(a: &[f64; 13]) -> Moments {
        let mut m = Moments {
            mass: a[0],
            first: [a[1], a[2], a[3]],
            ..Moments::default()
        };
        for r in 0..3 {
            m.second[r].copy_from_slice(&a[4 + 3 * r..7 + 3 * r]);
        }
        m
    }

    /// Mass, centre and inertia about the centre.
    pub fn properties(&self) -> MassProperties {
        mass_properties(self.mass, self.first, self.second)
    }
}

struct Partial {
    k: Vec<f64>,
    m: Vec<f64>,
    moments: Moments,
}

impl Partial {
    fn zeros(blocks: usize) -> Partial {
        Partial {
            k: vec![0.0; 9 * blocks],
            m: vec![0.0; blocks],
            moments: Moments::default(),
        }
    }
}

fn accumulate<S: Shape>(
    mesh: &Mesh,
    graph: &NodeGraph,
    lame: &Lame,
    range: std::ops::Range<usize>,
    counted: usize,
) -> Result<Partial, AssemblyError> {
    let nb = graph.rows.len();
    let mut part = Partial::zeros(nb);
    let p = S::NODES;
    let n3 = 3 * p;
    let mut x = vec![[0.0; 3]; p];
    for e in range {
        let tet = mesh.tet(e);
        for (xa, &n) in x.iter_mut().zip(tet) {
            *xa = mesh.nodes[n as usize];
        }
        let em = element::element_matrices::<S>(&x, lame).map_err(|BadJacobian { det }| {
            let mut at = [0.0; 3];
            for xa in &x[..4] {
                for c in 0..3 {
                    at[c] += xa[c] / 4.0;
                }
            }
            AssemblyError { element: e, at, det }
        })?;
        for a in 0..p {
            for b in 0..p {
                let (ga, gb) = (tet[a], tet[b]);
                if ga < gb {
                    continue;
                }
                let blk = graph.block(ga, gb);
                part.m[blk] += em.m[a * p + b];
                let kb = &mut part.k[9 * blk..9 * blk + 9];
                for ci in 0..3 {
                    for cj in 0..3 {
                        kb[3 * ci + cj] += em.k[(3 * a + ci) * n3 + 3 * b + cj];
                    }
                }
            }
        }
        if e < counted {
            let (mass, first, second) = em.moments;
            part.moments.add(&Moments { mass, first, second });
        }
    }
    Ok(part)
}

/// Assembles K and M of the mesh for the material, on the free DOFs of `dofs`.
pub fn assemble(mesh: &Mesh, material: &Material, dofs: &Dofs) -> Result<Assembled, AssemblyError> {
    assemble_with(mesh, material, dofs, &[])
}

/// [`assemble`] with surface springs added to K ([`super::springs`]).
pub fn assemble_with(
    mesh: &Mesh,
    material: &Material,
    dofs: &Dofs,
    springs: &[super::springs::NodeSpring],
) -> Result<Assembled, AssemblyError> {
    assemble_inner(mesh, material, dofs, mesh.tet_count(), springs).map(|(a, _)| a)
}

/// [`assemble`], and the moments of the first `counted` elements only (a rank's share of a
/// mesh holds the elements it owns first, then those it shares with other ranks: each element's
/// mass is counted once over all ranks). `Assembled::mass` is that of the counted ones.
pub fn assemble_counting(
    mesh: &Mesh,
    material: &Material,
    dofs: &Dofs,
    counted: usize,
) -> Result<(Assembled, Moments), AssemblyError> {
    assemble_inner(mesh, material, dofs, counted, &[])
}

fn assemble_inner(
    mesh: &Mesh,
    material: &Material,
    dofs: &Dofs,
    counted: usize,
    springs: &[super::springs::NodeSpring],
) -> Result<(Assembled, Moments), AssemblyError> {
    let lame = Lame::of(material);
    let graph = node_graph(mesh, springs);
    let ne = mesh.tet_count();
    // One partial per thread, then summed into the first in a fixed order (the same sums on
    // every run: a basis must be reproducible to the last bit). Collecting twice as many and
    // adding them into a separate total kept 2·threads + 1 full-size arrays alive at once.
    let chunks = rayon::current_num_threads().max(1);
    let step = ne.div_ceil(chunks).max(1);
    let ranges: Vec<_> = (0..ne).step_by(step).map(|s| s..(s + step).min(ne)).collect();
    let partials: Vec<Partial> = ranges
        .into_par_iter()
        .map(|r| match mesh.kind {
            Kind::Tet4 => accumulate::<Tet4>(mesh, &graph, &lame, r, counted),
            Kind::Tet10 => accumulate::<Tet10>(mesh, &graph, &lame, r, counted),
        })
        .collect::<Result<_, _>>()?;
    let mut partials = partials.into_iter();
    let mut total = partials.next().unwrap_or_else(|| Partial::zeros(graph.rows.len()));
    for p in partials {
        total.k.par_iter_mut().zip(&p.k).for_each(|(a, b)| *a += b);
        total.m.par_iter_mut().zip(&p.m).for_each(|(a, b)| *a += b);
        total.moments.add(&p.moments);
    }
    // Every spring's block is in the graph (made with them).
    for sp in springs {
        let blk = graph.block(sp.a, sp.b);
        for r in 0..3 {
            for c in 0..3 {
                total.k[9 * blk + 3 * r + c] += sp.block[r][c];
            }
        }
    }
    let moments = total.moments;
    let mass = moments.properties();

    // Expand node blocks to the free-DOF lower triangle, sized exactly up front (growing the
    // vectors would overshoot by up to 2×).
    let nf = dofs.free_count();
    let entries = |d: u32, mut each: Option<&mut dyn FnMut(usize, usize, usize, usize)>| {
        let (gj, cj) = (d as usize / 3, d as usize % 3);
        let mut count = 0;
        for blk in graph.col_ptr[gj]..graph.col_ptr[gj + 1] {
            let gi = graph.rows[blk] as usize;
            for ci in 0..3 {
                let row = 3 * gi + ci;
                let r = dofs.free_of[row];
                if row < d as usize || r == u32::MAX {
                    continue;
                }
                count += 1;
                if let Some(f) = each.as_mut() {
                    f(r as usize, blk, ci, cj);
                }
            }
        }
        count
    };
    let len: usize = dofs.free.iter().map(|&d| entries(d, None)).sum();
    let mut col_ptr = Vec::with_capacity(nf + 1);
    col_ptr.push(0usize);
    let mut row_idx = Vec::with_capacity(len);
    let (mut kv, mut mv) = (Vec::with_capacity(len), Vec::with_capacity(len));
    for &d in &dofs.free {
        entries(
            d,
            Some(&mut |r, blk, ci, cj| {
                row_idx.push(r);
                kv.push(total.k[9 * blk + 3 * ci + cj]);
                mv.push(if ci == cj { total.m[blk] } else { 0.0 });
            }),
        );
        col_ptr.push(row_idx.len());
    }
    drop(total);
    let pattern = SymbolicSparseColMat::new_checked(nf, nf, col_ptr, None, row_idx);
    Ok((
        Assembled {
            pattern,
            k: kv,
            m: mv,
            graph,
            mass,
        },
        moments,
    ))
}

fn mass_properties(mass: f64, first: [f64; 3], second: [[f64; 3]; 3]) -> MassProperties {
    let center = first.map(|f| f / mass);
    // ∫ρ r rᵀ about the centre, then I = tr(R)·1 − R.
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = second[i][j] - mass * center[i] * center[j];
        }
    }
    let tr = r[0][0] + r[1][1] + r[2][2];
    let mut inertia = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inertia[i][j] = if i == j { tr } else { 0.0 } - r[i][j];
        }
    }
    MassProperties {
        mass,
        center,
        inertia,
        free: ves_format::FreeMotions::all(),
    }
}
