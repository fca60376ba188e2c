//! Nodal load vectors of a load case: the consistent (work-equivalent) nodal forces of a traction
//! on surface triangles, and of gravity through the consistent mass.
//!
//! A traction t on a surface triangle loads node a with ∫ N_a t dA, N_a the triangle's shape
//! functions: the 3-node triangle of a 4-node tet's face, or the 6-node triangle of a 10-node
//! tet's face (whose corners then carry nothing of a uniform traction on a flat triangle and the
//! mid-edge nodes a third each). The integral is taken on the triangle's own (possibly curved)
//! geometry with a degree-4 rule, exact for the product of a quadratic shape function and the
//! quadratic area element of a curved 6-node triangle.

use crate::fem::element::{self, Kind, Lame, Shape, tet4::Tet4, tet10::Tet10};
use crate::scene::{Applied, LoadCase};
use crate::tet_mesh::{Mesh, TET10_EDGES};
use rayon::prelude::*;
use std::collections::HashMap;

/// Dunavant's 6-point degree-4 rule on the reference triangle: (ξ, η, weight), weights summing
/// to 1 (times the reference area ½ when integrating).
pub(crate) const TRIANGLE_RULE: [(f64, f64, f64); 6] = [
    (0.445_948_490_915_965, 0.445_948_490_915_965, 0.223_381_589_678_011),
    (0.445_948_490_915_965, 0.108_103_018_168_070, 0.223_381_589_678_011),
    (0.108_103_018_168_070, 0.445_948_490_915_965, 0.223_381_589_678_011),
    (0.091_576_213_509_771, 0.091_576_213_509_771, 0.109_951_743_655_322),
    (0.091_576_213_509_771, 0.816_847_572_980_459, 0.109_951_743_655_322),
    (0.816_847_572_980_459, 0.091_576_213_509_771, 0.109_951_743_655_322),
];

/// Radon's 7-point degree-5 rule on the reference triangle, as [`TRIANGLE_RULE`]: exact for a
/// flat triangle's quartic pressure times its linear shape functions (a contact patch's
/// triangle wholly inside the patch).
pub(crate) const DEGREE_5_RULE: [(f64, f64, f64); 7] = [
    (1.0 / 3.0, 1.0 / 3.0, 0.225),
    (
        0.101_286_507_323_456_3,
        0.101_286_507_323_456_3,
        0.125_939_180_544_827_2,
    ),
    (
        0.797_426_985_353_087_3,
        0.101_286_507_323_456_3,
        0.125_939_180_544_827_2,
    ),
    (
        0.101_286_507_323_456_3,
        0.797_426_985_353_087_3,
        0.125_939_180_544_827_2,
    ),
    (0.470_142_064_105_115, 0.470_142_064_105_115, 0.132_394_152_788_506_2),
    (0.059_715_871_789_769_9, 0.470_142_064_105_115, 0.132_394_152_788_506_2),
    (0.470_142_064_105_115, 0.059_715_871_789_769_9, 0.132_394_152_788_506_2),
];

/// One surface triangle's nodes: its three corners and, with 10-node tets, the mid-edge nodes of
/// its edges (0,1), (1,2), (2,0).
type TriangleNodes = Vec<u32>;

/// The nodes of surface triangles `picked` (indices into `mesh.surface`).
pub(crate) fn triangle_nodes(mesh: &Mesh, picked: &[usize]) -> Vec<TriangleNodes> {
    let corners = picked.iter().map(|&t| mesh.surface[t]);
    if mesh.kind == Kind::Tet4 {
        return corners.map(|c| c.to_vec()).collect();
    }
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut mid: HashMap<(u32, u32), u32> = picked
        .iter()
        .flat_map(|&t| {
            let f = mesh.surface[t];
            [key(f[0], f[1]), key(f[1], f[2]), key(f[2], f[0])]
        })
        .map(|e| (e, u32::MAX))
        .collect();
    let mut left = mid.len();
    for e in 0..mesh.tet_count() {
        let t = mesh.tet(e);
        for (k, (a, b)) in TET10_EDGES.iter().enumerate() {
            if let Some(m) = mid.get_mut(&key(t[*a], t[*b]))
                && *m == u32::MAX
            {
                *m = t[4 + k];
                left -= 1;
            }
        }
        if left == 0 {
            break;
        }
    }
    corners
        .map(|f| {
            let mut nodes = f.to_vec();
            for (a, b) in [(0, 1), (1, 2), (2, 0)] {
                nodes.push(mid[&key(f[a], f[b])]);
            }
            nodes
        })
        .collect()
}

