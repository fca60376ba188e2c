//! METIS graph partitioning and fill-reducing ordering (through the `metis-sys` declarations):
//! one call at a time with a fixed seed, since METIS draws its random numbers from process-wide
//! state, so orderings and partitions (and the round-off of everything after them) repeat.

use metis_sys as sys;

static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A symmetric graph in CSR form without self-loops: the neighbours of vertex `v` are
/// `adjacency[offsets[v]..offsets[v + 1]]`.
pub struct Graph<'a> {
    /// `n + 1` offsets, starting at 0.
    pub offsets: &'a [i32],
    /// Neighbour lists.
    pub adjacency: &'a [i32],
}

impl Graph<'_> {
    fn vertices(&self) -> Option<usize> {
        let n = self.offsets.len().checked_sub(1)?;
        let ok = self.offsets.first() == Some(&0)
            && self.offsets.windows(2).all(|w| w[0] <= w[1])
            && self.offsets.last().is_some_and(|&e| e as usize == self.adjacency.len())
            && self.adjacency.iter().all(|&a| a >= 0 && (a as usize) < n);
        ok.then_some(n)
    }
}

fn options() -> [sys::idx_t; sys::METIS_NOPTIONS as usize] {
    let mut options = [0 as sys::idx_t; sys::METIS_NOPTIONS as usize];
    // SAFETY: options has METIS_NOPTIONS entries.
    unsafe { sys::METIS_SetDefaultOptions(options.as_mut_ptr()) };
    options[sys::moptions_et_METIS_OPTION_SEED as usize] = 7;
    options
}

/// The vertices split into `parts` connected pieces of about equal total `weights` (k-way
/// partitioning; weights positive, one per vertex): the part of each vertex, or None when the
/// graph or weights are malformed or METIS fails.
pub fn partition(graph: &Graph<'_>, weights: &[i32], parts: usize) -> Option<Vec<u32>> {
    let n = graph.vertices()?;
    if weights.len() != n || weights.iter().any(|&w| w <= 0) || parts == 0 {
        return None;
    }
    let (mut xadj, mut adj, mut weight) = (graph.offsets.to_vec(), graph.adjacency.to_vec(), weights.to_vec());
    let (mut nv, mut ncon, mut np, mut cut) = (i32::try_from(n).ok()?, 1i32, i32::try_from(parts).ok()?, 0i32);
    let mut part = vec![0i32; n];
    let mut options = options();
    let _serial = LOCK.lock().unwrap_or_else(|p| p.into_inner());
    // SAFETY: CSR arrays of a checked graph of nv vertices, nv weights; `part` has length nv;
    // null arrays are METIS's defaults.
    let status = unsafe {
        sys::METIS_PartGraphKway(
            &mut nv,
            &mut ncon,
            xadj.as_mut_ptr(),
            adj.as_mut_ptr(),
            weight.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            &mut np,
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            &mut cut,
            part.as_mut_ptr(),
        )
    };
    (status == sys::rstatus_et_METIS_OK).then(|| part.into_iter().map(|p| p as u32).collect())
}

/// A fill-reducing ordering of the vertices (nested dissection): new → old, or None when the
/// graph is malformed or METIS fails.
pub fn nested_dissection(graph: &Graph<'_>) -> Option<Vec<i32>> {
    let n = graph.vertices()?;
    let (mut xadj, mut adj) = (graph.offsets.to_vec(), graph.adjacency.to_vec());
    let mut nv = i32::try_from(n).ok()?;
    let (mut perm, mut iperm) = (vec![0i32; n], vec![0i32; n]);
    let mut options = options();
    let _serial = LOCK.lock().unwrap_or_else(|p| p.into_inner());
    // SAFETY: CSR arrays of a checked graph of nv vertices; outputs have length nv.
    let status = unsafe {
        sys::METIS_NodeND(
            &mut nv,
            xadj.as_mut_ptr(),
            adj.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    (status == sys::rstatus_et_METIS_OK).then_some(perm)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path of 8 vertices: two parts of 4 consecutive vertices, and an ordering that is a
    /// permutation.
    #[test]
    fn a_path_splits_in_two_halves_and_orders_as_a_permutation() {
        let n = 8;
        let mut offsets = vec![0];
        let mut adjacency = Vec::new();
        for v in 0..n {
            if v > 0 {
                adjacency.push(v - 1);
            }
            if v + 1 < n {
                adjacency.push(v + 1);
            }
            offsets.push(adjacency.len() as i32);
        }
        let g = Graph {
            offsets: &offsets,
            adjacency: &adjacency,
        };
        let p = partition(&g, &[1; 8], 2).expect("partition");
        assert!(
            p[..4].iter().all(|&x| x == p[0]) && p[4..].iter().all(|&x| x == p[7]) && p[0] != p[7],
            "{p:?}"
        );
        let mut order = nested_dissection(&g).expect("ordering");
        order.sort_unstable();
        assert_eq!(order, (0..n).collect::<Vec<_>>());
        let bad = Graph {
            offsets: &[0, 1],
            adjacency: &[5],
        };
        assert!(partition(&bad, &[1], 1).is_none() && nested_dissection(&bad).is_none());
    }
}
