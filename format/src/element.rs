//! The kinds of element a basis file's mesh is made of, and everything that differs between
//! them: the node count, the file's `element_order` value, the gmsh element type and the VTK
//! cell. One place to change to add a kind (docs/architecture.md, "Adding an element kind").

/// gmsh → VTK order of a 10-node tet (gmsh numbers the last two mid-edge nodes (3,2), (3,1);
/// VTK (1,3), (2,3)).
pub const TET10_TO_VTK: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];

/// A tetrahedron kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ElementKind {
    /// 4-node linear tetrahedron.
    Tet4,
    /// 10-node quadratic tetrahedron (corners, then mid-edge nodes in gmsh's order).
    Tet10,
}

impl ElementKind {
    /// The kind of a polynomial order: the file's `element_order` and the scene's `mesh.order`
    /// (1 or 2; `None` otherwise).
    pub fn of_order(order: u32) -> Option<ElementKind> {
        match order {
            1 => Some(ElementKind::Tet4),
            2 => Some(ElementKind::Tet10),
            _ => None,
        }
    }

    /// The polynomial order (1 or 2): the file's `element_order` value.
    pub fn order(self) -> u8 {
        match self {
            ElementKind::Tet4 => 1,
            ElementKind::Tet10 => 2,
        }
    }

    /// Nodes per element (4 or 10).
    pub fn nodes(self) -> usize {
        match self {
            ElementKind::Tet4 => 4,
            ElementKind::Tet10 => 10,
        }
    }

    /// Whether the element has mid-edge nodes (curved edges possible).
    pub fn is_quadratic(self) -> bool {
        self == ElementKind::Tet10
    }

    /// gmsh's element type number (`gmsh/Common/GmshDefines.h`: 4 = TET_4, 11 = TET_10).
    pub fn gmsh_type(self) -> i32 {
        match self {
            ElementKind::Tet4 => 4,
            ElementKind::Tet10 => 11,
        }
    }

    /// VTK's cell type (`VTK_TETRA` = 10, `VTK_QUADRATIC_TETRA` = 24).
    pub fn vtk_cell_type(self) -> u8 {
        match self {
            ElementKind::Tet4 => 10,
            ElementKind::Tet10 => 24,
        }
    }

    /// For each of VTK's (and XDMF's) nodes of the element, its index in gmsh's order (the
    /// file's).
    pub fn vtk_node_order(self) -> &'static [usize] {
        match self {
            ElementKind::Tet4 => &[0, 1, 2, 3],
            ElementKind::Tet10 => &TET10_TO_VTK,
        }
    }

    /// XDMF's topology type.
    pub fn xdmf_topology(self) -> &'static str {
        match self {
            ElementKind::Tet4 => "Tetrahedron",
            ElementKind::Tet10 => "Tetrahedron_10",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::ElementKind;

    #[test]
    fn the_order_round_trips_and_only_1_and_2_are_kinds() {
        for k in [ElementKind::Tet4, ElementKind::Tet10] {
            assert_eq!(ElementKind::of_order(u32::from(k.order())), Some(k));
        }
        assert_eq!(ElementKind::of_order(0), None);
        assert_eq!(ElementKind::of_order(3), None);
        assert_eq!(ElementKind::Tet10.nodes(), 10);
        assert_eq!(ElementKind::Tet4.nodes(), 4);
    }
}
