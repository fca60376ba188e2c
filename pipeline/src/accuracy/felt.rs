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
use rayon::prelude::*;

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
    /// Each sampled point: the scene's `[[probe]]` positions first, then the most compliant,
    /// then spread over the surface.
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
    /// The largest mesh error of the exact compliance over the points where the part is
    /// compliant, and with the static correction over every such vertex too
    /// ([`discretization`]; None when not estimated).
    pub mesh_where_compliant: Option<f64>,
    /// The mesh error over every vertex a hand can touch where the part is compliant (as
    /// `largest_where_compliant`), when the exact compliance is known at each (the static
    /// correction): its median and 90th percentile (None otherwise).
    pub mesh_at_vertices: Option<Spread>,
    /// Seconds this took.
    pub seconds: f64,
    /// What a hand feels wrong at each vertex where it is known (the file's `felt/`): every
    /// vertex a hand can touch with the static correction, the sampled points without.
    #[serde(skip)]
    pub map: Option<ves_format::FeltErrors>,
}

/// A spread of relative errors over vertices.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Spread {
    /// Vertices.
    pub vertices: usize,
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Largest.
    pub largest: f64,
}

impl Spread {
    /// The spread of `values` (None when empty).
    pub fn of(mut values: Vec<f64>) -> Option<Spread> {
        values.sort_by(f64::total_cmp);
        let n = values.len();
        (n > 0).then(|| Spread {
            vertices: n,
            median: values[n / 2],
            p90: values[(9 * n / 10).min(n - 1)],
            largest: values[n - 1],
        })
    }
}

