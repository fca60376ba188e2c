//! Supported degrees of freedom: which DOFs the scene's `[[fixed]]` regions remove.

use crate::scene::{Region, Support};
use crate::tet_mesh::Mesh;

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

/// A support selects nothing; the message says where the part is.
#[derive(Debug, thiserror::Error)]
#[error("fixed[{index}] ({what}) selects no node of the mesh; {hint}")]
pub struct EmptySupport {
    /// Index of the `[[fixed]]` table.
    pub index: usize,
    /// The region, in words.
    pub what: String,
    /// Where the part lies, to help fix the value.
    pub hint: String,
}

/// Whether a support region holds point `p` (`default_tol`: 1e-6 × part size).
fn selects(region: &Region, p: [f64; 3], default_tol: f64) -> bool {
    match *region {
        Region::Plane { axis, value, tol } => (p[axis] - value).abs() <= tol.unwrap_or(default_tol),
        Region::Box(b) => b.contains(p, default_tol),
    }
}

/// The region in words, and where the part lies so the user can fix the value.
fn describe(region: &Region, lo: [f64; 3], hi: [f64; 3], default_tol: f64) -> (String, String) {
    match *region {
        Region::Plane { axis, value, tol } => {
            let name = ["x", "y", "z"][axis];
            (
                format!("plane {name} = {value} m, tol {:.3e} m", tol.unwrap_or(default_tol)),
                format!(
                    "the part spans {name} from {:.6} to {:.6} m: change `value` (in metres) or raise `tol`",
                    lo[axis], hi[axis]
                ),
            )
        }
        Region::Box(b) => (
            format!("box {:?}..{:?} m", b.min, b.max),
            format!("the part spans {lo:.6?} to {hi:.6?} m: move or enlarge the box (in metres)"),
        ),
    }
}

/// Applies the supports to the mesh's nodes (corner and mid-edge alike).
pub fn select(mesh: &Mesh, supports: &[Support]) -> Result<Dofs, EmptySupport> {
    let n = mesh.nodes.len();
    let mut fixed_mask = vec![false; 3 * n];
    let (lo, hi) = mesh.bounding_box();
    let default_tol = 1e-6 * mesh.diameter();
    for (index, s) in supports.iter().enumerate() {
        let mut any = false;
        for (i, p) in mesh.nodes.iter().enumerate() {
            if selects(&s.region, *p, default_tol) {
                any = true;
                for c in 0..3 {
                    fixed_mask[3 * i + c] |= s.components[c];
                }
            }
        }
        if !any {
            let (what, hint) = describe(&s.region, lo, hi, default_tol);
            return Err(EmptySupport { index, what, hint });
        }
    }
    Ok(Dofs::from_mask(&fixed_mask))
}
