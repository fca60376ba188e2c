//! The numbering of a mesh's free degrees of freedom: what assembly, the solvers and the
//! store share. Which DOFs are supported is decided elsewhere (`supports`, from the scene);
//! this module knows only the mask.

/// Numbering of the free DOFs (full index `3·node + component`).
#[derive(Clone, Debug)]
pub struct Dofs {
    /// Total DOFs, 3 × nodes.
    pub total: usize,
    /// Supported DOFs, ascending.
    pub fixed: Vec<u32>,
    /// Full index → free index, or `u32::MAX` when supported.
    pub free_of: Vec<u32>,
    /// Free index → full index (ascending, so the map preserves order).
    pub free: Vec<u32>,
}

impl Dofs {
    /// Number of unknowns.
    pub fn free_count(&self) -> usize {
        self.free.len()
    }

    /// Numbering from a per-DOF "supported" mask.
    pub fn from_mask(fixed_mask: &[bool]) -> Dofs {
        let mut free_of = vec![u32::MAX; fixed_mask.len()];
        let mut free = Vec::with_capacity(fixed_mask.len());
        let mut fixed = Vec::new();
        for (d, &f) in fixed_mask.iter().enumerate() {
            if f {
                fixed.push(d as u32);
            } else {
                free_of[d] = free.len() as u32;
                free.push(d as u32);
            }
        }
        Dofs {
            total: fixed_mask.len(),
            fixed,
            free_of,
            free,
        }
    }

    /// Expands a vector over free DOFs to all DOFs (zeros where supported).
    pub fn expand(&self, reduced: &[f64]) -> Vec<f64> {
        let mut full = vec![0.0; self.total];
        for (r, &f) in reduced.iter().zip(&self.free) {
            full[f as usize] = *r;
        }
        full
    }
}
