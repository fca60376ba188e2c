//! The error of what is felt: how much of the part's true static compliance at a contact patch
//! the kept modes miss. A hand feels W Φ Λ⁻¹ Φᵀ Wᵀ (the modal compliance of its patch, W the
//! patch's weights) where the part has W K⁻¹ Wᵀ; the difference is the modes left out, always
//! positive (K⁻¹ = Σ over every mode of φφᵀ/λ), so the modal part always feels stiffer than it
//! is. On the mesh itself this is exact and cheap: one factorisation of K and three solves per
//! point, at points sampled over the surface. It is the modal truncation only — the mesh's own
//! error adds to it (the frequency estimate speaks of that) — and it is zero where the static
//! correction is stored, which adds the missing part at every vertex.

use crate::fem::{Assembled, Dofs};
use crate::linsolve::factor_stiffness;
use crate::loads::patch::{Patches, Surface};
use crate::modes::Modes;
use crate::tet_mesh::Mesh;
use anyhow::Result;
use nalgebra::{Matrix3, Vector3};

/// Points sampled: spread over the surface, the most compliant first.
const SAMPLES: usize = 24;

/// A point is where the part is compliant when its exact compliance is at least this share of
/// the most compliant point's. Elsewhere a hand feels the coupling, not the part: on the
/// ribplate held by its base, the plate's top misses 100 % of 2.6e-8 m/N (the local
/// indentation no mode carries) beside 3.8e-6 m/N at the rib's tip, where 30 modes miss 2.9 %.
const COMPLIANT: f64 = 0.01;

/// The felt compliance's modal truncation at sampled surface points.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FeltTruncation {
    /// The static correction is stored: the felt compliance is the exact W K⁻¹ Wᵀ at every
    /// vertex, whatever the modes (no points are sampled).
    pub corrected: bool,
    /// The modes kept.
    pub modes: usize,
    /// Each sampled point, the most compliant first.
    pub points: Vec<FeltPoint>,
    /// The largest relative error along the surface normal over the points where the part is
    /// compliant (exact compliance at least [`COMPLIANT`] of the largest sampled): what a hand
    /// feels the part miss (0 when corrected).
    pub largest_where_compliant: f64,
    /// The largest relative error along the surface normal over all the points (0 when corrected).
    pub largest_along_normal: f64,
    /// The median of the same.
    pub median_along_normal: f64,
    /// The largest relative error in any direction over the points.
    pub largest_any_direction: f64,
    /// Seconds this took.
    pub seconds: f64,
}

impl FeltTruncation {
    /// One clause for a summary line: "; felt compliance: the 20 modes miss ≤ 2.59 % of it where
    /// the part is compliant, up to 86.83 % at stiff points (24 points; [static_correction]
    /// makes it exact)".
    pub fn text(&self) -> String {
        if self.corrected {
            return "; felt compliance exact (static correction)".into();
        }
        format!(
            "; felt compliance: the {} modes miss ≤ {:.2} % of it where the part is compliant, up to {:.2} % at \
             stiff points ({} points; [static_correction] makes it exact)",
            self.modes,
            100.0 * self.largest_where_compliant,
            100.0 * self.largest_along_normal,
            self.points.len()
        )
    }
}

/// One sampled contact patch.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FeltPoint {
    /// Its centre vertex (node index).
    pub node: u32,
    /// Where that is, m.
    pub position_m: [f64; 3],
    /// The outward surface normal there.
    pub normal: [f64; 3],
    /// The exact compliance along the inward normal, m/N: nᵀ W K⁻¹ Wᵀ n.
    pub exact_m_per_n: f64,
    /// The share of it the modes miss: 1 − nᵀ C_modal n / nᵀ C_exact n.
    pub along_normal: f64,
    /// The largest share in any direction d: max over d of dᵀ(C_exact − C_modal)d / dᵀ C_exact d.
    pub any_direction: f64,
}

/// A held space's modes and what they are measured against.
pub struct Space<'a> {
    /// Its mesh.
    pub mesh: &'a Mesh,
    /// Its DOFs (which are held).
    pub dofs: &'a Dofs,
    /// Its K and M.
    pub system: &'a Assembled,
    /// Its modes (no rigid ones).
    pub modes: &'a Modes,
    /// The hand's contact patches (none: each vertex alone).
    pub contact: Option<&'a Patches>,
    /// The static correction is stored.
    pub corrected: bool,
}

