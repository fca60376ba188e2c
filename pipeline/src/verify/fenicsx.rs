//! FEniCSx (Debian python3-dolfinx, SLEPc through slepc4py): `fenicsx_ref.py` under the Python
//! that has dolfinx, fed and read by `fx_bridge.py` (.npy files, so dolfinx's MPI build of HDF5
//! never meets h5py).

use super::error::VerifyError;
use super::reference::{Capabilities, Capability, Job, Reference, Solution, python_imports, run_checked, write_script};
use super::tolerances::Tolerances;
use std::process::Command;

const DRIVER: &str = include_str!("fenicsx_ref.py");
const BRIDGE: &str = include_str!("fx_bridge.py");

/// FEniCSx.
pub struct Fenicsx;

/// The Python that has dolfinx (Debian installs it for /usr/bin/python3 only).
fn python() -> Option<&'static str> {
    ["python3", "/usr/bin/python3"]
        .into_iter()
        .find(|py| python_imports(py, "dolfinx, slepc4py"))
}

impl Reference for Fenicsx {
    fn name(&self) -> &'static str {
        "fenicsx"
    }

    fn label(&self) -> &'static str {
        "FEniCSx"
    }

    fn about(&self) -> &'static str {
        "FEniCSx (Debian python3-dolfinx, SLEPc through slepc4py)"
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::of(&[Capability::Modes, Capability::Static, Capability::FreeBody])
    }

    fn missing(&self) -> Option<&'static str> {
        python()
            .is_none()
            .then_some("FEniCSx is not installed: run `apt-get install python3-dolfinx python3-slepc4py` (Debian 12)")
    }

    /// Exact integration on both sides (on straight-sided elements).
    fn tolerances(&self, _order: u8, curved: bool) -> Tolerances {
        Tolerances::same_discrete_problem(curved)
    }

    fn run(&self, job: &Job) -> Result<Solution, VerifyError> {
        let Some(fx) = python() else {
            return Err(VerifyError::Disappeared {
                input: job.input.to_string(),
                reference: self.label(),
            });
        };
        let (dir, result) = (job.dir, job.dir.join("result.h5"));
        let bridge = write_script(dir, "fx_bridge.py", BRIDGE)?;
        let bridged = |way: &str, args: [&std::path::Path; 2]| {
            run_checked(
                job.input,
                "fx_bridge.py",
                Command::new("python3").arg(&bridge).arg(way).args(args),
            )
        };
        bridged("in", [job.problem, dir])?;
        let driver = write_script(dir, "fenicsx_ref.py", DRIVER)?;
        run_checked(job.input, "fenicsx_ref.py", Command::new(fx).arg(driver).arg(dir))?;
        bridged("out", [dir, &result])?;
        Solution::read(&result, job.stress)
    }
}
