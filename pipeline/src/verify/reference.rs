//! A reference solver as `ves verify` sees it ([`Reference`]), the results every reference gives
//! back ([`Solution`], [`LoadSolution`]), and which of them `--against NAME` means ([`Against`]).

use super::REFERENCES;
use super::error::VerifyError;
use super::tolerances::Tolerances;
use ndarray::Array2;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Something a reference can check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Capability {
    /// The lowest elastic modes (every reference).
    Modes,
    /// The static displacement under the unit load at the load node (supported parts).
    Static,
    /// Free parts (the modes above the rigid ones).
    FreeBody,
    /// Its own nodal stress of each of its modes (`--stress`).
    NodalStress,
    /// A scene's service load cases, solved statically.
    LoadCases,
}

/// A set of [`Capability`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Capabilities(u8);

impl Capabilities {
    /// The set of `list`.
    pub const fn of(list: &[Capability]) -> Capabilities {
        let mut bits = 0;
        let mut i = 0;
        while i < list.len() {
            bits |= 1 << list[i] as u8;
            i += 1;
        }
        Capabilities(bits)
    }

    /// Whether `c` is in it.
    pub fn has(self, c: Capability) -> bool {
        self.0 & (1 << c as u8) != 0
    }
}

/// An independent solver `ves verify` compares against: what it is called, what it can check,
/// whether it is installed, how it runs, how long it takes. Each lives in a file of its own
/// (`verify/scikit_fem.rs`, …) and is listed once in [`REFERENCES`].
pub trait Reference: Sync {
    /// Its name on the command line (`--against NAME`).
    fn name(&self) -> &'static str;
    /// Its name in reports and messages.
    fn label(&self) -> &'static str;
    /// What it is and where it comes from, one line for `--help`.
    fn about(&self) -> &'static str;
    /// What it can check.
    fn capabilities(&self) -> Capabilities;
    /// Why it cannot run here (a program or module missing) and how to install it, in one
    /// line; `None` when it can.
    fn missing(&self) -> Option<&'static str>;
    /// Its default tolerances on elements of `order` (1 or 2), `curved` or straight-sided.
    fn tolerances(&self, order: u8, curved: bool) -> Tolerances;
    /// Expected wall time `a·n^b` s of a run on `n` unknowns, `(a, b)` as measured
    /// (docs/validation.md, "Progress and expected time"); `None` where nothing was measured.
    fn time_model(&self) -> Option<(f64, f64)> {
        None
    }
    /// Runs it on `job`'s problem: writes its own inputs into `job.dir`, runs its program and
    /// reads the results back.
    fn run(&self, job: &Job) -> Result<Solution, VerifyError>;

    /// What its load-case solver is called in reports ([`Capability::LoadCases`]).
    fn loads_label(&self) -> &'static str {
        self.label()
    }
    /// `(a, b)` of its expected time per load case, as [`Reference::time_model`].
    fn loads_time_model(&self) -> Option<(f64, f64)> {
        None
    }
    /// Solves `job`'s load cases ([`Capability::LoadCases`]).
    fn solve_loads(&self, job: &LoadJob) -> Result<LoadSolution, VerifyError> {
        Err(VerifyError::NotCapable {
            input: job.input.to_string(),
            reference: self.label(),
            what: "load cases",
        })
    }
}

/// A modal run asked of a reference.
pub struct Job<'a> {
    /// What is verified (a scene or basis path), for messages.
    pub input: &'a str,
    /// The problem every reference reads (HDF5: `nodes`, `tets`, `fixed_dofs`, `load`; the
    /// material, σ, element order, vertex, mode and rigid-mode counts and the load node as
    /// attributes).
    pub problem: &'a Path,
    /// A private folder of its own for its inputs and results.
    pub dir: &'a Path,
    /// Whether to read back its nodal stress of each mode (`--stress`).
    pub stress: bool,
}

/// What a reference computed, on the problem's nodes and DOF numbering (3i + c).
#[derive(Debug)]
pub struct Solution {
    /// The file it was read from, for messages.
    pub source: PathBuf,
    /// The solver and its version.
    pub solver: String,
    /// Its elastic frequencies, Hz, ascending.
    pub frequencies_hz: Vec<f64>,
    /// Its mode shapes, [3n, r].
    pub modes: Array2<f64>,
    /// Its static displacement under the problem's load, [3n] (when it wrote one).
    pub static_displacement: Option<Vec<f64>>,
    /// Its nodal stress of each mode, [6n, r], row 6i + k = Voigt component k at node i
    /// (when asked for).
    pub mode_stress: Option<Array2<f64>>,
}

