//! The discrete problem of one space: its mesh, DOF numbering and assembled K, M. The low-level
//! type every later stage (modes, static correction, transfer, store, checks) starts from.

use crate::fem;
use crate::fem::Dofs;
use crate::material::Material;
use crate::mesh::{self, Mesh};
use crate::modes::Model;
use crate::rigid_motions::free_rigid_count;
use crate::scene::{Scene, Voi};
use crate::supports;
use anyhow::{Context, Result};
use std::time::Instant;

/// The assembled problem of one space, before the eigen-solve (also used by tests and checks):
/// the numerics core's [`Model`] (mesh, DOFs, K and M, material, rigid motions; its fields read
/// through `Deref`) and what making it cost.
pub struct Discretized {
    /// Mesh, DOFs, K and M, material, rigid motions left by the supports.
    pub model: Model,
    /// Seconds spent meshing.
    pub mesh_s: f64,
    /// What making the mesh order 2 needed (repairs of curved tets).
    pub meshing: mesh::Meshing,
    /// Seconds spent selecting supports and assembling.
    pub assemble_s: f64,
}

impl std::ops::Deref for Discretized {
    type Target = Model;

    fn deref(&self) -> &Model {
        &self.model
    }
}

impl std::ops::DerefMut for Discretized {
    fn deref_mut(&mut self) -> &mut Model {
        &mut self.model
    }
}

/// One space meshed and its supports selected, K and M not yet assembled: what SLEPc under MPI
/// starts from (each rank assembles its own rows), and what [`Meshed::assemble`] makes a
/// [`Discretized`] of.
pub struct Meshed {
    /// The mesh.
    pub mesh: Mesh,
    /// DOF numbering.
    pub dofs: Dofs,
    /// The springs of the supports that hold by springs (sliding, bearing, elastic).
    pub springs: Vec<crate::fem::springs::NodeSpring>,
    /// The rigid motions the supports leave free, as twists about the origin.
    pub free: ves_format::FreeMotions,
    /// The material.
    pub material: Material,
    /// Seconds spent meshing.
    pub mesh_s: f64,
    /// What making the mesh order 2 needed (repairs of curved tets).
    pub meshing: mesh::Meshing,
    /// Seconds spent selecting supports, and assembling wherever that was done so far.
    pub assemble_s: f64,
}

/// Meshes and assembles one space.
pub fn discretize(scene: &Scene, voi: Option<&Voi>) -> Result<Discretized> {
    discretize_with(scene, voi, None, false)
}

/// [`discretize`]; `quiet` for a helper mesh (its warnings become info lines).
pub fn discretize_with(
    scene: &Scene,
    voi: Option<&Voi>,
    field: Option<&mesh::field::SizeField>,
    quiet: bool,
) -> Result<Discretized> {
    mesh_with_supports(scene, voi, field, quiet)?
        .assemble()
        .with_context(|| scene.geometry.display().to_string())
}

/// Meshes one space and selects its supports, without assembling K and M: for SLEPc under MPI,
/// where each rank assembles its rows.
pub fn mesh_with_supports(
    scene: &Scene,
    voi: Option<&Voi>,
    field: Option<&mesh::field::SizeField>,
    quiet: bool,
) -> Result<Meshed> {
    let t = Instant::now();
    let (mesh, meshing) = mesh::generate_with(scene, voi, field, quiet)?;
    let mesh_s = t.elapsed().as_secs_f64();
    // The part's extent is known only now; a VOI or probe off the part is refused before the solve.
    let (lo, hi) = mesh.bounding_box();
    scene.check_regions_on_part(lo, hi)?;
    if voi.is_none() {
        mesh::check_voi_budgets(scene, std::array::from_fn(|c| hi[c] - lo[c]))?;
    }
    let (quality, at) = mesh.worst_quality();
    tracing::info!(
        nodes = mesh.nodes.len(),
        tets = mesh.tet_count(),
        worst_quality = quality,
        "meshed"
    );
    let sliver = (quality < 0.02).then(|| {
        format!(
            "sliver tet (shape quality {quality:.1e}, 1 = regular) near ({:.6}, {:.6}, {:.6}) m: accuracy may suffer there; \
             change mesh.size or repair the geometry",
            at[0], at[1], at[2]
        )
    });
    if meshing.cached {
        // A cached mesh's warnings were said in full on the run that made it: here one line.
        if let Some(s) = &sliver {
            tracing::info!("(cached mesh) {s}");
        }
        let mut made = meshing.warnings_when_made();
        made.extend(sliver.map(|_| format!("a sliver tet of shape quality {quality:.1e}")));
        if !made.is_empty() && !quiet {
            tracing::warn!(
                "{}: cached mesh: {} warning(s) when it was made ({}); VES_LOG=info repeats them in full",
                scene.geometry.display(),
                made.len(),
                made.join("; ")
            );
        }
    } else if let Some(s) = sliver.filter(|_| !quiet) {
        tracing::warn!("{s}");
    }
    let t = Instant::now();
    let dofs = supports::select(&mesh, &scene.fixed).with_context(|| scene.path.display().to_string())?;
    if !dofs.fixed.is_empty() {
        unheld_body(&mesh, &dofs).with_context(|| scene.path.display().to_string())?;
    }
    let springs: Vec<_> = supports::springs(&mesh, &scene.fixed, scene.material.young)
        .with_context(|| scene.path.display().to_string())?
        .into_iter()
        .flatten()
        .collect();
    let free = crate::rigid_motions::free_motions(&mesh.nodes, &dofs, &springs, [0.0; 3]);
    Ok(Meshed {
        mesh,
        dofs,
        springs,
        free,
        material: scene.material,
        mesh_s,
        meshing,
        assemble_s: t.elapsed().as_secs_f64(),
    })
}

