//! The mesh a `target_error` refinement chose for a geometry, kept beside the mesh cache, under
//! two keys:
//!
//! - the *scenario*'s (geometry and supports, E, ν and the mode count as well, not the target):
//!   the same scene run again — a saved scene of the page, a batch rerun — starts from the mesh
//!   its last run ended on, reached or stopped, and gives that run's basis again instead of one
//!   from another path of refinement; asked with another target (the page's "accept" of a
//!   refinement that stopped), it starts there when that is a good start;
//! - the *geometry*'s (and the target's): another scenario of the same part (other supports, material, modes or
//!   loads change the error a little, and the refinement goes on from there when the target is
//!   not met) starts from it. Only a mesh that met its target is kept here: one a refinement
//!   stopped short on (a support on a line, whose error never falls) would send every later
//!   scenario of the part, a free body too, to that mesh.
//!
//! Both keys hold the geometry file's bytes, unit, element order, `refinement`,
//! the scene's `mesh.size` (the start), `max_dofs` and the space (the VOI's box and size), and the
//! VES version. An entry is JSON; anything unreadable or implausible at its path is a miss.

use super::cache;
use super::field::SizeField;
use crate::scene::{Scene, Voi};
use std::io::Read;
use std::path::PathBuf;

/// What a refinement chose.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Chosen {
    /// The uniform element size, m (the largest, with a size field).
    pub size: f64,
    /// The size field of a local refinement's last mesh.
    pub field: Option<SizeField>,
    /// Its free unknowns (with the supports of the run that chose it).
    pub dofs: usize,
    /// Its largest estimated error then.
    pub estimated_error: f64,
    /// Whether that met the target (false: the refinement stopped short of it). Entries written
    /// before this was kept read as false.
    #[serde(default)]
    pub reached: bool,
    /// The `target_error` it was refined for (None in entries written before it was kept).
    #[serde(default)]
    pub target: Option<f64>,
}

/// Longest entry read (a size field of a million vertices is about 60 MB of JSON).
const MAX_ENTRY: u64 = 256 << 20;

/// Which of the two keys a choice was found under.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// This very scenario ran before.
    Scenario,
    /// Another scenario of the geometry ran before.
    Geometry,
}

/// Where the choices for `voi`'s space of a scene live.
#[derive(Clone, Debug)]
pub struct Keys {
    scenario: PathBuf,
    geometry: PathBuf,
}

impl Keys {
    /// The keys of `voi`'s space of `scene`; None with the cache off, without a target, for a
    /// `.geo` script (it may read other files) or an unreadable geometry.
    pub fn of(scene: &Scene, voi: Option<&Voi>) -> Option<Keys> {
        let target = scene.mesh.target_error?;
        let ext = scene.geometry.extension()?.to_str()?.to_ascii_lowercase();
        if ext == "geo" {
            return None;
        }
        let dir = cache::dir()?;
        let geometry = crate::input::read(&scene.geometry).ok()?;
        let shape = serde_json::to_string(&(
            scene.unit,
            scene.mesh.order,
            scene.mesh.refinement,
            scene.mesh.size,
            scene.mesh.max_dofs,
            voi.map(|v| (v.bbox, v.size)),
        ))
        .ok()?;
        let mut h = crate::fingerprint::Fingerprint::default();
        h.field(b"chosen mesh")
            .field(env!("CARGO_PKG_VERSION").as_bytes())
            .field(shape.as_bytes())
            .field(ext.as_bytes())
            .field(&geometry);
        let mut of_geometry = h.clone();
        of_geometry.field(&target.to_le_bytes());
        // What else shapes the error: the supports, the stiffness against theirs and Poisson's
        // ratio, and the modes kept (`Debug` writes each f64 so that it reads back the same).
        // Not the density (it scales every frequency alike), the yield strength, nor the target:
        // a scenario asked again with another starts from its last mesh when that is a good start.
        let m = &scene.material;
        let scenario = format!("{:?} {:?} {:?} {}", scene.fixed, m.young, m.poisson, scene.modes.count);
        h.field(b"scenario").field(scenario.as_bytes());
        Some(Keys {
            scenario: dir.join(format!("{:016x}.chosen", h.value())),
            geometry: dir.join(format!("{:016x}.chosen", of_geometry.value())),
        })
    }

