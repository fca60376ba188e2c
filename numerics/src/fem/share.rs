//! A rank's share of a mesh for assembly under MPI (`--solver slepc`): the elements that touch
//! the rows of K and M the rank owns, their nodes, and the global numbers of their free DOFs.
//! From its share a rank assembles exactly its rows (an element on the border of two ranks is
//! computed on both, so no matrix entry travels between ranks), and rank 0, which meshes, never
//! holds the whole K and M.

use super::assembly::{AssemblyError, Moments, assemble_counting};
use crate::fem::Dofs;
use crate::material::Material;
use crate::tet_mesh::Mesh;

/// The free DOFs numbered rank by rank: rank r owns the rows `bounds[r]..bounds[r + 1]`, the
/// free DOFs of its nodes (one compact region of the part), each node's DOFs together.
#[derive(Clone, Debug, PartialEq)]
pub struct Numbering {
    /// Full DOF → its number here, or `u32::MAX` where supported.
    pub free_of: Vec<u32>,
    /// Each rank's first row, and the total.
    pub bounds: Vec<usize>,
    /// Number here → the free DOF's number in [`Dofs`].
    pub old_of_new: Vec<u32>,
}

impl Numbering {
    /// The free DOFs of `dofs` as they are, all on one rank.
    pub fn single(dofs: &Dofs) -> Numbering {
        let n = dofs.free_count();
        Numbering {
            free_of: dofs.free_of.clone(),
            bounds: vec![0, n],
            old_of_new: (0..n as u32).collect(),
        }
    }

    /// The free DOFs of `dofs` over `ranks` ranks, rank r owning the nodes with `part[i] == r`
    /// (the SLEPc solver takes them from METIS k-way on the node graph).
    pub fn from_parts(dofs: &Dofs, part: &[u32], ranks: usize) -> Numbering {
        let n = dofs.free_count();
        // Nodes by part (counting sort; ascending within a part).
        let mut start = vec![0usize; ranks + 1];
        for &p in part {
            start[p as usize + 1] += 1;
        }
        for r in 0..ranks {
            start[r + 1] += start[r];
        }
        let mut nodes = vec![0usize; part.len()];
        let mut at = start.clone();
        for (i, &p) in part.iter().enumerate() {
            nodes[at[p as usize]] = i;
            at[p as usize] += 1;
        }
        let mut free_of = vec![u32::MAX; dofs.total];
        let mut old_of_new = Vec::with_capacity(n);
        let mut bounds = vec![0usize; ranks + 1];
        for r in 0..ranks {
            for &i in &nodes[start[r]..start[r + 1]] {
                for c in 0..3 {
                    let f = dofs.free_of[3 * i + c];
                    if f != u32::MAX {
                        free_of[3 * i + c] = old_of_new.len() as u32;
                        old_of_new.push(f);
                    }
                }
            }
            bounds[r + 1] = old_of_new.len();
        }
        Numbering {
            free_of,
            bounds,
            old_of_new,
        }
    }

    /// Whether the numbering is that of [`Dofs`] itself.
    pub fn is_identity(&self) -> bool {
        self.old_of_new.iter().enumerate().all(|(i, &o)| i == o as usize)
    }

    /// Puts the columns of a column-major `n × k` array, rows in this numbering, back into the
    /// numbering of [`Dofs`], in place.
    pub fn restore(&self, columns: &mut [f64]) {
        let n = self.old_of_new.len();
        if n == 0 || self.is_identity() {
            return;
        }
        let mut scratch = vec![0.0; n];
        for col in columns.chunks_exact_mut(n) {
            scratch.copy_from_slice(col);
            for (new, &old) in self.old_of_new.iter().enumerate() {
                col[old as usize] = scratch[new];
            }
        }
    }
}

/// One rank's elements and their nodes, in a local numbering.
#[derive(Clone, Debug, PartialEq)]
pub struct Share {
    /// The element kind.
    pub kind: crate::fem::element::Kind,
    /// Node coordinates, 3 per local node (ascending global node number, so the mesh's corner
    /// vertices come first).
    pub xyz: Vec<f64>,
    /// Corner vertices among the local nodes.
    pub vertex_count: usize,
    /// 3 per local node: the global free DOF, or `u32::MAX` where supported.
    pub free: Vec<u32>,
    /// Connectivity on local nodes.
    pub tets: Vec<u32>,
    /// Global number of each element (to name one in an error).
    pub elements: Vec<u32>,
    /// The first `owned` elements are this rank's for the mass moments (each element is one
    /// rank's); the rest it shares with lower ranks.
    pub owned: usize,
}

