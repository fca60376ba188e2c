//! Every name of the file, once. Paths of datasets are relative to their space's group.

/// Value of the root `format` attribute.
pub const FORMAT: &str = "ves-modal-basis";
/// Newest file version this build reads and the version it writes.
pub const VERSION: u32 = 1;

/// Root attributes.
pub mod root {
    /// String: [`super::FORMAT`].
    pub const FORMAT: &str = "format";
    /// u32: the file version.
    pub const VERSION: &str = "version";
    /// String: the program that wrote the file.
    pub const GENERATOR: &str = "generator";
    /// String: the scene file's text.
    pub const SCENE_TOML: &str = "scene_toml";
    /// String: the space a reader opens when it names none.
    pub const DEFAULT_SPACE: &str = "default_space";
    /// String (optional): content hash of what the file was made from (`ves batch`).
    pub const SOURCE_HASH: &str = "source_hash";
}

/// The `/material` group and its f64 attributes.
pub mod material {
    /// Group name.
    pub const GROUP: &str = "material";
    /// Young's modulus, Pa.
    pub const YOUNG: &str = "young";
    /// Poisson's ratio.
    pub const POISSON: &str = "poisson";
    /// Density, kg/m³.
    pub const DENSITY: &str = "density";
    /// Rayleigh α, 1/s.
    pub const ALPHA: &str = "rayleigh_alpha";
    /// Rayleigh β, s.
    pub const BETA: &str = "rayleigh_beta";
    /// Optional: yield strength, Pa.
    pub const YIELD_STRENGTH: &str = "yield_strength";
}

/// Group holding one group per space.
pub const SPACES: &str = "spaces";
/// The space every file has.
pub const GLOBAL_SPACE: &str = "global";