    /// The choice to start from: this scenario's, reached or not (and with another `target`,
    /// reached or stopped, only when `good_start` of its estimate), else the geometry's when it
    /// met its target.
    pub fn lookup(&self, target: f64, good_start: impl Fn(f64) -> bool) -> Option<(Chosen, Scope)> {
        if let Some(c) = lookup(&self.scenario)
            .filter(|c| c.target == Some(target) || (c.target.is_some() && good_start(c.estimated_error)))
        {
            return Some((c, Scope::Scenario));
        }
        lookup(&self.geometry)
            .filter(|c| c.reached)
            .map(|c| (c, Scope::Geometry))
    }

    /// Keeps `chosen` for this scenario, and for the geometry when it met its target.
    pub fn store(&self, chosen: &Chosen) {
        store(&self.scenario, chosen);
        if chosen.reached {
            store(&self.geometry, chosen);
        }
    }
}

/// The choice stored under `key`, if a plausible one is there.
fn lookup(key: &std::path::Path) -> Option<Chosen> {
    let (file, size) = match cache::open_entry(key) {
        Ok(Some(f)) => f,
        Ok(None) => return None,
        Err(why) => {
            tracing::info!("{}: remembered refinement ignored ({why})", key.display());
            return None;
        }
    };
    if size > MAX_ENTRY {
        return None;
    }
    let mut text = Vec::new();
    file.take(size).read_to_end(&mut text).ok()?;
    let c: Chosen = serde_json::from_slice(&text).ok()?;
    let plausible = |x: f64| x.is_finite() && x > 0.0;
    let field_ok = c.field.as_ref().is_none_or(|f| {
        !f.points.is_empty()
            && f.sizes.len() == f.points.len()
            && f.sizes.iter().all(|&s| plausible(s))
            && f.tets.iter().flatten().all(|&v| (v as usize) < f.points.len())
    });
    (plausible(c.size) && field_ok).then_some(c)
}

/// Stores `chosen` under `key`; a failure only costs the next run its refinement (logged).
fn store(key: &std::path::Path, chosen: &Chosen) {
    cache::write_atomically(key, |w| {
        serde_json::to_writer(&mut *w, chosen).map_err(std::io::Error::other)
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A choice reads back as stored; an entry that is not one, or holds a size no mesh has,
    /// is a miss.
    #[test]
    fn a_choice_reads_back_and_a_bad_entry_is_a_miss() {
        let dir = std::env::temp_dir().join(format!("ves-remembered-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let key = dir.join("a.chosen");
        let chosen = Chosen {
            size: 0.0125,
            field: None,
            dofs: 32_787,
            estimated_error: 0.0031,
            reached: true,
            target: Some(0.01),
        };
        store(&key, &chosen);
        assert_eq!(lookup(&key), Some(chosen.clone()));
        for bad in [
            "{",
            "{\"size\": -1.0, \"field\": null, \"dofs\": 3, \"estimated_error\": 0.1}",
            "",
        ] {
            std::fs::write(&key, bad).expect("write");
            assert_eq!(lookup(&key), None, "{bad}");
        }
        let field = SizeField {
            points: vec![[0.0; 3]],
            tets: vec![[0, 0, 0, 7]],
            sizes: vec![0.01],
        };
        store(
            &key,
            &Chosen {
                field: Some(field),
                ..chosen
            },
        );
        assert_eq!(lookup(&key), None, "a tet on a vertex the field does not have");
        assert_eq!(lookup(&dir.join("absent.chosen")), None);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
