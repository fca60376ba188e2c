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
