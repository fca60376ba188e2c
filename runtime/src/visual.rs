//! Full-field update for drawing: u = Φ q over the kept vertices, f32, mode by mode (each mode a
//! contiguous axpy the compiler vectorises).

use crate::basis::Basis;

/// Writes u = Φ q (3 values per kept vertex) into `u`, using the first `q.len()` modes.
pub fn displacements(basis: &Basis, q: &[f64], u: &mut [f32]) {
    u.fill(0.0);
    for (j, &qj) in q.iter().enumerate().take(basis.mode_count()) {
        let qj = qj as f32;
        for (ui, pj) in u.iter_mut().zip(basis.mode(j)) {
            *ui += qj * pj;
        }
    }
}

/// Writes σ = Σ q_j σ_j (6 Voigt values per kept vertex: xx yy zz yz xz xy, Pa) into `sigma`;
/// false (and `sigma` untouched) when the basis holds no stress.
pub fn stresses(basis: &Basis, q: &[f64], sigma: &mut [f32]) -> bool {
    if basis.stress.is_none() {
        return false;
    }
    sigma.fill(0.0);
    for (j, &qj) in q.iter().enumerate().take(basis.mode_count()) {
        let qj = qj as f32;
        for (s, sj) in sigma.iter_mut().zip(basis.stress_mode(j).unwrap_or(&[])) {
            *s += qj * sj;
        }
    }
    true
}

/// Von Mises equivalent stress of a Voigt stress (xx yy zz yz xz xy), Pa.
pub fn von_mises(s: [f64; 6]) -> f64 {
    let [xx, yy, zz, yz, xz, xy] = s;
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2)) + 3.0 * (yz * yz + xz * xz + xy * xy)).sqrt()
}

/// Principal stresses of a Voigt stress (xx yy zz yz xz xy), Pa, largest first.
pub fn principal_stresses(s: [f64; 6]) -> [f64; 3] {
    let [xx, yy, zz, yz, xz, xy] = s;
    let m = nalgebra::Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    let mut e: [f64; 3] = m.symmetric_eigenvalues().into();
    e.sort_by(|a, b| b.total_cmp(a));
    e
}

/// Largest principal strain of an isotropic linear-elastic material from its principal
/// stresses `p` (largest first, [`principal_stresses`]): ε = ((1 + ν) σ − ν tr(σ) I) / E shares
/// σ's principal directions, so its largest eigenvalue is ((1 + ν) σ₁ − ν (σ₁ + σ₂ + σ₃)) / E.
pub fn principal_strain_max(p: [f64; 3], (young, poisson): (f64, f64)) -> f64 {
    ((1.0 + poisson) * p[0] - poisson * (p[0] + p[1] + p[2])) / young
}

/// The largest von Mises stress over the vertices of `sigma` (6 per vertex) and its vertex.
pub fn max_von_mises(sigma: &[f32]) -> (f64, usize) {
    sigma
        .chunks_exact(6)
        .map(|s| von_mises(std::array::from_fn(|k| f64::from(s[k]))))
        .enumerate()
        .fold((0.0, 0), |best, (i, v)| if v > best.0 { (v, i) } else { best })
}

/// The largest principal stress over the vertices of `sigma` (6 per vertex), Pa, and with
/// elastic constants the largest principal strain.
pub fn max_principal(sigma: &[f32], elastic: Option<(f64, f64)>) -> (f64, Option<f64>) {
    let (mut stress, mut strain) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for s in sigma.chunks_exact(6) {
        let p = principal_stresses(std::array::from_fn(|k| f64::from(s[k])));
        stress = stress.max(p[0]);
        if let Some(e) = elastic {
            strain = strain.max(principal_strain_max(p, e));
        }
    }
    (stress, elastic.map(|_| strain))
}

/// Writes deformed positions rest + u into `pos` (3 values per kept vertex).
pub fn positions(basis: &Basis, q: &[f64], pos: &mut [f32]) {
    displacements(basis, q, pos);
    for (p, r) in pos.chunks_exact_mut(3).zip(&basis.rest) {
        for c in 0..3 {
            p[c] += r[c] as f32;
        }
    }
}

/// Drawn positions from a published state: x + R(p₀ + u − c) for a free body, p₀ + u for a
/// supported one.
pub fn posed_positions(basis: &Basis, state: &crate::snapshot::Published, pos: &mut [f32]) {
    posed_positions_of(basis, state.modal(basis.mode_count()), state.pose(), pos);
}

/// The same with the modal coordinates and the pose (`Haptics::pose`) apart.
pub fn posed_positions_of(basis: &Basis, modal: &[f64], pose: &[f64], pos: &mut [f32]) {
    positions(basis, modal, pos);
    let Some(rigid) = basis.rigid else { return };
    let x = [pose[0], pose[1], pose[2]];
    let q = [pose[3], pose[4], pose[5], pose[6]];
    // An all-zero pose (nothing published yet) draws the part where it was meshed.
    if q == [0.0; 4] {
        return;
    }
    let rot = crate::rigid_body::rotation_of(q).to_rotation_matrix();
    let (x, center) = (nalgebra::Vector3::from(x), nalgebra::Vector3::from(rigid.center));
    for p in pos.chunks_exact_mut(3) {
        let d = nalgebra::Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) - center;
        let w = x + rot * d;
        for k in 0..3 {
            p[k] = w[k] as f32;
        }
    }
}

