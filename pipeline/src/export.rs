//! `ves export BASIS --vtu DIR`: a basis as VTK unstructured-grid files, for tools that read VTK
//! but not the XDMF sidecar (meshio, VTK scripts). Per space `<space>.vtu`: its 4- or 10-node
//! tets (VTK node order) with every mode shape as a point vector; with modal stress also
//! `<space>_vertices.vtu` on the corner vertices with each mode's stress as a symmetric tensor
//! (VTK's order xx yy zz xy yz xz). Array names as in the XDMF sidecar: `mode_01_displacement`,
//! `mode_01_stress`, `fixed`, `load_<name>_displacement`, `load_<name>_von_mises`, and the
//! frequencies as field data `frequencies_hz`. Binary data appended raw (little-endian, 64-bit
//! headers).
//!
//! A mode's amplitude is arbitrary (mass-normalised: `mode_01_stress` is Pa per unit modal
//! coordinate, peaks like 5e11 Pa), so the vertices file also holds each mode scaled to a stated
//! quantity: `mode_01_stress_per_mm` (tensor) and `mode_01_von_mises_per_mm` (scalar), Pa per
//! millimetre of the mode's peak displacement magnitude (over every node of the whole grid). Its
//! field data say the factors: `peak_displacement_m` (per mode, per unit modal coordinate) and
//! `per_mm_scale` = 1e-3 / `peak_displacement_m` (the `_per_mm` arrays are the plain ones times it).

use anyhow::{Context, Result, bail};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::output::Overwrite;

use crate::fem::element::Kind;
use ves_format::xdmf::{escape, load_array, mode_array};

/// VTK's symmetric-tensor order (xx yy zz xy yz xz) from the file's Voigt (xx yy zz yz xz xy).
const VOIGT_TO_VTK: [usize; 6] = [0, 1, 2, 5, 3, 4];

/// One array of an unstructured grid.
enum Data<'a> {
    F64(&'a [f64]),
    I64(&'a [i64]),
    U8(&'a [u8]),
}

impl Data<'_> {
    fn vtk_type(&self) -> &'static str {
        match self {
            Data::F64(_) => "Float64",
            Data::I64(_) => "Int64",
            Data::U8(_) => "UInt8",
        }
    }

    fn bytes(&self) -> Vec<u8> {
        match self {
            Data::F64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::I64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::U8(v) => v.to_vec(),
        }
    }
}

