//! The error of a load case's peak stress, from the mesh refined around it.
//!
//! A peak is where a mesh is least converged, and where it may not converge at all: at a
//! re-entrant edge or a support's edge the exact stress is infinite, and each refinement finds
//! more. Neither the frequency estimate nor a recovery estimate tells which, so each case's peaks
//! are solved again on two meshes whose element size around them is halved, then quartered
//! (the rest of the part as it was), and the three values judged by their successive changes
//! d₁ = σ₁ − σ₀, d₂ = σ₂ − σ₁:
//! - ratio d₂/d₁ ≤ [`CONVERGING_RATIO`] (order ≥ 0.5 per halving): **converging**, the value
//!   extrapolated at the observed rate (Richardson) and the error of the mesh's value its distance
//!   from it;
//! - up to [`SINGULAR_RATIO`]: **slow**, extrapolated alike (a large bound);
//! - a rise at least that steep, or a last rise above [`RISE`] of the value after none:
//!   **singular**, each refinement finds more (an r^(λ−1) field grows by 2^(1−λ) per halving);
//!   no error bound is given, only the values;
//! - anything else (a sign change, a fall that does not slow): **unsettled**, no bound.
//!
//! The peaks are a case's largest and up to two more away from the supports (a support's edge is
//! singular; the stress to judge a part by is elsewhere). The meshes are made by the
//! local-refinement machinery ([`crate::mesh::field`]): sizes at the basis mesh's vertices (each
//! vertex's mean edge length), made smaller within [`BALL`] local sizes of each peak and grading
//! back at [`GRADING`].

use crate::fem::element::Lame;
use crate::loads::LoadResult;
use crate::loads::peak::{PeakStress, Verdict, describe};
use crate::mesh::field::SizeField;
use crate::problem::{Discretized, discretize_with};
use crate::scene::Scene;
use anyhow::Result;

/// Peaks studied per load case at most: its largest and the next ones elsewhere.
pub const PEAKS_PER_CASE: usize = 3;

/// A peak other than a case's largest is studied when it is at least this share of it.
pub const SECONDARY_SHARE: f64 = 0.5;

/// Radius of the refined region around a peak, in its local element sizes.
pub const BALL: f64 = 1.5;

/// Growth of the element size per metre away from a refined region.
pub const GRADING: f64 = 0.5;

/// Changes falling at least this fast (order ≥ 0.5 per halving) converge.
pub const CONVERGING_RATIO: f64 = 0.71;

/// A rise whose changes fall slower than this is singular.
pub const SINGULAR_RATIO: f64 = 0.9;

/// A rise at the finest mesh beyond this share of the value, no smaller than the rise before,
/// is singular.
pub const RISE: f64 = 0.02;

/// Changes below this share of the value are noise, not a trend.
pub const NOISE: f64 = 1e-3;

/// A peak to study: a corner vertex of the basis's mesh.
#[derive(Clone, Copy, Debug)]
struct Site {
    at: [f64; 3],
    size: f64,
}

/// The three values and what they say: verdict, order, extrapolated value, error of `v[0]`.
pub fn judge(v: [f64; 3]) -> (Verdict, Option<f64>, Option<f64>, Option<f64>) {
    let tiny = NOISE * v[0].abs().max(v[1].abs()).max(v[2].abs());
    let (d1, d2) = (v[1] - v[0], v[2] - v[1]);
    if d2.abs() <= tiny {
        // The last refinement changed nothing beyond the noise: the first change and the noise
        // bound the error.
        return (Verdict::Converging, None, Some(v[2]), Some((v[2] - v[0]).abs() + tiny));
    }
    if d2 > RISE * v[1] && d2 >= SINGULAR_RATIO * d1 {
        // A clear rise at the finest mesh, no smaller than the one before (or after none, or a
        // fall within the mesh's noise: a weak singularity's first step can hide in how the
        // elements' corner values are averaged): no converged value.
        return (Verdict::Singular, None, None, None);
    }
    if d1.abs() <= tiny {
        // A change only at the finest mesh: no trend to read.
        return (Verdict::Unsettled, None, None, None);
    }
    let ratio = d2 / d1;
    if (0.0..SINGULAR_RATIO).contains(&ratio) {
        let extrapolated = v[2] + d2 * ratio / (1.0 - ratio);
        let verdict = if ratio <= CONVERGING_RATIO {
            Verdict::Converging
        } else {
            Verdict::Slow
        };
        return (
            verdict,
            Some(-ratio.log2()),
            Some(extrapolated),
            Some((extrapolated - v[0]).abs()),
        );
    }
    if (-CONVERGING_RATIO..0.0).contains(&ratio) {
        // Falling changes of alternating sign (the peak moving between vertices): the value lies
        // within the last change of the finest; no order to read.
        return (
            Verdict::Converging,
            None,
            Some(v[2]),
            Some((v[2] - v[0]).abs() + d2.abs()),
        );
    }
    if ratio >= SINGULAR_RATIO && d1 > 0.0 {
        return (Verdict::Singular, None, None, None);
    }
    (Verdict::Unsettled, None, None, None)
}

