//! Static correction (`[static_correction]`, docs/scene.md): the exact static compliance blocks
//! Gᵢᵢ = (K⁻¹)ᵢᵢ of the candidate contact vertices. The runtime adds (Gᵢᵢ − Φᵢ Λ⁻¹ Φᵢᵀ) F at the
//! active vertex, so the felt stiffness is exact whatever the number of modes kept.

use crate::linsolve::{Cholesky, factor_stiffness};
use crate::problem::Discretized;
use anyhow::{Result, bail};
use rayon::prelude::*;

/// Compliance blocks of some vertices.
#[derive(Clone, Debug, Default)]
pub struct Compliance {
    /// Node indices, ascending.
    pub nodes: Vec<u32>,
    /// (K⁻¹)ᵢᵢ per node, m/N (zero rows and columns for supported components).
    pub blocks: Vec<[[f64; 3]; 3]>,
}

fn require_supported(d: &Discretized) -> Result<()> {
    if d.rigid > 0 {
        bail!(
            "static correction needs a supported part: a free body's K is singular ({} rigid modes) and inertia \
             relief is not implemented; remove [static_correction] or add supports",
            d.rigid
        );
    }
    Ok(())
}

/// Vertices solved per block of right-hand sides (3 each): one pass over the factor serves them.
const VERTICES_PER_BLOCK: usize = 16;

/// Compliance blocks of every corner vertex on the surface.
pub fn surface_compliance(d: &Discretized) -> Result<Compliance> {
    // Before factorising: a free body's K is singular, and the reason should say why.
    require_supported(d)?;
    surface_compliance_with(d, &factor_stiffness(&d.system, &d.dofs)?)
}

/// The same with K's factor already at hand (`chol` must factor `d`'s K).
pub fn surface_compliance_with(d: &Discretized, chol: &Cholesky) -> Result<Compliance> {
    require_supported(d)?;
    let nodes = d.mesh.surface_vertices();
    let nf = d.dofs.free_count();
    let bar = crate::progress::bar(nodes.len() as u64, "vertices (static correction)");
    let blocks: Vec<[[f64; 3]; 3]> = nodes
        .par_chunks(VERTICES_PER_BLOCK)
        .flat_map_iter(|chunk| {
            let nrhs = 3 * chunk.len();
            let mut x = vec![0.0; nf * nrhs];
            for (k, &v) in chunk.iter().enumerate() {
                for c in 0..3 {
                    let f = d.dofs.free_of[3 * v as usize + c];
                    if f != u32::MAX {
                        x[(3 * k + c) * nf + f as usize] = 1.0;
                    }
                }
            }
            chol.solve_many_in_place(&mut x, nrhs);
            bar.inc(chunk.len() as u64);
            let out: Vec<[[f64; 3]; 3]> = chunk
                .iter()
                .enumerate()
                .map(|(k, &v)| {
                    std::array::from_fn(|a| {
                        std::array::from_fn(|b| {
                            let f = d.dofs.free_of[3 * v as usize + a];
                            if f == u32::MAX {
                                0.0
                            } else {
                                x[(3 * k + b) * nf + f as usize]
                            }
                        })
                    })
                })
                .collect();
            out
        })
        .collect();
    bar.finish_and_clear();
    Ok(Compliance { nodes, blocks })
}
