//! Static correction (`[static_correction]`, docs/scene.md): the exact static compliance blocks
//! Gᵢ = Wᵢ K⁻¹ Wᵢᵀ of the candidate contact vertices' patches (Wᵢ the patch weights,
//! `loads::patch`; (K⁻¹)ᵢᵢ for a point contact). The runtime adds (Gᵢ − Φ̄ᵢ Λ⁻¹ Φ̄ᵢᵀ) F at the
//! active vertex (Φ̄ᵢ = Wᵢ Φ), so the felt stiffness is exact whatever the number of modes kept.

use crate::linsolve::{Cholesky, factor_stiffness};
use crate::loads::patch::Patches;
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

/// Compliance blocks of every corner vertex on the surface, each for its contact patch.
pub fn surface_compliance(d: &Discretized, patches: &Patches) -> Result<Compliance> {
    // Before factorising: a free body's K is singular, and the reason should say why.
    require_supported(d)?;
    surface_compliance_with(d, &factor_stiffness(&d.system, &d.dofs)?, patches)
}

/// The same with K's factor already at hand (`chol` must factor `d`'s K): block k is
/// Wₖ K⁻¹ Wₖᵀ, Wₖ the weights of centre k's patch (one vertex for a point contact).
pub fn surface_compliance_with(d: &Discretized, chol: &Cholesky, patches: &Patches) -> Result<Compliance> {
    require_supported(d)?;
    let all: Vec<(&[u32], &[f64])> = (0..patches.centres.len()).map(|k| patches.patch(k)).collect();
    let bar = crate::progress::bar(all.len() as u64, "vertices (static correction)");
    let blocks = patch_blocks(d, chol, &all, || bar.inc(VERTICES_PER_BLOCK as u64));
    bar.finish_and_clear();
    Ok(Compliance {
        nodes: patches.centres.clone(),
        blocks,
    })
}

/// W K⁻¹ Wᵀ (m/N) for each patch (nodes, weights): how far the patch moves, on the average its
/// weights take, per newton spread over it. `tick` is called after each block of patches.
pub fn patch_blocks(
    d: &Discretized,
    chol: &Cholesky,
    patches: &[(&[u32], &[f64])],
    tick: impl Fn() + Sync,
) -> Vec<[[f64; 3]; 3]> {
    let nf = d.dofs.free_count();
    patches
        .par_chunks(VERTICES_PER_BLOCK)
        .flat_map_iter(|chunk| {
            let nrhs = 3 * chunk.len();
            let mut x = vec![0.0; nf * nrhs];
            for (k, (nodes, weights)) in chunk.iter().enumerate() {
                for c in 0..3 {
                    let rhs = &mut x[(3 * k + c) * nf..(3 * k + c + 1) * nf];
                    for (&a, &w) in nodes.iter().zip(*weights) {
                        let f = d.dofs.free_of[3 * a as usize + c];
                        if f != u32::MAX {
                            rhs[f as usize] += w;
                        }
                    }
                }
            }
            chol.solve_many_in_place(&mut x, nrhs);
            tick();
            let out: Vec<[[f64; 3]; 3]> = chunk
                .iter()
                .enumerate()
                .map(|(k, (nodes, weights))| {
                    let mut block = [[0.0; 3]; 3];
                    for (b, column) in (0..3).map(|b| (b, &x[(3 * k + b) * nf..(3 * k + b + 1) * nf])) {
                        for (&node, &w) in nodes.iter().zip(*weights) {
                            for (a, row) in block.iter_mut().enumerate() {
                                let f = d.dofs.free_of[3 * node as usize + a];
                                if f != u32::MAX {
                                    row[b] += w * column[f as usize];
                                }
                            }
                        }
                    }
                    block
                })
                .collect();
            out
        })
        .collect()
}