/// Names inside `/spaces/<name>/`.
pub mod space {
    /// u32 attribute: 1 (4-node tets) or 2 (10-node tets).
    pub const ELEMENT_ORDER: &str = "element_order";
    /// u32 attribute: rigid modes removed from the basis.
    pub const RIGID_MODES_DROPPED: &str = "rigid_modes_dropped";
    /// f64[3] attributes: the volume of interest's corners (VOI spaces only).
    pub const VOI_MIN: &str = "voi_min";
    /// See [`VOI_MIN`].
    pub const VOI_MAX: &str = "voi_max";
    /// Mesh group; holds the `vertex_count` attribute.
    pub const MESH: &str = "mesh";
    /// String attribute of [`MESH`] (optional): the meshing strategy that made it (the rung of
    /// the pipeline's meshing ladder), so a basis can be made again the same way.
    pub const MESHING_STRATEGY: &str = "meshing_strategy";
    /// u32 attribute of [`MESH`]: the first nv nodes are corner vertices.
    pub const VERTEX_COUNT: &str = "vertex_count";
    /// f64 [n, 3], metres.
    pub const NODES: &str = "mesh/nodes";
    /// u32 [m, 4|10], gmsh node order.
    pub const TETS: &str = "mesh/tets";
    /// u32 [k, 3], outward, on corner vertices.
    pub const SURFACE_TRIANGLES: &str = "mesh/surface_triangles";
    /// Optional u32 [k]: the CAD face (gmsh's surface tag of the geometry as imported) of each
    /// surface triangle; 0 where unknown.
    pub const SURFACE_FACES: &str = "mesh/surface_faces";
    /// u32 [c], supported DOFs 3i+c.
    pub const FIXED_DOFS: &str = "mesh/fixed_dofs";
    /// Modes group.
    pub const MODES: &str = "modes";
    /// f64 [r], λ = ω², ascending, elastic only.
    pub const EIGENVALUES: &str = "modes/eigenvalues";
    /// f64 [r].
    pub const FREQUENCIES_HZ: &str = "modes/frequencies_hz";
    /// f64 [3n, r], M-normalised; row 3i+c = component c of node i.
    pub const BASIS: &str = "modes/basis";
    /// f64 [r], ‖Kφ − λMφ‖ / ‖Kφ‖.
    pub const RELATIVE_RESIDUALS: &str = "modes/relative_residuals";
    /// Optional f64 [r]: each mode's estimated relative frequency error against the
    /// mesh-converged answer (Richardson over coarser meshes; docs/accuracy.md).
    pub const ESTIMATED_RELATIVE_ERROR: &str = "modes/estimated_relative_error";
    /// Optional f64 [6·nv, r]: row 6i+k = Voigt component k of the stress at corner vertex i,
    /// Pa per unit modal coordinate.
    pub const STRESS: &str = "modes/stress";
    /// Optional f64 [6·s, r] (held parts): row 6k+c = component c (force x, y, z in N, then
    /// moment x, y, z in N·m about [`SUPPORT_CENTRES`] row k) of what `[[fixed]]` support k
    /// exerts on the part, per unit modal coordinate: the reactions of u = Φq are Σ_j q_j·column j.
    pub const SUPPORT_REACTIONS: &str = "modes/support_reactions";
    /// Optional f64 [s, 3], m: the point each support's moment is about (the middle of the
    /// bounding box of the nodes it holds). Present exactly when [`SUPPORT_REACTIONS`] is.
    pub const SUPPORT_CENTRES: &str = "modes/support_centres";
    /// Optional f64 [q, 18·s] (parts held by several supports that leave no rigid motion):
    /// row i, column (6k + c)·3 + d = component c (as in [`SUPPORT_REACTIONS`]) of what
    /// support k exerts on the part per newton of a static load along axis d at corner vertex
    /// [`SUPPORT_INFLUENCE_NODES`] row i. Present only with [`SUPPORT_REACTIONS`].
    pub const SUPPORT_INFLUENCE: &str = "modes/support_influence";
    /// Optional u32 [q]: the corner vertices of [`SUPPORT_INFLUENCE`]'s rows, strictly
    /// ascending (the surface's). Present exactly when it is.
    pub const SUPPORT_INFLUENCE_NODES: &str = "modes/support_influence_nodes";
    /// String attribute of [`STRESS`]: the component order.
    pub const STRESS_COMPONENTS: &str = "components";
    /// Its value.
    pub const STRESS_COMPONENT_ORDER: &str = "xx yy zz yz xz xy";
    /// Group (parts that can move as a whole): attributes [`MASS`], [`CENTER_OF_MASS`],
    /// [`INERTIA`], and [`FREE_MOTIONS`] when some rigid motions are held.
    pub const RIGID: &str = "rigid";
    /// f64 [k, 6] in [`RIGID`], k = `rigid_modes_dropped` < 6: the rigid motions the supports
    /// leave free, each a twist (v, ω) about the centre of mass. Absent for a free body (all six).
    pub const FREE_MOTIONS: &str = "free_motions";
    /// f64 attribute, kg.
    pub const MASS: &str = "mass";
    /// f64[3] attribute, m.
    pub const CENTER_OF_MASS: &str = "center_of_mass";
    /// f64[3, 3] attribute, kg·m² about the centre of mass.
    pub const INERTIA: &str = "inertia";
    /// Optional group (a nonlinear model, `[model] kind = "nonlinear"`): the reduced St.
    /// Venant–Kirchhoff energy W(q) = ½ Σ λᵢ qᵢ² + qᵀ T s + ½ sᵀ H s of u = Φq, s the
    /// r(r+1)/2 products q_k q_l (k ≤ l, ordered (0,0), (0,1), …, (1,1), …). Attributes
    /// [`NONLINEAR_MODEL`], [`EIGENMODES`], [`DERIVATIVES_OF`].
    pub const NONLINEAR: &str = "nonlinear";
    /// String attribute of [`NONLINEAR`]: `"stvk"`.
    pub const NONLINEAR_MODEL: &str = "model";
    /// u32 attribute of [`NONLINEAR`]: the first columns of the basis that are eigenmodes; the
    /// rest are modal derivatives made M-orthonormal and K-orthogonal (their eigenvalues are
    /// Rayleigh quotients, and they have no error estimate).
    pub const EIGENMODES: &str = "eigenmodes";
    /// u32 attribute of [`NONLINEAR`]: how many lowest modes' pairwise derivatives were added.
    pub const DERIVATIVES_OF: &str = "derivatives_of";
    /// f64 [r, r(r+1)/2]: T, the cubic energy's coefficients.
    pub const NONLINEAR_CUBIC: &str = "nonlinear/cubic";
    /// f64 [r(r+1)/2, r(r+1)/2]: H, the quartic energy's (symmetric).
    pub const NONLINEAR_QUARTIC: &str = "nonlinear/quartic";
    /// Optional group: exact static compliance.
    pub const COMPLIANCE: &str = "compliance";
    /// u32 [p].
    pub const COMPLIANCE_NODES: &str = "compliance/nodes";
    /// f64 [p, 3, 3], m/N.
    pub const COMPLIANCE_BLOCKS: &str = "compliance/blocks";
    /// Optional group: what a hand feels wrong at surface vertices (attribute [`FELT_MODES`]).
    pub const FELT: &str = "felt";
    /// u32 attribute of [`FELT`]: the modes the truncation was measured with.
    pub const FELT_MODES: &str = "modes";
    /// u32 [p]: corner vertices, strictly ascending.
    pub const FELT_NODES: &str = "felt/nodes";
    /// f64 [p]: the share of the exact compliance the modes miss, in [0, 1].
    pub const FELT_TRUNCATION: &str = "felt/truncation";
    /// f64 [p]: the mesh's relative error of the exact compliance, ≥ 0.
    pub const FELT_MESH_ERROR: &str = "felt/mesh_error";
    /// Optional group: the hand's contact patches (attribute [`CONTACT_RADIUS`]).
    pub const CONTACT: &str = "contact";
    /// f64 attribute of [`CONTACT`], m.
    pub const CONTACT_RADIUS: &str = "radius";
    /// u32 [p]: the centres (surface corner vertices), ascending.
    pub const CONTACT_CENTRES: &str = "contact/centres";
    /// u32 [p + 1]: patch k is entries offsets[k]..offsets[k + 1] of nodes and weights.
    pub const CONTACT_OFFSETS: &str = "contact/offsets";
    /// u32 [nnz]: the loaded nodes.
    pub const CONTACT_NODES: &str = "contact/nodes";
    /// f64 [nnz]: each node's share of the force (each patch's sum to 1).
    pub const CONTACT_WEIGHTS: &str = "contact/weights";
    /// Optional group: `transfer/<from>` f64 [r_to, r_from].
    pub const TRANSFER: &str = "transfer";
    /// Optional u32 [n]: 1 where a support holds the node (any component), 0 elsewhere (what
    /// ParaView shows as the `fixed` point array).
    pub const FIXED_MASK: &str = "mesh/fixed_mask";
    /// Optional group: one group `loads/<name>` per static load case.
    pub const LOADS: &str = "loads";
    /// The datasets the writer compresses (deflate, shuffle), each of an extent the reader
    /// checks against uncompressed counts before reading it: `mesh/tets` (at most
    /// [`crate::checks::MAX_TETS_PER_NODE`] per node), `mesh/surface_faces` (one per surface
    /// triangle) and `mesh/fixed_mask` (one per node). Any other dataset must be stored
    /// uncompressed: its values are then no more bytes than the file holds, where deflate lets
    /// a 1 MB file hold a gigabyte of zeros.
    pub const COMPRESSED: [&str; 3] = [TETS, SURFACE_FACES, FIXED_MASK];
}

