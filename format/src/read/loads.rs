//! Reading the static load cases of a space (`loads/<name>/`) and the `fixed` mask: optional
//! (files written before them, or of scenes without loads, have none), checked when present.

use super::{ReadError, SpaceReader, f64_array_attr, scalar_attr};
use crate::checks;
use crate::names::{load as ld, space as sp};

/// One static load case as read, every array checked (shape, finite values within single
/// precision, the largest values as its attributes state them).
#[derive(Clone, Debug, PartialEq)]
pub struct LoadCase {
    /// Its name.
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: String,
    /// Sum of the applied nodal loads, N.
    pub total_force: [f64; 3],
    /// Total support reaction, N.
    pub reaction: [f64; 3],
    /// |reaction + total_force| over the sum of the nodal loads' magnitudes.
    pub balance_residual: f64,
    /// Largest nodal displacement magnitude, m.
    pub max_displacement: f64,
    /// Largest corner-vertex von Mises stress, Pa.
    pub max_von_mises: f64,
    /// Displacement, 3n (row 3i+c), m.
    pub displacement: Vec<f64>,
    /// Von Mises stress of every node, Pa.
    pub von_mises: Vec<f64>,
    /// Stress at the corner vertices, [nv, 6] row-major (Voigt xx yy zz yz xz xy), Pa.
    pub stress: Vec<f64>,
    /// Its largest von Mises peak as studied on meshes refined around it, when the file has it.
    pub peak: Option<crate::PeakRecord>,
    /// The largest studied peak that is not singular, when the largest is.
    pub regular_peak: Option<crate::PeakRecord>,
}

/// The peak record under `prefix` on `g`: none when its verdict is absent; refused (a message)
/// when present but incomplete or out of range.
fn read_peak(g: &hdf5::Group, prefix: &str) -> Result<Option<crate::PeakRecord>, String> {
    let name = |f: &str| crate::PeakRecord::attr(prefix, f);
    let Some(verdict) = crate::strings::read(g, &name("verdict")) else {
        return Ok(None);
    };
    if !ld::VERDICTS.contains(&verdict.as_str()) {
        return Err(format!(
            "{} is {verdict:?}, not one of {:?}",
            name("verdict"),
            ld::VERDICTS
        ));
    }
    let non_negative = |f: &str| {
        scalar_attr::<f64>(g, &name(f))
            .filter(|v| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| format!("{} missing, negative or not a finite f64", name(f)))
    };
    let value = non_negative("value")?;
    let error = if g.attr(&name("error")).is_ok() {
        Some(non_negative("error")?)
    } else {
        None
    };
    let refined = f64_array_attr(g, &name("refined"), 2)
        .filter(|v| v.iter().all(|x| *x >= 0.0))
        .ok_or_else(|| format!("{} missing or not two finite f64 ≥ 0", name("refined")))?;
    let position = f64_array_attr(g, &name("position"), 3)
        .ok_or_else(|| format!("{} missing or not three finite f64", name("position")))?;
    Ok(Some(crate::PeakRecord {
        verdict,
        value,
        error,
        refined: [refined[0], refined[1]],
        position: [position[0], position[1], position[2]],
    }))
}

