//! Reading the static load cases of a space (`loads/<name>/`) and the `fixed` mask: optional
//! (files written before them, or of scenes without loads, have none), checked when present.

use super::{ReadError, SpaceReader, f64_array_attr, scalar_attr};
use crate::names::{self, load as ld, space as sp};

/// One static load case as read, every array checked (shape, finite values).
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
}

impl SpaceReader<'_> {
    /// The names of the space's load cases, in the file's order (none: an empty list). At most
    /// [`ld::MAX_LOADS`], counted before any name is listed; each a valid identifier.
    pub fn load_names(&self) -> Result<Vec<String>, ReadError> {
        self.guard(|| {
            let Ok(g) = self.group.group(sp::LOADS) else {
                return Ok(Vec::new());
            };
            self.file
                .check_object(&g, &format!("{}/{}/{}", names::SPACES, self.name, sp::LOADS))?;
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
            crate::check_identifier("load case name", name).map_err(|m| self.err(m))?;
            let path = format!("{}/{name}", sp::LOADS);
            let g = self
                .group
                .group(&path)
                .map_err(|_| self.err(format!("no load case {name:?}")))?;
            self.file
                .check_object(&g, &format!("{}/{}/{path}", names::SPACES, self.name))?;
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
                let v = self.read_all::<f64>(&full, rank)?;
                self.finite(&full, v)
            };
            Ok(LoadCase {
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
            })
        })
    }

    /// Every load case, read and checked.
    pub fn loads(&self) -> Result<Vec<LoadCase>, ReadError> {
        self.load_names()?.iter().map(|n| self.load(n)).collect()
    }

    /// `mesh/fixed_mask` (1 where a support holds the node), one 0 or 1 per node, when the file
    /// has it (files written before it do not).
    pub fn fixed_mask(&self) -> Result<Option<Vec<u32>>, ReadError> {
        self.guard(|| {
            if self.group.dataset(sp::FIXED_MASK).is_err() {
                return Ok(None);
            }
            let v = self.read_all::<u32>(sp::FIXED_MASK, 1)?;
            if v.len() != self.node_count || v.iter().any(|&m| m > 1) {
                return Err(self.err(format!(
                    "{} holds {} values for {} nodes, or one that is not 0 or 1; the file is damaged",
                    sp::FIXED_MASK,
                    v.len(),
                    self.node_count
                )));
            }
            Ok(Some(v))
        })
    }
}
