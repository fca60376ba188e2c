//! The XDMF sidecar `B.xdmf` beside a basis `B.h5`: XML that points into the HDF5 file (no data
//! copied) so that ParaView opens each space's mesh, every mode shape and every modal stress.
//!
//! It is XDMF 2 (`Version="2.0"`), read by ParaView's "XDMF Reader": ParaView 5.11's Xdmf3
//! reader skips attributes given as a `HyperSlab` of a larger dataset ("Skipping unrecognized
//! array type"), and without hyperslabs each mode would have to be copied out of `modes/basis`.
//! The XDMF 2 reader takes them, and its `JOIN` interleaves columns, which maps gmsh's 10-node
//! order to VTK's (the last two mid-edge nodes swap) and the stress components to XDMF's
//! `Tensor6` order (xx xy xz yy yz zz) without a copy either.
//!
//! Array names are plain, for scripts: `mode_01_displacement`, `mode_01_stress`,
//! `load_<name>_displacement`, `load_<name>_von_mises`, `fixed` (1 where a support holds the
//! node), and the frequencies as the grid's field data `frequencies_hz`.

use crate::names::space as sp;
use std::fmt::Write;

/// What the sidecar needs to know of one space.
pub struct XdmfSpace<'a> {
    /// Space name.
    pub name: &'a str,
    /// All nodes.
    pub nodes: usize,
    /// Corner vertices (the first nodes).
    pub vertices: usize,
    /// Tets.
    pub tets: usize,
    /// The element kind.
    pub kind: crate::ElementKind,
    /// Mode frequencies, Hz (one per stored mode).
    pub frequencies_hz: &'a [f64],
    /// Whether `modes/stress` is stored.
    pub stress: bool,
    /// Whether `mesh/fixed_mask` is stored.
    pub fixed: bool,
    /// The load cases stored (`loads/<name>`).
    pub loads: &'a [String],
}

pub use crate::element::TET10_TO_VTK;

/// XDMF's Tensor6 order (xx xy xz yy yz zz) in terms of the file's (xx yy zz yz xz xy).
const VOIGT_TO_TENSOR6: [usize; 6] = [0, 5, 4, 1, 3, 2];