/// Writes the basis at `basis` into `dir` (created if missing); returns the files written. The
/// whole file is checked first ([`ves_format::BasisReader::validate`]). Every output is checked before the first is written ([`crate::output::check`]: a symbolic
/// link is replaced only under `overwrite.force`, the basis itself never), and a space name that
/// would leave `dir` or give two spaces one file is refused.
pub fn export(basis: &Path, dir: &Path, overwrite: Overwrite) -> Result<Vec<PathBuf>> {
    let file = ves_format::BasisReader::open(basis)?;
    // Everything is checked before anything is written: a damaged second space must not leave
    // the first one's files behind.
    file.validate()?;
    if dir.exists() && !dir.is_dir() {
        bail!("{}: is a file; give a directory for the VTK files", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the directory", dir.display()))?;
    // (space, its .vtu, its vertices' .vtu when it has stress)
    let mut plan: Vec<(String, PathBuf, Option<PathBuf>)> = Vec::new();
    for name in file.space_names()? {
        // The name becomes a file name: it must stay one name in `dir`.
        ves_format::check_identifier("space name", &name)
            .map_err(|e| anyhow::anyhow!("{}: {e}; precompute the basis again", basis.display()))?;
        // One vertex of one mode says whether the space has modal stress; load cases carry a
        // stress tensor at the vertices too.
        let s = file.space(&name)?;
        let stress =
            s.stress_rows(0..s.vertex_count.min(1), s.mode_count.min(1))?.is_some() || !s.load_names()?.is_empty();
        let grid = dir.join(format!("{name}.vtu"));
        let vertices = stress.then(|| dir.join(format!("{name}_vertices.vtu")));
        plan.push((name, grid, vertices));
    }
    let mut outputs: Vec<&Path> = Vec::new();
    for p in plan.iter().flat_map(|(_, g, v)| std::iter::once(g).chain(v)) {
        if outputs.contains(&p.as_path()) {
            bail!(
                "{}: two spaces of {} would both be written there (a VOI named like another space's \
                 `_vertices` file); rename that VOI in the scene and precompute again",
                p.display(),
                basis.display()
            );
        }
        crate::output::check(p, &[basis], overwrite)?;
        outputs.push(p);
    }
    let mut written = Vec::new();
    for (name, grid, vertices) in &plan {
        let s = file.space(name)?;
        let (n, nv, r) = (s.node_count, s.vertex_count, s.mode_count);
        let nodes: Vec<f64> = s.nodes(n)?.into_iter().flatten().collect();
        let tets = s.tets()?;
        let per = s.kind.nodes();
        let order = s.kind.vtk_node_order();
        let frequencies = s.frequencies_hz()?;
        let rows = s.basis_rows(0..3 * n, r)?;
        let mut shapes: Vec<(String, usize, Vec<f64>)> = (0..r)
            .map(|j| {
                let v = (0..3 * n).map(|i| rows[i * r + j]).collect();
                (mode_array(j, r, "displacement"), 3, v)
            })
            .collect();
        shapes.extend(point_fields(&s)?);
        let cells: Vec<i64> = tets
            .chunks_exact(per)
            .flat_map(|t| order.iter().map(move |&k| i64::from(t[k])))
            .collect();
        let field = [("frequencies_hz".to_string(), frequencies.clone())];
        write_grid(grid, &nodes, &cells, per, s.kind.vtk_cell_type(), &shapes, &field)?;
        written.push(grid.clone());
        if let Some(path) = vertices {
            let peaks = peak_displacements(&rows, n, r);
            let scales: Vec<f64> = peaks.iter().map(|&p| per_mm_scale(p)).collect();
            let mut fields: Vec<(String, usize, Vec<f64>)> = Vec::new();
            if let Some(stress) = s.stress_rows(0..nv, r)? {
                fields.extend((0..r).map(|j| {
                    let v = (0..nv)
                        .flat_map(|i| VOIGT_TO_VTK.map(|k| stress[(6 * i + k) * r + j]))
                        .collect();
                    (mode_array(j, r, "stress"), 6, v)
                }));
                for (j, &c) in scales.iter().enumerate() {
                    let tensor: Vec<f64> = fields[j].2.iter().map(|x| x * c).collect();
                    let von_mises = (0..nv)
                        .map(|i| {
                            let voigt: Vec<f64> = (0..6).map(|k| c * stress[(6 * i + k) * r + j]).collect();
                            crate::loads::von_mises(&voigt)
                        })
                        .collect();
                    fields.push((mode_array(j, r, "stress_per_mm"), 6, tensor));
                    fields.push((mode_array(j, r, "von_mises_per_mm"), 1, von_mises));
                }
            }
            // Each load case's stress tensor at the vertices, Pa (VTK's component order).
            for l in s.loads()? {
                let v = l
                    .stress
                    .chunks_exact(6)
                    .flat_map(|t| VOIGT_TO_VTK.map(|k| t[k]))
                    .collect();
                fields.push((load_array(&l.name, "stress"), 6, v));
            }
            let corners: Vec<i64> = tets
                .chunks_exact(per)
                .flat_map(|t| t[..4].iter().map(|&v| i64::from(v)))
                .collect();
            let (n, cell) = (Kind::Tet4.nodes(), Kind::Tet4.vtk_cell_type());
            let field = [
                ("frequencies_hz".to_string(), frequencies.clone()),
                ("peak_displacement_m".to_string(), peaks),
                ("per_mm_scale".to_string(), scales),
            ];
            write_grid(path, &nodes[..3 * nv], &corners, n, cell, &fields, &field)?;
            written.push(path.clone());
        }
    }
    Ok(written)
}

/// Each mode's largest displacement magnitude over the `n` nodes, m per unit modal coordinate,
/// from the basis rows (`rows[i * r + j]`: DOF i of mode j).
pub fn peak_displacements(rows: &[f64], n: usize, r: usize) -> Vec<f64> {
    (0..r)
        .map(|j| {
            (0..n)
                .map(|a| (0..3).map(|c| rows[(3 * a + c) * r + j].powi(2)).sum::<f64>().sqrt())
                .fold(0.0, f64::max)
        })
        .collect()
}

/// The factor that scales a mode to 1 mm of peak displacement: 1e-3 / `peak` (NaN for a mode
/// that does not move, which a checked basis never holds).
pub fn per_mm_scale(peak: f64) -> f64 {
    if peak > 0.0 { 1e-3 / peak } else { f64::NAN }
}

/// The whole grid's point arrays beside the modes: `fixed` (1 where a support holds the node,
/// from `mesh/fixed_dofs`) and each load case's displacement and von Mises stress.
fn point_fields(s: &ves_format::SpaceReader<'_>) -> Result<Vec<(String, usize, Vec<f64>)>> {
    let mut fixed = vec![0.0; s.node_count];
    for d in s.fixed_dofs()? {
        fixed[d as usize / 3] = 1.0;
    }
    let mut out = vec![("fixed".to_string(), 1, fixed)];
    for l in s.loads()? {
        out.push((load_array(&l.name, "displacement"), 3, l.displacement));
        out.push((load_array(&l.name, "von_mises"), 1, l.von_mises));
    }
    Ok(out)
}

// The grid's parts, as VTK's XML format lists them.
#[allow(clippy::too_many_arguments)]
fn write_grid(
    path: &Path,
    points: &[f64],
    cells: &[i64],
    per_cell: usize,
    kind: u8,
    fields: &[(String, usize, Vec<f64>)],
    field_data: &[(String, Vec<f64>)],
) -> Result<()> {
    let m = cells.len() / per_cell;
    let offsets: Vec<i64> = (1..=m).map(|e| (e * per_cell) as i64).collect();
    let types = vec![kind; m];
    // (name, components, data) in the order they are appended.
    let mut arrays: Vec<(&str, usize, Data<'_>)> = vec![("Points", 3, Data::F64(points))];
    arrays.extend(fields.iter().map(|(name, c, v)| (name.as_str(), *c, Data::F64(v))));
    arrays.push(("connectivity", 1, Data::I64(cells)));
    arrays.push(("offsets", 1, Data::I64(&offsets)));
    arrays.push(("types", 1, Data::U8(&types)));
    let field_start = arrays.len();
    arrays.extend(field_data.iter().map(|(name, v)| (name.as_str(), 1, Data::F64(v))));
    let mut xml = String::new();
    let mut offset = 0usize;
    let mut blobs = Vec::new();
    let mut item = |a: &(&str, usize, Data<'_>)| {
        let bytes = a.2.bytes();
        let tag = format!(
            r#"<DataArray type="{}" Name="{}" NumberOfComponents="{}" format="appended" offset="{offset}"/>"#,
            a.2.vtk_type(),
            escape(a.0),
            a.1
        );
        offset += 8 + bytes.len();
        blobs.push(bytes);
        tag
    };
    xml.push_str(r#"<?xml version="1.0"?>"#);
    xml.push('\n');
    xml.push_str(r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#);
    xml.push_str("\n<UnstructuredGrid>\n<FieldData>");
    for a in &arrays[field_start..] {
        // Field data names its tuple count.
        let tag = item(a);
        let tuples = match &a.2 {
            Data::F64(v) => v.len(),
            _ => 0,
        };
        xml.push_str(&tag.replace("/>", &format!(r#" NumberOfTuples="{tuples}"/>"#)));
    }
    xml.push_str("</FieldData>");
    xml.push_str(&format!(
        "\n<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{m}\">\n<Points>{}</Points>\n<PointData>",
        points.len() / 3,
        item(&arrays[0])
    ));
    for a in &arrays[1..1 + fields.len()] {
        xml.push_str(&item(a));
    }
    xml.push_str("</PointData>\n<Cells>");
    for a in &arrays[1 + fields.len()..field_start] {
        xml.push_str(&item(a));
    }
    xml.push_str("</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">_");
    crate::output::write_atomically(path, |tmp| {
        let mut w = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        w.write_all(xml.as_bytes())?;
        for b in &blobs {
            w.write_all(&(b.len() as u64).to_le_bytes())?;
            w.write_all(b)?;
        }
        w.write_all(b"\n</AppendedData>\n</VTKFile>\n")?;
        w.flush()?;
        Ok(())
    })
    .with_context(|| format!("{}: writing failed", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two nodes, two modes (DOF-major rows): the peaks are the largest displacement
    /// magnitudes, and each mode times its factor peaks at exactly 1 mm.
    #[test]
    fn a_mode_scaled_by_its_factor_peaks_at_one_millimetre() {
        let m0 = [3.0, 4.0, 0.0, 0.0, 0.0, 1.0];
        let m1 = [0.0, 0.0, 0.0, 0.0, -2.0, 0.0];
        let rows: Vec<f64> = (0..6).flat_map(|i| [m0[i], m1[i]]).collect();
        let peaks = peak_displacements(&rows, 2, 2);
        assert_eq!(peaks, vec![5.0, 2.0]);
        for (j, m) in [m0, m1].iter().enumerate() {
            let c = per_mm_scale(peaks[j]);
            let scaled: Vec<f64> = m.iter().map(|x| x * c).collect();
            let peak = scaled
                .chunks_exact(3)
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                .fold(0.0, f64::max);
            assert!((peak - 1e-3).abs() < 1e-18, "mode {j}: {peak}");
        }
        assert!(per_mm_scale(0.0).is_nan());
    }
}
