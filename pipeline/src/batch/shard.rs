//! Shards of one batch for job arrays: every node lists the same scenes, orders them the same
//! way and splits them by expected cost, so shard K of N takes its share without talking to
//! the others.

use crate::scene::Scene;
use anyhow::{Result, bail};

/// Most shards accepted.
pub const MAX_SHARDS: usize = 100_000;

/// Shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1…count.
    pub index: usize,
    /// How many shards share the batch.
    pub count: usize,
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// `K/N` (1 ≤ K ≤ N), or `auto`: from a Slurm job array's environment.
    pub fn parse(text: &str) -> Result<Shard> {
        if text == "auto" {
            return Shard::from_env(&|k| std::env::var(k).ok());
        }
        let bad = || {
            anyhow::anyhow!(
                "--shard {text:?}: give K/N with 1 ≤ K ≤ N ≤ {MAX_SHARDS} (e.g. 2/8), or `auto` in a Slurm job array"
            )
        };
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (k, n) = (
            k.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if k == 0 || k > n || n > MAX_SHARDS {
            return Err(bad());
        }
        Ok(Shard { index: k, count: n })
    }

    /// The shard of a Slurm job-array task: its place among the array's task ids
    /// (`SLURM_ARRAY_TASK_ID`, `_MIN`, `_STEP`) of `SLURM_ARRAY_TASK_COUNT`.
    pub fn from_env(var: &dyn Fn(&str) -> Option<String>) -> Result<Shard> {
        let num = |k: &str| -> Result<Option<usize>> {
            match var(k) {
                None => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<usize>()
                    .map(Some)
                    .map_err(|_| anyhow::anyhow!("--shard auto: {k}={v:?} is not a whole number")),
            }
        };
        let (id, count) = match (num("SLURM_ARRAY_TASK_ID")?, num("SLURM_ARRAY_TASK_COUNT")?) {
            (Some(id), Some(count)) => (id, count),
            (id, count) => {
                let missing: Vec<&str> = [("SLURM_ARRAY_TASK_ID", id), ("SLURM_ARRAY_TASK_COUNT", count)]
                    .iter()
                    .filter(|(_, v)| v.is_none())
                    .map(|(k, _)| *k)
                    .collect();
                bail!(
                    "--shard auto: {} not set (not a Slurm job array); give --shard K/N",
                    missing.join(" and ") + if missing.len() > 1 { " are" } else { " is" }
                );
            }
        };
        let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
        let step = num("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1);
        if step == 0 {
            bail!("--shard auto: SLURM_ARRAY_TASK_STEP=0 is no step; give --shard K/N");
        }
        if id < min || (id - min) % step != 0 {
            bail!("--shard auto: task {id} is not in the array from {min} by steps of {step}; give --shard K/N");
        }
        let index = (id - min) / step + 1;
        if count == 0 || count > MAX_SHARDS || index > count {
            bail!(
                "--shard auto: task {id} is number {index} of an array of {count} tasks (from {min} by {step}; at most {MAX_SHARDS}); give --shard K/N"
            );
        }
        Ok(Shard { index, count })
    }
}

/// A scene's expected precompute cost, in arbitrary units proportional to time: what matters
/// is how scenes compare. From the part's extent (STEP: the bounding box of its vertices, in its
/// own unit) and the scene's settings: the unknowns of the first mesh (size, order), grown to
/// what `target_error` would need (the eigenvalue error falls as h^(2p)), capped by `max_dofs`;
/// a sparse factorisation's time grows about as unknowns^1.5; more modes, the error estimate,
/// static correction and loads add their share; reading and meshing add a share that grows with
/// the geometry file. A part whose extent cannot be read (IGES, BREP, a `.geo` script) counts as
/// a mid-sized part.
pub fn expected_cost(scene: &Scene) -> f64 {
    let p = f64::from(scene.mesh.order.clamp(1, 2));
    // Nodes per h³ of a tet mesh of edge h: about 1.5 vertices, 12 with the edges' midpoints.
    let nodes_per_h3 = if p == 1.0 { 1.5 } else { 12.0 };
    let dofs = match extent_m(scene) {
        Some(d) => {
            let largest = d.iter().copied().fold(0.0, f64::max);
            let h = if scene.mesh.size > 0.0 {
                scene.mesh.size
            } else {
                largest / 15.0
            };
            // At least one element across a thin wall; about a third of the box is material.
            let volume: f64 = d.iter().map(|&x| x.max(h)).product::<f64>() / 3.0;
            3.0 * nodes_per_h3 * volume / h.powi(3)
        }
        None => 3.0e4,
    };
    // The error at the first mesh, from the corpus's runs: a few percent (4-node), under one
    // percent (10-node).
    let first_error = if p == 1.0 { 0.05 } else { 0.008 };
    let grow = scene
        .mesh
        .target_error
        .map_or(1.0, |t| (first_error / t.max(1e-6)).powf(3.0 / (2.0 * p)).max(1.0));
    let dofs = (dofs * grow).clamp(1e3, scene.mesh.max_dofs.max(1000) as f64);
    let mut factor = 1.0 + scene.modes.count as f64 / 30.0;
    if scene.mesh.error_estimate.on() {
        factor += 0.3;
    }
    if scene.static_correction.is_some() {
        factor += 0.5;
    }
    factor += 0.1 * scene.loads.len() as f64 + 0.5 * scene.voi.len() as f64;
    // Reading and meshing grow with the part's detail more than with its mesh: a constant and
    // a term per megabyte of geometry. Both weights fitted by least squares to 25 scenes of the
    // corpus (bench/batch_shards.py: about 2.4 s + 2.7 s per MB against 3.4e-7 s per unit of
    // the solve term).
    let megabytes = std::fs::metadata(&scene.geometry).map_or(0.3, |m| m.len() as f64 / 1e6);
    dofs.powf(1.5) * factor + 7.0e6 + 8.0e6 * megabytes
}

/// The extents of a STEP part (x, y, z), m: the bounding box of its B-rep's vertices
/// (`VERTEX_POINT`s; all `CARTESIAN_POINT`s when it has none). Placements, annotations and
/// spline control points lie off the part (a PMI block's points spanned 49×82×192 mm, its
/// vertices 19.5×10×6 mm); a vertex box misses at most the bulge of curved edges. `None` for
/// other geometries or a file that does not read.
fn extent_m(scene: &Scene) -> Option<[f64; 3]> {
    let ext = scene.geometry.extension()?.to_string_lossy().to_ascii_lowercase();
    if ext != "step" && ext != "stp" {
        return None;
    }
    let bytes = crate::input::read(&scene.geometry).ok()?;
    let text = String::from_utf8_lossy(&bytes);
    let metres = crate::step_units::length_unit(&text).map_or(scene.unit.to_metres(), |u| u.metres);
    let mut points: std::collections::HashMap<u64, [f64; 3]> = std::collections::HashMap::new();
    let mut vertices: Vec<u64> = Vec::new();
    for (id, body) in crate::step_units::statements(&text) {
        let body = body.trim_start();
        if body.starts_with("CARTESIAN_POINT") {
            // `('name',(x,y,z))`: the last parenthesis opened.
            let inner = body
                .rfind('(')
                .map_or("", |i| body[i + 1..].split(')').next().unwrap_or(""));
            let xyz: Vec<f64> = inner.split(',').filter_map(|v| v.trim().parse().ok()).collect();
            if let &[x, y, z] = xyz.as_slice() {
                points.insert(id, [x, y, z]);
            }
        } else if body.starts_with("VERTEX_POINT")
            && let Some(r) = body.rsplit('#').next()
        {
            let digits: String = r.chars().take_while(char::is_ascii_digit).collect();
            if let Ok(r) = digits.parse() {
                vertices.push(r);
            }
        }
    }
    let chosen: Vec<[f64; 3]> = if vertices.is_empty() {
        points.into_values().collect()
    } else {
        vertices.iter().filter_map(|v| points.get(v).copied()).collect()
    };
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in chosen.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    let d = [0, 1, 2].map(|i| (hi[i] - lo[i]) * metres);
    d.iter()
        .all(|x| x.is_finite() && *x >= 0.0)
        .then_some(d)
        .filter(|d| d.iter().any(|&x| x > 0.0))
}

/// Splits items of the given costs into `count` shards: the longest first, each to the shard
/// with the least cost so far (ties to the lowest shard). Returns each item's shard (1-based).
/// The same costs in the same order give the same split on every node.
pub fn split(costs: &[f64], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..costs.len()).collect();
    // Stable: equal costs keep the (agreed) listing order.
    order.sort_by(|&a, &b| costs[b].total_cmp(&costs[a]));
    let mut load = vec![0.0f64; count.max(1)];
    let mut shard = vec![0; costs.len()];
    for i in order {
        let (least, _) = load.iter().enumerate().fold(
            (0, f64::INFINITY),
            |best, (k, &l)| if l < best.1 { (k, l) } else { best },
        );
        load[least] += costs[i];
        shard[i] = least + 1;
    }
    shard
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_from_the_command_line_and_a_slurm_array() {
        assert_eq!(Shard::parse("2/3").expect("2/3"), Shard { index: 2, count: 3 });
        for bad in ["0/3", "4/3", "3", "a/b", "1/0", "1/1000001", "-1/3"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
        };
        // --array=0-3: task 2 is the third of four.
        let s = Shard::from_env(&env(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
        ]));
        assert_eq!(s.expect("slurm"), Shard { index: 3, count: 4 });
        // --array=1-9:4 (tasks 1, 5, 9): task 9 is the third of three.
        let s = Shard::from_env(&env(&[
            ("SLURM_ARRAY_TASK_ID", "9"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_STEP", "4"),
        ]));
        assert_eq!(s.expect("slurm"), Shard { index: 3, count: 3 });
        let e = Shard::from_env(&env(&[])).expect_err("no array");
        assert!(e.to_string().contains("--shard K/N"), "{e}");
        let e = Shard::from_env(&env(&[("SLURM_ARRAY_TASK_ID", "2")])).expect_err("no count");
        assert!(e.to_string().contains("SLURM_ARRAY_TASK_COUNT is not set"), "{e}");
        // Below the array's first task, a step of 0, more tasks than shards allowed: refused.
        for bad in [
            [
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
                ("SLURM_ARRAY_TASK_MIN", "5"),
                ("SLURM_ARRAY_TASK_STEP", "1"),
            ],
            [
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_STEP", "0"),
            ],
            [
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "200000"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_STEP", "1"),
            ],
        ] {
            let pairs: &'static [(&str, &str)] = Box::leak(Box::new(bad));
            let e = Shard::from_env(&env(pairs)).expect_err("refused");
            assert!(e.to_string().contains("give --shard K/N"), "{e}");
        }
    }

    /// The vertex box of real parts against their extents from gmsh (the corpus's SOURCES.md):
    /// the PMI block's annotation points are left out, the inch bracket is in metres.
    #[test]
    fn extents_of_real_step_parts() {
        let corpus = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus");
        let scene = |file: &str| {
            let text = format!(
                "name = \"p\"\n[geometry]\nstep = \"{}\"\nunit = \"mm\"\n[material]\nyoung = 2.1e11\npoisson = 0.3\ndensity = 7850.0\n[mesh]\nsize = 0.01\norder = 1\n[modes]\ncount = 4\n",
                corpus.join(file).display()
            );
            Scene::parse(&corpus.join("scene.toml"), &text).expect("scene")
        };
        for (file, want_mm) in [
            ("pmi_block_2holes.step", [20.0, 10.0, 6.0]),
            ("bracket_ribbed_ap209.step", [63.9, 127.0, 146.5]),
            ("crankshaft.step", [19.0, 63.0, 18.3]),
        ] {
            let got = extent_m(&scene(file)).expect("extent");
            for i in 0..3 {
                let ratio = got[i] * 1000.0 / want_mm[i];
                // Circles with one vertex: the box may miss up to their bulge.
                assert!(
                    (0.6..=1.05).contains(&ratio),
                    "{file}: {got:?} m against {want_mm:?} mm"
                );
            }
        }
    }

    #[test]
    fn the_split_balances_cost_not_count() {
        // One large scene and six small ones over two shards: 10 | 6×1 + ... not 4 and 3.
        let costs = [1.0, 10.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        let s = split(&costs, 2);
        let load = |k: usize| -> f64 { costs.iter().zip(&s).filter(|(_, sh)| **sh == k).map(|(c, _)| c).sum() };
        assert_eq!(s[1], 1, "the large scene first, to shard 1");
        assert_eq!((load(1), load(2)), (10.0, 6.0));
        // Every item in exactly one shard; more shards than items leaves some empty.
        let s = split(&[3.0, 2.0], 5);
        assert_eq!(s, [1, 2]);
        assert!(split(&[], 3).is_empty());
    }
}
