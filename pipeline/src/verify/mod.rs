//! `ves verify`: the same mesh, material and supports through independent, real solvers
//! (scikit-fem, CalculiX, FEniCSx), and how far our modes, static response and load cases are
//! from theirs.
//!
//! Each reference solver is a file behind the [`Reference`] trait (what it can check, whether it
//! is installed, how it runs, how long it takes) and one line of [`REFERENCES`]. Its drivers are
//! small Python programs embedded in the binary and written to a private work folder at run
//! time, so an installed `ves` needs no source tree.

use crate::linsolve::factor_stiffness;
use crate::modes::Modes;
use crate::modes::{SolverChoice, solve};
use crate::problem::{Discretized, discretize};
use crate::scene::Scene;
use anyhow::{Context, Result};
use ndarray::{Array1, Array2};
use serde::Serialize;
use std::path::Path;

mod compare;
pub mod error;
pub mod loads;
pub mod reference;
pub mod tolerances;

pub use error::VerifyError;
pub use reference::{Against, Capabilities, Capability, Reference};
pub use tolerances::{STRESS_TOLERANCE, ToleranceOverrides, Tolerances};

// The reference solvers, a file each.
mod calculix;
mod fenicsx;
mod scikit_fem;

/// Every reference solver, in the order `--against all` runs them; `--against NAME` looks its
/// name up here.
pub static REFERENCES: &[&dyn Reference] = &[&scikit_fem::ScikitFem, &calculix::Calculix, &fenicsx::Fenicsx];

/// One mode compared.
#[derive(Debug, Serialize)]
pub struct ModeRow {
    /// Index (0-based, elastic modes).
    pub mode: usize,
    /// The reference's mode it is paired with (0-based): the one of largest MAC, one to one.
    pub reference_mode: usize,
    /// Ours, Hz.
    pub ours_hz: f64,
    /// Reference, Hz.
    pub reference_hz: f64,
    /// |ours − ref| / ref.
    pub rel_diff: f64,
    /// Modal assurance criterion with the paired reference mode (M-weighted).
    pub mac: f64,
    /// Group of (near-)repeated frequencies this mode belongs to.
    pub group: usize,
    /// Largest principal angle between the group's subspaces, rad.
    pub group_angle_rad: f64,
    /// With `--stress`: relative difference of our stress recovered from the reference's mode
    /// shape and the reference's nodal stress of that shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stress_rel_diff: Option<f64>,
    /// The same with the volume-weighted averaging a basis stores (information: CalculiX
    /// averages arithmetically, so this gap is the averaging's, not an error of either).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stress_rel_diff_volume_weighted: Option<f64>,
}

/// One reference's comparison.
#[derive(Debug, Serialize)]
pub struct ReferenceReport {
    /// Solver and version.
    pub solver: String,
    /// Per-mode rows.
    pub modes: Vec<ModeRow>,
    /// Worst frequency difference.
    pub max_rel_freq_diff: f64,
    /// Worst MAC among isolated modes.
    pub min_mac_isolated: f64,
    /// Worst principal angle among groups of close frequencies, rad (`None`: no such group).
    pub max_group_angle_rad: Option<f64>,
    /// Static displacement at the load node, ours vs reference, relative.
    pub static_rel_diff: Option<f64>,
    /// With `--stress`: the largest relative stress difference over the modes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_stress_rel_diff: Option<f64>,
    /// Wall time of the reference run, s.
    pub seconds: f64,
    /// Tolerances applied.
    pub tolerances: Tolerances,
    /// Within tolerances.
    pub pass: bool,
}

/// The whole report.
#[derive(Debug, Serialize)]
pub struct VerifyReport {
    /// What was verified.
    pub input: String,
    /// Nodes (corner vertices and mid-edge nodes).
    pub nodes: usize,
    /// Tets.
    pub tets: usize,
    /// 1 or 2.
    pub element_order: u8,
    /// Free DOFs.
    pub dofs: usize,
    /// The node of the static check's unit load (index).
    pub load_node: usize,
    /// The unit load's direction.
    pub load_direction: [f64; 3],
    /// One entry per reference.
    pub references: Vec<ReferenceReport>,
    /// The references `--against all` left out (not installed, or not applicable), and why.
    pub skipped: Vec<Skipped>,
    /// Every reference within tolerances.
    pub pass: bool,
    /// A scene's static load cases against the first reference asked for that solves them
    /// (CalculiX `*STATIC`; absent without loads or when no such reference was asked for).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<loads::LoadComparison>,
    /// Wall time of the load cases' reference run, s (absent when there was none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loads_seconds: Option<f64>,
    /// What solved the load cases (the reference's [`Reference::loads_label`]), for the table.
    #[serde(skip)]
    pub loads_solver: Option<&'static str>,
}

