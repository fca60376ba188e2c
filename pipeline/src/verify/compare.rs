//! How far a reference's modes and static response are from ours: frequencies, shapes paired
//! by MAC, the subspaces of close frequencies by their principal angle, the static displacement
//! at the load node and, when asked, the nodal stresses of its mode shapes.

use super::ModeRow;
use super::ReferenceReport;
use super::error::VerifyError;
use super::reference::Solution;
use super::tolerances::Tolerances;
use crate::fem::element::Lame;
use crate::fem::stress::{Averaging, Fields, vertex_stress_averaged};
use crate::linsolve::sym_matvec;
use crate::modes::Modes;
use crate::problem::Discretized;

/// Relative gap below which two neighbouring frequencies are treated as one group.
const GROUP_GAP: f64 = 1e-3;

/// Full-DOF vectors restricted to the free DOFs, and M times each: the pieces of their
/// M-inner products ([`gram`]), M applied once per vector.
fn with_m(d: &Discretized, x: &[Vec<f64>]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let free: Vec<Vec<f64>> = x
        .iter()
        .map(|v| d.dofs.free.iter().map(|&g| v[g as usize]).collect())
        .collect();
    let m = free
        .iter()
        .map(|v| {
            let mut mv = vec![0.0; v.len()];
            sym_matvec(&d.system.pattern, &d.system.m, v, &mut mv);
            mv
        })
        .collect();
    (free, m)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// G_ij = x_iᵀ (M y)_j, from free vectors and the M products of [`with_m`].
fn gram(x: &[Vec<f64>], my: &[Vec<f64>]) -> faer::Mat<f64> {
    faer::Mat::from_fn(x.len(), my.len(), |i, j| dot(&x[i], &my[j]))
}

/// MAC of every pair (ours j, reference k): (aᵀMb)² / (aᵀMa · bᵀMb) on the free DOFs.
fn mac_matrix(d: &Discretized, ours: &[Vec<f64>], theirs: &[Vec<f64>]) -> faer::Mat<f64> {
    let ((a, ma), (b, mb)) = (with_m(d, ours), with_m(d, theirs));
    let na: Vec<f64> = a.iter().zip(&ma).map(|(v, m)| dot(v, m)).collect();
    let nb: Vec<f64> = b.iter().zip(&mb).map(|(v, m)| dot(v, m)).collect();
    let g = gram(&a, &mb);
    faer::Mat::from_fn(a.len(), b.len(), |j, k| g[(j, k)].powi(2) / (na[j] * nb[k]))
}

/// One-to-one pairs of largest MAC (greedy: the best remaining pair first); `partner[j]` is the
/// column paired with row j. Square matrices only.
fn pair_by_mac(macs: &faer::Mat<f64>) -> Vec<usize> {
    let r = macs.nrows();
    let mut all: Vec<(usize, usize)> = (0..r).flat_map(|j| (0..r).map(move |k| (j, k))).collect();
    // Ties (and NaN, last) go to the pair of nearer indices: the order the modes came in.
    all.sort_by(|&(j, k), &(a, b)| {
        let (x, y) = (macs[(j, k)], macs[(a, b)]);
        y.partial_cmp(&x)
            .unwrap_or_else(|| x.is_nan().cmp(&y.is_nan()))
            .then(j.abs_diff(k).cmp(&a.abs_diff(b)))
    });
    let mut partner = vec![usize::MAX; r];
    let mut taken = vec![false; r];
    for (j, k) in all {
        if partner[j] == usize::MAX && !taken[k] {
            partner[j] = k;
            taken[k] = true;
        }
    }
    partner
}

/// Largest principal angle between span(A) and span(B) (full-DOF column sets), M-inner product.
fn principal_angle(d: &Discretized, a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    let ((fa, ma), (fb, mb)) = (with_m(d, a), with_m(d, b));
    let (gaa, gbb, gab) = (gram(&fa, &ma), gram(&fb, &mb), gram(&fa, &mb));
    let (Ok(la), Ok(lb)) = (gaa.llt(faer::Side::Lower), gbb.llt(faer::Side::Lower)) else {
        return std::f64::consts::FRAC_PI_2;
    };
    // C = La⁻¹ Gab Lb⁻ᵀ; its singular values are the cosines of the principal angles.
    let mut c = gab.clone();
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(la.L(), c.as_mut(), faer::Par::Seq);
    let mut ct = c.transpose().to_owned();
    faer::linalg::triangular_solve::solve_lower_triangular_in_place(lb.L(), ct.as_mut(), faer::Par::Seq);
    let cos = ct
        .singular_values()
        .map(|s| s.iter().copied().fold(f64::INFINITY, f64::min))
        .unwrap_or(0.0);
    cos.clamp(-1.0, 1.0).acos()
}

/// One reference's `theirs` against our modes (and our static displacement under the unit load
/// at `load_node`, on supported parts), within `tol`; with `stress`, also our stress recovered
/// from its mode shapes against its own nodal stress.
pub(super) fn compare(
    d: &Discretized,
    ours: &Modes,
    theirs: &Solution,
    static_ours: Option<&[f64]>,
    load_node: usize,
    tol: &Tolerances,
    stress: Option<&Lame>,
) -> Result<ReferenceReport, VerifyError> {
    check_modes(d, theirs)?;
    let (mut rows, shapes) = mode_rows(d, ours, theirs);
    if let Some(lame) = stress {
        stress_gaps(d, lame, theirs, &shapes, &mut rows)?;
    }
    let static_rel = static_ours.map(|u| static_gap(d, u, theirs, load_node)).transpose()?;
    let max_stress = rows.iter().filter_map(|x| x.stress_rel_diff).reduce(f64::max);
    let isolated = |row: &ModeRow| rows.iter().filter(|o| o.group == row.group).count() == 1;
    let max_rel = rows.iter().map(|x| x.rel_diff).fold(0.0, f64::max);
    let min_mac = rows.iter().filter(|x| isolated(x)).map(|x| x.mac).fold(1.0, f64::min);
    // Over groups of close frequencies only (isolated modes are judged by their MAC); `None`
    // when there is no such group, rather than a 0 that reads like a perfect match.
    let max_angle = rows
        .iter()
        .filter(|x| !isolated(x))
        .map(|x| x.group_angle_rad)
        .reduce(f64::max);
    let pass = rows.len() == ours.eigenvalues.len()
        && max_rel <= tol.freq
        && min_mac >= tol.mac
        && max_angle.is_none_or(|a| a <= tol.angle)
        && static_rel.is_none_or(|s| s <= tol.static_rel)
        && max_stress.is_none_or(|s| s <= tol.stress);
    Ok(ReferenceReport {
        solver: theirs.solver.clone(),
        tolerances: *tol,
        modes: rows,
        max_rel_freq_diff: max_rel,
        min_mac_isolated: min_mac,
        max_group_angle_rad: max_angle,
        static_rel_diff: static_rel,
        max_stress_rel_diff: max_stress,
        seconds: 0.0,
        pass,
    })
}

/// The reference's output is another program's: its modes are checked before they are indexed.
fn check_modes(d: &Discretized, theirs: &Solution) -> Result<(), VerifyError> {
    let (n3, freqs) = (3 * d.mesh.nodes.len(), &theirs.frequencies_hz);
    if theirs.modes.nrows() != n3 || freqs.iter().any(|x| !x.is_finite() || *x <= 0.0) {
        return Err(VerifyError::Unusable {
            path: theirs.source.clone(),
            detail: format!(
                "the reference solver wrote {} mode rows for {n3} DOFs and frequencies {:?}: its output is unusable",
                theirs.modes.nrows(),
                &freqs[..freqs.len().min(6)]
            ),
        });
    }
    Ok(())
}

/// A row per mode compared (as many as both have), each of ours paired with the reference's
/// mode of largest MAC, and the reference's mode shapes (full DOF vectors) in its order.
fn mode_rows(d: &Discretized, ours: &Modes, theirs: &Solution) -> (Vec<ModeRow>, Vec<Vec<f64>>) {
    let (freqs, modes) = (&theirs.frequencies_hz, &theirs.modes);
    let nf = d.dofs.free_count();
    let ours_f = ours.frequencies_hz();
    let r = ours_f.len().min(freqs.len()).min(modes.ncols());
    let ours_full: Vec<Vec<f64>> = (0..r)
        .map(|j| d.dofs.expand(&ours.vectors[j * nf..(j + 1) * nf]))
        .collect();
    let shapes: Vec<Vec<f64>> = (0..r).map(|j| modes.column(j).to_vec()).collect();
    // Groups of (near-)repeated frequencies, from our spectrum.
    let mut group = vec![0usize; r];
    for j in 1..r {
        group[j] = if (ours_f[j] - ours_f[j - 1]) / ours_f[j] < GROUP_GAP {
            group[j - 1]
        } else {
            group[j - 1] + 1
        };
    }
    // Pairs by shape, not by index: two modes close in frequency can come in the other order
    // from another discretisation (the P1 ribplate against CalculiX's C3D4: two modes 0.75 %
    // apart swap, and index pairs compared different shapes, MAC 2e-8).
    let macs = mac_matrix(d, &ours_full, &shapes);
    let partner = pair_by_mac(&macs);
    let mut rows = Vec::with_capacity(r);
    for j in 0..r {
        let p = partner[j];
        let mac = macs[(j, p)];
        let members: Vec<usize> = (0..r).filter(|&k| group[k] == group[j]).collect();
        let angle = if members.len() > 1 {
            let sa: Vec<Vec<f64>> = members.iter().map(|&k| ours_full[k].clone()).collect();
            let sb: Vec<Vec<f64>> = members.iter().map(|&k| shapes[partner[k]].clone()).collect();
            principal_angle(d, &sa, &sb)
        } else {
            mac.clamp(0.0, 1.0).sqrt().acos()
        };
        rows.push(ModeRow {
            mode: j,
            reference_mode: p,
            ours_hz: ours_f[j],
            reference_hz: freqs[p],
            rel_diff: (ours_f[j] - freqs[p]).abs() / freqs[p],
            mac,
            group: group[j],
            group_angle_rad: angle,
            stress_rel_diff: None,
            stress_rel_diff_volume_weighted: None,
        });
    }
    (rows, shapes)
}

/// Fills each row's stress differences: our stress recovered from the reference's shape `j`,
/// averaged as the reference averages (and as a basis stores it), against its own nodal stress.
fn stress_gaps(
    d: &Discretized,
    lame: &Lame,
    theirs: &Solution,
    shapes: &[Vec<f64>],
    rows: &mut [ModeRow],
) -> Result<(), VerifyError> {
    let unusable = |detail: &str| VerifyError::Unusable {
        path: theirs.source.clone(),
        detail: detail.to_string(),
    };
    let theirs_stress = theirs
        .mode_stress
        .as_ref()
        .ok_or_else(|| unusable("the reference wrote no nodal stress"))?;
    let nv = d.mesh.vertex_count;
    if theirs_stress.nrows() != 6 * d.mesh.nodes.len() || theirs_stress.ncols() < rows.len() {
        return Err(unusable("the reference's nodal stress has the wrong shape"));
    }
    let gap = |ours: &[f64], j: usize| {
        let (mut diff, mut norm) = (0.0, 0.0);
        for (i, o) in ours.iter().enumerate().take(6 * nv) {
            let t = theirs_stress[(i, j)];
            diff += (o - t).powi(2);
            norm += t * t;
        }
        (diff / norm.max(f64::MIN_POSITIVE)).sqrt()
    };
    for (j, row) in rows.iter_mut().enumerate() {
        let shape = Fields::one(shapes[j].clone());
        let like = vertex_stress_averaged(&d.mesh, lame, &shape, Averaging::Arithmetic);
        let stored = vertex_stress_averaged(&d.mesh, lame, &shape, Averaging::Volume);
        row.stress_rel_diff = Some(gap(&like, j));
        row.stress_rel_diff_volume_weighted = Some(gap(&stored, j));
    }
    Ok(())
}

/// |u_ours − u_ref| / |u_ours| at the load node.
fn static_gap(d: &Discretized, u: &[f64], theirs: &Solution, load_node: usize) -> Result<f64, VerifyError> {
    let n3 = 3 * d.mesh.nodes.len();
    let reference = theirs.static_displacement.as_deref().unwrap_or_default();
    if reference.len() != n3 || u.len() != n3 || load_node >= n3 / 3 {
        return Err(VerifyError::Unusable {
            path: theirs.source.clone(),
            detail: format!(
                "the reference's static displacement has {} values for {n3} DOFs",
                reference.len()
            ),
        });
    }
    let k = 3 * load_node;
    let diff = (0..3)
        .map(|c| (u[k + c] - reference[k + c]).powi(2))
        .sum::<f64>()
        .sqrt();
    let norm = (0..3).map(|c| u[k + c].powi(2)).sum::<f64>().sqrt();
    Ok(diff / norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Array1, Array2};

    /// The reference's output is another program's: `compare` indexed into it unchecked.
    #[test]
    fn a_reference_output_of_the_wrong_shape_is_refused() {
        let mesh = crate::tet_mesh::Mesh::structured_box([2, 1, 1], 0.1, crate::fem::element::Kind::Tet4, |_, p| p);
        let n = mesh.nodes.len();
        let dofs = crate::fem::Dofs::from_mask(&vec![false; 3 * n]);
        let d = Discretized::assemble(mesh, dofs, crate::material::Material::elastic(2e11, 0.3, 7800.0))
            .expect("assembles");
        let nf = d.dofs.free_count();
        let ours = Modes {
            eigenvalues: vec![1e6],
            vectors: vec![1.0; nf],
            rigid_dropped: 6,
            residuals: vec![0.0],
            orthonormality_error: 0.0,
            sigma: 0.0,
            factorize_s: 0.0,
            eigensolve_s: 0.0,
            factored: None,
        };
        let dir = tempfile::tempdir().expect("tempdir");
        let tol = Tolerances::same_discrete_problem(false);
        for (name, rows, freq) in [("short.h5", 3 * n - 3, 100.0), ("nan.h5", 3 * n, f64::NAN)] {
            let path = dir.path().join(name);
            let f = ves_format::file::create(&path, false).expect("create");
            f.new_dataset_builder()
                .with_data(&Array1::from(vec![freq]))
                .create("frequencies_hz")
                .expect("freqs");
            f.new_dataset_builder()
                .with_data(&Array2::<f64>::zeros((rows, 1)))
                .create("modes")
                .expect("modes");
            f.close().expect("close");
            let theirs = Solution::read(&path, false).expect("readable");
            let e = compare(&d, &ours, &theirs, None, 0, &tol, None).expect_err("refused");
            assert!(e.to_string().contains("unusable"), "{name}: {e}");
        }
    }

    /// Two modes that swap order between the discretisations are paired by shape; a shared
    /// MAC (a repeated frequency) keeps the order they came in.
    #[test]
    fn modes_are_paired_by_mac_one_to_one() {
        let macs = faer::mat![
            [0.99, 0.01, 0.0, 0.0],
            [0.0, 0.02, 0.97, 0.0],
            [0.0, 0.98, 0.03, 0.0],
            [0.0, 0.0, 0.0, f64::NAN],
        ];
        assert_eq!(pair_by_mac(&macs), vec![0, 2, 1, 3]);
        let tie = faer::mat![[0.5, 0.5], [0.5, 0.5]];
        assert_eq!(pair_by_mac(&tie), vec![0, 1]);
    }
}