/// Names inside `/spaces/<space>/loads/<name>/` (one static load case).
pub mod load {
    /// f64 [n, 3]: static displacement of each node, m.
    pub const DISPLACEMENT: &str = "displacement";
    /// f64 [n]: von Mises stress of each node, Pa.
    pub const VON_MISES: &str = "von_mises";
    /// f64 [nv, 6]: stress at the corner vertices, Voigt order xx yy zz yz xz xy, Pa.
    pub const STRESS: &str = "stress";
    /// String attribute: `force`, `pressure` or `gravity`.
    pub const KIND: &str = "kind";
    /// f64[3] attribute: sum of the applied nodal loads, N.
    pub const TOTAL_FORCE: &str = "total_force";
    /// f64[3] attribute: total force the supports exert, N.
    pub const REACTION: &str = "reaction";
    /// f64 attribute: |reaction + total_force| over the sum of the nodal loads' magnitudes.
    pub const BALANCE_RESIDUAL: &str = "balance_residual";
    /// f64 attribute: largest nodal displacement magnitude, m.
    pub const MAX_DISPLACEMENT: &str = "max_displacement";
    /// f64 attribute: largest von Mises stress at a corner vertex, Pa.
    pub const MAX_VON_MISES: &str = "max_von_mises";
    /// The values of [`KIND`].
    pub const KINDS: [&str; 3] = ["force", "pressure", "gravity"];
    /// Prefix of the optional attributes of the case's largest von Mises peak as studied on
    /// meshes refined around it: `peak_verdict` (string, one of [`VERDICTS`]), `peak_value`
    /// (f64, Pa), `peak_error` (f64, Pa: the value's estimated error; absent when none is
    /// stated), `peak_refined` (f64[2], Pa: the value with the element size there halved, then
    /// quartered), `peak_position` (f64[3], m).
    pub const PEAK: &str = "peak";
    /// Prefix of the same attributes for the largest peak that is not singular, when the
    /// largest is.
    pub const REGULAR_PEAK: &str = "regular_peak";
    /// The values of a peak's verdict.
    pub const VERDICTS: [&str; 4] = ["converging", "slow", "singular", "unsettled"];
    /// Most load cases a space may hold (counted before any is read).
    pub const MAX_LOADS: usize = 64;
}

