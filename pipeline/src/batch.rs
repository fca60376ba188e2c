//! `ves batch`: precompute many scenes unattended. Scenes whose output is up to date (same
//! content hash of tool version, scene, mode count and geometry) are skipped, a bad scene is
//! reported and the batch goes on, and because every output is written to a temporary name and
//! renamed, an interrupted batch resumes where it stopped (stale temporary files are removed).

use crate::modes::SolverChoice;
use crate::precompute;
use crate::scene::Scene;
use crate::store;
use anyhow::{Result, bail};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Batch settings.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// Scenes precomputed at once.
    pub jobs: usize,
    /// Output directory (default: beside each scene).
    pub out: Option<PathBuf>,
    /// Eigen-solver.
    pub solver: SolverChoice,
    /// Accept .geo geometries (gmsh scripts).
    pub allow_geo_scripts: bool,
}

/// What happened to one scene.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Precomputed now.
    Done,
    /// Its output was up to date.
    UpToDate,
    /// It failed; see the error.
    Failed,
}

/// One scene's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// Scene file.
    pub scene: String,
    /// Output file (when one could be named).
    pub output: Option<String>,
    /// What happened.
    pub status: Status,
    /// The one-line error of a failed scene.
    pub error: Option<String>,
    /// Seconds spent.
    pub seconds: f64,
}

/// Scene files named by `inputs`: files as given, directories searched recursively for
/// `*.toml`, sorted. A path that does not exist is an error.
pub fn collect(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in inputs {
        if p.is_dir() {
            let mut found = Vec::new();
            walk(p, &mut found)?;
            found.sort();
            out.extend(found);
        } else if p.is_file() {
            out.push(p.clone());
        } else {
            bail!("{}: no such scene file or directory", p.display());
        }
    }
    out.dedup();
    if out.is_empty() {
        bail!("no scene files (*.toml) found in {inputs:?}");
    }
    Ok(out)
}

fn walk(dir: &Path, found: &mut Vec<PathBuf>) -> Result<()> {
    for e in std::fs::read_dir(dir)? {
        let path = e?.path();
        if path.is_dir() {
            walk(&path, found)?;
        } else if path.extension().is_some_and(|x| x == "toml") {
            found.push(path);
        }
    }
    Ok(())
}

/// Precomputes every scene; never stops at a failed one.
pub fn run(scenes: &[PathBuf], opts: &BatchOptions) -> Result<Vec<Outcome>> {
    if let Some(dir) = &opts.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create the output directory: {e}", dir.display()))?;
    }
    let bar = crate::progress::outer_bar(scenes.len() as u64, "scenes");
    crate::progress::hide_inner(true);
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Outcome>>> = Mutex::new(vec![None; scenes.len()]);
    // Outputs claimed so far: two scenes may not write one file.
    let claimed: Mutex<Vec<(PathBuf, String)>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.clamp(1, 64) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(path) = scenes.get(i) else { break };
                    bar.set_message(path.display().to_string());
                    let o = one(path, opts, &claimed);
                    // On stderr as it happens (the bar, if shown, is redrawn below it).
                    match &o.status {
                        Status::Failed => {
                            bar.suspend(|| eprintln!("failed: {}: {}", o.scene, o.error.as_deref().unwrap_or("")))
                        }
                        Status::Done => {
                            bar.suspend(|| eprintln!("done: {} → {}", o.scene, o.output.as_deref().unwrap_or("")))
                        }
                        Status::UpToDate => {}
                    }
                    results.lock().unwrap_or_else(|p| p.into_inner())[i] = Some(o);
                    bar.inc(1);
                }
            });
        }
    });
    crate::progress::hide_inner(false);
    bar.finish_and_clear();
    Ok(results
        .into_inner()
        .unwrap_or_else(|p| p.into_inner())
        .into_iter()
        .flatten()
        .collect())
}

fn one(path: &Path, opts: &BatchOptions, claimed: &Mutex<Vec<(PathBuf, String)>>) -> Outcome {
    let start = Instant::now();
    let mut outcome = Outcome {
        scene: path.display().to_string(),
        output: None,
        status: Status::Failed,
        error: None,
        seconds: 0.0,
    };
    let result = (|| -> Result<Status> {
        let scene = Scene::load_with(
            path,
            crate::scene::SceneOptions {
                allow_geo_scripts: opts.allow_geo_scripts,
            },
        )?;
        let out = match &opts.out {
            Some(dir) => dir.join(format!("{}.h5", scene.name)),
            None => scene.path.with_file_name(format!("{}.h5", scene.name)),
        };
        outcome.output = Some(out.display().to_string());
        {
            let mut c = claimed.lock().unwrap_or_else(|p| p.into_inner());
            let key = std::path::absolute(&out).unwrap_or(out.clone());
            if let Some((_, other)) = c.iter().find(|(o, _)| *o == key) {
                bail!(
                    "output {} is also written by {other}; give one of the scenes another `name`",
                    out.display()
                );
            }
            c.push((key, outcome.scene.clone()));
        }
        crate::output::remove_stale_temps(&out);
        let hash = store::source_hash(&scene)?;
        if out.is_file() && store::stored_source_hash(&out).as_deref() == Some(hash.as_str()) {
            if store::repair_sidecar(&out)? {
                tracing::warn!(output = %out.display(), "the XDMF sidecar did not match its basis; rewritten");
            }
            return Ok(Status::UpToDate);
        }
        precompute::run(&scene, &out, opts.solver)?;
        Ok(Status::Done)
    })();
    match result {
        Ok(s) => outcome.status = s,
        Err(e) => outcome.error = Some(format!("{e:#}").replace('\n', " ")),
    }
    outcome.seconds = start.elapsed().as_secs_f64();
    outcome
}