impl FeltTruncation {
    /// One clause for a summary line: "; felt compliance: the 20 modes miss ≤ 2.59 % of it where
    /// the part is compliant, up to 86.83 % at stiff points (24 points; [static_correction]
    /// makes it exact)".
    pub fn text(&self) -> String {
        let mut mesh = self.mesh_where_compliant.map_or(String::new(), |m| {
            format!("; the mesh's own error of it ≤ {:.2} % where compliant", 100.0 * m)
        });
        if let Some(v) = self.mesh_at_vertices {
            mesh += &format!(
                " (at all {} such vertices: median {:.2} %, 90 % of them ≤ {:.2} %)",
                v.vertices,
                100.0 * v.median,
                100.0 * v.p90
            );
        }
        if self.corrected {
            return format!("; felt compliance exact on the mesh (static correction){mesh}");
        }
        format!(
            "; felt compliance: the {} modes miss ≤ {:.2} % of it where the part is compliant, up to {:.2} % at \
             stiff points ({} points; [static_correction] makes it exact){mesh}",
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
    /// The outward surface normal there (for a named point, the direction opposite its probe's
    /// force).
    pub normal: [f64; 3],
    /// The exact compliance along the inward normal, m/N: nᵀ W K⁻¹ Wᵀ n.
    pub exact_m_per_n: f64,
    /// The share of it the modes miss: 1 − nᵀ C_modal n / nᵀ C_exact n.
    pub along_normal: f64,
    /// The largest share in any direction d: max over d of dᵀ(C_exact − C_modal)d / dᵀ C_exact d.
    pub any_direction: f64,
    /// The mesh's own relative error of `exact_m_per_n` (|c_h − c*| / c*), from the same
    /// patch on two coarser meshes ([`discretization`]); None when not estimated.
    pub mesh_error: Option<f64>,
    /// What a hand there feels wrong in all, along the normal: the modes' share and the mesh's
    /// error together, a + e − a·e (a finite-element part is too stiff, and so is a truncated
    /// one: the two add); None when the mesh error is not estimated.
    pub felt_error: Option<f64>,
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
    /// Points to sample first (the scene's `[[probe]]` positions, and the direction opposite
    /// each probe's force): a patch centred on the surface point nearest each, its compliance
    /// along that direction, so two meshes of a part compare at the same places and directions.
    pub first: Vec<([f64; 3], [f64; 3])>,
    /// The contact patch's radius, m (0: a point).
    pub radius: f64,
    /// K's factor when an earlier stage made it (none: made here).
    pub factor: Option<&'a crate::linsolve::Cholesky>,
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
    // W φ: a patch's weighted motion in field φ (free DOFs).
    let weighted = |(nodes, weights): (&[u32], &[f64]), phi: &[f64]| -> Vector3<f64> {
        Vector3::from_fn(|c, _| {
            nodes
                .iter()
                .zip(weights)
                .filter_map(|(&a, &w)| free_of(a, c).map(|f| w * phi[f]))
                .sum()
        })
    };
    // Σⱼ (W φⱼ)(W φⱼ)ᵀ / λⱼ for a patch; with the static correction the runtime adds the rest:
    // what is felt is the exact block.
    let modal = |patch: (&[u32], &[f64])| -> Matrix3<f64> {
        if s.corrected {
            return Matrix3::zeros();
        }
        s.modes
            .eigenvalues
            .iter()
            .enumerate()
            .fold(Matrix3::zeros(), |acc, (j, &l)| {
                let v = weighted(patch, &s.modes.vectors[j * nf..(j + 1) * nf]);
                acc + v * v.transpose() / l
            })
    };
    // The most compliant movable patch, each scored once (by its modal compliance; with the
    // static correction by the first mode's, a cheap proxy).
    let score = |k: usize| -> f64 {
        if s.corrected {
            weighted(patches.patch(k), &s.modes.vectors[..nf]).norm_squared()
        } else {
            modal(patches.patch(k)).trace()
        }
    };
    let softest = movable
        .iter()
        .map(|&k| (k, score(k)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(movable[0], |(k, _)| k);
    let surface = Surface::new(s.mesh);
    let at = |k: usize| s.mesh.nodes[patches.centres[k] as usize];
    let dist2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>();
    // The named points: a patch centred exactly where asked (two meshes compare there), its
    // node and normal those of the nearest movable patch's centre.
    let mut named: Vec<(crate::loads::patch::Patch, u32, [f64; 3])> = Vec::new();
    let mut directions: Vec<[f64; 3]> = Vec::new();
    let mut near: Vec<usize> = Vec::new();
    // At most as many as the points sampled: each costs three solves, and the scene's probe list
    // has no bound of its own.
    for &(p, direction) in s.first.iter().take(SAMPLES) {
        // Spread facing the asked direction, as on the coarser meshes (`discretization`): at an
        // edge the closest triangle alone may be either face's.
        let facing = surface.at_point_facing(p, direction, s.radius);
        let (Some(k), Some((patch, centre))) = (
            movable
                .iter()
                .copied()
                .min_by(|&a, &b| dist2(at(a), p).total_cmp(&dist2(at(b), p))),
            facing.or_else(|| surface.at_point(p, s.radius).map(|(patch, c, _)| (patch, c))),
        ) else {
            continue;
        };
        if patch.nodes.iter().all(|&a| (0..3).all(|c| free_of(a, c).is_some())) {
            named.push((patch, patches.centres[k], centre));
            directions.push(direction);
            near.push(k);
        }
    }
    let sampled = sample(&s.mesh.nodes, patches, &movable, &near, softest);
    let mut chosen: Vec<Chosen<'_>> = named
        .iter()
        .map(|(p, node, at)| Chosen {
            nodes: &p.nodes,
            weights: &p.weights,
            node: *node,
            at: *at,
        })
        .collect();
    for &k in &sampled[near.len()..] {
        let (nodes, weights) = patches.patch(k);
        chosen.push(Chosen {
            nodes,
            weights,
            node: patches.centres[k],
            at: at(k),
        });
    }
    let mut own = None;
    let chol = crate::linsolve::given_or_made(system, s.dofs, s.factor, &mut own)?;
    let list: Vec<(&[u32], &[f64])> = chosen.iter().map(|c| (c.nodes, c.weights)).collect();
    let exact = crate::compliance::patch_blocks(s.dofs, chol, &list, || {})?;
    let points: Vec<FeltPoint> = chosen
        .iter()
        .zip(&exact)
        .enumerate()
        .map(
            |(
                i,
                (
                    &Chosen {
                        nodes,
                        weights,
                        node,
                        at: position,
                    },
                    c,
                ),
            )| {
                let normal = directions.get(i).copied().unwrap_or_else(|| surface.normal_at(node));
                let c = Matrix3::from_fn(|a, b| 0.5 * (c[a][b] + c[b][a]));
                let missed = if s.corrected {
                    Matrix3::zeros()
                } else {
                    c - modal((nodes, weights))
                };
                let n = Vector3::from(normal);
                let exact_n = (n.transpose() * c * n)[0];
                FeltPoint {
                    node,
                    position_m: position,
                    normal,
                    exact_m_per_n: exact_n,
                    along_normal: if exact_n > 0.0 {
                        (n.transpose() * missed * n)[0] / exact_n
                    } else {
                        0.0
                    },
                    any_direction: worst_share(&c, &missed),
                    mesh_error: None,
                    felt_error: None,
                }
            },
        )
        .collect();
    let mut along: Vec<f64> = points.iter().map(|p| p.along_normal).collect();
    along.sort_by(f64::total_cmp);
    let softest = points.iter().map(|p| p.exact_m_per_n).fold(0.0, f64::max);
    Ok(Some(FeltTruncation {
        corrected: s.corrected,
        modes: r,
        largest_where_compliant: points
            .iter()
            .filter(|p| p.exact_m_per_n >= COMPLIANT * softest)
            .map(|p| p.along_normal)
            .fold(0.0, f64::max),
        largest_along_normal: along.last().copied().unwrap_or(0.0),
        median_along_normal: along.get(along.len() / 2).copied().unwrap_or(0.0),
        largest_any_direction: points.iter().map(|p| p.any_direction).fold(0.0, f64::max),
        mesh_where_compliant: None,
        mesh_at_vertices: None,
        points,
        seconds: start.elapsed().as_secs_f64(),
        map: None,
    }))
}

/// A patch sampled: its nodes and weights, the vertex it is told by, and where its centre is.
#[derive(Clone, Copy)]
struct Chosen<'a> {
    nodes: &'a [u32],
    weights: &'a [f64],
    node: u32,
    at: [f64; 3],
}

/// Whether [`discretization`] will mesh the scene's coarser meshes: a held, linear part with a
/// contact patch (a free body has no felt check; a point contact no finite compliance), whose
/// scene asks for error estimates (`mesh.error_estimate = false` asks for none: the mesh error
/// of the felt compliance is one, and its two coarser meshes took 27–50 % of a held corpus
/// part's precompute).
pub fn needs_coarser_meshes(scene: &crate::scene::Scene) -> bool {
    !scene.fixed.is_empty() && scene.nonlinear.is_none() && scene.contact_radius > 0.0 && scene.mesh.error_estimate.on()
}

/// Coarser meshes the mesh error of the felt compliance is read from: each vertex's size times
/// these (as the frequency estimate's, [`super::COARSENING`] and its square).
const COARSER: [f64; 2] = [super::COARSENING, super::COARSENING * super::COARSENING];

/// The exact compliance at every surface vertex (the static correction's blocks): the mesh
/// error is then stated at each vertex a hand can touch, not only at the sampled points.
pub struct Everywhere<'a> {
    /// The blocks, W K⁻¹ Wᵀ for each vertex's contact patch.
    pub compliance: &'a crate::compliance::Compliance,
    /// The contact patches they are for.
    pub patches: &'a Patches,
    /// Which DOFs are held.
    pub dofs: &'a Dofs,
}

/// A place the compliance is compared at on each mesh.
struct Target {
    at: [f64; 3],
    normal: [f64; 3],
    node: u32,
    exact: f64,
}

/// The mesh's own error of each sampled point's exact compliance: the same patch (the scene's
/// contact radius, centred at the point, along the point's direction) on two meshes 1.5× and
/// 2.25× coarser (`size`, the size `mesh` was made at, coarsened as the frequency estimate
/// coarsens it; each vertex's measured size, through a gmsh size field, for a locally refined
/// mesh), and the three compliances extrapolated at their measured
/// rate
/// ([`super::richardson`]; a compliance is an energy, converging as the eigenvalues do); where
/// the patch is smaller than the elements under it, plus the local indentation none of the
/// meshes resolves (Boussinesq's for the patch on a half-space, times 1 − radius/size). Fills
/// each point's `mesh_error` and `felt_error` and the largest where the part is compliant; with
/// `everywhere`, the same at every vertex a hand can touch (`map`, `mesh_at_vertices`), else
/// `map` holds the sampled points.
pub fn discretization(
    scene: &crate::scene::Scene,
    mesh: &Mesh,
    size: f64,
    fine_dofs: usize,
    felt: &mut FeltTruncation,
    everywhere: Option<Everywhere<'_>>,
) -> Result<()> {
    // A point contact's exact compliance is infinite (a point load on a solid): no error to state.
    if felt.points.is_empty() || !needs_coarser_meshes(scene) {
        return Ok(());
    }
    let start = std::time::Instant::now();
    let sizes = super::peak::vertex_sizes(mesh);
    let mut targets: Vec<Target> = felt
        .points
        .iter()
        .map(|p| Target {
            at: p.position_m,
            normal: p.normal,
            node: p.node,
            exact: p.exact_m_per_n,
        })
        .collect();
    if let Some(e) = &everywhere {
        targets.extend(vertex_targets(mesh, e));
    }
    // A mesh of one size (the scene's, or the last of a uniform refinement) is coarsened as the
    // frequency estimate coarsens it (the same meshes: the mesh cache has them when the
    // estimate made them; gmsh meshes a size faster than a size field: the flange's felt check
    // 6.12 → 3.82 s); a locally refined one by each vertex's measured size.
    let graded = scene.mesh.target_error.is_some() && scene.mesh.refinement == crate::scene::Refinement::Local;
    let field = graded.then(|| crate::mesh::field::SizeField::on(mesh, sizes.clone()));
    let mut sized = scene.clone();
    sized.mesh.size = size;
    let mut levels: Vec<(usize, Vec<Option<f64>>)> = Vec::new();
    for factor in COARSER {
        let d = match &field {
            Some(f) => crate::problem::discretize_with(scene, None, Some(&f.scaled(factor)), true)?,
            None => {
                let (at, _, _) = super::coarser(&sized, None, None, factor);
                crate::problem::discretize_with(&at, None, None, true)?
            }
        };
        let surface = Surface::new(&d.mesh);
        // The same patch, centred exactly at each point (a coarser mesh has no vertex there) on
        // the triangles facing the point's way.
        let patches: Vec<Option<crate::loads::patch::Patch>> = targets
            .par_iter()
            .map(|t| {
                surface
                    .at_point_facing(t.at, t.normal, scene.contact_radius)
                    .map(|(patch, _)| patch)
                    .or_else(|| surface.at_point(t.at, scene.contact_radius).map(|(patch, _, _)| patch))
                    .filter(|p| {
                        p.nodes
                            .iter()
                            .all(|&a| (0..3).all(|c| d.dofs.free_of[3 * a as usize + c] != u32::MAX))
                    })
            })
            .collect();
        let chol = factor_stiffness(&d.system, &d.dofs)?;
        let list: Vec<(&[u32], &[f64])> = patches
            .iter()
            .flatten()
            .map(|p| (p.nodes.as_slice(), p.weights.as_slice()))
            .collect();
        let mut blocks = crate::compliance::patch_blocks(&d.dofs, &chol, &list, || {})?.into_iter();
        let along: Vec<Option<f64>> = targets
            .iter()
            .zip(&patches)
            .map(|(t, p)| {
                p.as_ref()?;
                let c = blocks.next()?;
                let n = Vector3::from(t.normal);
                let c = Matrix3::from_fn(|a, b| 0.5 * (c[a][b] + c[b][a]));
                Some((n.transpose() * c * n)[0])
            })
            .collect();
        levels.push((d.dofs.free_count(), along));
    }
    let max_rate = super::max_rate(mesh.kind.order());
    let (e, nu, a) = (scene.material.young, scene.material.poisson, scene.contact_radius);
    let errors: Vec<Option<f64>> = targets
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let mut dofs = vec![fine_dofs];
            let mut values = vec![t.exact];
            for (n, v) in &levels {
                dofs.push(*n);
                values.push(v[i]?);
            }
            // A patch smaller than the elements under it is not resolved by any of the three
            // meshes: its local indentation (a disk of radius a on a half-space, Boussinesq:
            // 2(1 − ν²)/(π E a) at its centre) is missed in the share the elements cannot see,
            // 1 − a/h.
            let h = sizes.get(t.node as usize).copied().unwrap_or(0.0);
            let local = if h > a {
                2.0 * (1.0 - nu * nu) / (std::f64::consts::PI * e * a) * (1.0 - a / h)
            } else {
                0.0
            };
            let unresolved = local / (t.exact + local);
            super::richardson::estimate(&dofs, &values, max_rate).map(|e| e.relative + unresolved)
        })
        .collect();
    let n_points = felt.points.len();
    for (p, e) in felt.points.iter_mut().zip(&errors) {
        p.mesh_error = *e;
        p.felt_error = p.mesh_error.map(|e| p.along_normal + e - p.along_normal * e);
    }
    let softest = felt.points.iter().map(|p| p.exact_m_per_n).fold(0.0, f64::max);
    felt.mesh_where_compliant = felt
        .points
        .iter()
        .filter(|p| p.exact_m_per_n >= COMPLIANT * softest)
        .filter_map(|p| p.mesh_error)
        .reduce(f64::max);
    // Each vertex once, ascending; the sampled points' own values where there are no others.
    let mut known: Vec<(u32, f64, f64, f64)> = match everywhere {
        Some(_) => targets[n_points..]
            .iter()
            .zip(&errors[n_points..])
            .filter_map(|(t, e)| Some((t.node, 0.0, (*e)?, t.exact)))
            .collect(),
        None => felt
            .points
            .iter()
            .filter_map(|p| Some((p.node, p.along_normal, p.mesh_error?, p.exact_m_per_n)))
            .collect(),
    };
    known.sort_by_key(|k| k.0);
    known.dedup_by_key(|k| k.0);
    if everywhere.is_some() {
        // Where the part is compliant, as for the points: at a stiff vertex a hand feels the
        // fingertip's local indentation, which a mesh coarser than the patch does not resolve.
        let softest = known.iter().map(|k| k.3).fold(0.0, f64::max);
        felt.mesh_at_vertices = Spread::of(
            known
                .iter()
                .filter(|k| k.3 >= COMPLIANT * softest)
                .map(|k| k.2)
                .collect(),
        );
        // The largest is then the largest over every such vertex, not over the samples alone.
        if let Some(v) = felt.mesh_at_vertices {
            felt.mesh_where_compliant = Some(felt.mesh_where_compliant.map_or(v.largest, |m| m.max(v.largest)));
        }
    }
    felt.map = Some(ves_format::FeltErrors {
        modes: felt.modes as u32,
        nodes: known.iter().map(|k| k.0).collect(),
        truncation: known.iter().map(|k| k.1).collect(),
        mesh_error: known.iter().map(|k| k.2).collect(),
    });
    felt.seconds += start.elapsed().as_secs_f64();
    Ok(())
}