/// Each corner vertex's element size: the mean length of the tet edges that meet there.
pub fn vertex_sizes(mesh: &crate::tet_mesh::Mesh) -> Vec<f64> {
    let nv = mesh.vertex_count;
    let (mut sum, mut count) = (vec![0.0; nv], vec![0u32; nv]);
    for e in 0..mesh.tet_count() {
        let t = mesh.tet(e);
        for (a, b) in crate::tet_mesh::TET10_EDGES {
            let (a, b) = (t[a] as usize, t[b] as usize);
            let l = distance(&mesh.nodes[a], &mesh.nodes[b]);
            for v in [a, b] {
                sum[v] += l;
                count[v] += 1;
            }
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
        .collect()
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Corner vertices within `rings` layers of tets of a node in `held` (a node's DOFs held by a
/// support): a support's edge is singular, so the peaks to judge a part by lie outside.
fn near_held(mesh: &crate::tet_mesh::Mesh, held: &[bool], rings: usize) -> Vec<bool> {
    let nv = mesh.vertex_count;
    let mut near: Vec<bool> = (0..nv).map(|v| held.get(v).copied().unwrap_or(false)).collect();
    for _ in 0..rings {
        let mut next = near.clone();
        for e in 0..mesh.tet_count() {
            let t = &mesh.tet(e)[..4];
            if t.iter().any(|&v| near[v as usize]) {
                t.iter().for_each(|&v| next[v as usize] = true);
            }
        }
        near = next;
    }
    near
}

/// A case's peaks: its largest corner value, then up to [`PEAKS_PER_CASE`] − 1 more away from
/// the supports (`near`: vertices too close to one), each the largest there of at least
/// [`SECONDARY_SHARE`] of the largest there, and further than 4 [`BALL`] sizes from those chosen.
fn peaks_of(mesh: &crate::tet_mesh::Mesh, sizes: &[f64], near: &[bool], von_mises: &[f64]) -> Vec<Site> {
    let nv = mesh.vertex_count;
    let mut order: Vec<usize> = (0..nv).filter(|&v| von_mises[v] > 0.0).collect();
    order.sort_by(|&a, &b| von_mises[b].total_cmp(&von_mises[a]));
    let Some(&top) = order.first() else {
        return Vec::new();
    };
    let site = |v: usize| Site {
        at: mesh.nodes[v],
        size: sizes[v],
    };
    let mut chosen = vec![site(top)];
    let away: Vec<usize> = order.into_iter().filter(|&v| !near[v]).collect();
    let Some(&largest_away) = away.first() else {
        return chosen;
    };
    for v in away {
        if chosen.len() == PEAKS_PER_CASE || von_mises[v] < SECONDARY_SHARE * von_mises[largest_away] {
            break;
        }
        let at = mesh.nodes[v];
        if chosen
            .iter()
            .all(|s| distance(&s.at, &at) > 4.0 * BALL * s.size.max(sizes[v]))
        {
            chosen.push(site(v));
        }
    }
    chosen
}

/// The size field with the element size divided by 2^`level` within [`BALL`] sizes of each
/// site, graded back to `sizes` beyond.
fn refined_field(mesh: &crate::tet_mesh::Mesh, sizes: &[f64], sites: &[Site], level: i32) -> SizeField {
    let shrink = 0.5f64.powi(level);
    let local: Vec<f64> = (0..mesh.vertex_count)
        .map(|v| {
            let x = &mesh.nodes[v];
            sites.iter().fold(sizes[v], |h, s| {
                let beyond = (distance(x, &s.at) - BALL * s.size).max(0.0);
                h.min(s.size * shrink + GRADING * beyond)
            })
        })
        .collect();
    SizeField::on(mesh, local)
}

/// The largest corner von Mises of every case on a mesh, within `radius` of each of `sites`
/// (per case, per site).
fn largest_near(mesh: &crate::tet_mesh::Mesh, cases: &[Vec<f64>], sites: &[Vec<Site>]) -> Vec<Vec<f64>> {
    cases
        .iter()
        .zip(sites)
        .map(|(vm, sites)| {
            sites
                .iter()
                .map(|s| {
                    (0..mesh.vertex_count)
                        .filter(|&v| distance(&mesh.nodes[v], &s.at) <= BALL * s.size)
                        .map(|v| vm[v])
                        .fold(0.0, f64::max)
                })
                .collect()
        })
        .collect()
}

/// Every case's von Mises at the corner vertices of `d`'s mesh (linear model, K u = f).
fn corner_von_mises(scene: &Scene, d: &Discretized) -> Result<Vec<Vec<f64>>> {
    let f = crate::loads::load_vectors(scene, d)?;
    let u = crate::loads::solve_static(d, &f)?;
    let r = u.len();
    let fields = crate::fem::stress::Fields::from_each(&u);
    let stress = crate::fem::stress::vertex_stress(&d.mesh, &Lame::of(&scene.material), &fields);
    let nv = d.mesh.vertex_count;
    Ok((0..r)
        .map(|j| {
            (0..nv)
                .map(|v| {
                    let s: Vec<f64> = (0..6).map(|c| stress[(6 * v + c) * r + j]).collect();
                    crate::loads::von_mises(&s)
                })
                .collect()
        })
        .collect())
}

/// Studies the peaks of every linear load case in `results` (solved on `mesh`, the whole
/// part's, supports holding the DOFs `fixed`), filling each case's `peaks`.
pub fn study(scene: &Scene, mesh: &crate::tet_mesh::Mesh, fixed: &[u32], results: &mut [LoadResult]) -> Result<()> {
    if results.is_empty() {
        return Ok(());
    }
    let sizes = vertex_sizes(mesh);
    let mut held = vec![false; mesh.nodes.len()];
    for &g in fixed {
        if let Some(h) = held.get_mut(g as usize / 3) {
            *h = true;
        }
    }
    let near = near_held(mesh, &held, 2);
    let sites: Vec<Vec<Site>> = results
        .iter()
        .map(|l| peaks_of(mesh, &sizes, &near, &l.von_mises))
        .collect();
    let all: Vec<Site> = sites.iter().flatten().copied().collect();
    if all.is_empty() {
        return Ok(());
    }
    let base: Vec<Vec<f64>> = results.iter().map(|l| l.von_mises.clone()).collect();
    let mut values = vec![largest_near(mesh, &base, &sites)];
    for level in 1..=2 {
        let field = refined_field(mesh, &sizes, &all, level);
        let refined = discretize_with(scene, None, Some(&field), true)?;
        tracing::info!(
            level,
            dofs = refined.dofs.free_count(),
            "peak stress: the mesh refined around the peaks"
        );
        let vm = corner_von_mises(scene, &refined)?;
        values.push(largest_near(&refined.mesh, &vm, &sites));
    }
    for (j, l) in results.iter_mut().enumerate() {
        l.peaks = sites[j]
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let v = [values[0][j][k], values[1][j][k], values[2][j][k]];
                let (verdict, order, extrapolated_pa, error_pa) = judge(v);
                let mut p = PeakStress {
                    at_m: s.at,
                    value_pa: v[0],
                    refined_pa: [v[1], v[2]],
                    local_size_m: s.size,
                    verdict,
                    order,
                    extrapolated_pa,
                    error_pa,
                    text: String::new(),
                };
                p.text = describe(&p.record());
                p
            })
            .collect();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth peak converging at order 2 (changes quartering) is extrapolated exactly; one
    /// rising by 2^0.3 per halving (the stress at a clamped edge, r^-0.3) is singular; a sign
    /// change is unsettled; changes within the noise converge with their own size as the error.
    #[test]
    fn peaks_are_judged_by_their_successive_changes() {
        let exact = 100.0;
        let v = [exact - 16.0, exact - 4.0, exact - 1.0];
        let (verdict, order, x, e) = judge(v);
        assert_eq!(verdict, Verdict::Converging);
        assert!((order.unwrap() - 2.0).abs() < 1e-12);
        assert!((x.unwrap() - exact).abs() < 1e-12);
        assert!((e.unwrap() - 16.0).abs() < 1e-12);

        let g = 2f64.powf(0.3);
        assert_eq!(judge([100.0, 100.0 * g, 100.0 * g * g]).0, Verdict::Singular);
        // The cantilever's clamp alone under its tip force: no rise, then 25 %.
        assert_eq!(judge([23.57, 23.52, 29.38]).0, Verdict::Singular);
        // A falling value that does not slow is not called singular: singular peaks rise.
        assert_eq!(judge([100.0, 90.0, 80.0]).0, Verdict::Unsettled);
        // Alternating changes: falling ones bound the value, growing ones say nothing.
        let (verdict, _, _, e) = judge([100.0, 110.0, 105.0]);
        assert_eq!(verdict, Verdict::Converging);
        assert!((e.unwrap() - 10.0).abs() < 1e-9);
        assert_eq!(judge([100.0, 110.0, 100.0]).0, Verdict::Unsettled);
        // Settled to the noise after one change: that change bounds the error.
        let (verdict, _, _, e) = judge([91.85, 94.24, 94.2399]);
        assert_eq!(verdict, Verdict::Converging);
        assert!(e.unwrap() > 2.39 && e.unwrap() < 2.5);
        assert_eq!(judge([100.0, 100.01, 101.0]).0, Verdict::Unsettled);
        // Order 0.4: slow, extrapolated with a bound several times the last change.
        let r = 0.5f64.powf(0.4);
        let (verdict, _, x, e) = judge([100.0, 110.0, 110.0 + 10.0 * r]);
        assert_eq!(verdict, Verdict::Slow);
        assert!(x.unwrap() > 110.0 + 10.0 * r && e.unwrap() > 30.0);
    }
}
