//! A rank's share of a mesh for assembly under MPI (`--solver slepc`): the elements that touch
//! the rows of K and M the rank owns, their nodes, and the global numbers of their free DOFs.
//! From its share a rank assembles exactly its rows (an element on the border of two ranks is
//! computed on both, so no matrix entry travels between ranks), and rank 0, which meshes, never
//! holds the whole K and M.

use super::assembly::{AssemblyError, Moments, assemble_counting};
use crate::mesh::Mesh;
use crate::supports::Dofs;

/// One rank's elements and their nodes, in a local numbering.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Share {
    /// Element order (1 or 2).
    pub order: u8,
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

/// Each rank's elements (those it owns first) and how many it owns, for ranks owning the
/// contiguous ranges `bounds[r]..bounds[r + 1]` of the free DOFs: every element that touches a
/// rank's DOFs is in its share. An element belongs to the lowest rank it touches; one that
/// touches no free DOF (all its nodes supported) to rank 0, for its mass.
pub fn partition(mesh: &Mesh, dofs: &Dofs, bounds: &[usize]) -> Vec<(Vec<u32>, usize)> {
    let ranks = bounds.len().saturating_sub(1).max(1);
    let owner = |d: usize| bounds.partition_point(|&b| b <= d).saturating_sub(1).min(ranks - 1);
    let mut owned = vec![Vec::new(); ranks];
    let mut shared = vec![Vec::new(); ranks];
    let mut touched = Vec::with_capacity(3 * mesh.nodes_per_tet());
    for e in 0..mesh.tet_count() {
        touched.clear();
        for &node in mesh.tet(e) {
            for c in 0..3 {
                let f = dofs.free_of[3 * node as usize + c];
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
    /// The share holding `elements` of the mesh, the first `owned` of them owned.
    pub fn of(mesh: &Mesh, dofs: &Dofs, elements: Vec<u32>, owned: usize) -> Share {
        let mut nodes: Vec<u32> = elements.iter().flat_map(|&e| mesh.tet(e as usize)).copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        let mut local = vec![u32::MAX; mesh.nodes.len()];
        for (i, &g) in nodes.iter().enumerate() {
            local[g as usize] = i as u32;
        }
        Share {
            order: mesh.order,
            xyz: nodes.iter().flat_map(|&g| mesh.nodes[g as usize]).collect(),
            vertex_count: nodes.partition_point(|&g| (g as usize) < mesh.vertex_count),
            free: nodes
                .iter()
                .flat_map(|&g| (0..3).map(move |c| dofs.free_of[3 * g as usize + c]))
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
            order: self.order,
            tets: self.tets.clone(),
            surface: Vec::new(),
        };
        let mask: Vec<bool> = self.free.iter().map(|&f| f == u32::MAX).collect();
        let dofs = Dofs::from_mask(&mask);
        let global = dofs.free.iter().map(|&d| self.free[d as usize]).collect();
        (mesh, dofs, global)
    }

    /// Assembles the share (E, ν, ρ): its lower-triangular K and M in the local numbering, the
    /// global free DOF of each local one, and the moments of the elements it owns. An element
    /// that fails is named by its global number.
    pub fn assemble(
        &self,
        (young, poisson, density): (f64, f64, f64),
    ) -> Result<(super::Assembled, Vec<u32>, Moments, Mesh, Dofs), AssemblyError> {
        let (mesh, dofs, global) = self.local();
        let (a, moments) = assemble_counting(&mesh, young, poisson, density, &dofs, self.owned).map_err(|mut e| {
            e.element = self.elements.get(e.element).map_or(e.element, |&g| g as usize);
            e
        })?;
        Ok((a, global, moments, mesh, dofs))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over any number of ranks, every element is owned once, each rank's share holds every
    /// element touching its DOFs, and the shares' moments add up to the whole part's.
    #[test]
    fn shares_cover_each_rank_rows_and_count_each_element_once() {
        let mesh = Mesh::structured_box([6, 3, 2], 0.1, 2, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-12; 3]).collect();
        let dofs = Dofs::from_mask(&mask);
        let n = dofs.free_count();
        let material = (2e11, 0.3, 7800.0);
        let (whole, whole_moments) =
            assemble_counting(&mesh, material.0, material.1, material.2, &dofs, mesh.tet_count()).unwrap();
        for ranks in [1usize, 2, 3, 7] {
            let bounds: Vec<usize> = (0..=ranks).map(|r| r * n / ranks).collect();
            let parts = partition(&mesh, &dofs, &bounds);
            let owned: usize = parts.iter().map(|(_, o)| o).sum();
            assert_eq!(owned, mesh.tet_count(), "{ranks} ranks");
            let mut total = Moments::default();
            for (r, (elements, count)) in parts.into_iter().enumerate() {
                let share = Share::of(&mesh, &dofs, elements, count);
                let (a, global, moments, _, _) = share.assemble(material).unwrap();
                total.add(&moments);
                // Each entry of the share's rows equals the whole assembly's.
                let (cp, ri) = (a.pattern.col_ptr(), a.pattern.row_idx());
                let (wcp, wri) = (whole.pattern.col_ptr(), whole.pattern.row_idx());
                let mut checked = 0;
                for j in 0..global.len() {
                    for e in cp[j]..cp[j + 1] {
                        let (gi, gj) = (global[ri[e]] as usize, global[j] as usize);
                        let (row, col) = (gi.max(gj), gi.min(gj));
                        if !(bounds[r]..bounds[r + 1]).contains(&row) && !(bounds[r]..bounds[r + 1]).contains(&col) {
                            continue;
                        }
                        let at = wcp[col] + wri[wcp[col]..wcp[col + 1]].binary_search(&row).unwrap();
                        let scale = whole.k[at].abs().max(1.0);
                        assert!(
                            (a.k[e] - whole.k[at]).abs() <= 1e-9 * scale,
                            "K({row},{col}) on rank {r}"
                        );
                        assert!((a.m[e] - whole.m[at]).abs() <= 1e-12 * whole.m[at].abs().max(1e-9));
                        checked += 1;
                    }
                }
                assert!(checked > 0);
            }
            assert!((total.mass - whole_moments.mass).abs() < 1e-12 * whole_moments.mass);
        }
    }
}