/// Each rank's elements (those it owns first) and how many it owns, for ranks owning the rows
/// `bounds[r]..bounds[r + 1]` of a [`Numbering`]: every element that touches a rank's DOFs is in
/// its share. An element belongs to the lowest rank it touches; one that touches no free DOF
/// (all its nodes supported) to rank 0, for its mass.
pub fn partition(mesh: &Mesh, numbering: &Numbering) -> Vec<(Vec<u32>, usize)> {
    let (bounds, free_of) = (&numbering.bounds, &numbering.free_of);
    let ranks = bounds.len().saturating_sub(1).max(1);
    let owner = |d: usize| bounds.partition_point(|&b| b <= d).saturating_sub(1).min(ranks - 1);
    let mut owned = vec![Vec::new(); ranks];
    let mut shared = vec![Vec::new(); ranks];
    let mut touched = Vec::with_capacity(3 * mesh.nodes_per_tet());
    for e in 0..mesh.tet_count() {
        touched.clear();
        for &node in mesh.tet(e) {
            for c in 0..3 {
                let f = free_of[3 * node as usize + c];
                if f != u32::MAX {
                    touched.push(owner(f as usize));
                }
            }
        }
        touched.sort_unstable();
        touched.dedup();
        match touched.split_first() {
            None => owned[0].push(e as u32),
            Some((&first, rest)) => {
                owned[first].push(e as u32);
                rest.iter().for_each(|&r| shared[r].push(e as u32));
            }
        }
    }
    owned
        .into_iter()
        .zip(shared)
        .map(|(mut list, rest)| {
            let count = list.len();
            list.extend(rest);
            (list, count)
        })
        .collect()
}

impl Share {
    /// The share holding `elements` of the mesh, the first `owned` of them owned, its DOFs
    /// numbered by `numbering`.
    pub fn of(mesh: &Mesh, numbering: &Numbering, elements: Vec<u32>, owned: usize) -> Share {
        let mut nodes: Vec<u32> = elements.iter().flat_map(|&e| mesh.tet(e as usize)).copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        let mut local = vec![u32::MAX; mesh.nodes.len()];
        for (i, &g) in nodes.iter().enumerate() {
            local[g as usize] = i as u32;
        }
        Share {
            kind: mesh.kind,
            xyz: nodes.iter().flat_map(|&g| mesh.nodes[g as usize]).collect(),
            vertex_count: nodes.partition_point(|&g| (g as usize) < mesh.vertex_count),
            free: nodes
                .iter()
                .flat_map(|&g| (0..3).map(move |c| numbering.free_of[3 * g as usize + c]))
                .collect(),
            tets: elements
                .iter()
                .flat_map(|&e| mesh.tet(e as usize))
                .map(|&g| local[g as usize])
                .collect(),
            elements,
            owned,
        }
    }

    /// The share as a mesh of its own, its DOF numbering, and the global free DOF of each of
    /// its free DOFs.
    pub fn local(&self) -> (Mesh, Dofs, Vec<u32>) {
        let mesh = Mesh {
            nodes: self.xyz.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
            vertex_count: self.vertex_count,
            kind: self.kind,
            tets: self.tets.clone(),
            surface: Vec::new(),
            surface_faces: Vec::new(),
        };
        let mask: Vec<bool> = self.free.iter().map(|&f| f == u32::MAX).collect();
        let dofs = Dofs::from_mask(&mask);
        let global = dofs.free.iter().map(|&d| self.free[d as usize]).collect();
        (mesh, dofs, global)
    }