impl Solution {
    /// Reads the result file every reference driver writes (`frequencies_hz`, `modes`,
    /// optionally `static` and `mode_stress`, attribute `solver`); the stress only if `stress`.
    pub fn read(path: &Path, stress: bool) -> Result<Solution, VerifyError> {
        let read = || -> hdf5::Result<Solution> {
            let f = ves_format::file::open(path)?;
            let optional = |name: &str| f.link_exists(name).then(|| f.dataset(name)).transpose();
            Ok(Solution {
                source: path.to_path_buf(),
                solver: ves_format::strings::read(&f, "solver").unwrap_or_default(),
                frequencies_hz: f.dataset("frequencies_hz")?.read_raw()?,
                modes: f.dataset("modes")?.read_2d()?,
                static_displacement: optional("static")?.map(|d| d.read_raw()).transpose()?,
                mode_stress: match stress {
                    true => optional("mode_stress")?.map(|d| d.read_2d()).transpose()?,
                    false => None,
                },
            })
        };
        read().map_err(|source| VerifyError::ReadResults {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// The load cases asked of a reference.
pub struct LoadJob<'a> {
    /// What is verified, for messages.
    pub input: &'a str,
    /// The problem (HDF5: `nodes`, `tets`, `fixed_dofs`, `loads` [cases, 3n] in N per DOF;
    /// `young`, `poisson` as attributes).
    pub problem: &'a Path,
    /// A private folder of its own.
    pub dir: &'a Path,
}

/// A reference's solution of the load cases.
#[derive(Debug)]
pub struct LoadSolution {
    /// The file it was read from, for messages.
    pub source: PathBuf,
    /// Each case's displacement of every DOF, [cases, 3n].
    pub displacement: Array2<f64>,
    /// Each case's internal force K u summed over the supported DOFs, per component, [cases, 3].
    pub reaction: Array2<f64>,
}

/// Which references `--against NAME` means: one of [`REFERENCES`], or all of them.
#[derive(Clone, Copy)]
pub enum Against {
    /// Every one installed and applicable.
    All,
    /// That one.
    One(&'static dyn Reference),
}

impl Against {
    /// The references it stands for, in the order of [`REFERENCES`].
    pub fn references(self) -> Vec<&'static dyn Reference> {
        match self {
            Against::All => REFERENCES.to_vec(),
            Against::One(r) => vec![r],
        }
    }

    /// Whether it means all references.
    pub fn is_all(self) -> bool {
        matches!(self, Against::All)
    }
}

/// What `--against` accepts besides the references' names.
pub const ALL: &str = "all";

/// The names `--against` accepts, quoted, as a sentence: `"scikit-fem", … or "all"`.
pub fn known_names() -> String {
    let names: Vec<String> = REFERENCES.iter().map(|r| format!("{:?}", r.name())).collect();
    format!("{} or {ALL:?}", names.join(", "))
}

impl std::str::FromStr for Against {
    type Err = VerifyError;

    fn from_str(name: &str) -> Result<Against, VerifyError> {
        if name == ALL {
            return Ok(Against::All);
        }
        REFERENCES
            .iter()
            .find(|r| r.name() == name)
            .map(|&r| Against::One(r))
            .ok_or_else(|| VerifyError::UnknownReference {
                name: name.to_string(),
                known: known_names(),
            })
    }
}

impl std::fmt::Debug for Against {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Against::All => f.write_str(ALL),
            Against::One(r) => f.write_str(r.name()),
        }
    }
}

/// Writes a reference's driver script `name` into `dir`; returns its path.
pub(super) fn write_script(dir: &Path, name: &str, text: &str) -> Result<PathBuf, VerifyError> {
    let path = dir.join(name);
    crate::workdir::write(&path, text.as_bytes()).map_err(|source| VerifyError::Write {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// Runs a reference's program on the problem made from `input`; its failure names `input` and
/// the program's last line of stderr (a Python traceback's exception).
pub(super) fn run_checked(input: &str, what: &str, cmd: &mut Command) -> Result<(), VerifyError> {
    let out = cmd.output().map_err(|source| VerifyError::CannotRun {
        input: input.to_string(),
        what: what.to_string(),
        source,
    })?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(VerifyError::Failed {
            input: input.to_string(),
            what: what.to_string(),
            message: ves_format::names::escape_for_terminal(
                err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no message"),
            ),
        });
    }
    Ok(())
}

/// Whether `python` imports every one of `modules`.
pub(super) fn python_imports(python: &str, modules: &str) -> bool {
    Command::new(python)
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success())
}