/// Largest basis of a nonlinear model (modes and derivatives): its quartic coefficients are
/// (r(r+1)/2)² values, 11 MB at 48, and each haptic step reads them.
pub const MAX_NONLINEAR_BASIS: usize = 48;

/// Most spaces a file may hold: "global" and one per volume of interest. A file listing more is
/// refused before any space is read, so a crafted file cannot multiply the reading work.
pub const MAX_SPACES: usize = 64;

/// Longest space name, bytes (it becomes a file name in `ves export`).
pub const MAX_SPACE_NAME_BYTES: usize = crate::identifier::MAX_IDENTIFIER_BYTES;

pub use crate::identifier::escape_for_terminal;

/// Checks a space name as the scene and the file may give it: an identifier
/// ([`crate::check_identifier`]: names are printed to terminals and become file names). `Err`
/// says what is wrong.
pub fn check_space_name(name: &str) -> Result<(), crate::IdentifierError> {
    crate::check_identifier("space name", name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn space_names_that_would_drive_a_terminal_or_a_path_are_refused() {
        for bad in [
            "",
            "a/b",
            "..",
            "\u{1b}]0;x\u{7}",
            "x\u{202E}y",
            "x\u{2066}",
            "tab\there",
            "a\\b",
        ] {
            assert!(check_space_name(bad).is_err(), "{bad:?}");
        }
        assert!(check_space_name(&"x".repeat(MAX_SPACE_NAME_BYTES + 1)).is_err());
        for good in ["global", "rib 1", "Rippe_ä", "voi-2.5"] {
            assert!(check_space_name(good).is_ok(), "{good:?}");
        }
        assert_eq!(escape_for_terminal("a\u{1b}[2Jb\u{202E}"), "a\\u{1b}[2Jb\\u{202e}");
    }
}