/// Largest engineering strain |ℓ/ℓ₀ − 1| over the surface edges, from the elastic
/// displacement `u` (3 per kept vertex, part frame) and the rest positions in f64: rigid motion
/// carries no strain, and a strain far below f32's resolution of a coordinate (6e-8 m near
/// 1 m) is still seen. The whole-part counterpart of the haptic thread's watch at the hands: a
/// strain peak away from the hands (a clamped root) shows here.
pub fn max_edge_strain(basis: &Basis, u: &[f32]) -> f64 {
    let mut worst = 0.0f64;
    for i in 0..basis.rest.len() {
        let (lo, hi) = (basis.neighbour_ptr[i] as usize, basis.neighbour_ptr[i + 1] as usize);
        for &k in &basis.neighbours[lo..hi] {
            let k = k as usize;
            if k < i {
                continue; // each edge once
            }
            let (a, b) = (&basis.rest[i], &basis.rest[k]);
            let (mut l0, mut l) = (0.0f64, 0.0f64);
            for c in 0..3 {
                let d0 = b[c] - a[c];
                let d = d0 + (f64::from(u[3 * k + c]) - f64::from(u[3 * i + c]));
                l0 += d0 * d0;
                l += d * d;
            }
            if l0 > 0.0 {
                worst = worst.max((l.sqrt() / l0.sqrt() - 1.0).abs());
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {

    /// Principal values against hand-worked cases: a rotated uniaxial stress and pure shear.
    #[test]
    fn principal_stress_and_strain_of_known_states() {
        // Uniaxial 100 MPa along (1, 1, 0)/√2: σxx = σyy = σxy = 50 MPa.
        let s = [50e6, 50e6, 0.0, 0.0, 0.0, 50e6];
        let p = principal_stresses(s);
        assert!(
            (p[0] - 100e6).abs() < 1e-3 && p[1].abs() < 1e-3 && p[2].abs() < 1e-3,
            "{p:?}"
        );
        // Its largest principal strain is σ/E (the lateral ones are −νσ/E).
        let e = principal_strain_max(p, (200e9, 0.3));
        assert!((e - 100e6 / 200e9).abs() < 1e-15, "{e}");
        // Pure shear τ in yz: principal ±τ, von Mises √3 τ.
        let t = [0.0, 0.0, 0.0, 10e6, 0.0, 0.0];
        let p = principal_stresses(t);
        assert!((p[0] - 10e6).abs() < 1e-3 && (p[2] + 10e6).abs() < 1e-3, "{p:?}");
        assert!((von_mises(t) - 3f64.sqrt() * 10e6).abs() < 1e-3);
        // Its largest principal strain is τ(1 + ν)/E = γ/2.
        let e = principal_strain_max(p, (200e9, 0.3));
        assert!((e - 10e6 * 1.3 / 200e9).abs() < 1e-15, "{e}");
    }
    use super::*;

    /// Von Mises of uniaxial tension is the tension, of pure shear √3 times the shear; the
    /// modal sum and its maximum follow q.
    #[test]
    fn von_mises_of_known_states_and_of_a_modal_sum() {
        assert!((von_mises([5.0, 0.0, 0.0, 0.0, 0.0, 0.0]) - 5.0).abs() < 1e-12);
        assert!((von_mises([0.0, 0.0, 0.0, 0.0, 0.0, 2.0]) - 2.0 * 3f64.sqrt()).abs() < 1e-12);
        assert!(von_mises([7.0, 7.0, 7.0, 0.0, 0.0, 0.0]).abs() < 1e-12, "hydrostatic");
        let b = crate::basis::stretch_grid(1.0, 1.0, 0.0);
        let n = b.vertex_count();
        // One mode whose stress is uniaxial 1 MPa per unit q at vertex 2 only.
        let mut rows = vec![0.0; 6 * n];
        rows[6 * 2] = 1e6;
        let b = b.with_stress(&rows).unwrap();
        let mut sigma = vec![0.0f32; 6 * n];
        assert!(stresses(&b, &[3.0], &mut sigma));
        let (vm, at) = max_von_mises(&sigma);
        assert_eq!(at, 2);
        assert!((vm - 3e6).abs() < 1.0, "{vm}");
    }

    /// A uniform stretch by ε along x of a 3 × 3 grid of 1 cm edges, 1 m from the origin: the
    /// largest edge strain is ε (x edges), down to 1e-9, where f32 positions (rounded by 6e-8 m
    /// near 1 m) gave a floor of ~6e-6.
    #[test]
    fn edge_strain_of_a_stretched_grid_far_from_the_origin() {
        let mut b = crate::basis::stretch_grid(1.0, 1.0, 0.0);
        for p in &mut b.rest {
            p[0] += 1.0;
        }
        let mut u = vec![0.0f32; 3 * b.vertex_count()];
        for eps in [0.0, 1e-9, 1e-7, 1e-3, 0.05] {
            displacements(&b, &[eps], &mut u);
            let s = max_edge_strain(&b, &u);
            assert!((s - eps).abs() <= 1e-6 * eps, "{s} vs {eps}");
        }
    }
}
