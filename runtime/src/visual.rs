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
