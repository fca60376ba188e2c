//! A mesh size that varies over the part: sizes at the corner vertices of an earlier mesh of it,
//! linear inside each of its tets. gmsh reads it as a background mesh (a "PostView" field on a
//! list-based view), which is how local refinement asks for small elements only where the error
//! is.

use super::Mesh;

/// A mesh size chosen from computed numbers (an estimate, an indicator), rounded to the four
/// significant digits it is printed with: the round-off of a parallel sum moved the cylinder head's
/// planned size by 1e-12 between two runs of the same scene, and gmsh made 338,784 unknowns of
/// one and 337,881 of the other. Rounded, the same scene makes the same meshes on any machine
/// and thread count (unless a size lies within round-off of a rounding boundary), and the size
/// a refinement prints is the one a scene can give.
pub fn rounded_size(size: f64) -> f64 {
    if !size.is_finite() || size <= 0.0 {
        return size;
    }
    format!("{size:.3e}").parse().unwrap_or(size)
}

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

#[cfg(test)]
mod tests {
    use super::rounded_size;

    /// The two planned sizes of the cylinder head's third mesh, 1e-12 apart, are one size, the
    /// one printed; what is not a size passes through.
    #[test]
    fn sizes_a_round_off_apart_are_one_size() {
        let (a, b) = (6.478234408966694e-4, 6.478234408961777e-4);
        assert_ne!(a, b);
        assert_eq!(rounded_size(a), 6.478e-4);
        assert_eq!(rounded_size(a), rounded_size(b));
        assert_eq!(format!("{:.3e}", rounded_size(a)), format!("{a:.3e}"));
        assert_eq!(rounded_size(0.0), 0.0);
        assert!(rounded_size(f64::NAN).is_nan());
        assert_eq!(rounded_size(f64::INFINITY), f64::INFINITY);
    }
}
