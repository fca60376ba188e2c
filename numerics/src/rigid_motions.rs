//! Rigid-body motions: how many the supports leave free, and the vectors themselves.

use crate::fem::Dofs;

/// The six rigid motions sampled at the nodes (full DOF vectors): three translations, then
/// rotations about the axes through `center`, scaled by 1/`length` so all six are O(1).
pub fn rigid_motions(nodes: &[[f64; 3]], center: [f64; 3], length: f64) -> [Vec<f64>; 6] {
    std::array::from_fn(|r| {
        let mut u = vec![0.0; 3 * nodes.len()];
        for (i, p) in nodes.iter().enumerate() {
            let x = [
                (p[0] - center[0]) / length,
                (p[1] - center[1]) / length,
                (p[2] - center[2]) / length,
            ];
            let d = match r {
                0 => [1.0, 0.0, 0.0],
                1 => [0.0, 1.0, 0.0],
                2 => [0.0, 0.0, 1.0],
                3 => [0.0, -x[2], x[1]],
                4 => [x[2], 0.0, -x[0]],
                _ => [-x[1], x[0], 0.0],
            };
            u[3 * i..3 * i + 3].copy_from_slice(&d);
        }
        u
    })
}

/// [`rigid_motions`] about the centre of the nodes' bounding box, scaled by its largest side.
fn scaled_rigid_motions(nodes: &[[f64; 3]]) -> [Vec<f64>; 6] {
    let (center, length) = frame(nodes);
    rigid_motions(nodes, center, length)
}

/// The centre of the nodes' bounding box and its largest side: the frame the rigid motions of
/// [`on_free_dofs`] are taken in (a part of the mesh must use the whole mesh's frame for its
/// pieces of the vectors to be pieces of the same rigid motions).
pub fn frame(nodes: &[[f64; 3]]) -> ([f64; 3], f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in nodes {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let center = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, (lo[2] + hi[2]) / 2.0];
    let length = (0..3).map(|c| hi[c] - lo[c]).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    (center, length)
}

/// The six rigid motions on the free DOFs, six values per free DOF (row-major `free × 6`): the
/// near-null space an algebraic multigrid preconditioner of elasticity needs.
pub fn on_free_dofs(nodes: &[[f64; 3]], dofs: &Dofs) -> Vec<f64> {
    on_free_dofs_in(nodes, dofs, frame(nodes))
}

/// [`on_free_dofs`] in a given [`frame`].
pub fn on_free_dofs_in(nodes: &[[f64; 3]], dofs: &Dofs, (center, length): ([f64; 3], f64)) -> Vec<f64> {
    let modes = rigid_motions(nodes, center, length);
    dofs.free
        .iter()
        .flat_map(|&g| modes.iter().map(move |m| m[g as usize]))
        .collect()
}

/// Number of rigid motions the supports do not prevent: 6 − rank of the rigid motions
/// restricted to the supported DOFs. 6 for a free body, 0 for a clamped one, 3 for a plate
/// supported only out of plane.
pub fn free_rigid_count(nodes: &[[f64; 3]], dofs: &Dofs) -> usize {
    free_rigid_count_with(nodes, dofs, &[])
}

/// [`free_rigid_count`] with surface springs holding the part too: a rigid motion they stretch
/// is held.
pub fn free_rigid_count_with(nodes: &[[f64; 3]], dofs: &Dofs, springs: &[crate::fem::springs::NodeSpring]) -> usize {
    if dofs.fixed.is_empty() && springs.is_empty() {
        return 6;
    }
    let modes = scaled_rigid_motions(nodes);
    let held = crate::fem::springs::rigid_gram(springs, &modes);
    // Gram matrix of the restrictions to the fixed DOFs, plus the springs' energy of each pair,
    // each scaled to a largest diagonal of 1; its rank is the constrained count.
    let fixed = faer::Mat::<f64>::from_fn(6, 6, |a, b| {
        dofs.fixed
            .iter()
            .map(|&d| modes[a][d as usize] * modes[b][d as usize])
            .sum()
    });
    let unit = |d: f64| if d > 0.0 { 1.0 / d } else { 0.0 };
    let (sf, ss) = (
        unit((0..6).map(|p| fixed[(p, p)]).fold(0.0f64, f64::max)),
        unit((0..6).map(|p| held[p][p]).fold(0.0f64, f64::max)),
    );
    let gram = faer::Mat::<f64>::from_fn(6, 6, |a, b| sf * fixed[(a, b)] + ss * held[a][b]);
    let eig = match gram.self_adjoint_eigenvalues(faer::Side::Lower) {
        Ok(e) => e,
        Err(_) => return 6,
    };
    let top = eig.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
    let rank = eig.iter().filter(|&&v| v > 1e-10 * top).count();
    6 - rank
}
