//! `ves matrices`: the assembled K and M of a scene's global space, for external solvers and
//! benchmarks (scipy reads them with h5py). Lower triangles in CSC form on the free DOFs.

use crate::problem::Discretized;
use anyhow::{Context, Result};
use ndarray::{Array1, Array2};
use std::path::Path;

/// The file's `storage` attribute: how `k` and `m` are stored, in words a reader acts on.
pub const STORAGE: &str = "k and m are symmetric and stored as their lower triangles only (diagonal included), \
     compressed sparse columns over the free DOFs: column j holds row_idx[col_ptr[j]..col_ptr[j+1]]; \
     the whole matrix is L + L^T - diag(L), e.g. in scipy: L = csc_matrix((k, row_idx, col_ptr)); \
     K = L + L.T - diags(L.diagonal())";

/// Writes `col_ptr`, `row_idx`, `k`, `m` (lower-triangle CSC), `free_dofs`, `nodes`, `tets`, and
/// the attributes `rigid_modes` and `storage` (how to read them, [`STORAGE`]).
/// The file is written atomically (the caller checked `out` with [`crate::output::check`]).
pub fn write_matrices(out: &Path, d: &Discretized) -> Result<()> {
    Ok(crate::output::write_atomically(out, |tmp| write_to(tmp, d))?)
}

fn write_to(out: &Path, d: &Discretized) -> Result<()> {
    // Strong close: closing really closes (errors are ours), and the read-back below reads the
    // disk, not this handle's cache.
    let file = ves_format::file::create(out, false).with_context(|| format!("cannot create {}", out.display()))?;
    let p = &d.system.pattern;
    let as_u64 = |v: &[usize]| Array1::from(v.iter().map(|&x| x as u64).collect::<Vec<_>>());
    file.new_dataset_builder()
        .with_data(&as_u64(p.col_ptr()))
        .create("col_ptr")?;
    file.new_dataset_builder()
        .with_data(&as_u64(p.row_idx()))
        .create("row_idx")?;
    file.new_dataset_builder()
        .with_data(&Array1::from(d.system.k.clone()))
        .create("k")?;
    file.new_dataset_builder()
        .with_data(&Array1::from(d.system.m.clone()))
        .create("m")?;
    file.new_dataset_builder()
        .with_data(&Array1::from(d.dofs.free.clone()))
        .create("free_dofs")?;
    let n = d.mesh.nodes.len();
    file.new_dataset_builder()
        .with_data(&Array2::from_shape_fn((n, 3), |(i, c)| d.mesh.nodes[i][c]))
        .create("nodes")?;
    let tets = Array2::from_shape_vec((d.mesh.tet_count(), d.mesh.nodes_per_tet()), d.mesh.tets.clone())?;
    file.new_dataset_builder().with_data(&tets).create("tets")?;
    file.new_attr::<u32>()
        .create("rigid_modes")?
        .write_scalar(&(d.rigid as u32))?;
    // The file says how to read it: a user who took `k` for a whole matrix solved with half of
    // it (his first frequencies were 60× off), and nothing in the file told him otherwise.
    let storage: hdf5::types::VarLenUnicode = STORAGE.parse().context("the storage note")?;
    file.new_attr::<hdf5::types::VarLenUnicode>()
        .create("storage")?
        .write_scalar(&storage)?;
    // Errors of writes HDF5 deferred (metadata, cached raw data) surface here, not in a drop.
    file.flush().context("flushing the file")?;
    file.close().context("closing the file")?;
    // Read back in full: a write the disk could not hold, whatever layer swallowed its error,
    // is found before the rename.
    let back = ves_format::file::open(out).context("reading the written file back")?;
    let count = |name: &str| -> Result<usize> {
        let ds = back.dataset(name)?;
        Ok(match name {
            "k" | "m" | "nodes" => ds.read_raw::<f64>()?.len(),
            "col_ptr" | "row_idx" => ds.read_raw::<u64>()?.len(),
            _ => ds.read_raw::<u32>()?.len(),
        })
    };
    let expected = [
        ("col_ptr", p.col_ptr().len()),
        ("row_idx", p.row_idx().len()),
        ("k", d.system.k.len()),
        ("m", d.system.m.len()),
        ("free_dofs", d.dofs.free.len()),
        ("nodes", 3 * n),
        ("tets", d.mesh.tets.len()),
    ];
    for (name, len) in expected {
        let got = count(name).with_context(|| format!("{name}: unreadable after writing"))?;
        anyhow::ensure!(got == len, "{name}: {got} values read back, {len} written");
    }
    Ok(())
}