impl Meshed {
    /// How many rigid motions the supports leave free.
    pub fn rigid(&self) -> usize {
        self.free.count()
    }

    /// Assembles K, M and the mass on this process; its seconds join `assemble_s`.
    pub fn assemble(self) -> Result<Discretized, fem::assembly::AssemblyError> {
        let t = Instant::now();
        let mut system = fem::assembly::assemble_with(&self.mesh, &self.material, &self.dofs, &self.springs)?;
        system.mass.free = self.free.moved([0.0; 3], system.mass.center);
        let rigid = self.rigid();
        Ok(Discretized {
            model: Model {
                mesh: self.mesh,
                dofs: self.dofs,
                system,
                material: self.material,
                rigid,
            },
            mesh_s: self.mesh_s,
            meshing: self.meshing,
            assemble_s: self.assemble_s + t.elapsed().as_secs_f64(),
        })
    }
}

impl Discretized {
    /// Of the meshing seconds, what did not go into making the mesh itself (starting gmsh,
    /// reading the geometry, the cache): what a mesh of any size costs.
    pub fn fixed_mesh_s(&self) -> f64 {
        if self.meshing.cached {
            return 0.0;
        }
        (self.mesh_s - self.meshing.generate_s).max(0.0)
    }

    /// Assembles K and M on a given mesh and DOF numbering; stage times left at zero.
    pub fn assemble(mesh: Mesh, dofs: Dofs, material: Material) -> Result<Discretized> {
        Ok(Discretized {
            model: Model::assemble(mesh, dofs, material)?,
            mesh_s: 0.0,
            meshing: mesh::Meshing::default(),
            assemble_s: 0.0,
        })
    }
}

/// Disconnected bodies of the mesh: the body index of each node (bodies share no tet).
fn bodies(mesh: &Mesh) -> (Vec<usize>, usize) {
    let n = mesh.nodes.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for tet in mesh.tets.chunks_exact(mesh.nodes_per_tet()) {
        let a = root(&mut parent, tet[0] as usize);
        for &v in &tet[1..] {
            let b = root(&mut parent, v as usize);
            parent[b] = a;
        }
    }
    let mut label = vec![usize::MAX; n];
    let mut count = 0;
    let body = (0..n)
        .map(|i| {
            let r = root(&mut parent, i);
            if label[r] == usize::MAX {
                label[r] = count;
                count += 1;
            }
            label[r]
        })
        .collect();
    (body, count)
}

/// With supports given, every separate body must be held by them: a body the supports do not
/// reach would float (singular K) and used to fail later as a "mode check" with the wrong advice.
fn unheld_body(mesh: &Mesh, dofs: &Dofs) -> Result<(), supports::SupportError> {
    let (body, count) = bodies(mesh);
    if count < 2 {
        return Ok(());
    }
    for b in 0..count {
        let nodes: Vec<usize> = (0..mesh.nodes.len()).filter(|&i| body[i] == b).collect();
        let mut mask = vec![false; 3 * nodes.len()];
        for (k, &i) in nodes.iter().enumerate() {
            for c in 0..3 {
                mask[3 * k + c] = dofs.free_of[3 * i + c] == u32::MAX;
            }
        }
        let xyz: Vec<[f64; 3]> = nodes.iter().map(|&i| mesh.nodes[i]).collect();
        let free = free_rigid_count(&xyz, &Dofs::from_mask(&mask));
        if free > 0 {
            let mut c = [0.0; 3];
            for p in &xyz {
                for k in 0..3 {
                    c[k] += p[k] / xyz.len() as f64;
                }
            }
            return Err(supports::SupportError::UnheldBody {
                bodies: count,
                body: b + 1,
                nodes: xyz.len(),
                centre: c,
                free,
            });
        }
    }
    Ok(())
}
