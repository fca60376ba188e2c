//! scikit-fem (PyPI) with scipy's eigsh, shift-invert with SuperLU: the same discrete problem as
//! ours, assembled independently (`skfem_ref.py`).

use super::error::VerifyError;
use super::reference::{Capabilities, Capability, Job, Reference, Solution, python_imports, run_checked, write_script};
use super::tolerances::Tolerances;
use std::process::Command;

const DRIVER: &str = include_str!("skfem_ref.py");

/// scikit-fem.
pub struct ScikitFem;

impl Reference for ScikitFem {
    fn name(&self) -> &'static str {
        "scikit-fem"
    }

    fn label(&self) -> &'static str {
        "scikit-fem"
    }

    fn about(&self) -> &'static str {
        "scikit-fem (PyPI) with scipy's eigsh"
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::of(&[Capability::Modes, Capability::Static, Capability::FreeBody])
    }

    fn missing(&self) -> Option<&'static str> {
        (!python_imports("python3", "skfem, h5py"))
            .then_some("scikit-fem is not installed for python3: run `pip install scikit-fem h5py scipy`")
    }

    /// Exact integration on both sides (on straight-sided elements).
    fn tolerances(&self, _order: u8, curved: bool) -> Tolerances {
        Tolerances::same_discrete_problem(curved)
    }

    /// Fitted on cases/cantilever at three mesh sizes on the 2-core VM.
    fn time_model(&self) -> Option<(f64, f64)> {
        Some((3.634e-5, 1.367))
    }

    fn run(&self, job: &Job) -> Result<Solution, VerifyError> {
        let driver = write_script(job.dir, "skfem_ref.py", DRIVER)?;
        let result = job.dir.join("result.h5");
        run_checked(
            job.input,
            "skfem_ref.py",
            Command::new("python3").arg(driver).arg(job.problem).arg(&result),
        )?;
        Solution::read(&result, job.stress)
    }
}