/// A reference left out of the comparison.
#[derive(Debug, Serialize)]
pub struct Skipped {
    /// Which: the reference's label (`scikit-fem`, `CalculiX`, `FEniCSx`), or its load-case
    /// solver's (`CalculiX *STATIC`).
    pub solver: &'static str,
    /// Why, and how to include it.
    pub reason: String,
}

/// A duration for a person: "12 s", "3.4 min", "1.2 h".
pub fn human_seconds(s: f64) -> String {
    if s < 1.0 {
        "under 1 s".to_string()
    } else if s < 90.0 {
        format!("{s:.0} s")
    } else if s < 5400.0 {
        format!("{:.1} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

/// The line said before reference `r` runs on `n` unknowns.
fn announce(r: &dyn Reference, n: usize) -> String {
    match r.time_model() {
        Some((a, b)) => format!(
            "{}: {n} unknowns, expected about {} (a·n^b model, docs/validation.md)",
            r.label(),
            human_seconds(a * (n as f64).powf(b))
        ),
        None => format!("{}: {n} unknowns (no timing measured for it)", r.label()),
    }
}

/// The line said before reference `r` solves `cases` load cases on `n` unknowns.
fn announce_loads(r: &dyn Reference, cases: usize, n: usize) -> String {
    let label = r.loads_label();
    match r.loads_time_model() {
        Some((a, b)) => format!(
            "{label}: {cases} load case(s), {n} unknowns, expected about {} (docs/validation.md)",
            human_seconds(cases as f64 * a * (n as f64).powf(b))
        ),
        None => format!("{label}: {cases} load case(s), {n} unknowns (no timing measured for it)"),
    }
}

/// Runs the comparison for a scene (meshed and solved here) or a basis file (its mesh,
/// supports, material and stored modes) against the references `against` stands for; `All`
/// leaves out, with a word, those not installed or not applicable.
pub fn verify_input(
    input: &Path,
    against: Against,
    modes: Option<usize>,
    overrides: &ToleranceOverrides,
    stress: bool,
) -> Result<VerifyReport> {
    let is_scene = input.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let mut scene = None;
    let (d, ours) = if is_scene {
        let sc = Scene::load(input)?;
        crate::progress::stage("meshing and assembling", 0.0)?;
        let d = discretize(&sc, None)?;
        crate::progress::stage(&format!("our modes: {} unknowns", d.dofs.free_count()), 0.0)?;
        let (ours, _) = solve(d.space(), modes.unwrap_or(sc.modes.count), SolverChoice::Arpack)?;
        scene = Some(sc);
        (d, ours)
    } else {
        crate::progress::stage("reading the basis and rebuilding its stiffness and mass", 0.0)?;
        discretize_basis(input, modes)?
    };
    let asked = against.references();
    if stress {
        stress_compared_by(&asked)?;
    }
    let name = input.display().to_string();
    let (running, skipped) = select(&name, against, d.rigid)?;
    let mut report = verify(&name, &d, &ours, &running, overrides, stress)?;
    report.skipped = skipped;
    // The load cases go to the first reference asked for that solves them.
    let by_loads = asked.into_iter().find(|r| r.capabilities().has(Capability::LoadCases));
    if let (Some(sc), Some(r)) = (scene.filter(|s| !s.loads.is_empty()), by_loads) {
        if running.iter().any(|x| x.name() == r.name()) {
            crate::progress::stage(&announce_loads(r, sc.loads.len(), d.dofs.free_count()), 1.0)?;
            let t = std::time::Instant::now();
            report.loads = loads::compare_loads(&name, &sc, &d, r, overrides.load)?;
            report.loads_seconds = Some(t.elapsed().as_secs_f64());
            report.loads_solver = Some(r.loads_label());
            report.pass &= report.loads.iter().all(|l| l.pass);
        } else {
            let reason = format!("the load cases are checked with {}, which did not run", r.label());
            tracing::warn!("{} skipped: {reason}", r.loads_label());
            report.skipped.push(Skipped {
                solver: r.loads_label(),
                reason,
            });
        }
    }
    Ok(report)
}

/// `--stress` needs a reference that compares nodal stresses among those `asked`.
fn stress_compared_by(asked: &[&'static dyn Reference]) -> Result<(), VerifyError> {
    let able = |r: &dyn Reference| r.capabilities().has(Capability::NodalStress);
    if asked.iter().any(|r| able(*r)) {
        return Ok(());
    }
    let all: Vec<_> = REFERENCES.iter().filter(|r| able(**r)).collect();
    Err(VerifyError::StressNotCompared {
        labels: all.iter().map(|r| r.label()).collect::<Vec<_>>().join(" or "),
        names: all.iter().map(|r| r.name()).collect::<Vec<_>>().join(" or "),
    })
}

/// Rebuilds the discrete problem of a basis file's global space (its own mesh, supports and
/// material) and takes its stored modes. The whole file is checked first by the one reader, so a
/// damaged or crafted basis ends in its one-line message naming the file, not in a solver's failure.
pub fn discretize_basis(path: &Path, modes: Option<usize>) -> Result<(Discretized, Modes)> {
    let crate::store::StoredSpace {
        mesh,
        material,
        fixed,
        eigenvalues: lam,
        rows: basis,
        r,
        ..
    } = crate::store::read_global(path, modes)?;
    let mut mask = vec![false; 3 * mesh.nodes.len()];
    for &f in &fixed {
        mask[f as usize] = true;
    }
    let dofs = crate::fem::Dofs::from_mask(&mask);
    let d = Discretized::assemble(mesh, dofs, material)
        .with_context(|| format!("{}: rebuilding its stiffness and mass", path.display()))?;
    let nf = d.dofs.free_count();
    let mut vectors = Vec::with_capacity(nf * r);
    for j in 0..r {
        vectors.extend(d.dofs.free.iter().map(|&k| basis[k as usize * r + j]));
    }
    let problem = crate::modes::EigenProblem::of(&d.system);
    let sigma = -1e-8 * problem.scales().stiffness();
    let ours = Modes {
        eigenvalues: lam[..r].to_vec(),
        vectors,
        rigid_dropped: d.rigid,
        residuals: vec![],
        orthonormality_error: f64::NAN,
        sigma,
        factorize_s: 0.0,
        eigensolve_s: 0.0,
        factored: None,
    };
    Ok((d, ours))
}

/// The references of `against` that can run on this part, and those left out with why. One
/// reference asked for by name that is not installed is an error; so is none left to run.
fn select(
    input: &str,
    against: Against,
    rigid: usize,
) -> Result<(Vec<&'static dyn Reference>, Vec<Skipped>), VerifyError> {
    let (mut running, mut skipped) = (Vec::new(), Vec::new());
    for r in against.references() {
        let free = (rigid > 0 && !r.capabilities().has(Capability::FreeBody)).then(|| {
            format!(
                "the part is free ({rigid} rigid modes) and the {} reference runs on supported parts only",
                r.label()
            )
        });
        match (r.missing(), free) {
            (Some(advice), _) if !against.is_all() => {
                return Err(VerifyError::NotInstalled {
                    input: input.to_string(),
                    advice,
                });
            }
            (Some(advice), _) => skip(&mut skipped, r, advice.to_string()),
            (None, Some(reason)) => skip(&mut skipped, r, reason),
            (None, None) => running.push(r),
        }
    }
    if running.is_empty() {
        let why: Vec<String> = skipped.iter().map(|s| format!("{}: {}", s.solver, s.reason)).collect();
        return Err(VerifyError::NoneCouldRun {
            input: input.to_string(),
            why: why.join("; "),
        });
    }
    Ok((running, skipped))
}

/// Leaves `r` out, with a warning.
fn skip(skipped: &mut Vec<Skipped>, r: &dyn Reference, reason: String) {
    tracing::warn!("{} skipped: {reason}", r.label());
    skipped.push(Skipped {
        solver: r.label(),
        reason,
    });
}

/// The static check's load: 1 N at the node that moves most in the first mode, along that
/// motion. Its node and direction.
fn load_point(d: &Discretized, ours: &Modes) -> (usize, [f64; 3]) {
    let n = d.mesh.nodes.len();
    let nf = d.dofs.free_count();
    let phi1 = d.dofs.expand(&ours.vectors[..nf]);
    let load_node = (0..n)
        .max_by(|&a, &b| {
            let m = |i: usize| (0..3).map(|c| phi1[3 * i + c].powi(2)).sum::<f64>();
            m(a).total_cmp(&m(b))
        })
        .unwrap_or(0);
    let norm = (0..3)
        .map(|c| phi1[3 * load_node + c].powi(2))
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE);
    (load_node, [0, 1, 2].map(|c| phi1[3 * load_node + c] / norm))
}

/// Compares a discrete problem and our modes with each of `running`, one after the other.
fn verify(
    input: &str,
    d: &Discretized,
    ours: &Modes,
    running: &[&'static dyn Reference],
    overrides: &ToleranceOverrides,
    stress: bool,
) -> Result<VerifyReport> {
    let n = d.mesh.nodes.len();
    let nf = d.dofs.free_count();
    let (load_node, dir) = load_point(d, ours);
    let mut load = vec![0.0; 3 * n];
    load[3 * load_node..3 * load_node + 3].copy_from_slice(&dir);
    let static_ours = if d.rigid == 0 {
        Some(static_solve(d, &load)?)
    } else {
        None
    };

    // A private work folder (mode 0700, unpredictable name, removed even on SIGTERM): the
    // problem file all references read, and a folder of each one's own.
    let tmp = crate::workdir::WorkDir::new("verify").map_err(|source| VerifyError::WorkDir {
        what: "the reference solvers",
        source,
    })?;
    let problem = tmp.path().join("problem.h5");
    write_problem(&problem, d, ours, &load, load_node)?;

    let curved = !d.mesh.curved_tets().is_empty();
    let lame = crate::fem::element::Lame::of(&d.material);
    let mut reports = Vec::new();
    for (i, &r) in running.iter().enumerate() {
        crate::progress::stage(&announce(r, nf), i as f64 / running.len() as f64)?;
        let t = std::time::Instant::now();
        let dir = tmp.path().join(r.name());
        crate::workdir::create_dir(&dir).map_err(|source| VerifyError::Write {
            path: dir.clone(),
            source,
        })?;
        let with_stress = stress && r.capabilities().has(Capability::NodalStress);
        let theirs = r.run(&reference::Job {
            input,
            problem: &problem,
            dir: &dir,
            stress: with_stress,
        })?;
        let tol = r.tolerances(d.mesh.kind.order(), curved).overridden(overrides);
        let static_checked = static_ours
            .as_deref()
            .filter(|_| r.capabilities().has(Capability::Static));
        let stress_of = with_stress.then_some(&lame);
        let mut rep = compare::compare(d, ours, &theirs, static_checked, load_node, &tol, stress_of)?;
        rep.seconds = t.elapsed().as_secs_f64();
        reports.push(rep);
    }
    if std::env::var_os("VES_KEEP_VERIFY").is_some() {
        eprintln!("reference files kept in {}", tmp.keep().display());
    }
    let pass = reports.iter().all(|r| r.pass);
    Ok(VerifyReport {
        input: input.to_string(),
        nodes: n,
        tets: d.mesh.tet_count(),
        element_order: d.mesh.kind.order(),
        dofs: nf,
        load_node,
        load_direction: dir,
        references: reports,
        skipped: Vec::new(),
        pass,
        loads: Vec::new(),
        loads_seconds: None,
        loads_solver: None,
    })
}

/// Our static displacement under `load` (a full DOF vector), from one factorisation of K.
fn static_solve(d: &Discretized, load: &[f64]) -> Result<Vec<f64>> {
    let chol = factor_stiffness(&d.system, &d.dofs)?;
    let mut f: Vec<f64> = d.dofs.free.iter().map(|&g| load[g as usize]).collect();
    chol.solve_many_in_place(&mut f, 1);
    Ok(d.dofs.expand(&f))
}

/// The problem's nodes, tets and fixed DOFs, as the reference drivers read them.
pub(super) fn write_mesh(f: &hdf5::File, d: &Discretized) -> hdf5::Result<()> {
    let n = d.mesh.nodes.len();
    f.new_dataset_builder()
        .with_data(&Array2::from_shape_fn((n, 3), |(i, c)| d.mesh.nodes[i][c]))
        .create("nodes")?;
    let p = d.mesh.nodes_per_tet();
    f.new_dataset_builder()
        .with_data(&Array2::from_shape_fn((d.mesh.tet_count(), p), |(e, k)| {
            d.mesh.tets[e * p + k]
        }))
        .create("tets")?;
    f.new_dataset_builder()
        .with_data(&Array1::from(d.dofs.fixed.clone()))
        .create("fixed_dofs")?;
    Ok(())
}

/// The problem every reference reads ([`reference::Job::problem`]), sealed (0600).
fn write_problem(
    path: &Path,
    d: &Discretized,
    ours: &Modes,
    load: &[f64],
    load_node: usize,
) -> Result<(), VerifyError> {
    let write = || -> hdf5::Result<()> {
        let f = ves_format::file::create(path, false)?;
        write_mesh(&f, d)?;
        f.new_dataset_builder()
            .with_data(&Array1::from(load.to_vec()))
            .create("load")?;
        let m = &d.material;
        for (k, v) in [
            ("young", m.young),
            ("poisson", m.poisson),
            ("density", m.density),
            ("sigma", ours.sigma),
        ] {
            f.new_attr::<f64>().create(k)?.write_scalar(&v)?;
        }
        for (k, v) in [
            ("order", u64::from(d.mesh.kind.order())),
            ("vertex_count", d.mesh.vertex_count as u64),
            ("modes", ours.eigenvalues.len() as u64),
            ("rigid", d.rigid as u64),
            ("load_node", load_node as u64),
        ] {
            f.new_attr::<u64>().create(k)?.write_scalar(&v)?;
        }
        Ok(())
    };
    seal_problem(path, write)
}

/// Writes a problem file for the references with `write`, then seals it (0600); each failure
/// named with the file.
fn seal_problem(path: &Path, write: impl FnOnce() -> hdf5::Result<()>) -> Result<(), VerifyError> {
    write().map_err(|source| VerifyError::WriteProblem {
        path: path.to_path_buf(),
        source,
    })?;
    crate::workdir::seal(path).map_err(|source| VerifyError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The time model reproduces what it was fitted on (cases/cantilever at mesh.size 0.025,
    /// 0.018 and 0.013: docs/validation.md) within 20 %, and the announcement names the solver,
    /// the size and the expected time.
    #[test]
    fn the_expected_time_follows_the_measured_runs() {
        let by_name = |name: &str| match name.parse::<Against>() {
            Ok(Against::One(r)) => r,
            other => panic!("{name}: {other:?}"),
        };
        let measured = [
            ("scikit-fem", [(11652, 14.4), (26082, 33.1), (59751, 133.9)]),
            ("calculix", [(11652, 7.1), (26082, 18.6), (59751, 47.8)]),
        ];
        for (name, runs) in measured {
            let (a, b) = by_name(name).time_model().expect("a model");
            for (n, t) in runs {
                let model = a * (n as f64).powf(b);
                assert!(
                    (model / t - 1.0).abs() < 0.2,
                    "{name} at {n}: model {model:.1} s, measured {t} s"
                );
            }
        }
        assert_eq!(
            announce(by_name("scikit-fem"), 59751),
            "scikit-fem: 59751 unknowns, expected about 2.0 min (a·n^b model, docs/validation.md)"
        );
        assert!(announce(by_name("fenicsx"), 10).contains("no timing measured"));
        assert_eq!(human_seconds(0.2), "under 1 s");
        assert_eq!(human_seconds(7200.0), "2.0 h");
    }

    /// Every reference is found by its `--against` name, and the names are unique.
    #[test]
    fn every_reference_is_found_by_its_name() {
        for r in REFERENCES {
            assert!(matches!(r.name().parse::<Against>(), Ok(Against::One(x)) if x.name() == r.name()));
            assert_eq!(REFERENCES.iter().filter(|x| x.name() == r.name()).count(), 1);
            assert!(r.capabilities().has(Capability::Modes), "{}", r.name());
        }
        assert!(matches!("all".parse::<Against>(), Ok(Against::All)));
        let e = "abaqus".parse::<Against>().expect_err("unknown");
        assert!(
            e.to_string()
                .contains(r#""scikit-fem", "calculix", "fenicsx" or "all""#),
            "{e}"
        );
    }
}
