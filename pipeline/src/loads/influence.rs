//! What each support carries of a static load at any surface vertex: its influence coefficients,
//! from the supports' constraint modes by Betti's theorem.
//!
//! Move support k's ground by a unit rigid motion T_c (a translation along axis c, or a rotation
//! about axis c through the support's centre), the other supports held, no load: the part takes
//! the shape w_kc. For a load f at vertex v (supports held), Betti's reciprocity gives what
//! support k exerts on the part, component c (force, or moment about its centre):
//! R_kc = −w_kc(v) · f. One factorisation of K and 6 solves per support give every vertex's
//! coefficients; a session adds them to the modes' reactions for the share the truncated modes
//! leave out (the runtime's `Basis::support_reactions_loaded`), so a load held steady is carried
//! whole by the supports, split between them as the FE model splits it.

use super::{degenerate, spring_forces};
use crate::fem::Dofs;
use crate::fem::element::Lame;
use crate::fem::springs::NodeSpring;
use crate::tet_mesh::Mesh;
use anyhow::Result;
use rayon::prelude::*;

/// The most supports whose coefficients are made: each adds 18 values per surface vertex to
/// the runtime's memory and 6 right-hand sides to the solve.
pub const MAX_SUPPORTS: usize = 6;

/// Each support's reaction per newton at each surface vertex (the file's
/// `modes/support_influence`).
#[derive(Clone, Debug, PartialEq)]
pub struct Influence {
    /// Surface corner vertices, ascending.
    pub nodes: Vec<u32>,
    /// Row-major [nodes, 18·s]: column (6k + c)·3 + d is component c (force x y z, N; moment
    /// x y z about the support's centre, N·m) of what support k exerts on the part per newton
    /// of a load along axis d at the row's vertex.
    pub values: Vec<f64>,
}

/// The unit rigid motion c (0–2 translations, 3–5 rotations about `centre`) at `x`.
fn rigid_motion(c: usize, centre: [f64; 3], x: [f64; 3]) -> [f64; 3] {
    let d = [x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]];
    match c {
        0..=2 => std::array::from_fn(|a| f64::from(u8::from(a == c))),
        3 => [0.0, -d[2], d[1]],
        4 => [d[2], 0.0, -d[0]],
        _ => [-d[1], d[0], 0.0],
    }
}

/// The influence coefficients of supports `held` (each one's removed DOFs) and `springs`
/// (each one's spring blocks), moments about `centres`, on a part whose supports hold every
/// rigid motion. `near` holds the elements that touch a held node (K w at the free DOFs of a
/// motion prescribed on held DOFs comes from them alone); `chol` factors K on `dofs`' free
/// DOFs (the springs in it).
#[allow(clippy::too_many_arguments)]
pub fn support_influence(
    mesh: &Mesh,
    near: &Mesh,
    lame: &Lame,
    dofs: &Dofs,
    chol: &crate::linsolve::Cholesky,
    held: &[Vec<u32>],
    springs: &[Vec<NodeSpring>],
    centres: &[[f64; 3]],
) -> Result<Influence> {
    let (s, nf, n3) = (held.len(), dofs.free_count(), 3 * mesh.nodes.len());
    // Which support removes each DOF (the first that lists it, as the reactions count it).
    let mut owner = vec![u32::MAX; n3];
    for (k, list) in held.iter().enumerate() {
        for &g in list {
            if owner[g as usize] == u32::MAX {
                owner[g as usize] = k as u32;
            }
        }
    }
    let all_springs: Vec<NodeSpring> = springs.iter().flatten().copied().collect();
    // Right-hand sides, column (6k + c): K_s,k T_c − K w_c at the free DOFs, where w_c is T_c
    // on support k's held DOFs (0 elsewhere) and K holds the elements and every spring. Asked
    // for first: 6 columns a support of every free DOF.
    let mut x = crate::memory::try_zeros::<f64>("the supports' influence solves", nf * 6 * s)?;
    // A support's six columns together: the elements near the held nodes made once for them.
    for (k, block) in x.chunks_mut((6 * nf).max(1)).enumerate() {
        let ws: Vec<Vec<f64>> = (0..6)
            .map(|c| {
                let mut w = vec![0.0; n3];
                for &g in &held[k] {
                    let g = g as usize;
                    if owner[g] == k as u32 {
                        w[g] = rigid_motion(c, centres[k], mesh.nodes[g / 3])[g % 3];
                    }
                }
                w
            })
            .collect();
        let refs: Vec<&[f64]> = ws.iter().map(Vec::as_slice).collect();
        let mut k_ws = crate::loads::vector::internal_forces_many(near, lame, &refs).map_err(degenerate)?;
        block
            .par_chunks_mut(nf.max(1))
            .zip(ws.par_iter().zip(k_ws.par_chunks_mut(n3.max(1))))
            .enumerate()
            .for_each(|(c, (out, (w, rhs)))| {
                spring_forces(&all_springs, w, |g, v| rhs[g] += v);
                rhs.iter_mut().for_each(|v| *v = -*v);
                // The ground of support k's springs moved by T_c pulls the part with K_s,k T_c.
                if !springs[k].is_empty() {
                    let ground: Vec<f64> = (0..n3)
                        .map(|g| rigid_motion(c, centres[k], mesh.nodes[g / 3])[g % 3])
                        .collect();
                    spring_forces(&springs[k], &ground, |g, v| rhs[g] += v);
                }
                for (o, &g) in out.iter_mut().zip(&dofs.free) {
                    *o = rhs[g as usize];
                }
            });
    }
    chol.solve_many_in_place(&mut x, 6 * s);
    let mut nodes: Vec<u32> = mesh.surface.iter().flatten().copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    let mut values = vec![0.0; nodes.len() * 18 * s];
    for (row, &v) in values.chunks_exact_mut(18 * s).zip(&nodes) {
        for col in 0..6 * s {
            let k = col / 6;
            for d in 0..3 {
                let g = 3 * v as usize + d;
                let w = match dofs.free_of[g] {
                    u32::MAX if owner[g] == k as u32 => rigid_motion(col % 6, centres[k], mesh.nodes[v as usize])[d],
                    u32::MAX => 0.0,
                    f => x[col * nf + f as usize],
                };
                row[3 * col + d] = -w;
            }
        }
    }
    if values.iter().any(|v| !v.is_finite()) {
        anyhow::bail!("the supports' influence coefficients are not finite: K is singular on these supports");
    }
    Ok(Influence { nodes, values })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigid_motions_are_the_unit_translations_and_rotations_about_the_centre() {
        let (c, x) = ([1.0, 2.0, 3.0], [2.0, 2.0, 3.0]);
        assert_eq!(rigid_motion(1, c, x), [0.0, 1.0, 0.0]);
        // A turn about z moves a point on +x along +y; about y, along −z.
        assert_eq!(rigid_motion(5, c, x), [0.0, 1.0, 0.0]);
        assert_eq!(rigid_motion(4, c, x), [0.0, 0.0, -1.0]);
        assert_eq!(rigid_motion(3, c, x), [0.0, 0.0, 0.0]);
    }
}
