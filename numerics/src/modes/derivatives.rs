//! Modal derivatives (Idelsohn & Cardona 1985; Barbič & James 2005): how the modes change as
//! the part deforms along them, ψᵢⱼ = −K⁻¹ ∂²f/∂φᵢ∂φⱼ — the directions a large deformation takes
//! that the linear modes miss (a bent beam's axial shortening, the stretching that stiffens a
//! plate). A nonlinear reduced model's basis is the modes and these, made M-orthonormal and
//! K-orthogonal to the modes and to each other (Rayleigh–Ritz among the derivatives), so that the
//! linear part of the model stays diagonal.

use super::{Modes, Space};
use crate::fem::element::Lame;
use crate::fem::stvk::{self, Points};
use crate::linsolve::{FactorError, factor_stiffness, sym_matvec};
use nalgebra::{DMatrix, SymmetricEigen};

/// The vectors a nonlinear model adds to the modes.
#[derive(Clone, Debug)]
pub struct Enrichment {
    /// Column-major `free × e`: M-orthonormal, M- and K-orthogonal to the modes and to each
    /// other, ordered by their Rayleigh quotient.
    pub vectors: Vec<f64>,
    /// Their Rayleigh quotients vᵀ K v (ascending).
    pub ritz_values: Vec<f64>,
    /// Derivatives left out as (numerically) in the span of the modes and the others.
    pub dropped: usize,
    /// max |φᵢᵀ K vⱼ| / √(λᵢ θⱼ) over the modes and the added vectors: their coupling through
    /// K, 0 for exact eigenvectors.
    pub coupling: f64,
}

