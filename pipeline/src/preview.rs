//! The part's surface and its CAD faces before any compute: what a viewer needs to show the
//! faces and let the user pick those a support holds (`[[fixed]] faces`, docs/scene.md).

use crate::mesh;
use crate::scene::Scene;
use anyhow::{Context, Result};

/// The surface of a part with its CAD faces.
#[derive(Clone, Debug)]
pub struct SurfacePreview {
    /// The corner vertices on the surface, m.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles over `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Each triangle's CAD face: gmsh's surface tag, what `[[fixed]] faces` names; 0 where
    /// unknown.
    pub faces: Vec<u32>,
}

/// The surface of the scene's part as the global space's mesh has it.
///
/// The mesh is the one `ves precompute` makes of the scene (same geometry bytes, unit, size and
/// order), through the mesh cache: a cache hit costs the reading of one entry, and a miss
/// meshes the part and stores it, so the compute that follows skips gmsh. Supports are not
/// applied (a face support naming a tag the part lacks is no error here).
pub fn surface_preview(scene: &Scene) -> Result<SurfacePreview> {
    let (m, _) = mesh::generate(scene, None).with_context(|| scene.path.display().to_string())?;
    let vertices = m.surface_vertices();
    let mut slot = vec![u32::MAX; m.vertex_count];
    for (k, &v) in vertices.iter().enumerate() {
        slot[v as usize] = k as u32;
    }
    let triangles = m.surface.iter().map(|t| t.map(|v| slot[v as usize])).collect();
    let xyz = vertices.iter().map(|&v| m.nodes[v as usize]).collect();
    Ok(SurfacePreview {
        vertices: xyz,
        triangles,
        faces: m.surface_faces,
    })
}
