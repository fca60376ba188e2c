//! A mesh size that varies over the part: sizes at the corner vertices of an earlier mesh of it,
//! linear inside each of its tets. gmsh reads it as a background mesh (a "PostView" field on a
//! list-based view), which is how local refinement asks for small elements only where the error
//! is.

use super::Mesh;

/// Element sizes given at the vertices of a tet mesh, metres.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SizeField {
    /// Vertices, metres.
    pub points: Vec<[f64; 3]>,
    /// Tets on `points`.
    pub tets: Vec<[u32; 4]>,
    /// Size at each point, metres.
    pub sizes: Vec<f64>,
}

impl SizeField {
    /// Sizes `sizes` (one per corner vertex) over the corner tets of `mesh`.
    pub fn on(mesh: &Mesh, sizes: Vec<f64>) -> SizeField {
        SizeField {
            points: mesh.nodes[..mesh.vertex_count].to_vec(),
            tets: (0..mesh.tet_count())
                .map(|e| std::array::from_fn(|k| mesh.tet(e)[k]))
                .collect(),
            sizes,
        }
    }

    /// The same field with every size times `factor`.
    pub fn scaled(&self, factor: f64) -> SizeField {
        SizeField {
            sizes: self.sizes.iter().map(|s| s * factor).collect(),
            ..self.clone()
        }
    }

    /// The largest size.
    pub fn largest(&self) -> f64 {
        self.sizes.iter().copied().fold(0.0, f64::max)
    }

    /// The smallest size.
    pub fn smallest(&self) -> f64 {
        self.sizes.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// About how many tets a mesh following the field has: Σ volume / volume of a regular tet
    /// of the tet's mean size.
    pub fn expected_tets(&self) -> f64 {
        self.tets
            .iter()
            .map(|t| {
                let volume = super::signed_volume(&self.points, t).abs() / 6.0;
                let h = t.iter().map(|&v| self.sizes[v as usize]).sum::<f64>() / 4.0;
                volume / super::regular_tet_volume(h)
            })
            .sum()
    }

    /// gmsh's list data for scalar tets ("SS"), coordinates divided by `scale` (metres per gmsh
    /// unit): per tet x₁…x₄, y₁…y₄, z₁…z₄, then the four sizes.
    pub fn list_data(&self, scale: f64) -> Vec<f64> {
        let mut data = Vec::with_capacity(16 * self.tets.len());
        for t in &self.tets {
            for c in 0..3 {
                data.extend(t.iter().map(|&v| self.points[v as usize][c] / scale));
            }
            data.extend(t.iter().map(|&v| self.sizes[v as usize] / scale));
        }
        data
    }

    /// A fingerprint of the field for the mesh cache's key.
    pub fn fingerprint(&self) -> u64 {
        let mut h = crate::fingerprint::Fingerprint::default();
        let bytes = |v: &mut Vec<u8>, x: f64| v.extend_from_slice(&x.to_le_bytes());
        let mut buf = Vec::with_capacity(8 * (3 * self.points.len() + self.sizes.len()) + 16 * self.tets.len());
        self.points.iter().flatten().for_each(|&x| bytes(&mut buf, x));
        self.sizes.iter().for_each(|&x| bytes(&mut buf, x));
        self.tets
            .iter()
            .flatten()
            .for_each(|&v| buf.extend_from_slice(&v.to_le_bytes()));
        h.field(&buf);
        h.value()
    }
}