/// The sidecar's text for the basis file named `h5_name` (a file name, resolved beside it).
pub fn sidecar(h5_name: &str, spaces: &[XdmfSpace<'_>]) -> String {
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" ?>"#);
    let _ = writeln!(
        x,
        "<!-- VES modal basis {}: open with ParaView's \"XDMF Reader\". Each space is a grid with every \
         mode shape (mode_01_displacement, m per unit modal coordinate), fixed (1 where a support holds the \
         node), each load case's load_NAME_displacement (m) and load_NAME_von_mises (Pa), and the frequencies \
         as field data (frequencies_hz); with modal stress, a second grid on its corner vertices holds each \
         mode's stress tensor (mode_01_stress, Pa per unit modal coordinate). -->",
        escape(h5_name)
    );
    let _ = writeln!(x, r#"<Xdmf Version="2.0">"#);
    let _ = writeln!(x, " <Domain>");
    for s in spaces {
        space_grids(&mut x, h5_name, s);
    }
    let _ = writeln!(x, " </Domain>");
    let _ = writeln!(x, "</Xdmf>");
    x
}

fn space_grids(x: &mut String, h5: &str, s: &XdmfSpace<'_>) {
    let group = format!("/spaces/{}", s.name);
    let data = |path: &str| format!("{}:{group}/{path}", escape(h5));
    let per_tet = s.kind.nodes();
    let r = s.frequencies_hz.len();
    let tets = hdf(s.tets, per_tet, r#"NumberType="UInt" Precision="4""#, &data(sp::TETS));
    let nodes = hdf(s.nodes, 3, F64, &data(sp::NODES));
    let _ = writeln!(x, r#"  <Grid Name="{}" GridType="Uniform">"#, escape(s.name));
    let _ = writeln!(
        x,
        r#"   <Topology TopologyType="{}" NumberOfElements="{}">"#,
        s.kind.xdmf_topology(),
        s.tets
    );
    match s.kind {
        crate::ElementKind::Tet4 => {
            let _ = writeln!(x, "    {tets}");
        }
        // The columns read in VTK's node order.
        crate::ElementKind::Tet10 => {
            let columns: Vec<String> = s
                .kind
                .vtk_node_order()
                .iter()
                .map(|&c| slab(s.tets, 1, (0, c), (1, 1), &tets))
                .collect();
            join(x, &format!("{} {per_tet}", s.tets), &columns);
        }
    }
    geometry(x, &nodes);
    frequencies(x, r, &data(sp::FREQUENCIES_HZ));
    let basis = hdf(3 * s.nodes, r, F64, &data(sp::BASIS));
    for j in 0..r {
        let _ = writeln!(
            x,
            r#"   <Attribute Name="{}" AttributeType="Vector" Center="Node">"#,
            mode_array(j, r, "displacement")
        );
        // Column j of [3n, r], read as n × 3.
        let _ = writeln!(
            x,
            "    {}",
            slab_as(&format!("{} 3", s.nodes), 3 * s.nodes, 1, (0, j), (1, 1), &basis)
        );
        let _ = writeln!(x, "   </Attribute>");
    }
    point_fields(x, s, &data);
    let _ = writeln!(x, "  </Grid>");
    if !s.stress && s.loads.is_empty() {
        return;
    }
    // Corner vertices only: linear tets on the first four columns, the first nv nodes.
    let _ = writeln!(x, r#"  <Grid Name="{} vertices" GridType="Uniform">"#, escape(s.name));
    let _ = writeln!(
        x,
        r#"   <Topology TopologyType="Tetrahedron" NumberOfElements="{}">"#,
        s.tets
    );
    let _ = writeln!(x, "    {}", slab(s.tets, 4, (0, 0), (1, 1), &tets));
    geometry(x, &slab(s.vertices, 3, (0, 0), (1, 1), &nodes));
    frequencies(x, r, &data(sp::FREQUENCIES_HZ));
    // Each load case's stress tensor, [nv, 6] Voigt: its columns in XDMF's order.
    for name in s.loads {
        let item = hdf(
            s.vertices,
            6,
            F64,
            &data(&format!("{}/{name}/{}", sp::LOADS, crate::names::load::STRESS)),
        );
        let _ = writeln!(
            x,
            r#"   <Attribute Name="{}" AttributeType="Tensor6" Center="Node">"#,
            escape(&load_array(name, "stress"))
        );
        let components: Vec<String> = VOIGT_TO_TENSOR6
            .iter()
            .map(|&k| slab(s.vertices, 1, (0, k), (1, 1), &item))
            .collect();
        join(x, &format!("{} 6", s.vertices), &components);
        let _ = writeln!(x, "   </Attribute>");
    }
    if !s.stress {
        let _ = writeln!(x, "  </Grid>");
        return;
    }
    let stress = hdf(6 * s.vertices, r, F64, &data(sp::STRESS));
    for j in 0..r {
        let _ = writeln!(
            x,
            r#"   <Attribute Name="{}" AttributeType="Tensor6" Center="Node">"#,
            mode_array(j, r, "stress")
        );
        // Component k of every vertex: rows k, k + 6, … of column j.
        let components: Vec<String> = VOIGT_TO_TENSOR6
            .iter()
            .map(|&k| slab(s.vertices, 1, (k, j), (6, 1), &stress))
            .collect();
        join(x, &format!("{} 6", s.vertices), &components);
        let _ = writeln!(x, "   </Attribute>");
    }
    let _ = writeln!(x, "  </Grid>");
}

const F64: &str = r#"NumberType="Float" Precision="8""#;

/// A `rows × cols` dataset of the basis file, of XDMF type `ty`.
fn hdf(rows: usize, cols: usize, ty: &str, path: &str) -> String {
    format!(r#"<DataItem Dimensions="{rows} {cols}" {ty} Format="HDF">{path}</DataItem>"#)
}

/// Closes the topology and gives the node coordinates.
fn geometry(x: &mut String, nodes: &str) {
    let _ = writeln!(x, "   </Topology>");
    let _ = writeln!(x, r#"   <Geometry GeometryType="XYZ">"#);
    let _ = writeln!(x, "    {nodes}");
    let _ = writeln!(x, "   </Geometry>");
}

/// `mode_07_displacement`: mode j + 1, zero-padded to at least two digits (to the width of r
/// beyond 99 modes) so that ParaView lists them in order.
pub fn mode_array(j: usize, r: usize, what: &str) -> String {
    let width = r.to_string().len().max(2);
    format!("mode_{:0width$}_{what}", j + 1)
}

/// `load_<name>_<what>`: a load case's array.
pub fn load_array(name: &str, what: &str) -> String {
    format!("load_{name}_{what}")
}

/// The frequencies (`r` values) as the grid's field data `frequencies_hz`.
fn frequencies(x: &mut String, r: usize, path: &str) {
    let _ = writeln!(
        x,
        r#"   <Attribute Name="frequencies_hz" AttributeType="Scalar" Center="Grid">"#
    );
    let _ = writeln!(
        x,
        r#"    <DataItem Dimensions="{r}" {F64} Format="HDF">{path}</DataItem>"#
    );
    let _ = writeln!(x, "   </Attribute>");
}

/// The whole grid's point arrays beside the modes: `fixed` and each load case's displacement
/// and von Mises stress.
fn point_fields(x: &mut String, s: &XdmfSpace<'_>, data: &dyn Fn(&str) -> String) {
    let n = s.nodes;
    let scalar = |x: &mut String, name: &str, item: String| {
        let _ = writeln!(
            x,
            r#"   <Attribute Name="{}" AttributeType="Scalar" Center="Node">"#,
            escape(name)
        );
        let _ = writeln!(x, "    {item}");
        let _ = writeln!(x, "   </Attribute>");
    };
    if s.fixed {
        let mask = format!(
            r#"<DataItem Dimensions="{n}" NumberType="UInt" Precision="4" Format="HDF">{}</DataItem>"#,
            data(sp::FIXED_MASK)
        );
        scalar(x, "fixed", mask);
    }
    for name in s.loads {
        let group = format!("{}/{name}", sp::LOADS);
        let _ = writeln!(
            x,
            r#"   <Attribute Name="{}" AttributeType="Vector" Center="Node">"#,
            escape(&load_array(name, "displacement"))
        );
        let _ = writeln!(
            x,
            "    {}",
            hdf(
                n,
                3,
                F64,
                &data(&format!("{group}/{}", crate::names::load::DISPLACEMENT))
            )
        );
        let _ = writeln!(x, "   </Attribute>");
        let vm = format!(
            r#"<DataItem Dimensions="{n}" {F64} Format="HDF">{}</DataItem>"#,
            data(&format!("{group}/{}", crate::names::load::VON_MISES))
        );
        scalar(x, &load_array(name, "von_mises"), vm);
    }
}

/// A hyperslab of `rows × cols` values of the 2-D dataset `item`, starting at `start` with
/// `stride`.
fn slab(rows: usize, cols: usize, start: (usize, usize), stride: (usize, usize), item: &str) -> String {
    slab_as(&format!("{rows} {cols}"), rows, cols, start, stride, item)
}

/// [`slab`] read with other dimensions (the same number of values).
fn slab_as(dims: &str, rows: usize, cols: usize, start: (usize, usize), stride: (usize, usize), item: &str) -> String {
    format!(
        r#"<DataItem ItemType="HyperSlab" Dimensions="{dims}" Type="HyperSlab"><DataItem Dimensions="3 2" Format="XML">{} {} {} {} {rows} {cols}</DataItem>{item}</DataItem>"#,
        start.0, start.1, stride.0, stride.1
    )
}

/// The columns `parts` side by side (XDMF's JOIN interleaves them row by row).
fn join(x: &mut String, dims: &str, parts: &[String]) {
    let args: Vec<String> = (0..parts.len()).map(|i| format!("${i}")).collect();
    let _ = writeln!(
        x,
        r#"    <DataItem ItemType="Function" Function="JOIN({})" Dimensions="{dims}">"#,
        args.join(", ")
    );
    for p in parts {
        let _ = writeln!(x, "     {p}");
    }
    let _ = writeln!(x, "    </DataItem>");
}

/// `s` escaped for an XML attribute or text (shared with the VTU writer).
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sidecar_names_every_mode_and_maps_the_node_order() {
        let f = [10.0, 20.5];
        let x = sidecar(
            "a&b.h5",
            &[XdmfSpace {
                name: "global",
                nodes: 20,
                vertices: 8,
                tets: 3,
                kind: crate::ElementKind::Tet10,
                frequencies_hz: &f,
                stress: true,
                fixed: true,
                loads: &["tip".to_string()],
            }],
        );
        assert!(x.contains("a&amp;b.h5:/spaces/global/mesh/nodes"));
        assert!(x.contains(r#"Name="mode_01_displacement""#) && x.contains(r#"Name="mode_02_stress""#));
        assert!(x.contains(r#"Name="fixed""#) && x.contains("/spaces/global/mesh/fixed_mask"));
        assert!(x.contains(r#"Name="load_tip_displacement""#) && x.contains("/spaces/global/loads/tip/von_mises"));
        assert!(x.contains(r#"Name="frequencies_hz" AttributeType="Scalar" Center="Grid""#));
        // The tenth VTK node is gmsh's ninth column.
        let topology = &x[x.find("Tetrahedron_10").unwrap()..x.find("</Topology>").unwrap()];
        let starts: Vec<&str> = topology
            .match_indices(">0 ")
            .map(|(i, _)| &topology[i + 3..i + 4])
            .collect();
        assert_eq!(starts, ["0", "1", "2", "3", "4", "5", "6", "7", "9", "8"]);
        assert_eq!(x.matches("<Grid ").count(), 2);
    }
}
