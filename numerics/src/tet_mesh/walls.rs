//! Walls meshed one element thick. A tet whose four corners all lie on the surface spans the
//! part from face to face: where most of the volume is in such tets, bending across the wall
//! rests on a single element through the thickness (measured: 97–99 % of the volume on the
//! 200:1 plate and the ribplate at their default sizes, 16 % on the cantilever with two
//! elements through its 50 mm).

use super::Mesh;
use nalgebra::Vector3;

/// What the mesh says about its walls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Walls {
    /// Fraction of the volume in tets with all four corners on the surface.
    pub spanning_fraction: f64,
    /// Typical wall thickness 2V/A, m (V volume, A surface area: exact for a thin plate).
    pub thickness: f64,
}

/// Above this fraction of spanning volume the walls are taken as one element thick.
pub const ONE_ELEMENT_THICK: f64 = 0.5;

impl Mesh {
    /// How much of the part is one element thick, and how thick its walls are.
    pub fn walls(&self) -> Walls {
        let mut on_surface = vec![false; self.vertex_count];
        for &v in self.surface.iter().flatten() {
            on_surface[v as usize] = true;
        }
        let (mut total, mut spanning) = (0.0, 0.0);
        for e in 0..self.tet_count() {
            let t = &self.tet(e)[..4];
            let v = self.corner_volume(e);
            total += v;
            if t.iter().all(|&n| on_surface[n as usize]) {
                spanning += v;
            }
        }
        let area: f64 = self
            .surface
            .iter()
            .map(|f| {
                let p = f.map(|n| Vector3::from(self.nodes[n as usize]));
                0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()
            })
            .sum();
        Walls {
            spanning_fraction: if total > 0.0 { spanning / total } else { 0.0 },
            thickness: if area > 0.0 { 2.0 * total / area } else { 0.0 },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plate_one_element_thick_is_found_and_a_block_is_not() {
        // 10 × 10 × 1 cubes of side 0.01: a 0.1 × 0.1 × 0.01 m plate.
        let plate = Mesh::structured_box([10, 10, 1], 0.01, ves_format::ElementKind::Tet10, |_, p| p);
        let w = plate.walls();
        assert!(w.spanning_fraction > 0.99, "{w:?}");
        // 2V/A = 2·1e-4 / (2·0.01 + 4·0.001) = 8.3e-3 m.
        assert!((w.thickness - 2e-4 / 0.024).abs() < 1e-12, "{w:?}");
        let block = Mesh::structured_box([4, 4, 4], 0.01, ves_format::ElementKind::Tet10, |_, p| p);
        assert!(
            block.walls().spanning_fraction < ONE_ELEMENT_THICK,
            "{:?}",
            block.walls()
        );
    }
}
