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

/// Writes deformed positions rest + u into `pos` (3 values per kept vertex).
pub fn positions(basis: &Basis, q: &[f64], pos: &mut [f32]) {
    displacements(basis, q, pos);
    for (p, r) in pos.chunks_exact_mut(3).zip(&basis.rest) {
        for c in 0..3 {
            p[c] += r[c] as f32;
        }
    }
}

/// Drawn positions from a published state (q followed by the pose, see
/// `Haptics::write_published`): x + R(p₀ + u − c) for a free body, p₀ + u for a supported one.
pub fn posed_positions(basis: &Basis, published: &[f64], pos: &mut [f32]) {
    let r = basis.mode_count();
    positions(basis, &published[..r], pos);
    let Some(rigid) = basis.rigid else { return };
    let x = [published[r], published[r + 1], published[r + 2]];
    let q = [published[r + 3], published[r + 4], published[r + 5], published[r + 6]];
    // An all-zero pose (nothing published yet) draws the part where it was meshed.
    if q == [0.0; 4] {
        return;
    }
    let rot = crate::rigid::rotation_matrix(q);
    for p in pos.chunks_exact_mut(3) {
        let d = [
            f64::from(p[0]) - rigid.center[0],
            f64::from(p[1]) - rigid.center[1],
            f64::from(p[2]) - rigid.center[2],
        ];
        for k in 0..3 {
            p[k] = (x[k] + rot[k][0] * d[0] + rot[k][1] * d[1] + rot[k][2] * d[2]) as f32;
        }
    }
}
