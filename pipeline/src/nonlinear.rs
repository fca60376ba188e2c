//! The geometrically nonlinear model (`[model] kind = "nonlinear"`, docs/nonlinear.md): the
//! modes enriched with their modal derivatives, and the reduced St. Venant–Kirchhoff energy of
//! that basis, whose coefficients the basis file stores for the runtime. Load cases are the
//! static equilibria of this same reduced model, so that they show what the hand would feel.

use crate::fem::element::Lame;
use crate::fem::stvk::{self, Points, Polynomial};
use crate::linsolve::sym_matvec;
use crate::modes::{Modes, derivatives};
use crate::problem::Discretized;
use anyhow::{Context, Result};

/// A space's nonlinear model.
#[derive(Clone, Debug)]
pub struct NonlinearModel {
    /// The first basis columns that are eigenmodes (the rest are derivatives).
    pub eigenmodes: usize,
    /// How many lowest modes' derivatives were added.
    pub derivatives_of: usize,
    /// Derivatives left out as dependent on the others.
    pub dropped: usize,
    /// Largest coupling through K between the modes and the added vectors (0: exact).
    pub coupling: f64,
    /// The reduced energy of the whole basis; its linear part diagonal, the eigenvalues.
    pub reduced: Polynomial,
}

/// What `--json` and `ves info` say of a nonlinear model.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Summary {
    /// The first basis columns that are eigenmodes.
    pub eigenmodes: usize,
    /// How many lowest modes' derivatives were asked for.
    pub derivatives_of: usize,
    /// Derivative vectors in the basis (after the eigenmodes; fewer than of(of+1)/2 when some
    /// were dependent).
    pub derivatives: usize,
    /// Largest coupling through K between the modes and the derivatives (the precompute's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coupling: Option<f64>,
}

impl Summary {
    /// ", nonlinear: 6 modes + 10 derivatives" for the one-line summaries.
    pub fn text(&self) -> String {
        format!(
            ", nonlinear (St. Venant–Kirchhoff): {} modes + {} derivatives",
            self.eigenmodes, self.derivatives
        )
    }
}

/// The largest residual of the eigenmodes (the first `eigenmodes`; all without a nonlinear
/// model): a derivative is no eigenvector and its residual says nothing of the solve.
pub fn max_residual(residuals: &[f64], eigenmodes: Option<usize>) -> f64 {
    let m = eigenmodes.unwrap_or(residuals.len()).min(residuals.len());
    residuals[..m].iter().fold(0.0, |a: f64, &b| a.max(b))
}

/// Appends the derivatives of the lowest `of` modes to `modes`, and for each of the scene's
/// load cases (`loads`, nodal forces) its linear response and that response's derivative
/// (their Rayleigh quotients as eigenvalues, their true residuals ‖Kv − θMv‖/‖Kv‖), and
/// integrates the reduced energy of the whole basis.
pub fn enrich(d: &Discretized, modes: &mut Modes, of: usize, loads: &[Vec<f64>]) -> Result<NonlinearModel> {
    let m = modes.eigenvalues.len();
    let extra = derivatives::enrich(&d.space(), modes, of, loads)?;
    let nf = d.dofs.free_count();
    let sys = &d.system;
    let (mut kv, mut mv) = (vec![0.0; nf], vec![0.0; nf]);
    for (c, &theta) in extra.ritz_values.iter().enumerate() {
        let v = &extra.vectors[c * nf..(c + 1) * nf];
        sym_matvec(&sys.pattern, &sys.k, v, &mut kv);
        sym_matvec(&sys.pattern, &sys.m, v, &mut mv);
        let res: f64 = kv
            .iter()
            .zip(&mv)
            .map(|(k, m)| (k - theta * m).powi(2))
            .sum::<f64>()
            .sqrt();
        let norm: f64 = kv.iter().map(|k| k * k).sum::<f64>().sqrt();
        modes.residuals.push(res / norm.max(f64::MIN_POSITIVE));
    }
    modes.eigenvalues.extend_from_slice(&extra.ritz_values);
    modes.vectors.extend_from_slice(&extra.vectors);
    let r = modes.eigenvalues.len();
    let full = full_columns(d, modes);
    let points = Points::of(&d.mesh).context("the nonlinear model")?;
    let mut reduced = stvk::reduce(&points, &d.mesh, &Lame::of(&d.material), &full, r);
    // Its linear part is Φᵀ K Φ = Λ up to the modes' residuals: the runtime integrates the
    // linear part mode by mode with the eigenvalues, so the stored model uses them too.
    let off = (0..r)
        .flat_map(|i| (0..r).filter(move |&j| j != i).map(move |j| (i, j)))
        .map(|(i, j)| reduced.k[i * r + j].abs() / (modes.eigenvalues[i] * modes.eigenvalues[j]).sqrt())
        .fold(extra.coupling, f64::max);
    for i in 0..r {
        for j in 0..r {
            reduced.k[i * r + j] = if i == j { modes.eigenvalues[i] } else { 0.0 };
        }
    }
    tracing::info!(
        modes = m,
        derivatives = r - m,
        dropped = extra.dropped,
        coupling = off,
        "nonlinear basis"
    );
    Ok(NonlinearModel {
        eigenmodes: m,
        derivatives_of: of,
        dropped: extra.dropped,
        coupling: off,
        reduced,
    })
}

/// The basis over all 3n DOFs, column-major (zero at supported DOFs).
pub fn full_columns(d: &Discretized, modes: &Modes) -> Vec<f64> {
    let nf = d.dofs.free_count();
    (0..modes.eigenvalues.len())
        .flat_map(|j| d.dofs.expand(&modes.vectors[j * nf..(j + 1) * nf]))
        .collect()
}

/// The equilibrium of the reduced model under the nodal load `f` (3n): the displacement u = Φq
/// (3n) and the full model's internal force at it (3n), from which the supports' reactions are
/// read. 20 load increments.
pub fn static_response(
    d: &Discretized,
    model: &NonlinearModel,
    basis: &[f64],
    f: &[f64],
    points: &Points,
) -> Result<(Vec<f64>, Vec<f64>, stvk::Equilibrium)> {
    let (n3, r) = (f.len(), model.reduced.r);
    let g: Vec<f64> = (0..r)
        .map(|j| basis[j * n3..(j + 1) * n3].iter().zip(f).map(|(a, b)| a * b).sum())
        .collect();
    let eq = model.reduced.equilibrium(&g, 20)?;
    let mut u = vec![0.0; n3];
    for (j, q) in eq.q.iter().enumerate() {
        u.iter_mut()
            .zip(&basis[j * n3..(j + 1) * n3])
            .for_each(|(a, b)| *a += q * b);
    }
    let internal = stvk::internal_force(points, &d.mesh, &Lame::of(&d.material), &u);
    Ok((u, internal, eq))
}
