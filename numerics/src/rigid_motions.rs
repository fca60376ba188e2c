//! Rigid-body motions: how many the supports leave free, and the vectors themselves.

use crate::fem::Dofs;

/// The six rigid motions sampled at the nodes (full DOF vectors): three translations, then
/// rotations about the axes through `center`, scaled by 1/`length` so all six are O(1).
pub fn rigid_motions(nodes: &[[f64; 3]], center: [f64; 3], length: f64) -> [Vec<f64>; 6] {
    std::array::from_fn(|r| nodes.iter().flat_map(|p| rigid_at(*p, center, length)[r]).collect())
}

/// The six rigid motions of [`rigid_motions`] at one point: row r is motion r's displacement.
pub fn rigid_at(p: [f64; 3], center: [f64; 3], length: f64) -> [[f64; 3]; 6] {
    let x = [
        (p[0] - center[0]) / length,
        (p[1] - center[1]) / length,
        (p[2] - center[2]) / length,
    ];
    [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, -x[2], x[1]],
        [x[2], 0.0, -x[0]],
        [-x[1], x[0], 0.0],
    ]
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
    free_motions(nodes, dofs, &[], [0.0; 3]).count()
}

/// The rigid motions the supports (fixed DOFs, and springs: a motion they stretch is held)
/// leave free, as twists `(v, ω)` about `center`: the null space of the Gram matrix of the six
/// rigid motions restricted to the fixed DOFs plus the springs' energy of each pair, each part
/// scaled to a largest diagonal of 1 (the same rank test as the count, so the two agree).
pub fn free_motions(
    nodes: &[[f64; 3]],
    dofs: &Dofs,
    springs: &[crate::fem::springs::NodeSpring],
    center: [f64; 3],
) -> ves_format::FreeMotions {
    if dofs.fixed.is_empty() && springs.is_empty() {
        return ves_format::FreeMotions::all();
    }
    let (middle, length) = frame(nodes);
    let at = |i: usize| rigid_at(nodes[i], middle, length);
    let held = crate::fem::springs::rigid_gram(springs, at);
    let mut fixed = [[0.0; 6]; 6];
    for &d in &dofs.fixed {
        let m = at(d as usize / 3);
        let c = d as usize % 3;
        for a in 0..6 {
            for b in 0..6 {
                fixed[a][b] += m[a][c] * m[b][c];
            }
        }
    }
    let unit = |d: f64| if d > 0.0 { 1.0 / d } else { 0.0 };
    let (sf, ss) = (
        unit((0..6).map(|p| fixed[p][p]).fold(0.0f64, f64::max)),
        unit((0..6).map(|p| held[p][p]).fold(0.0f64, f64::max)),
    );
    let gram = nalgebra::Matrix6::from_fn(|a, b| sf * fixed[a][b] + ss * held[a][b]);
    let eig = nalgebra::SymmetricEigen::new(0.5 * (gram + gram.transpose()));
    if eig.eigenvalues.iter().any(|v| !v.is_finite()) {
        return ves_format::FreeMotions::all();
    }
    let top = eig.eigenvalues.iter().fold(0.0f64, |a, &v| a.max(v.abs()));
    // A null vector (t, ω_s) moves x by t + ω_s × (x − middle)/length: about `center` that is
    // the twist (t + ω × (center − middle), ω) with ω = ω_s/length.
    let twists: Vec<[f64; 6]> = (0..6)
        .filter(|&i| eig.eigenvalues[i] <= 1e-10 * top)
        .map(|i| {
            let u = eig.eigenvectors.column(i);
            let w = nalgebra::Vector3::new(u[3], u[4], u[5]) / length;
            let off = nalgebra::Vector3::from(center) - nalgebra::Vector3::from(middle);
            let v = nalgebra::Vector3::new(u[0], u[1], u[2]) + w.cross(&off);
            [v[0], v[1], v[2], w[0], w[1], w[2]]
        })
        .collect();
    ves_format::FreeMotions::new(&twists).unwrap_or_else(ves_format::FreeMotions::all)
}