/// Shape functions of a 3- or 6-node triangle at (ξ, η), and their derivatives in ξ and η.
/// In arrays of six (zeros past a 3-node triangle's three): a contact patch evaluates this at
/// every quadrature point of every cell, and two vectors allocated per point were a third of
/// that stage.
fn triangle_shape(nodes: usize, xi: f64, eta: f64) -> ([f64; 6], [[f64; 2]; 6]) {
    let l = [1.0 - xi - eta, xi, eta];
    let dl = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
    let mut n = [0.0; 6];
    let mut d = [[0.0; 2]; 6];
    if nodes == 3 {
        n[..3].copy_from_slice(&l);
        d[..3].copy_from_slice(&dl);
        return (n, d);
    }
    for i in 0..3 {
        n[i] = l[i] * (2.0 * l[i] - 1.0);
        d[i] = dl[i].map(|g| (4.0 * l[i] - 1.0) * g);
    }
    for (k, (a, b)) in [(0, 1), (1, 2), (2, 0)].into_iter().enumerate() {
        n[3 + k] = 4.0 * l[a] * l[b];
        d[3 + k] = [0, 1].map(|c| 4.0 * (l[b] * dl[a][c] + l[a] * dl[b][c]));
    }
    (n, d)
}

/// The area vector ∂x/∂ξ × ∂x/∂η of a triangle at (ξ, η) (outward for a surface triangle) and
/// its shape function values there (the first `x.len()` of six).
pub(crate) fn area_vector(x: &[[f64; 3]], xi: f64, eta: f64) -> ([f64; 3], [f64; 6]) {
    let (n, d) = triangle_shape(x.len(), xi, eta);
    let mut g = [[0.0; 3]; 2];
    for (xa, da) in x.iter().zip(&d) {
        for k in 0..2 {
            for c in 0..3 {
                g[k][c] += da[k] * xa[c];
            }
        }
    }
    let v = [
        g[0][1] * g[1][2] - g[0][2] * g[1][1],
        g[0][2] * g[1][0] - g[0][0] * g[1][2],
        g[0][0] * g[1][1] - g[0][1] * g[1][0],
    ];
    (v, n)
}

