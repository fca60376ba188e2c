//! Where a mesh's error is, for local refinement: a Zienkiewicz–Zhu indicator per element and
//! mode (the energy of the difference between the recovered vertex stress and the element's own
//! stress), and from it the size field of the next mesh.
//!
//! The indicator only says *where*; *how much* comes from the Richardson estimate of each mode.
//! The next sizes minimise the number of elements Σ V/h'³ subject to every mode's predicted error
//! E_j Σ_e s_ej (h'_e/h_e)^q_j reaching the goal (s_ej: element e's share of mode j's indicated
//! error, q_j: the mode's credited rate): h'_e ∝ (V_e h_e^q / a_e)^(1/(q+3)) with a_e the
//! shares weighted by how far each mode is from the goal.

use crate::fem::element::{Lame, Shape, tet4::Tet4, tet10::Tet10};
use crate::fem::stress::{Corners, Fields, vertex_stress_in_order};
use crate::mesh::field::SizeField;
use crate::tet_mesh::Mesh;
use rayon::prelude::*;

/// A step makes an element at most this many times smaller.
pub const MAX_SHRINK: f64 = 2.0;

/// Part of each mode's share spread evenly by volume: the indicator does not see every error
/// (a wall one element thick bends with little jump in stress between its elements), so no
/// region is left entirely unrefined.
pub const EVEN_SHARE: f64 = 0.2;

/// Per element `e` and field `j`, the share of field `j`'s indicated error in element `e`,
/// row-major [tets, r] (each column sums to 1; an all-zero column when a field has no error).
pub fn shares(mesh: &Mesh, mat: &Lame, u: &Fields) -> Vec<f64> {
    let r = u.r;
    let mut eta = element_energies(mesh, mat, u);
    for j in 0..r {
        let total: f64 = eta.iter().skip(j).step_by(r).sum();
        let inv = if total > 0.0 { 1.0 / total } else { 0.0 };
        eta.iter_mut().skip(j).step_by(r).for_each(|x| *x *= inv);
    }
    eta
}

/// Per element `e` and field `j`, η²_ej (below), row-major [tets, r].
pub fn element_energies(mesh: &Mesh, mat: &Lame, u: &Fields) -> Vec<f64> {
    match mesh.kind {
        crate::fem::element::Kind::Tet4 => element_errors::<Tet4>(mesh, mat, u),
        crate::fem::element::Kind::Tet10 => element_errors::<Tet10>(mesh, mat, u),
    }
}

/// η²_ej = ∫_e (σ* − σ_h) : C⁻¹ : (σ* − σ_h) dV, the difference taken at the corners and
/// interpolated linearly (exact for straight-sided 10-node tets, whose stress is linear).
fn element_errors<S: Shape>(mesh: &Mesh, mat: &Lame, u: &Fields) -> Vec<f64> {
    let r = u.r;
    // Both loops walk the tets in Morton order (their vertices' rows then stay in cache).
    let order = mesh.tets_in_space_order();
    let recovered = vertex_stress_in_order(mesh, mat, u, &order);
    let tets = mesh.tet_count();
    // Compliance form: x : C⁻¹ : y = (x:y − λ/(3λ + 2μ) tr x tr y) / 2μ, Voigt shear counted
    // twice; `form(x, y, j)` of field j of two [6, r] blocks.
    let k = mat.lambda / (3.0 * mat.lambda + 2.0 * mat.mu);
    let inv_2mu = 1.0 / (2.0 * mat.mu);
    let form = |x: &[f64], y: &[f64], j: usize| {
        let c = |i: usize| x[i * r + j] * y[i * r + j];
        let dot = c(0) + c(1) + c(2) + 2.0 * (c(3) + c(4) + c(5));
        let tr = |z: &[f64]| z[j] + z[r + j] + z[2 * r + j];
        (dot - k * tr(x) * tr(y)) * inv_2mu
    };
    let mut eta = vec![0.0; tets * r];
    // Written in that order, each tet's row then put back in place.
    let mut ordered = vec![0.0; tets * r];
    ordered.par_chunks_mut(r.max(1)).zip(order.par_iter()).for_each_init(
        || (Corners::<S>::new(r), vec![0.0; 6 * r], vec![0.0; 6 * r], vec![0.0; r]),
        |(corners, diff, total, own), (out, &e)| {
            let e = e as usize;
            let valid = corners.evaluate(mesh, mat, u, e);
            let t = mesh.tet(e);
            let volume = mesh.corner_volume(e);
            // ∫ of a linear field's product over a tet: V/20 Σ_ab (1 + δ_ab) f_a g_b, which for
            // a bilinear form is V/20 (form(Σ_a f_a, Σ_a f_a) + Σ_a form(f_a, f_a)): five forms,
            // not sixteen. An invalid corner's difference is zero.
            total.fill(0.0);
            own.fill(0.0);
            for c in (0..4).filter(|&c| valid[c]) {
                let v = t[c] as usize;
                let rec = &recovered[6 * v * r..6 * (v + 1) * r];
                diff.iter_mut()
                    .zip(rec.iter().zip(corners.at(c)))
                    .for_each(|(d, (x, s))| *d = x - s);
                total.iter_mut().zip(diff.iter()).for_each(|(t, d)| *t += d);
                for (j, o) in own.iter_mut().enumerate() {
                    *o += form(diff, diff, j);
                }
            }
            for (j, o) in out.iter_mut().enumerate() {
                *o = (volume / 20.0 * (form(total, total, j) + own[j])).max(0.0);
            }
        },
    );
    for (row, &e) in ordered.chunks_exact(r.max(1)).zip(&order) {
        let e = e as usize;
        eta[e * r..(e + 1) * r].copy_from_slice(row);
    }
    eta
}