impl SpaceReader<'_> {
    /// The names of the space's load cases, in the file's order (none: an empty list). At most
    /// [`ld::MAX_LOADS`], counted before any name is listed; each a valid identifier.
    pub fn load_names(&self) -> Result<Vec<String>, ReadError> {
        self.guard(|| {
            let Some(g) = self.optional_group(sp::LOADS)? else {
                return Ok(Vec::new());
            };
            let count = usize::try_from(g.len()).unwrap_or(usize::MAX);
            if count > ld::MAX_LOADS {
                return Err(self.err(format!(
                    "{} holds {count} load cases, more than {}: refused before reading them",
                    sp::LOADS,
                    ld::MAX_LOADS
                )));
            }
            let listed = g
                .member_names()
                .map_err(|_| self.err(format!("{} unreadable; the file is damaged", sp::LOADS)))?;
            for n in &listed {
                crate::check_identifier("load case name", n).map_err(|m| self.err(format!("{}: {m}", sp::LOADS)))?;
            }
            Ok(listed)
        })
    }

    /// Load case `name`, all of it read and checked.
    pub fn load(&self, name: &str) -> Result<LoadCase, ReadError> {
        self.guard(|| {
            crate::check_identifier("load case name", name).map_err(|m| self.err(m.to_string()))?;
            let path = format!("{}/{name}", sp::LOADS);
            if self.optional_group(sp::LOADS)?.is_none() {
                return Err(self.err(format!("no load case {name:?}")));
            }
            let g = self
                .optional_group(&path)?
                .ok_or_else(|| self.err(format!("no load case {name:?}")))?;
            let bad = |what: String| self.err(format!("{path}: {what}; the file is damaged"));
            let kind = crate::strings::read(&g, ld::KIND)
                .filter(|k| ld::KINDS.contains(&k.as_str()))
                .ok_or_else(|| bad(format!("{} missing or not one of {:?}", ld::KIND, ld::KINDS)))?;
            let vec3 = |key: &str| {
                f64_array_attr(&g, key, 3)
                    .map(|v| [v[0], v[1], v[2]])
                    .ok_or_else(|| bad(format!("{key} missing or not three finite f64")))
            };
            let scalar = |key: &str| {
                scalar_attr::<f64>(&g, key)
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .ok_or_else(|| bad(format!("{key} missing, negative or not a finite f64")))
            };
            let (n, nv) = (self.node_count, self.vertex_count);
            let array = |dataset: &str, rank: usize, want: &[usize]| -> Result<Vec<f64>, ReadError> {
                let full = format!("{path}/{dataset}");
                let shape = self.shape::<f64>(&full, rank)?;
                if shape != want {
                    return Err(bad(format!("{dataset} has shape {shape:?}, expected {want:?}")));
                }
                let v = self.finite(&full, self.read_all::<f64>(&full, rank)?)?;
                match v.iter().position(|x| x.abs() > checks::MAX_SINGLE) {
                    Some(i) => Err(self.err(format!(
                        "{full} holds {:e} at entry {i}, beyond single precision ({:.1e}), in which the runtime \
                         and the page hold it; the file is damaged",
                        v[i],
                        checks::MAX_SINGLE
                    ))),
                    None => Ok(v),
                }
            };
            let case = LoadCase {
                name: name.to_string(),
                kind,
                total_force: vec3(ld::TOTAL_FORCE)?,
                reaction: vec3(ld::REACTION)?,
                balance_residual: scalar(ld::BALANCE_RESIDUAL)?,
                max_displacement: scalar(ld::MAX_DISPLACEMENT)?,
                max_von_mises: scalar(ld::MAX_VON_MISES)?,
                displacement: array(ld::DISPLACEMENT, 2, &[n, 3])?,
                von_mises: array(ld::VON_MISES, 1, &[n])?,
                stress: array(ld::STRESS, 2, &[nv, 6])?,
                peak: read_peak(&g, ld::PEAK).map_err(bad)?,
                regular_peak: read_peak(&g, ld::REGULAR_PEAK).map_err(bad)?,
            };
            // The attributes are what a page shows first: they must be the data's.
            let largest_u = case
                .displacement
                .chunks_exact(3)
                .map(|u| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt())
                .fold(0.0, f64::max);
            checks::stated_max(case.max_displacement, largest_u).map_err(|m| {
                bad(format!(
                    "{} {m} (largest nodal displacement magnitude)",
                    ld::MAX_DISPLACEMENT
                ))
            })?;
            if let Some(i) = case.von_mises.iter().position(|&v| v < 0.0) {
                return Err(bad(format!(
                    "{} is {} at node {i}: it is ≥ 0",
                    ld::VON_MISES,
                    case.von_mises[i]
                )));
            }
            let largest_vm = case.von_mises[..nv].iter().copied().fold(0.0, f64::max);
            checks::stated_max(case.max_von_mises, largest_vm)
                .map_err(|m| bad(format!("{} {m} (largest at a corner vertex)", ld::MAX_VON_MISES)))?;
            Ok(case)
        })
    }

    /// Every load case, read and checked.
    pub fn loads(&self) -> Result<Vec<LoadCase>, ReadError> {
        self.load_names()?.iter().map(|n| self.load(n)).collect()
    }

    /// `mesh/fixed_mask` (1 where a support holds the node), one per node, when the file has it
    /// (files written before it do not): 1 exactly at the nodes with a DOF in
    /// `mesh/fixed_dofs`, 0 elsewhere.
    pub fn fixed_mask(&self) -> Result<Option<Vec<u32>>, ReadError> {
        self.guard(|| {
            if !self.has_dataset(sp::FIXED_MASK)? {
                return Ok(None);
            }
            // Deflated: its extent is checked against the node count before it is read.
            self.expect_len::<u32>(sp::FIXED_MASK, self.node_count, "nodes")?;
            let v = self.read_all::<u32>(sp::FIXED_MASK, 1)?;
            let mut held = vec![0u32; self.node_count];
            for d in self.fixed_dofs()? {
                held[d as usize / 3] = 1;
            }
            if let Some(i) = (0..v.len()).find(|&i| v[i] != held[i]) {
                return Err(self.err(format!(
                    "{} is {} at node {i} but {} {} it; the file is damaged",
                    sp::FIXED_MASK,
                    v[i],
                    sp::FIXED_DOFS,
                    if held[i] == 1 { "holds" } else { "does not hold" }
                )));
            }
            Ok(Some(v))
        })
    }
}
