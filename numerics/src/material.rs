//! The part's material, one type from the scene to the element integrals: what the scene's
//! `[material]` table holds, what K and M are assembled from, what a basis file's `/material`
//! gives back to `ves verify`.

use serde::Deserialize;

/// Isotropic linear-elastic material (SI units).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Yield strength, Pa (optional): the runtime's safety-factor watch.
    #[serde(default)]
    pub yield_strength: Option<f64>,
}

impl Material {
    /// E, ν and ρ without a yield strength (tests, a rank's own copy).
    pub fn elastic(young: f64, poisson: f64, density: f64) -> Material {
        Material {
            young,
            poisson,
            density,
            yield_strength: None,
        }
    }
}

impl Material {
    /// A likely unit slip, said in one line with what to write instead: a Young's modulus in
    /// MPa or GPa (the CAE habit: `young = 70000` for aluminium gives f1 ≈ 1000× too low) or a
    /// density in g/cm³. `None` for anything a real solid can be. The bounds leave room for
    /// soft tissue and gels (E ~ 1 kPa at 1000 kg/m³) and foams (E ~ 2 kPa at 30 kg/m³): no
    /// solid denser than 1500 kg/m³ is softer than 1 MPa (filled silicone rubber is ~1–5 MPa),
    /// none denser than 2000 kg/m³ softer than 100 MPa (PTFE: 0.5 GPa at 2200 kg/m³), and
    /// none has E/ρ above 1e9 m²/s² (diamond: 3e8, a wave speed of 18 km/s).
    pub fn unit_slip(&self) -> Option<String> {
        let (e, rho) = (self.young, self.density);
        if e / rho > 1e9 {
            return Some(if rho < 100.0 {
                format!(
                    "material.density = {rho} kg/m³ with young = {e:e} Pa is stiffer for its weight than any solid \
                     (E/ρ = {:.1e} m²/s², diamond 3e8): if that density was in g/cm³, write density = {}",
                    e / rho,
                    rho * 1000.0
                )
            } else {
                format!(
                    "material.young = {e:e} Pa with density {rho} kg/m³ is stiffer for its weight than any solid \
                     (E/ρ = {:.1e} m²/s², diamond 3e8): young is in Pa (steel 2.1e11)",
                    e / rho
                )
            });
        }
        let floor = if rho >= 2000.0 {
            1e8
        } else if rho >= 1500.0 {
            1e6
        } else {
            return None;
        };
        (e < floor).then(|| {
            // The reading (MPa or GPa) that gives a real solid's stiffness for its weight.
            let real = |x: f64| (1e6..=3.5e8).contains(&(x / rho));
            let guess = [e * 1e6, e * 1e9].into_iter().find(|&x| real(x)).unwrap_or(e * 1e6);
            format!(
                "material.young = {e} Pa with density {rho} kg/m³: no solid that dense is that soft (below \
                 {floor:e} Pa; aluminium 7e10, steel 2.1e11); young is in Pa: if {e} was MPa or GPa, write \
                 young = {guess:e}"
            )
        })
    }
}

impl From<&ves_format::Material> for Material {
    /// The material a basis file was made with (its Rayleigh damping is the runtime's).
    fn from(m: &ves_format::Material) -> Material {
        Material {
            young: m.young,
            poisson: m.poisson,
            density: m.density,
            yield_strength: m.yield_strength,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Real materials pass; moduli in MPa or GPa and densities in g/cm³ are named, with the
    /// value to write.
    #[test]
    fn unit_slips_are_named_and_real_materials_pass() {
        for (e, rho) in [
            (2.1e11, 7850.0),  // steel
            (7e10, 2700.0),    // aluminium
            (5e8, 2200.0),     // PTFE
            (2.3e9, 1050.0),   // ABS
            (2e6, 1500.0),     // filled silicone
            (1e3, 1000.0),     // soft tissue, gel
            (2e3, 30.0),       // foam
            (1.05e12, 3500.0), // diamond
        ] {
            assert_eq!(Material::elastic(e, 0.3, rho).unit_slip(), None, "{e} {rho}");
        }
        let mpa = Material::elastic(70000.0, 0.33, 2700.0).unit_slip().expect("MPa");
        assert!(
            mpa.contains("material.young = 70000") && mpa.contains("young = 7e10"),
            "{mpa}"
        );
        let gpa = Material::elastic(210.0, 0.3, 7850.0).unit_slip().expect("GPa");
        assert!(gpa.contains("young = 2.1e11"), "{gpa}");
        let gcc = Material::elastic(2.1e11, 0.3, 7.85).unit_slip().expect("g/cm³");
        assert!(
            gcc.contains("material.density = 7.85") && gcc.contains("density = 7850"),
            "{gcc}"
        );
    }
}