/// Mean corner-to-corner edge length of tet `e`: its size as meshed.
fn edge_length(mesh: &Mesh, e: usize) -> f64 {
    let t = mesh.tet(e);
    let p = |k: usize| nalgebra::Vector3::from(mesh.nodes[t[k] as usize]);
    [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
        .iter()
        .map(|&(a, b)| (p(a) - p(b)).norm())
        .sum::<f64>()
        / 6.0
}

/// Predicted tets of `mesh`, made at the uniform size `size`, made again at `factor` × `size`,
/// over its own: a tet the size made (as large as it, or larger: gmsh's edges run longer than
/// the size asked) shrinks by `factor`, its count × factor⁻³; a tet smaller than the new size —
/// sized by the part's curvature or a thin wall, not by the size asked — stays; one between
/// shrinks to the new size. A cube law for every tet overstated a part's first step 1.7–3.7×
/// (docs/accuracy.md, "Forecasts of the next mesh").
pub fn uniform_growth(mesh: &Mesh, size: f64, factor: f64) -> f64 {
    let (mut now, mut next) = (0.0, 0.0);
    for e in 0..mesh.tet_count() {
        let (v, h) = (mesh.corner_volume(e), edge_length(mesh, e));
        if h > 0.0 && v.is_finite() {
            let after = if h >= size { h * factor } else { h.min(size * factor) };
            now += v / h.powi(3);
            next += v / after.powi(3);
        }
    }
    if now > 0.0 { next / now } else { 1.0 }
}

/// The next mesh's size field.
pub struct NextField {
    /// Sizes at the corner vertices of the mesh it was made from.
    pub field: SizeField,
    /// Predicted tets of the next mesh over those of this one.
    pub growth: f64,
    /// Per mode, its predicted error on the next mesh.
    pub predicted: Vec<f64>,
}

/// The size field that brings every mode's error (`errors`, at `rates`) to `goal` with the
/// fewest elements, from the indicator `shares` ([tets, r]) of `mesh`. Modes with no finite
/// error are left out; None when no mode has one.
pub fn next_field(mesh: &Mesh, shares: &[f64], errors: &[f64], rates: &[f64], goal: f64) -> Option<NextField> {
    let r = errors.len();
    let tets = mesh.tet_count();
    let modes: Vec<usize> = (0..r).filter(|&j| errors[j].is_finite() && errors[j] > 0.0).collect();
    if modes.is_empty() || tets == 0 {
        return None;
    }
    let volume: Vec<f64> = (0..tets).map(|e| mesh.corner_volume(e)).collect();
    let total_volume: f64 = volume.iter().sum();
    let h: Vec<f64> = (0..tets).map(|e| edge_length(mesh, e)).collect();
    let share = |e: usize, j: usize| (1.0 - EVEN_SHARE) * shares[e * r + j] + EVEN_SHARE * volume[e] / total_volume;
    // The size distribution of the optimum at rate 2 (the largest credited).
    const Q: f64 = 2.0;
    let shape: Vec<f64> = (0..tets)
        .map(|e| {
            let a: f64 = modes.iter().map(|&j| errors[j] / goal * share(e, j)).sum();
            (volume[e] * h[e].powf(Q) / a.max(f64::MIN_POSITIVE)).powf(1.0 / (Q + 3.0))
        })
        .collect();
    let sizes = |k: f64| -> Vec<f64> {
        (0..tets)
            .map(|e| (k * shape[e]).clamp(h[e] / MAX_SHRINK, h[e]))
            .collect()
    };
    let predict = |sized: &[f64]| -> Vec<f64> {
        (0..r)
            .map(|j| {
                if !modes.contains(&j) {
                    return errors[j];
                }
                let q = rates[j].clamp(0.5, 2.0 * Q);
                errors[j] * (0..tets).map(|e| share(e, j) * (sized[e] / h[e]).powf(q)).sum::<f64>()
            })
            .collect()
    };
    let worst = |k: f64| predict(&sizes(k)).into_iter().fold(0.0, f64::max);
    // Bisection on log k: the predicted worst error grows with k.
    let (mut lo, mut hi) = (1e-12_f64.ln(), 1e12_f64.ln());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if worst(mid.exp()) > goal {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let next = sizes(lo.exp());
    let predicted = predict(&next);
    let growth = (0..tets).map(|e| volume[e] / next[e].powi(3)).sum::<f64>()
        / (0..tets).map(|e| volume[e] / h[e].powi(3)).sum::<f64>();
    // A vertex takes the smallest size of its tets: the refined region includes its rim.
    let mut at_vertex = vec![f64::INFINITY; mesh.vertex_count];
    for (e, s) in next.iter().enumerate() {
        for &v in &mesh.tet(e)[..4] {
            at_vertex[v as usize] = at_vertex[v as usize].min(*s);
        }
    }
    // A vertex of no tet (none in gmsh's meshes) keeps a finite size.
    let largest = next.iter().copied().fold(0.0, f64::max);
    at_vertex
        .iter_mut()
        .filter(|s| !s.is_finite())
        .for_each(|s| *s = largest);
    // The sizes as printed: a round-off in the indicator's sums changes no mesh.
    at_vertex
        .iter_mut()
        .for_each(|s| *s = crate::mesh::field::rounded_size(*s));
    Some(NextField {
        field: SizeField::on(mesh, at_vertex),
        growth,
        predicted,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mesh made at the size its tets have grows by the cube of the size ratio; one whose
    /// tets are all far below the size it was asked for (sized by the part, not the size) does
    /// not grow until the new size reaches them; in between, only the tets above the new size
    /// shrink, to it.
    #[test]
    fn a_uniform_step_refines_the_tets_the_size_made() {
        // Graded along x: tets from small to large (a valid map: its Jacobian stays positive).
        let mesh = Mesh::structured_box([8, 2, 2], 0.1, crate::fem::element::Kind::Tet4, |_, p| {
            let s = 1.0 + 2.0 * p[0];
            [p[0] + p[0] * p[0], p[1] * s, p[2] * s]
        });
        let h: Vec<f64> = (0..mesh.tet_count()).map(|e| edge_length(&mesh, e)).collect();
        let (lo, hi) = (
            h.iter().copied().fold(f64::INFINITY, f64::min),
            h.iter().copied().fold(0.0, f64::max),
        );
        assert!(hi > 2.0 * lo, "{lo} {hi}");
        assert!((uniform_growth(&mesh, lo, 0.5) - 8.0).abs() < 1e-9);
        assert!((uniform_growth(&mesh, 10.0 * hi, 0.2) - 1.0).abs() < 1e-12);
        let new = (lo * hi).sqrt();
        let between = uniform_growth(&mesh, 10.0 * hi, new / (10.0 * hi));
        assert!(between > 1.0 && between < 8.0, "{between}");
        let want = {
            let (now, next): (f64, f64) = (0..mesh.tet_count())
                .map(|e| {
                    let v = mesh.corner_volume(e);
                    (v / h[e].powi(3), v / h[e].min(new).powi(3))
                })
                .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
            next / now
        };
        assert!((between - want).abs() < 1e-9 * want, "{between} against {want}");
    }

    /// A field the elements represent exactly has no indicated error; a bending field on 4-node
    /// tets (constant stress per element) has, and most of it where its stress varies fastest.
    #[test]
    fn indicator_is_zero_for_a_representable_field_and_finds_the_gradient() {
        let mat = Lame::new(2.0e11, 0.3, 7800.0);
        let mesh = Mesh::structured_box([4, 2, 2], 0.1, crate::fem::element::Kind::Tet10, |_, p| p);
        // Quadratic displacement: linear strain, exact in 10-node tets.
        let u: Vec<f64> = mesh
            .nodes
            .iter()
            .flat_map(|p| [1e-3 * p[0] * p[1], 1e-3 * p[2] * p[2], 2e-3 * p[0]])
            .collect();
        let eta = element_errors::<Tet10>(&mesh, &mat, &Fields::one(u));
        let energy: f64 = eta.iter().sum();
        assert!(energy < 1e-20, "a representable field shows an error of {energy:e}");

        // u_x = x³ on 4-node tets: the strain 3x² changes fastest at large x.
        let mesh = Mesh::structured_box([8, 1, 1], 0.1, crate::fem::element::Kind::Tet4, |_, p| p);
        let u: Vec<f64> = mesh.nodes.iter().flat_map(|p| [p[0].powi(3), 0.0, 0.0]).collect();
        let s = shares(&mesh, &mat, &Fields::one(u));
        assert!((s.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let centre = |e: usize| mesh.tet(e)[..4].iter().map(|&v| mesh.nodes[v as usize][0]).sum::<f64>() / 4.0;
        let (near, far): (Vec<usize>, Vec<usize>) = (0..mesh.tet_count()).partition(|&e| centre(e) < 0.4);
        let sum = |set: &[usize]| set.iter().map(|&e| s[e]).sum::<f64>();
        assert!(
            sum(&far) > 3.0 * sum(&near),
            "share at large x {} vs small x {}",
            sum(&far),
            sum(&near)
        );
    }

    /// The field meets the goal as predicted, refines where the shares are, and never asks an
    /// element to grow or to shrink by more than MAX_SHRINK.
    #[test]
    fn next_field_refines_where_the_error_is_and_meets_the_goal() {
        let mesh = Mesh::structured_box([8, 1, 1], 0.1, crate::fem::element::Kind::Tet10, |_, p| p);
        let tets = mesh.tet_count();
        // All of the indicated error in the tets beyond x = 0.6.
        let hot: Vec<bool> = (0..tets)
            .map(|e| {
                mesh.tet(e)[..4]
                    .iter()
                    .all(|&v| mesh.nodes[v as usize][0] >= 0.6 - 1e-12)
            })
            .collect();
        let n_hot = hot.iter().filter(|&&x| x).count() as f64;
        let shares: Vec<f64> = hot.iter().map(|&x| if x { 1.0 / n_hot } else { 0.0 }).collect();
        let next = next_field(&mesh, &shares, &[0.02], &[2.0], 0.007).expect("a field");
        assert!(
            (next.predicted[0] - 0.007).abs() < 1e-6,
            "predicted {:?}",
            next.predicted
        );
        let h = 0.1 * (3.0 + 2.0 * 2f64.sqrt() + 3f64.sqrt()) / 6.0; // mean edge of these tets
        for (v, p) in next.field.points.iter().enumerate() {
            let s = next.field.sizes[v];
            assert!(
                s <= h * (1.0 + 1e-9) && s >= h / MAX_SHRINK * (1.0 - 1e-9),
                "size {s} at {p:?}"
            );
        }
        let mean = |f: &dyn Fn(f64) -> bool| {
            let (sum, n) = next
                .field
                .points
                .iter()
                .zip(&next.field.sizes)
                .filter(|(p, _)| f(p[0]))
                .fold((0.0, 0), |(s, n), (_, z)| (s + z, n + 1));
            sum / n as f64
        };
        assert!(
            mean(&|x| x > 0.65) < 0.7 * mean(&|x| x < 0.35),
            "hot {} cold {}",
            mean(&|x| x > 0.65),
            mean(&|x| x < 0.35)
        );
        assert!(next.growth > 1.0);
    }
}