/// The felt compliance's truncation of space `s` (its modes and K); None for a free body (its
/// K is singular: what a hand feels there is the rigid motion) or a part without a movable
/// surface vertex.
pub fn truncation(s: &Space<'_>) -> Result<Option<FeltTruncation>> {
    let start = std::time::Instant::now();
    let system = s.system;
    if s.modes.rigid_dropped > 0 {
        return Ok(None);
    }
    let r = s.modes.eigenvalues.len();
    if s.corrected {
        return Ok(Some(FeltTruncation {
            corrected: true,
            modes: r,
            points: Vec::new(),
            largest_where_compliant: 0.0,
            largest_along_normal: 0.0,
            median_along_normal: 0.0,
            largest_any_direction: 0.0,
            seconds: start.elapsed().as_secs_f64(),
        }));
    }
    let point_patches;
    let patches: &Patches = match s.contact {
        Some(p) => p,
        None => {
            point_patches = crate::loads::patch::vertex_patches(s.mesh, 0.0, |_| true);
            &point_patches
        }
    };
    let nf = s.dofs.free_count();
    let free_of = |node: u32, c: usize| match s.dofs.free_of[3 * node as usize + c] {
        u32::MAX => None,
        f => Some(f as usize),
    };
    // A patch touching a held component is not a place a hand feels anything but the support.
    let movable: Vec<usize> = (0..patches.centres.len())
        .filter(|&k| {
            let (nodes, _) = patches.patch(k);
            nodes.iter().all(|&a| (0..3).all(|c| free_of(a, c).is_some()))
        })
        .collect();
    if movable.is_empty() || r == 0 {
        return Ok(None);
    }
    // Σⱼ (W φⱼ)(W φⱼ)ᵀ / λⱼ for patch k.
    let modal = |k: usize| -> Matrix3<f64> {
        let (nodes, weights) = patches.patch(k);
        s.modes
            .eigenvalues
            .iter()
            .enumerate()
            .fold(Matrix3::zeros(), |acc, (j, &l)| {
                let phi = &s.modes.vectors[j * nf..(j + 1) * nf];
                let v = Vector3::from_fn(|c, _| {
                    nodes
                        .iter()
                        .zip(weights)
                        .filter_map(|(&a, &w)| free_of(a, c).map(|f| w * phi[f]))
                        .sum()
                });
                acc + v * v.transpose() / l
            })
    };
    // The most compliant movable patch, each scored once.
    let softest = movable
        .iter()
        .map(|&k| (k, modal(k).trace()))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(movable[0], |(k, _)| k);
    let chosen = sample(&s.mesh.nodes, patches, &movable, softest);
    let chol = factor_stiffness(system, s.dofs)?;
    let list: Vec<(&[u32], &[f64])> = chosen.iter().map(|&k| patches.patch(k)).collect();
    let exact = crate::compliance::patch_blocks(s.dofs, &chol, &list, || {})?;
    let surface = Surface::new(s.mesh);
    let points: Vec<FeltPoint> = chosen
        .iter()
        .zip(&exact)
        .map(|(&k, c)| {
            let node = patches.centres[k];
            let normal = surface.normal_at(node);
            let c = Matrix3::from_fn(|a, b| 0.5 * (c[a][b] + c[b][a]));
            let missed = c - modal(k);
            let n = Vector3::from(normal);
            let exact_n = (n.transpose() * c * n)[0];
            FeltPoint {
                node,
                position_m: s.mesh.nodes[node as usize],
                normal,
                exact_m_per_n: exact_n,
                along_normal: if exact_n > 0.0 {
                    (n.transpose() * missed * n)[0] / exact_n
                } else {
                    0.0
                },
                any_direction: worst_share(&c, &missed),
            }
        })
        .collect();
    let mut along: Vec<f64> = points.iter().map(|p| p.along_normal).collect();
    along.sort_by(f64::total_cmp);
    let softest = points.iter().map(|p| p.exact_m_per_n).fold(0.0, f64::max);
    Ok(Some(FeltTruncation {
        corrected: false,
        modes: r,
        largest_where_compliant: points
            .iter()
            .filter(|p| p.exact_m_per_n >= COMPLIANT * softest)
            .map(|p| p.along_normal)
            .fold(0.0, f64::max),
        largest_along_normal: along.last().copied().unwrap_or(0.0),
        median_along_normal: along.get(along.len() / 2).copied().unwrap_or(0.0),
        largest_any_direction: points.iter().map(|p| p.any_direction).fold(0.0, f64::max),
        points,
        seconds: start.elapsed().as_secs_f64(),
    }))
}

/// The largest eigenvalue of C⁻¹ᐟ² D C⁻¹ᐟ² (C the exact block, positive definite at a movable
/// patch; D what the modes miss): the largest share of the compliance they miss in any
/// direction. 0 when C is not positive definite.
fn worst_share(c: &Matrix3<f64>, missed: &Matrix3<f64>) -> f64 {
    let Some(l) = c.cholesky() else { return 0.0 };
    let Some(inv) = l.l().try_inverse() else { return 0.0 };
    let m = inv * missed * inv.transpose();
    let m = 0.5 * (m + m.transpose());
    m.symmetric_eigenvalues().max()
}

/// [`SAMPLES`] of the patches `candidates` (indices into `patches`): `first` (where the modes
/// make the part softest), then each the candidate farthest from those chosen, so the points
/// spread over the whole surface.
fn sample(nodes: &[[f64; 3]], patches: &Patches, candidates: &[usize], first: usize) -> Vec<usize> {
    let at = |k: usize| nodes[patches.centres[k] as usize];
    let dist2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>();
    let mut chosen = vec![first];
    let mut nearest: Vec<f64> = candidates.iter().map(|&k| dist2(at(k), at(first))).collect();
    while chosen.len() < SAMPLES.min(candidates.len()) {
        let (i, _) = nearest
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap_or((0, &0.0));
        let k = candidates[i];
        chosen.push(k);
        for (d, &c) in nearest.iter_mut().zip(candidates) {
            *d = d.min(dist2(at(c), at(k)));
        }
    }
    chosen
}