/// Why the derivatives could not be made.
#[derive(Debug, thiserror::Error)]
pub enum DerivativeError {
    /// The part moves freely: K is singular.
    #[error(
        "a nonlinear model needs a held part ({0} rigid motion(s) left free by the supports); \
         hold it ([[fixed]]) or use [model] kind = \"linear\""
    )]
    FreeBody(usize),
    /// An element is degenerate.
    #[error(transparent)]
    Degenerate(#[from] stvk::DegenerateElement),
    /// K could not be factorised.
    #[error(transparent)]
    Factor(#[from] FactorError),
    /// Fewer modes than asked to differentiate.
    #[error("derivatives of the first {asked} modes were asked for, but only {have} were computed")]
    TooFew {
        /// Asked.
        asked: usize,
        /// Computed.
        have: usize,
    },
}

/// The derivatives of each pair of the lowest `of` modes of `modes` on `space`, and for each
/// load in `loads` (nodal forces, all 3n DOFs) its linear static response K⁻¹f and that
/// response's own derivative (a load the modes carry poorly, such as a block pressed along its
/// stiff axis, is then carried to second order); orthogonalised against all of `modes` and each
/// other. One factorisation of K, all right-hand sides at once.
pub fn enrich(space: &Space<'_>, modes: &Modes, of: usize, loads: &[Vec<f64>]) -> Result<Enrichment, DerivativeError> {
    if space.rigid > 0 {
        return Err(DerivativeError::FreeBody(space.rigid));
    }
    let have = modes.eigenvalues.len();
    if of > have {
        return Err(DerivativeError::TooFew { asked: of, have });
    }
    let (dofs, sys) = (space.dofs, space.system);
    let nf = dofs.free_count();
    let lame = Lame::of(&space.material);
    let points = Points::of(space.mesh)?;
    let full: Vec<Vec<f64>> = (0..of)
        .map(|j| dofs.expand(&modes.vectors[j * nf..(j + 1) * nf]))
        .collect();
    let pairs: Vec<(usize, usize)> = (0..of).flat_map(|i| (i..of).map(move |j| (i, j))).collect();
    let chol = factor_stiffness(sys, dofs)?;
    // The loads' linear responses first (their derivatives need them).
    let nl = loads.len();
    let mut responses = vec![0.0; nf * nl];
    for (c, f) in loads.iter().enumerate() {
        for (k, &g) in dofs.free.iter().enumerate() {
            responses[c * nf + k] = f[g as usize];
        }
    }
    if nl > 0 {
        chol.solve_many_in_place(&mut responses, nl);
    }
    let responses_full: Vec<Vec<f64>> = (0..nl).map(|c| dofs.expand(&responses[c * nf..(c + 1) * nf])).collect();
    let count = pairs.len() + nl;
    let mut x = vec![0.0; nf * count];
    let directions = pairs
        .iter()
        .map(|&(i, j)| (&full[i], &full[j]))
        .chain(responses_full.iter().map(|u| (u, u)));
    for (c, (a, b)) in directions.enumerate() {
        let d = stvk::second_derivative(&points, space.mesh, &lame, a, b);
        for (k, &g) in dofs.free.iter().enumerate() {
            x[c * nf + k] = -d[g as usize];
        }
    }
    if count > 0 {
        chol.solve_many_in_place(&mut x, count);
    }
    // The candidates in order: mode-pair derivatives, load responses, their derivatives.
    let mut candidates = x[..nf * pairs.len()].to_vec();
    candidates.extend_from_slice(&responses);
    candidates.extend_from_slice(&x[nf * pairs.len()..]);
    let x = candidates;
    let total = pairs.len() + 2 * nl;
    // M-Gram–Schmidt (twice) against the modes and the derivatives kept so far.
    let mut kept: Vec<Vec<f64>> = Vec::new();
    let mut mv = vec![0.0; nf];
    let mut dropped = 0;
    for c in 0..total {
        let mut v = x[c * nf..(c + 1) * nf].to_vec();
        sym_matvec(&sys.pattern, &sys.m, &v, &mut mv);
        let before = dot(&v, &mv).max(0.0).sqrt();
        for _ in 0..2 {
            sym_matvec(&sys.pattern, &sys.m, &v, &mut mv);
            let basis = (0..have)
                .map(|j| &modes.vectors[j * nf..(j + 1) * nf])
                .chain(kept.iter().map(|k| k.as_slice()));
            let coeffs: Vec<f64> = basis.clone().map(|b| dot(b, &mv)).collect();
            for (b, a) in basis.zip(coeffs) {
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= a * y);
            }
        }
        sym_matvec(&sys.pattern, &sys.m, &v, &mut mv);
        let after = dot(&v, &mv).max(0.0).sqrt();
        if after.partial_cmp(&(1e-8 * before)) != Some(std::cmp::Ordering::Greater) || !after.is_finite() {
            dropped += 1;
            continue;
        }
        v.iter_mut().for_each(|x| *x /= after);
        kept.push(v);
    }
    // Rayleigh–Ritz among the kept vectors: Vᵀ K V = Y Θ Yᵀ, V ← V Y.
    let e = kept.len();
    let kv: Vec<Vec<f64>> = kept
        .iter()
        .map(|v| {
            let mut y = vec![0.0; nf];
            sym_matvec(&sys.pattern, &sys.k, v, &mut y);
            y
        })
        .collect();
    let kr = DMatrix::from_fn(e, e, |i, j| 0.5 * (dot(&kept[i], &kv[j]) + dot(&kept[j], &kv[i])));
    let eig = SymmetricEigen::new(kr);
    let mut order: Vec<usize> = (0..e).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let mut vectors = vec![0.0; nf * e];
    for (c, &o) in order.iter().enumerate() {
        let out = &mut vectors[c * nf..(c + 1) * nf];
        for (k, v) in kept.iter().enumerate() {
            let y = eig.eigenvectors[(k, o)];
            out.iter_mut().zip(v).for_each(|(a, b)| *a += y * b);
        }
    }
    let ritz_values: Vec<f64> = order.iter().map(|&o| eig.eigenvalues[o]).collect();
    // Coupling through K between the modes and the added vectors.
    let mut coupling: f64 = 0.0;
    let mut ky = vec![0.0; nf];
    for (c, theta) in ritz_values.iter().enumerate() {
        sym_matvec(&sys.pattern, &sys.k, &vectors[c * nf..(c + 1) * nf], &mut ky);
        for (j, lam) in modes.eigenvalues.iter().enumerate() {
            let kij = dot(&modes.vectors[j * nf..(j + 1) * nf], &ky);
            coupling = coupling.max(kij.abs() / (lam * theta).abs().sqrt().max(f64::MIN_POSITIVE));
        }
    }
    Ok(Enrichment {
        vectors,
        ritz_values,
        dropped,
        coupling,
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::element::Kind;
    use crate::material::Material;
    use crate::modes::{Model, SolverChoice};
    use crate::tet_mesh::Mesh;

    /// The elastica of a cantilever under a tip load perpendicular to its axis, α = PL²/EI:
    /// θ'' = −α cos θ, θ(0) = 0, θ'(1) = 0, shot on θ'(0). Returns the tip's transverse
    /// deflection and axial shortening over L.
    pub(crate) fn elastica(alpha: f64) -> (f64, f64) {
        let run = |k0: f64| {
            let n = 4000;
            let h = 1.0 / n as f64;
            let (mut th, mut k, mut x, mut y) = (0.0f64, k0, 0.0, 0.0);
            let rhs = |th: f64, k: f64| (k, -alpha * th.cos(), th.cos(), th.sin());
            for _ in 0..n {
                let a = rhs(th, k);
                let b = rhs(th + h / 2.0 * a.0, k + h / 2.0 * a.1);
                let c = rhs(th + h / 2.0 * b.0, k + h / 2.0 * b.1);
                let d = rhs(th + h * c.0, k + h * c.1);
                th += h / 6.0 * (a.0 + 2.0 * b.0 + 2.0 * c.0 + d.0);
                k += h / 6.0 * (a.1 + 2.0 * b.1 + 2.0 * c.1 + d.1);
                x += h / 6.0 * (a.2 + 2.0 * b.2 + 2.0 * c.2 + d.2);
                y += h / 6.0 * (a.3 + 2.0 * b.3 + 2.0 * c.3 + d.3);
            }
            (k, y, 1.0 - x)
        };
        // θ'(1) falls as θ'(0) falls; θ'(0) = α ∫cos θ ≤ α.
        let (mut lo, mut hi) = (0.0, alpha);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if run(mid).0 > 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let (_, w, u) = run(0.5 * (lo + hi));
        (w, u)
    }

    #[test]
    fn elastica_reproduces_the_published_tip_deflections() {
        // Bisshopp & Drucker (1945): α = 1 → 0.3017, 0.0566; α = 3 → 0.6032, 0.2544.
        let (w, u) = elastica(1.0);
        assert!((w - 0.3017).abs() < 2e-4 && (u - 0.0566).abs() < 2e-4, "{w} {u}");
        let (w, u) = elastica(3.0);
        assert!((w - 0.6032).abs() < 2e-4 && (u - 0.2544).abs() < 2e-4, "{w} {u}");
    }

    /// A soft cantilever (E = 1 MPa, 10-node tets, L/h = 20) under tip loads up to PL²/EI = 3:
    /// the reduced St. Venant–Kirchhoff model on 6 modes and the derivatives of the first 4
    /// against the elastica, with EI taken from the same mesh's linear solve (so that the
    /// comparison measures the reduction and not the mesh's bending error).
    #[test]
    fn soft_cantilever_follows_the_elastica() {
        let (l, cells) = (0.2, [40, 2, 2]);
        let h = l / cells[0] as f64;
        let mesh = Mesh::structured_box(cells, h, Kind::Tet10, |_, p| p);
        let mask: Vec<bool> = mesh.nodes.iter().flat_map(|p| [p[0] < 1e-12; 3]).collect();
        let dofs = crate::fem::Dofs::from_mask(&mask);
        let model = Model::assemble(mesh, dofs, Material::elastic(1.0e6, 0.3, 1000.0)).expect("assembles");
        let space = model.space();
        let (modes, _) = crate::modes::solve(model.space(), 6, SolverChoice::Auto).expect("modes");
        let extra = enrich(&space, &modes, 4, &[]).expect("derivatives");
        let nf = model.dofs.free_count();
        let r = modes.eigenvalues.len() + extra.ritz_values.len();
        let cols: Vec<f64> = modes.vectors.iter().chain(&extra.vectors).copied().collect();
        let full: Vec<f64> = (0..r)
            .flat_map(|j| model.dofs.expand(&cols[j * nf..(j + 1) * nf]))
            .collect();
        let lame = Lame::of(&model.material);
        let points = Points::of(&model.mesh).expect("valid");
        let reduced = stvk::reduce(&points, &model.mesh, &lame, &full, r);
        // Uᵀ K U is diagonal with the eigenvalues and Ritz values.
        let lam: Vec<f64> = modes.eigenvalues.iter().chain(&extra.ritz_values).copied().collect();
        for i in 0..r {
            for j in 0..r {
                let want = if i == j { lam[i] } else { 0.0 };
                assert!((reduced.k[i * r + j] - want).abs() < 1e-6 * lam[r - 1], "K[{i},{j}]");
            }
        }
        // Tip load −z shared equally by the end face's nodes; tip = their mean displacement.
        let end: Vec<usize> = (0..model.mesh.nodes.len())
            .filter(|&n| (model.mesh.nodes[n][0] - l).abs() < 1e-12)
            .collect();
        let n3 = 3 * model.mesh.nodes.len();
        let unit: Vec<f64> = (0..n3)
            .map(|i| {
                if i % 3 == 2 && end.contains(&(i / 3)) {
                    -1.0 / end.len() as f64
                } else {
                    0.0
                }
            })
            .collect();
        let tip = |u: &[f64], c: usize| end.iter().map(|&n| u[3 * n + c]).sum::<f64>() / end.len() as f64;
        // EI of this mesh from its linear static solve.
        let chol = crate::linsolve::factor_stiffness(&model.system, &model.dofs).expect("factor");
        let mut x: Vec<f64> = model.dofs.free.iter().map(|&g| unit[g as usize]).collect();
        chol.solve_many_in_place(&mut x, 1);
        let ei = l.powi(3) / (3.0 * -tip(&model.dofs.expand(&x), 2));
        for alpha in [0.5, 1.0, 2.0, 3.0] {
            let p = alpha * ei / (l * l);
            let g: Vec<f64> = (0..r).map(|j| p * dot(&full[j * n3..(j + 1) * n3], &unit)).collect();
            let eq = reduced.equilibrium(&g, 10).expect("converges");
            let u: Vec<f64> = (0..n3)
                .map(|i| (0..r).map(|j| eq.q[j] * full[j * n3 + i]).sum())
                .collect();
            let (w, s) = (-tip(&u, 2) / l, -tip(&u, 0) / l);
            let (we, se) = elastica(alpha);
            eprintln!(
                "α {alpha}: w/L {w:.4} (elastica {we:.4}, {:+.1} %), shortening/L {s:.4} ({se:.4}, {:+.1} %), linear {:.4}, {} iterations",
                100.0 * (w / we - 1.0),
                100.0 * (s / se - 1.0),
                alpha / 3.0,
                eq.iterations
            );
            assert!(eq.residual < 1e-10);
            assert!((w / we - 1.0).abs() < 0.01, "α {alpha}: tip deflection {w} vs {we}");
            assert!((s / se - 1.0).abs() < 0.02, "α {alpha}: shortening {s} vs {se}");
        }
    }
}
