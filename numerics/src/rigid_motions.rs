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

/// A rigid motion a part's supports leave free, described as an engineer names it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum FreeMotion {
    /// A translation along `direction` (unit).
    Slide {
        /// Unit direction.
        direction: [f64; 3],
    },
    /// A rotation about the axis along `direction` (unit) through `point` (m).
    Turn {
        /// The axis's unit direction.
        direction: [f64; 3],
        /// The point of the axis nearest the centre of mass, m.
        point: [f64; 3],
    },
    /// A rotation about an axis with a slide along it of `pitch` metres per radian.
    Screw {
        /// The axis's unit direction.
        direction: [f64; 3],
        /// The point of the axis nearest the centre of mass, m.
        point: [f64; 3],
        /// Metres along the axis per radian about it.
        pitch: f64,
    },
}

/// The free motions `twists` (rows `(v, ω)` about `center`, any basis of them) as slides (the
/// translations among them, orthonormal) and turns or screws about axes (the rest, with what of
/// their translation the slides already give removed). `length` is the part's size (m): ω is
/// compared with v at that lever arm.
pub fn describe(twists: &[[f64; 6]], center: [f64; 3], length: f64) -> Vec<FreeMotion> {
    use nalgebra::{DMatrix, Vector3};
    let k = twists.len();
    if k == 0 || length.is_nan() || length <= 0.0 {
        return Vec::new();
    }
    let v = |t: &[f64; 6]| Vector3::new(t[0], t[1], t[2]);
    let w = |t: &[f64; 6]| Vector3::new(t[3], t[4], t[5]);
    // The combinations of the twists that turn nothing: the null space of their ω-Gram matrix,
    // measured against the whole twists' size.
    let turns = DMatrix::from_fn(k, k, |a, b| length * length * w(&twists[a]).dot(&w(&twists[b])));
    let whole = DMatrix::from_fn(k, k, |a, b| v(&twists[a]).dot(&v(&twists[b]))) + &turns;
    let scale = whole.symmetric_eigenvalues().iter().fold(0.0f64, |a, &x| a.max(x));
    let eig = nalgebra::SymmetricEigen::new(turns);
    let combine = |y: nalgebra::DVectorView<'_, f64>| {
        (0..k).fold((Vector3::zeros(), Vector3::zeros()), |(sv, sw), i| {
            (sv + y[i] * v(&twists[i]), sw + y[i] * w(&twists[i]))
        })
    };
    let mut slides: Vec<Vector3<f64>> = Vec::new();
    let mut rotations = Vec::new();
    for i in 0..k {
        let (tv, tw) = combine(eig.eigenvectors.column(i));
        if eig.eigenvalues[i] <= 1e-10 * scale {
            // Gram–Schmidt among the slides found so far.
            let d = slides.iter().fold(tv, |d, s| d - s * s.dot(&d));
            if d.norm() > 1e-8 * tv.norm().max(f64::MIN_POSITIVE) {
                slides.push(d.normalize());
            }
        } else {
            rotations.push((tv, tw));
        }
    }
    let mut out: Vec<FreeMotion> = slides
        .iter()
        .map(|s| FreeMotion::Slide { direction: (*s).into() })
        .collect();
    for (tv, tw) in rotations {
        let tv = slides.iter().fold(tv, |d, s| d - s * s.dot(&d));
        let n2 = tw.norm_squared();
        let direction = tw / n2.sqrt();
        let pitch = tv.dot(&tw) / n2;
        let point = Vector3::from(center) + tw.cross(&tv) / n2;
        out.push(if pitch.abs() <= 1e-6 * length {
            FreeMotion::Turn {
                direction: direction.into(),
                point: point.into(),
            }
        } else {
            FreeMotion::Screw {
                direction: direction.into(),
                point: point.into(),
                pitch,
            }
        });
    }
    out
}

#[cfg(test)]
mod describe_tests {
    use super::*;

    /// A shaft's free motions given as two mixed screws (the turn about an axis off the centre
    /// and the slide along it, combined) read back as one slide along the axis and one turn
    /// about it through the right point; a plate held out of plane, as two slides and a turn.
    #[test]
    fn mixed_twists_read_as_a_slide_and_a_turn() {
        let c = [0.1, 0.2, 0.3];
        // The axis along x through (0, 0.25, 0.3): a turn ω = x̂ moves c with v = ω × (c − p).
        let turn = [0.0, 0.0, -0.05, 1.0, 0.0, 0.0];
        let slide = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mix = |a: f64, b: f64| -> [f64; 6] { std::array::from_fn(|i| a * turn[i] + b * slide[i]) };
        let got = describe(&[mix(0.6, 0.8), mix(0.8, -0.6)], c, 0.5);
        assert_eq!(got.len(), 2, "{got:?}");
        let FreeMotion::Slide { direction } = got[0] else {
            panic!("{got:?}")
        };
        assert!((direction[0].abs() - 1.0).abs() < 1e-12, "{direction:?}");
        let FreeMotion::Turn { direction, point } = got[1] else {
            panic!("{got:?}")
        };
        assert!((direction[0].abs() - 1.0).abs() < 1e-12, "{direction:?}");
        for (g, w) in point.iter().zip([0.1, 0.25, 0.3]) {
            assert!((g - w).abs() < 1e-12, "{point:?}");
        }
        let plate = describe(
            &[
                [1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
                [1.0, -1.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 2.0],
            ],
            [0.0; 3],
            1.0,
        );
        assert_eq!(plate.len(), 3, "{plate:?}");
        assert!(matches!(plate[2], FreeMotion::Turn { direction, .. } if (direction[2].abs() - 1.0).abs() < 1e-12));
        assert!(
            plate[..2]
                .iter()
                .all(|m| matches!(m, FreeMotion::Slide { direction } if direction[2] == 0.0))
        );
        // A screw stays a screw.
        let screw = describe(&[[0.0, 0.0, 0.01, 0.0, 0.0, 1.0]], [0.0; 3], 1.0);
        assert!(
            matches!(screw[0], FreeMotion::Screw { pitch, .. } if (pitch - 0.01).abs() < 1e-15),
            "{screw:?}"
        );
    }
}