/// Every vertex whose whole contact patch is free to move, with its exact compliance along its
/// outward normal.
fn vertex_targets(mesh: &Mesh, e: &Everywhere<'_>) -> Vec<Target> {
    let surface = Surface::new(mesh);
    let free = |a: u32| (0..3).all(|c| e.dofs.free_of[3 * a as usize + c] != u32::MAX);
    e.compliance
        .nodes
        .iter()
        .zip(&e.compliance.blocks)
        .filter_map(|(&node, c)| {
            let k = e.patches.centres.binary_search(&node).ok()?;
            let (nodes, _) = e.patches.patch(k);
            if !nodes.iter().all(|&a| free(a)) {
                return None;
            }
            let normal = surface.normal_at(node);
            let n = Vector3::from(normal);
            let c = Matrix3::from_fn(|a, b| 0.5 * (c[a][b] + c[b][a]));
            let exact = (n.transpose() * c * n)[0];
            (exact > 0.0 && n.norm() > 0.5).then(|| Target {
                at: mesh.nodes[node as usize],
                normal,
                node,
                exact,
            })
        })
        .collect()
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

/// [`SAMPLES`] of the patches `candidates` (indices into `patches`): `named` (asked for), then
/// `first` (where the modes make the part softest), then each the candidate farthest from those
/// chosen, so the points spread over the whole surface.
fn sample(nodes: &[[f64; 3]], patches: &Patches, candidates: &[usize], named: &[usize], first: usize) -> Vec<usize> {
    let at = |k: usize| nodes[patches.centres[k] as usize];
    let dist2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>();
    let mut chosen: Vec<usize> = named.to_vec();
    if !chosen.contains(&first) {
        chosen.push(first);
    }
    let mut nearest: Vec<f64> = candidates
        .iter()
        .map(|&k| {
            chosen
                .iter()
                .map(|&c| dist2(at(k), at(c)))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
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
