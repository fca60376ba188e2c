//! Writing the static load cases of a space (`loads/<name>/`) and the `fixed` mask.

use super::{Ctx, WriteError, attr_f64, attr_str, attr_vec3};
use crate::names::{load as ld, space as sp};
use ndarray::{Array1, Array2};

/// One static load case as written (`loads/<name>/`, docs/format.md).
pub struct LoadData<'a> {
    /// The case's name (a plain identifier).
    pub name: &'a str,
    /// `force`, `pressure` or `gravity`.
    pub kind: &'a str,
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
    pub displacement: &'a [f64],
    /// Von Mises stress of every node, n, Pa.
    pub von_mises: &'a [f64],
    /// Stress at the corner vertices, [nv, 6] row-major (Voigt), Pa.
    pub stress: &'a [f64],
    /// Its largest von Mises peak as studied on meshes refined around it, if studied.
    pub peak: Option<PeakRecord>,
    /// The largest studied peak that is not singular, when the largest is.
    pub regular_peak: Option<PeakRecord>,
}

/// A von Mises peak of a load case studied on meshes refined around it (`peak_*` and
/// `regular_peak_*` attributes, docs/format.md).
#[derive(Clone, Debug, PartialEq)]
pub struct PeakRecord {
    /// `converging`, `slow`, `singular` or `unsettled`.
    pub verdict: String,
    /// Its value on the file's mesh, Pa.
    pub value: f64,
    /// The value's estimated error, Pa (none for a singular or unsettled peak).
    pub error: Option<f64>,
    /// The value with the element size there halved, then quartered, Pa.
    pub refined: [f64; 2],
    /// Where it is, m.
    pub position: [f64; 3],
}

impl PeakRecord {
    /// The attribute named `field` of the record written under `prefix`.
    pub fn attr(prefix: &str, field: &str) -> String {
        format!("{prefix}_{field}")
    }
}

fn write_peak(c: &hdf5::Group, prefix: &str, p: &PeakRecord) -> Result<(), WriteError> {
    let name = |f: &str| PeakRecord::attr(prefix, f);
    attr_str(c, &name("verdict"), &p.verdict)?;
    attr_f64(c, &name("value"), p.value)?;
    if let Some(e) = p.error {
        attr_f64(c, &name("error"), e)?;
    }
    c.new_attr_builder()
        .with_data(&Array1::from(p.refined.to_vec()))
        .create(name("refined").as_str())
        .map(drop)
        .ctx(&name("refined"))?;
    attr_vec3(c, &name("position"), p.position)
}

/// Writes `mesh/fixed_mask` (1 where a node has a supported DOF) of `n` nodes.
pub(super) fn write_fixed_mask(g: &hdf5::Group, n: usize, fixed_dofs: &[u32]) -> Result<(), WriteError> {
    let mut mask = vec![0u32; n];
    for &d in fixed_dofs {
        if let Some(m) = mask.get_mut(d as usize / 3) {
            *m = 1;
        }
    }
    g.new_dataset_builder()
        .with_data(&Array1::from(mask))
        .chunk(n.clamp(1, 65536))
        .shuffle()
        .deflate(4)
        .create(sp::FIXED_MASK)
        .ctx(sp::FIXED_MASK)?;
    Ok(())
}

/// Writes every load case of a space of `n` nodes, `nv` corner vertices.
pub(super) fn write_loads(g: &hdf5::Group, n: usize, nv: usize, loads: &[LoadData<'_>]) -> Result<(), WriteError> {
    if loads.is_empty() {
        return Ok(());
    }
    let group = g.create_group(sp::LOADS).ctx(sp::LOADS)?;
    for l in loads {
        let what = format!("{}/{}", sp::LOADS, l.name);
        let bad = |message: String| WriteError {
            what: what.clone(),
            message,
        };
        if l.displacement.len() != 3 * n || l.von_mises.len() != n || l.stress.len() != 6 * nv {
            return Err(bad(format!(
                "{} displacement, {} von Mises and {} stress values for {n} nodes and {nv} vertices",
                l.displacement.len(),
                l.von_mises.len(),
                l.stress.len()
            )));
        }
        let c = group.create_group(l.name).ctx(&what)?;
        let u = Array2::from_shape_vec((n, 3), l.displacement.to_vec()).map_err(|e| bad(e.to_string()))?;
        c.new_dataset_builder()
            .with_data(&u)
            .create(ld::DISPLACEMENT)
            .ctx(&what)?;
        c.new_dataset_builder()
            .with_data(&Array1::from(l.von_mises.to_vec()))
            .create(ld::VON_MISES)
            .ctx(&what)?;
        let s = Array2::from_shape_vec((nv, 6), l.stress.to_vec()).map_err(|e| bad(e.to_string()))?;
        c.new_dataset_builder().with_data(&s).create(ld::STRESS).ctx(&what)?;
        attr_str(&c, ld::KIND, l.kind)?;
        attr_vec3(&c, ld::TOTAL_FORCE, l.total_force)?;
        attr_vec3(&c, ld::REACTION, l.reaction)?;
        attr_f64(&c, ld::BALANCE_RESIDUAL, l.balance_residual)?;
        attr_f64(&c, ld::MAX_DISPLACEMENT, l.max_displacement)?;
        attr_f64(&c, ld::MAX_VON_MISES, l.max_von_mises)?;
        if let Some(p) = &l.peak {
            write_peak(&c, ld::PEAK, p)?;
        }
        if let Some(p) = &l.regular_peak {
            write_peak(&c, ld::REGULAR_PEAK, p)?;
        }
    }
    Ok(())
}