    /// Assembles the share: its lower-triangular K and M in the local numbering, the
    /// global free DOF of each local one, and the moments of the elements it owns. An element
    /// that fails is named by its global number.
    pub fn assemble(
        &self,
        material: &Material,
    ) -> Result<(super::Assembled, Vec<u32>, Moments, Mesh, Dofs), AssemblyError> {
        let (mesh, dofs, global) = self.local();
        let (a, moments) = assemble_counting(&mesh, material, &dofs, self.owned).map_err(|mut e| {
            e.element = self.elements.get(e.element).map_or(e.element, |&g| g as usize);
            e
        })?;
        Ok((a, global, moments, mesh, dofs))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over any number of ranks, the numbering is a permutation, every element is owned once,
    /// each rank's share holds every entry of its rows (equal to the whole assembly's, mapped
    /// back), the shares' moments add up to the whole part's, and a share is a region, not the
    /// whole mesh.
    #[test]
    fn shares_cover_each_rank_rows_and_count_each_element_once() {
        let mesh = Mesh::structured_box([8, 3, 2], 0.1, crate::fem::element::Kind::Tet10, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-12; 3]).collect();
        let dofs = Dofs::from_mask(&mask);
        let n = dofs.free_count();
        let material = Material::elastic(2e11, 0.3, 7800.0);
        let (whole, whole_moments) = assemble_counting(&mesh, &material, &dofs, mesh.tet_count()).unwrap();
        for ranks in [1usize, 2, 3, 4] {
            // Slabs along x: compact regions, as METIS would give.
            let part: Vec<u32> = mesh
                .nodes
                .iter()
                .map(|p| ((p[0] / 0.8 * ranks as f64) as usize).min(ranks - 1) as u32)
                .collect();
            let numbering = Numbering::from_parts(&dofs, &part, ranks);
            let mut seen = numbering.old_of_new.clone();
            seen.sort_unstable();
            assert!(seen.iter().enumerate().all(|(i, &o)| i == o as usize), "a permutation");
            assert_eq!(numbering.bounds.len(), ranks + 1);
            let sizes: Vec<usize> = numbering.bounds.windows(2).map(|b| b[1] - b[0]).collect();
            assert!(
                sizes.iter().all(|&s| s > 0 && s < n * 2 / ranks.max(1) + 3),
                "balanced: {sizes:?}"
            );
            let parts = partition(&mesh, &numbering);
            let owned: usize = parts.iter().map(|(_, o)| o).sum();
            assert_eq!(owned, mesh.tet_count(), "{ranks} ranks");
            let mut total = Moments::default();
            for (r, (elements, count)) in parts.into_iter().enumerate() {
                if ranks >= 2 {
                    assert!(
                        elements.len() < mesh.tet_count() * 3 / 4,
                        "rank {r} of {ranks}: {} elements",
                        elements.len()
                    );
                }
                let (lo, hi) = (numbering.bounds[r], numbering.bounds[r + 1]);
                let share = Share::of(&mesh, &numbering, elements, count);
                let (a, global, moments, _, _) = share.assemble(&material).unwrap();
                total.add(&moments);
                let (cp, ri) = (a.pattern.col_ptr(), a.pattern.row_idx());
                let (wcp, wri) = (whole.pattern.col_ptr(), whole.pattern.row_idx());
                let mut rows_seen = vec![false; hi - lo];
                for j in 0..global.len() {
                    for e in cp[j]..cp[j + 1] {
                        let (gi, gj) = (global[ri[e]] as usize, global[j] as usize);
                        let mine = |g: usize| (lo..hi).contains(&g);
                        if !mine(gi) && !mine(gj) {
                            continue;
                        }
                        for g in [gi, gj].into_iter().filter(|&g| mine(g)) {
                            rows_seen[g - lo] = true;
                        }
                        // The same entry in the whole assembly, in the numbering of `dofs`.
                        let (oi, oj) = (numbering.old_of_new[gi] as usize, numbering.old_of_new[gj] as usize);
                        let (row, col) = (oi.max(oj), oi.min(oj));
                        let at = wcp[col] + wri[wcp[col]..wcp[col + 1]].binary_search(&row).unwrap();
                        let scale = whole.k[at].abs().max(1.0);
                        assert!(
                            (a.k[e] - whole.k[at]).abs() <= 1e-9 * scale,
                            "K({row},{col}) on rank {r}"
                        );
                        assert!((a.m[e] - whole.m[at]).abs() <= 1e-12 * whole.m[at].abs().max(1e-9));
                    }
                }
                assert!(rows_seen.iter().all(|&s| s), "every row of rank {r} present");
            }
            assert!((total.mass - whole_moments.mass).abs() < 1e-12 * whole_moments.mass);
            // Back to the numbering of `dofs`.
            let mut column: Vec<f64> = numbering.old_of_new.iter().map(|&o| o as f64).collect();
            numbering.restore(&mut column);
            assert!(column.iter().enumerate().all(|(i, &v)| v == i as f64));
        }
    }
}
