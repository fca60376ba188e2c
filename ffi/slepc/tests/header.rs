//! The hand-written PETSc/SLEPc declarations against the installed headers: a C program built
//! with `pkg-config --cflags slepc` prints every constant and type size `src/sys.rs` declares,
//! and each must equal the Rust one (review once found `SAME_NONZERO_PATTERN` declared as 0,
//! which PETSc reads as DIFFERENT_NONZERO_PATTERN).
#![cfg(feature = "slepc")]

use std::collections::HashMap;
use std::process::Command;
use ves_slepc::sys;

#[test]
fn every_declared_constant_and_type_size_matches_the_headers() {
    let rust: Vec<(&str, i64)> = vec![
        ("PETSC_TRUE", sys::PETSC_TRUE.into()),
        ("PETSC_DECIDE", sys::PETSC_DECIDE.into()),
        ("PETSC_DEFAULT", sys::PETSC_DEFAULT.into()),
        ("INSERT_VALUES", sys::INSERT_VALUES.into()),
        ("SCATTER_FORWARD", sys::SCATTER_FORWARD.into()),
        ("MAT_FINAL_ASSEMBLY", sys::MAT_FINAL_ASSEMBLY.into()),
        ("MAT_SYMMETRIC", sys::MAT_SYMMETRIC.into()),
        ("EPS_GHEP", sys::EPS_GHEP.into()),
        ("EPS_TARGET_MAGNITUDE", sys::EPS_TARGET_MAGNITUDE.into()),
        ("EPS_ERROR_RELATIVE", sys::EPS_ERROR_RELATIVE.into()),
        ("SAME_NONZERO_PATTERN", sys::SAME_NONZERO_PATTERN.into()),
        ("NORM_2", sys::NORM_2.into()),
        ("sizeof(PetscInt)", std::mem::size_of::<sys::PetscInt>() as i64),
        ("sizeof(PetscMPIInt)", std::mem::size_of::<sys::PetscMPIInt>() as i64),
        ("sizeof(PetscScalar)", std::mem::size_of::<sys::PetscScalar>() as i64),
        ("sizeof(PetscReal)", std::mem::size_of::<sys::PetscReal>() as i64),
        ("sizeof(PetscBool)", std::mem::size_of::<sys::PetscBool>() as i64),
        (
            "sizeof(PetscErrorCode)",
            std::mem::size_of::<sys::PetscErrorCode>() as i64,
        ),
        ("sizeof(MPI_Comm)", std::mem::size_of::<sys::MPI_Comm>() as i64),
        ("sizeof(Mat)", std::mem::size_of::<sys::Mat>() as i64),
        ("sizeof(Vec)", std::mem::size_of::<sys::PetscVec>() as i64),
        ("sizeof(EPS)", std::mem::size_of::<sys::EPS>() as i64),
        ("sizeof(ST)", std::mem::size_of::<sys::ST>() as i64),
        ("sizeof(KSP)", std::mem::size_of::<sys::KSP>() as i64),
        ("sizeof(PC)", std::mem::size_of::<sys::PC>() as i64),
        ("sizeof(VecScatter)", std::mem::size_of::<sys::VecScatter>() as i64),
        ("sizeof(MatNullSpace)", std::mem::size_of::<sys::MatNullSpace>() as i64),
        ("PETSC_FALSE", sys::PETSC_FALSE as i64),
        ("PetscScalar is real", 1),
        ("MPI_INT is &ompi_mpi_int", 1),
        ("MPI_SUM is &ompi_mpi_op_sum", 1),
        ("MPI_MIN is &ompi_mpi_op_min", 1),
        ("MPI_MAX is &ompi_mpi_op_max", 1),
        ("MPI_DOUBLE is &ompi_mpi_double", 1),
        ("MPI_BYTE is &ompi_mpi_byte", 1),
        ("MPI_STATUS_IGNORE is NULL", 1),
        ("sizeof(int)", std::mem::size_of::<std::os::raw::c_int>() as i64),
    ];
    let mut c = String::from("#include <stdio.h>\n#include <slepceps.h>\nint main(void) {\n");
    for (name, _) in &rust {
        let expr = match *name {
            "PetscScalar is real" => "(long)(sizeof(PetscScalar) == sizeof(PetscReal))".to_string(),
            // The addresses the Rust side passes for Open MPI's predefined handles.
            "MPI_INT is &ompi_mpi_int" => "(long)((void *)MPI_INT == (void *)&ompi_mpi_int)".to_string(),
            "MPI_SUM is &ompi_mpi_op_sum" => "(long)((void *)MPI_SUM == (void *)&ompi_mpi_op_sum)".to_string(),
            "MPI_MIN is &ompi_mpi_op_min" => "(long)((void *)MPI_MIN == (void *)&ompi_mpi_op_min)".to_string(),
            "MPI_MAX is &ompi_mpi_op_max" => "(long)((void *)MPI_MAX == (void *)&ompi_mpi_op_max)".to_string(),
            "MPI_DOUBLE is &ompi_mpi_double" => "(long)((void *)MPI_DOUBLE == (void *)&ompi_mpi_double)".to_string(),
            "MPI_BYTE is &ompi_mpi_byte" => "(long)((void *)MPI_BYTE == (void *)&ompi_mpi_byte)".to_string(),
            "MPI_STATUS_IGNORE is NULL" => "(long)((void *)MPI_STATUS_IGNORE == (void *)0)".to_string(),
            n => format!("(long)({n})"),
        };
        c += &format!("  printf(\"%s\\t%ld\\n\", \"{name}\", {expr});\n");
    }
    c += "  return 0;\n}\n";
    let dir = tempfile::tempdir().expect("temp dir");
    let src = dir.path().join("check.c");
    std::fs::write(&src, c).expect("write C");
    // PETSc's headers include mpi.h: OpenMPI's flags too (the MPI the bindings assume).
    let cflags = Command::new("pkg-config")
        .args(["--cflags", "slepc", "ompi"])
        .output()
        .expect("pkg-config runs");
    assert!(
        cflags.status.success(),
        "pkg-config --cflags slepc ompi: install libslepc-real-dev"
    );
    let exe = dir.path().join("check");
    let cc = Command::new("cc")
        .arg(&src)
        .args(String::from_utf8_lossy(&cflags.stdout).split_whitespace())
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("cc runs");
    assert!(cc.status.success(), "C build: {}", String::from_utf8_lossy(&cc.stderr));
    let out = Command::new(&exe).output().expect("check runs");
    let c_values: HashMap<String, i64> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_once('\t'))
        .map(|(k, v)| (k.to_string(), v.parse().expect("a number")))
        .collect();
    let wrong: Vec<String> = rust
        .iter()
        .filter(|(n, v)| c_values.get(*n) != Some(v))
        .map(|(n, v)| format!("{n}: Rust {v}, headers {:?}", c_values.get(*n)))
        .collect();
    assert!(
        wrong.is_empty(),
        "declarations differ from PETSc/SLEPc's headers: {wrong:?}"
    );
}
