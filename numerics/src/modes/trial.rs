//! An upper bound of a part's first elastic eigenvalue before any solve: Rayleigh–Ritz on
//! polynomial displacement fields (each component a polynomial of degree ≤ 2 in the node's
//! position). By Courant–Fischer the Ritz values bound the eigenvalues from above in order, so
//! the one after the rigid motions' (which the linear fields hold) bounds λ₁. A free body's
//! shift-invert solve needs a shift a little below the spectrum: from the mesh's stiffness
//! scale alone it could land 10⁴ × λ₁ below, where the low modes crowd together as seen from
//! it, and the solve had to be made again nearer (the corpus cast housing: two factorisations
//! and 400 block solves instead of one and 160).

use super::EigenProblem;
use crate::fem::Dofs;
use crate::linsolve::sym_matmul;
use nalgebra::{DMatrix, SymmetricEigen};

/// Monomials of degree ≤ 2 in three variables: 1, x, y, z, x², y², z², xy, yz, zx.
const MONOMIALS: usize = 10;

fn monomials(p: [f64; 3]) -> [f64; MONOMIALS] {
    let [x, y, z] = p;
    [1.0, x, y, z, x * x, y * y, z * z, x * y, y * z, z * x]
}

/// The Ritz value after the `rigid` lowest of `problem` on the trial fields over `nodes`
/// (coordinates of the mesh nodes, `dofs` numbering their components): an upper bound of the
/// first elastic eigenvalue. `None` when the fields do not reach past the rigid motions (too
/// few independent ones on the free DOFs) or the result is not a finite positive number.
pub fn first_elastic_bound(problem: &EigenProblem<'_>, dofs: &Dofs, nodes: &[[f64; 3]], rigid: usize) -> Option<f64> {
    let n = problem.size();
    let fields = 3 * MONOMIALS;
    if n < 2 * fields || nodes.is_empty() {
        return None;
    }
    // Positions centred and scaled to about [−1, 1]: the monomials stay of one size.
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in nodes {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let half = (0..3).map(|c| 0.5 * (hi[c] - lo[c])).fold(0.0, f64::max);
    if half <= 0.0 || !half.is_finite() {
        return None;
    }
    // Three blocks of 30 vectors: asked for first, and no bound (the solve's own shift) when
    // memory is short.
    let zeros = || crate::memory::try_zeros::<f64>("the trial fields of λ₁'s bound", n * fields).ok();
    let (mut v, mut kv, mut mv) = (zeros()?, zeros()?, zeros()?);
    for (g, &f) in dofs.free_of.iter().enumerate() {
        if f == u32::MAX {
            continue;
        }
        let (node, a) = (g / 3, g % 3);
        let p = nodes.get(node)?;
        let xi = std::array::from_fn(|c| (p[c] - 0.5 * (lo[c] + hi[c])) / half);
        for (k, m) in monomials(xi).iter().enumerate() {
            v[(3 * k + a) * n + f as usize] = *m;
        }
    }
    sym_matmul(problem.pattern, problem.k, &v, &mut kv);
    sym_matmul(problem.pattern, problem.m, &v, &mut mv);
    // Vᵀ W as one dense product (faer's, threaded).
    let vm = faer::MatRef::from_column_major_slice(&v, n, fields);
    let gram = |w: &[f64]| {
        let p = vm.transpose() * faer::MatRef::from_column_major_slice(w, n, fields);
        DMatrix::from_fn(fields, fields, |i, j| p[(i, j)])
    };
    let (kr, mr) = (gram(&kv), gram(&mv));
    // An M-orthonormal basis of the fields' span, dropping directions M cannot tell apart.
    let m_eig = SymmetricEigen::new(0.5 * (&mr + mr.transpose()));
    let largest = m_eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let kept: Vec<usize> = (0..fields)
        .filter(|&i| m_eig.eigenvalues[i] > 1e-12 * largest)
        .collect();
    if kept.len() <= rigid {
        return None;
    }
    let b = DMatrix::from_fn(fields, kept.len(), |i, j| {
        m_eig.eigenvectors[(i, kept[j])] / m_eig.eigenvalues[kept[j]].sqrt()
    });
    let a = b.transpose() * kr * &b;
    let mut ritz: Vec<f64> = SymmetricEigen::new(0.5 * (&a + a.transpose()))
        .eigenvalues
        .iter()
        .copied()
        .collect();
    ritz.sort_by(f64::total_cmp);
    ritz.get(rigid).copied().filter(|l| l.is_finite() && *l > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modes::{Model, SolverChoice, solve};
    use crate::tet_mesh::Mesh;

    /// A free steel beam (1.2 × 0.1 × 0.1 m, 10-node tets): the bound is above its first
    /// elastic eigenvalue, and near it (a uniform-curvature field against the first free–free
    /// bending mode: Euler–Bernoulli's 720 / 500.6 = 1.44×), and the free body solved with it
    /// gives the same modes as the dense solver.
    #[test]
    fn the_polynomial_fields_bound_a_free_beam_s_first_mode_from_above() {
        let mesh = Mesh::structured_box([12, 1, 1], 0.1, crate::fem::element::Kind::Tet10, |_, p| p);
        let n = 3 * mesh.nodes.len();
        let d = Model::assemble(
            mesh,
            Dofs::from_mask(&vec![false; n]),
            crate::material::Material::elastic(2e11, 0.3, 7800.0),
        )
        .expect("assembles");
        assert_eq!(d.rigid, 6);
        let problem = EigenProblem::of(&d.system);
        let bound = first_elastic_bound(&problem, &d.dofs, &d.mesh.nodes, d.rigid).expect("a bound");
        let (block, _) = solve(d.space(), 4, SolverChoice::Block).expect("solves");
        let (dense, _) = solve(d.space(), 4, SolverChoice::Dense).expect("solves");
        let l1 = dense.eigenvalues[0];
        println!("bound {bound:.4e}, λ₁ {l1:.4e} ({:.3}×)", bound / l1);
        assert!(bound >= l1 && bound < 2.0 * l1, "bound {bound:.4e} against λ₁ {l1:.4e}");
        for (a, b) in block.eigenvalues.iter().zip(&dense.eigenvalues) {
            assert!((a - b).abs() < 1e-9 * b, "{a} against {b}");
        }
    }
}