/// `each(a, w·N_a, n dA)` at every quadrature point of a triangle, `w` the rule's weight times
/// the reference area and `n dA` the outward area vector there.
fn integrate(x: &[[f64; 3]], mut each: impl FnMut(usize, f64, [f64; 3])) {
    for (xi, eta, w) in TRIANGLE_RULE {
        let (da, n) = area_vector(x, xi, eta);
        for (a, na) in n.iter().take(x.len()).enumerate() {
            each(a, 0.5 * w * na, da);
        }
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The area of a 3- or 6-node triangle (curved when its mid-edge nodes are off the chords).
fn triangle_area(x: &[[f64; 3]]) -> f64 {
    TRIANGLE_RULE
        .iter()
        .map(|&(xi, eta, w)| 0.5 * w * norm(area_vector(x, xi, eta).0))
        .sum()
}

/// A surface load: a total force spread in proportion to area, or a pressure.
#[derive(Clone, Copy, Debug)]
pub enum Traction {
    /// Total force, N.
    Force([f64; 3]),
    /// Pressure, Pa, along the inward normal.
    Pressure(f64),
}

/// The consistent nodal loads (3n, N) of a traction on surface triangles `picked` (indices into
/// `mesh.surface`).
pub fn surface_loads(mesh: &Mesh, picked: &[usize], traction: Traction) -> Vec<f64> {
    let ids = triangle_nodes(mesh, picked);
    let tris: Vec<Vec<[f64; 3]>> = ids
        .iter()
        .map(|t| t.iter().map(|&v| mesh.nodes[v as usize]).collect())
        .collect();
    let mut f = vec![0.0; 3 * mesh.nodes.len()];
    // Per unit area: the force over the region's (curved) area, or −p n.
    let per_area = |da: [f64; 3]| -> [f64; 3] {
        match traction {
            Traction::Force(_) => [0.0; 3],
            Traction::Pressure(p) => da.map(|c| -p * c),
        }
    };
    let spread = match traction {
        Traction::Force(total) => {
            let area: f64 = tris.iter().map(|x| triangle_area(x)).sum();
            Some(total.map(|c| c / area))
        }
        Traction::Pressure(_) => None,
    };
    for (x, t) in tris.iter().zip(&ids) {
        integrate(x, |a, w, da| {
            let load = match spread {
                Some(t) => t.map(|c| c * norm(da)),
                None => per_area(da),
            };
            let node = t[a] as usize;
            for c in 0..3 {
                f[3 * node + c] += w * load[c];
            }
        });
    }
    f
}

/// The nodal loads (3n, N) of a uniform acceleration `g` (m/s²) through the consistent mass:
/// node a of each element gets Σ_b M_ab g.
pub fn gravity_loads(mesh: &Mesh, lame: &Lame, g: [f64; 3]) -> Result<Vec<f64>, element::BadJacobian> {
    match mesh.kind {
        Kind::Tet4 => gravity_with::<Tet4>(mesh, lame, g),
        Kind::Tet10 => gravity_with::<Tet10>(mesh, lame, g),
    }
}

fn gravity_with<S: Shape>(mesh: &Mesh, lame: &Lame, g: [f64; 3]) -> Result<Vec<f64>, element::BadJacobian> {
    let p = S::NODES;
    sum_over_elements::<S>(mesh, lame, 1, |t, em, f| {
        for a in 0..p {
            let row: f64 = em.m[a * p..(a + 1) * p].iter().sum();
            for c in 0..3 {
                f[3 * t[a] as usize + c] += row * g[c];
            }
        }
    })
}

/// Σₑ of what `add` makes of each element's matrices, into `width` vectors over every DOF side
/// by side (`width · 3·nodes` values): one partial per thread over a fixed share of the
/// elements, summed in a fixed order, so a run's sums are the next run's to the last bit.
fn sum_over_elements<S: Shape>(
    mesh: &Mesh,
    lame: &Lame,
    width: usize,
    add: impl Fn(&[u32], &element::ElementMatrices, &mut [f64]) + Sync,
) -> Result<Vec<f64>, element::BadJacobian> {
    let len = width * 3 * mesh.nodes.len();
    let ne = mesh.tet_count();
    let chunks = rayon::current_num_threads().clamp(1, ne.max(1));
    let per = ne.div_ceil(chunks);
    let partials = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut f = crate::memory::written_zeros(len);
            for e in c * per..((c + 1) * per).min(ne) {
                let t = mesh.tet(e);
                let x: Vec<[f64; 3]> = t.iter().map(|&v| mesh.nodes[v as usize]).collect();
                add(t, &element::element_matrices::<S>(&x, lame)?, &mut f);
            }
            Ok(f)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut partials = partials.into_iter();
    let mut total = partials.next().unwrap_or_else(|| vec![0.0; len]);
    for p in partials {
        total.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
    }
    Ok(total)
}

/// K u over all DOFs, supported ones included, element by element (the assembled K holds the
/// free DOFs only): at a supported DOF, minus the applied load, it is the support's reaction.
pub fn internal_forces(mesh: &Mesh, lame: &Lame, u: &[f64]) -> Result<Vec<f64>, element::BadJacobian> {
    internal_forces_many(mesh, lame, &[u])
}

/// [`internal_forces`] of several fields (each `3·nodes` long) at once, side by side in the
/// result (field j at `j·3·nodes ..`): each element's matrices made once for all of them, not
/// once per field (a basis's modal reactions made them again for each of its modes).
pub fn internal_forces_many(mesh: &Mesh, lame: &Lame, us: &[&[f64]]) -> Result<Vec<f64>, element::BadJacobian> {
    match mesh.kind {
        Kind::Tet4 => internal_with::<Tet4>(mesh, lame, us),
        Kind::Tet10 => internal_with::<Tet10>(mesh, lame, us),
    }
}

fn internal_with<S: Shape>(mesh: &Mesh, lame: &Lame, us: &[&[f64]]) -> Result<Vec<f64>, element::BadJacobian> {
    let (p3, r) = (3 * S::NODES, us.len());
    // The fields interleaved DOF by DOF (field j of DOF i at i·r + j), the sums too: an element
    // reads and adds each of its DOFs' values of every field in one contiguous row. Side by
    // side it touched 2·r scattered places per DOF: 0.39 s of the ribplate's 0.42 s reactions
    // stage (30 modes, 26k tets at the held face).
    let u = crate::fem::stress::Fields::from_each(us).values;
    let sums = sum_over_elements::<S>(mesh, lame, r, |t, em, f| {
        let dof = |i: usize| 3 * t[i / 3] as usize + i % 3;
        for i in 0..p3 {
            let row = &em.k[i * p3..(i + 1) * p3];
            let out = &mut f[dof(i) * r..(dof(i) + 1) * r];
            for (k, &kik) in row.iter().enumerate() {
                let uk = &u[dof(k) * r..(dof(k) + 1) * r];
                out.iter_mut().zip(uk).for_each(|(o, v)| *o += kik * v);
            }
        }
    })?;
    // Side by side again, as the callers take them.
    Ok(crate::fem::stress::Fields { values: sums, r }.side_by_side())
}

/// A load case that cannot be applied to the mesh.
#[derive(Debug, thiserror::Error)]
pub enum LoadCaseError {
    /// Its surface region selects nothing or names an unknown face.
    #[error(transparent)]
    Region(#[from] crate::supports::RegionError),
    /// Gravity met an element with a non-positive Jacobian.
    #[error("{key}: an element is degenerate (det J = {det:.3e})")]
    Degenerate {
        /// The scene entry (`gravity`).
        key: String,
        /// The element's Jacobian determinant.
        det: f64,
    },
}

/// The nodal loads of a load case (3n, N); `key` names its scene entry in errors.
pub fn nodal_loads(mesh: &Mesh, lame: &Lame, case: &LoadCase, key: &str) -> Result<Vec<f64>, LoadCaseError> {
    match &case.applied {
        Applied::Force { region, total } => {
            let picked = crate::supports::region_triangles(mesh, key, region)?;
            Ok(surface_loads(mesh, &picked, Traction::Force(*total)))
        }
        Applied::Pressure { region, pascal } => {
            let picked = crate::supports::region_triangles(mesh, key, region)?;
            Ok(surface_loads(mesh, &picked, Traction::Pressure(*pascal)))
        }
        Applied::Gravity { acceleration } => {
            gravity_loads(mesh, lame, *acceleration).map_err(|e| LoadCaseError::Degenerate {
                key: key.to_string(),
                det: e.det,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    /// Each rule integrates every monomial ξ^i η^j up to its degree exactly over the reference
    /// triangle (∫ = i! j! / (i + j + 2)!), and not one degree beyond.
    #[test]
    fn triangle_rules_are_exact_to_their_degree() {
        let fact = |n: u32| (1..=n).map(f64::from).product::<f64>();
        let error = |rule: &[(f64, f64, f64)], i: u32, j: u32| {
            let q: f64 = rule
                .iter()
                .map(|&(x, y, w)| 0.5 * w * x.powi(i as i32) * y.powi(j as i32))
                .sum();
            (q - fact(i) * fact(j) / fact(i + j + 2)).abs()
        };
        for (rule, degree) in [(&super::TRIANGLE_RULE[..], 4), (&super::DEGREE_5_RULE[..], 5)] {
            for i in 0..=degree {
                for j in 0..=degree - i {
                    assert!(
                        error(rule, i, j) < 1e-15,
                        "degree {degree}: ξ^{i} η^{j} off by {:e}",
                        error(rule, i, j)
                    );
                }
            }
            let beyond = (0..=degree + 1)
                .map(|i| error(rule, i, degree + 1 - i))
                .fold(0.0, f64::max);
            assert!(
                beyond > 1e-8,
                "degree {degree} rule exact beyond its degree ({beyond:e})"
            );
        }
    }

    use super::*;

    /// A unit cube of 2 × 2 × 2 cells, as 4- or 10-node tets.
    fn cube(kind: Kind) -> Mesh {
        Mesh::structured_box([2, 2, 2], 0.5, kind, |_, p| p)
    }

    fn totals(f: &[f64]) -> [f64; 3] {
        let mut t = [0.0; 3];
        for (i, v) in f.iter().enumerate() {
            t[i % 3] += v;
        }
        t
    }

    /// A force on the face x = 1 sums to the force; on a flat 6-node triangle the corners carry
    /// nothing and each mid-edge node a third of the triangle's share.
    #[test]
    fn a_face_force_sums_to_the_force_and_follows_the_shape_functions() {
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = cube(kind);
            let picked: Vec<usize> = (0..mesh.surface.len())
                .filter(|&t| {
                    mesh.surface[t]
                        .iter()
                        .all(|&v| (mesh.nodes[v as usize][0] - 1.0).abs() < 1e-12)
                })
                .collect();
            assert!(!picked.is_empty());
            let f = surface_loads(&mesh, &picked, Traction::Force([0.0, 0.0, -6.0]));
            let t = totals(&f);
            assert!((t[2] + 6.0).abs() < 1e-12 && t[0].abs() < 1e-14, "{kind:?}: {t:?}");
            if kind == Kind::Tet10 {
                for v in 0..mesh.vertex_count {
                    assert!(f[3 * v + 2].abs() < 1e-12, "corner {v} loaded: {}", f[3 * v + 2]);
                }
            }
            // A pressure of 1 Pa on the same unit face: 1 N along −x (into the part).
            let p = totals(&surface_loads(&mesh, &picked, Traction::Pressure(1.0)));
            assert!((p[0] + 1.0).abs() < 1e-12 && p[1].abs() < 1e-14, "{kind:?}: {p:?}");
        }
    }

    /// Several fields at once give each field's own element forces to the last bit (the same
    /// sums in the same order).
    #[test]
    fn many_fields_at_once_are_each_field_alone() {
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = cube(kind);
            let lame = Lame::new(2.0e11, 0.3, 7850.0);
            let n3 = 3 * mesh.nodes.len();
            let fields: Vec<Vec<f64>> = (0..3)
                .map(|j| (0..n3).map(|i| ((i * 7 + j * 13) % 11) as f64 * 1e-4 - 5e-4).collect())
                .collect();
            let refs: Vec<&[f64]> = fields.iter().map(Vec::as_slice).collect();
            let together = internal_forces_many(&mesh, &lame, &refs).unwrap();
            assert_eq!(together.len(), 3 * n3);
            for (u, f) in fields.iter().zip(together.chunks(n3)) {
                assert_eq!(f, internal_forces(&mesh, &lame, u).unwrap(), "{kind:?}");
            }
            assert!(
                together[..n3].iter().any(|v| v.abs() > 1.0),
                "{kind:?}: a field that strains"
            );
        }
    }

    /// Gravity loads sum to the mass times g; a rigid translation has no internal force.
    #[test]
    fn gravity_sums_to_mass_times_g_and_translation_is_free_of_stress() {
        for kind in [Kind::Tet4, Kind::Tet10] {
            let mesh = cube(kind);
            let lame = Lame::new(2.0e11, 0.3, 7850.0);
            let t = totals(&gravity_loads(&mesh, &lame, [0.0, 0.0, -9.81]).unwrap());
            assert!((t[2] + 7850.0 * 9.81).abs() < 1e-9 * 7850.0 * 9.81, "{kind:?}: {t:?}");
            let u: Vec<f64> = (0..3 * mesh.nodes.len()).map(|i| [1e-3, -2e-3, 5e-4][i % 3]).collect();
            let k_u = internal_forces(&mesh, &lame, &u).unwrap();
            let scale = 2.0e11 * 1e-3;
            assert!(k_u.iter().all(|v| v.abs() < 1e-9 * scale), "{kind:?}");
        }
    }
}
