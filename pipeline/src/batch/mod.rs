//! `ves batch`: precompute many scenes unattended. Scenes whose output is up to date (same
//! content hash of tool version, scene, mode count and geometry) are skipped, a bad scene is
//! reported and the batch goes on, and because every output is written to a temporary name and
//! renamed, an interrupted batch resumes where it stopped (stale temporary files are removed).
//!
//! Many processes may share one batch: shards of a job array ([`shard`]) each take their share
//! of the same ordered list, and every process claims a scene in the output folder before
//! computing it ([`claim`]), so shards and whole batches started at once compute each scene once.

pub mod claim;
pub mod shard;
mod walk;

pub use shard::Shard;
pub use walk::collect;

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
    /// This process's share of the batch (all of it when `None`).
    pub shard: Option<Shard>,
    /// How long a claim of this process outlives its silence, s ([`claim`]).
    pub lease_s: f64,
    /// At the end, wait for this process's scenes that others had claimed: until they are done,
    /// or their owner is gone and this process computes them.
    pub wait: bool,
    /// A shard done with its share takes the other shards' unclaimed scenes.
    pub steal: bool,
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            jobs: 1,
            out: None,
            solver: SolverChoice::Auto,
            allow_geo_scripts: false,
            shard: None,
            lease_s: claim::DEFAULT_LEASE_S,
            wait: true,
            steal: true,
        }
    }
}

/// What happened to one scene.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Precomputed now.
    Done,
    /// Its output was up to date (possibly made meanwhile by another process).
    UpToDate,
    /// Another process, alive, holds its claim (see `claimed_by`); it was left to it.
    ClaimedElsewhere,
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
    /// Who held the claim, for a scene claimed elsewhere: "host pid N (shard K/N), for S s".
    pub claimed_by: Option<String>,
    /// The scene's shard, when sharding (another than this process's for a scene it took from
    /// a shard that had not reached it).
    pub shard: Option<usize>,
    /// Seconds spent.
    pub seconds: f64,
}

/// One scene of a batch before it is computed: the scene as loaded, its output, expected cost
/// and shard.
#[derive(Clone, Debug)]
pub struct Planned {
    /// Scene file.
    pub scene: PathBuf,
    /// The scene, or why it does not load (one line).
    pub loaded: std::result::Result<Scene, String>,
    /// Its output (None when the scene does not load).
    pub output: Option<PathBuf>,
    /// Expected cost ([`shard::expected_cost`]; 0 for a scene that does not load).
    pub cost: f64,
    /// Its shard (1-based; 1 without sharding).
    pub shard: usize,
}

/// Orders the scenes the same way on every node (by output name, then scene path) and assigns
/// each to a shard by expected cost. A scene that does not load goes to a shard too, which
/// reports it as failed.
pub fn plan(scenes: &[PathBuf], opts: &BatchOptions) -> Vec<Planned> {
    let mut items: Vec<Planned> = scenes
        .iter()
        .map(|path| {
            let loaded = load(path, opts).map_err(|e| e.to_string().replace('\n', " "));
            Planned {
                scene: path.clone(),
                output: loaded.as_ref().ok().map(|s| output_of(s, opts)),
                cost: loaded.as_ref().map_or(0.0, shard::expected_cost),
                loaded,
                shard: 1,
            }
        })
        .collect();
    let name = |p: &Planned| p.output.as_ref().and_then(|o| o.file_name()).map(|n| n.to_os_string());
    items.sort_by(|a, b| name(a).cmp(&name(b)).then_with(|| a.scene.cmp(&b.scene)));
    if let Some(s) = opts.shard {
        let costs: Vec<f64> = items.iter().map(|p| p.cost).collect();
        for (p, k) in items.iter_mut().zip(shard::split(&costs, s.count)) {
            p.shard = k;
        }
    }
    items
}

fn load(path: &Path, opts: &BatchOptions) -> Result<Scene, crate::scene::SceneError> {
    Scene::load_with(
        path,
        crate::scene::SceneOptions {
            allow_geo_scripts: opts.allow_geo_scripts,
        },
    )
}

/// Each output and the scene that writes it: of scenes naming one output, the first in the
/// agreed order (the others are refused).
fn writers(planned: &[Planned]) -> Vec<(PathBuf, String)> {
    let mut named: Vec<(PathBuf, String)> = Vec::new();
    for p in planned {
        if let Some(out) = &p.output {
            let key = std::path::absolute(out).unwrap_or(out.clone());
            if !named.iter().any(|(o, _)| *o == key) {
                named.push((key, p.scene.display().to_string()));
            }
        }
    }
    named
}

/// Why a scene is refused whose output `first` writes.
fn clash(out: &Path, first: &str) -> String {
    format!(
        "output {} is also written by {first}; give one of the scenes another `name`",
        out.display()
    )
}

/// Where a scene's basis goes.
fn output_of(scene: &Scene, opts: &BatchOptions) -> PathBuf {
    match &opts.out {
        Some(dir) => dir.join(format!("{}.h5", scene.name)),
        None => scene.path.with_file_name(format!("{}.h5", scene.name)),
    }
}

/// One scene to do: its file, its shard (when sharding) and whether it is another shard's.
struct Item {
    path: PathBuf,
    shard: Option<usize>,
    taken: bool,
}

/// Precomputes every scene of this process's share; never stops at a failed one. Without a
/// shard the scenes are done in the order given. A shard does its share costliest first, then
/// (unless `steal` is off) takes the other shards' scenes nobody has claimed yet, the last
/// each would reach first, then waits for its own scenes that others had claimed.
pub fn run(scenes: &[PathBuf], opts: &BatchOptions) -> Result<Vec<Outcome>> {
    if let Some(dir) = &opts.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create the output directory: {e}", dir.display()))?;
    }
    // Outputs named so far: two scenes may not write one file. A shard knows the whole batch:
    // of scenes naming one output, the first in the agreed order writes it, on every shard alike.
    let mut named: Vec<(PathBuf, String)> = Vec::new();
    let items: Vec<Item> = match opts.shard {
        None => scenes
            .iter()
            .map(|p| Item {
                path: p.clone(),
                shard: None,
                taken: false,
            })
            .collect(),
        Some(s) => {
            let planned = plan(scenes, opts);
            named = writers(&planned);
            // Each shard's list as it does it: costliest first.
            let mut lists: Vec<Vec<Planned>> = vec![Vec::new(); s.count];
            for p in planned {
                lists[p.shard - 1].push(p);
            }
            for l in &mut lists {
                l.sort_by(|a, b| b.cost.total_cmp(&a.cost));
            }
            let item = |p: &Planned, taken: bool| Item {
                path: p.scene.clone(),
                shard: Some(p.shard),
                taken,
            };
            let mut items: Vec<Item> = lists[s.index - 1].iter().map(|p| item(p, false)).collect();
            if opts.steal {
                // The others' last scenes first, round by round.
                let longest = lists.iter().map(Vec::len).max().unwrap_or(0);
                for back in 1..=longest {
                    for (k, l) in lists.iter().enumerate() {
                        // A scene that does not load is its own shard's to report.
                        if k + 1 != s.index && back <= l.len() && l[l.len() - back].output.is_some() {
                            items.push(item(&l[l.len() - back], true));
                        }
                    }
                }
            }
            items
        }
    };
    let own = items.iter().filter(|i| !i.taken).count();
    let named = Mutex::new(named);
    let outer = crate::progress::innermost();
    let note = |line: String| {
        if let Some(w) = &outer {
            w.note(&line);
        }
    };
    if let Some(s) = opts.shard {
        note(format!(
            "shard {s}: {own} of {} scenes, the costliest first",
            scenes.len()
        ));
    }
    let bar = crate::progress::count(own as u64, "scenes");
    // The scenes' own stages and counts are not drawn: the batch's count is.
    let _quiet = outer
        .clone()
        .map(|w| crate::progress::watch(std::sync::Arc::new(crate::progress::Quiet(w))));
    // One pass over some items, `jobs` at a time.
    let pass = |todo: &[usize], first: bool| -> Vec<(usize, Outcome)> {
        let next = AtomicUsize::new(0);
        let done: Mutex<Vec<(usize, Outcome)>> = Mutex::new(Vec::new());
        std::thread::scope(|s| {
            for _ in 0..opts.jobs.clamp(1, 64) {
                s.spawn(|| {
                    while let Some(&i) = todo.get(next.fetch_add(1, Ordering::Relaxed)) {
                        let item = &items[i];
                        bar.message(&item.path.display().to_string());
                        let mut o = one(&item.path, opts, &named, item.taken);
                        o.shard = item.shard;
                        let from = match (item.taken, item.shard) {
                            (true, Some(k)) => format!(" (taken from shard {k})"),
                            _ => String::new(),
                        };
                        // Told as it happens (the terminal prints it above the batch's bar).
                        match &o.status {
                            Status::Failed if !item.taken => {
                                note(format!("failed: {}: {}", o.scene, o.error.as_deref().unwrap_or("")))
                            }
                            Status::Done => note(format!(
                                "done: {}{from} → {}",
                                o.scene,
                                o.output.as_deref().unwrap_or("")
                            )),
                            Status::ClaimedElsewhere if first && !item.taken => note(format!(
                                "claimed elsewhere: {} (by {}), left to it",
                                o.scene,
                                o.claimed_by.as_deref().unwrap_or("another process")
                            )),
                            Status::UpToDate | Status::ClaimedElsewhere | Status::Failed => {}
                        }
                        if o.status != Status::ClaimedElsewhere && !item.taken {
                            bar.inc(1);
                        }
                        done.lock().unwrap_or_else(|p| p.into_inner()).push((i, o));
                    }
                });
            }
        });
        done.into_inner().unwrap_or_else(|p| p.into_inner())
    };
    let mut results: Vec<Option<Outcome>> = vec![None; items.len()];
    for (i, o) in pass(&(0..own).collect::<Vec<_>>(), true) {
        results[i] = Some(o);
    }
    // Another shard's scene is reported only when this process computed it: a failure is its
    // own shard's to report (recorded beside the output, where that shard tries it once more).
    for (i, o) in pass(&(own..items.len()).collect::<Vec<_>>(), false) {
        if o.status == Status::Done {
            results[i] = Some(o);
        }
    }
    let claimed = |r: &[Option<Outcome>]| -> Vec<usize> {
        (0..own)
            .filter(|&i| r[i].as_ref().is_some_and(|o| o.status == Status::ClaimedElsewhere))
            .collect()
    };
    let poll = std::time::Duration::from_secs_f64((opts.lease_s / 4.0).clamp(0.25, 5.0));
    let mut waiting = None;
    let mut todo = claimed(&results);
    while opts.wait && !todo.is_empty() {
        if waiting != Some(todo.len()) {
            waiting = Some(todo.len());
            note(format!(
                "waiting for {} scene(s) claimed by other processes (until done, or their owner is gone)",
                todo.len()
            ));
        }
        std::thread::sleep(poll);
        for (i, o) in pass(&todo, false) {
            results[i] = Some(o);
        }
        todo = claimed(&results);
    }
    Ok(results.into_iter().flatten().collect())
}

/// The record a failed scene leaves beside its output (`<output>.failed`): which source failed
/// and why, so that other shards do not take the same failure up again and `--status` can say
/// it. Its own shard (or a whole batch) still tries the scene again; a success removes it.
#[derive(Serialize, serde::Deserialize)]
struct Failure {
    source_hash: String,
    error: String,
    host: String,
    pid: u32,
    at_unix: f64,
}

fn failure_path(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_os_string();
    name.push(".failed");
    PathBuf::from(name)
}

/// The failure recorded for `out`, if it is of the source `hash`.
fn failure_of(out: &Path, hash: &str) -> Option<String> {
    let bytes = crate::input::read_scene(&failure_path(out)).ok()?;
    let f: Failure = serde_json::from_str(&bytes).ok()?;
    (f.source_hash == hash)
        .then(|| ves_format::names::escape_for_terminal(&f.error.chars().take(400).collect::<String>()))
}

fn one(path: &Path, opts: &BatchOptions, named: &Mutex<Vec<(PathBuf, String)>>, taken: bool) -> Outcome {
    let start = Instant::now();
    let mut outcome = Outcome {
        scene: path.display().to_string(),
        output: None,
        status: Status::Failed,
        error: None,
        claimed_by: None,
        shard: None,
        seconds: 0.0,
    };
    let result = (|| -> Result<Status> {
        let scene = load(path, opts)?;
        let out = output_of(&scene, opts);
        outcome.output = Some(out.display().to_string());
        {
            let mut n = named.lock().unwrap_or_else(|p| p.into_inner());
            let key = std::path::absolute(&out).unwrap_or(out.clone());
            match n.iter().find(|(o, _)| *o == key) {
                Some((_, other)) if *other != outcome.scene => bail!("{}", clash(&out, other)),
                Some(_) => {}
                None => n.push((key, outcome.scene.clone())),
            }
        }
        let hash = store::source_hash(&scene)?;
        let up_to_date = || out.is_file() && store::stored_source_hash(&out).as_deref() == Some(hash.as_str());
        if up_to_date() {
            // The basis is whole: a sidecar that cannot be rewritten (a read-only folder) is a
            // warning, not a failed scene.
            match store::repair_sidecar(&out) {
                Ok(true) => {
                    tracing::warn!(output = %out.display(), "the XDMF sidecar did not match its basis; rewritten")
                }
                Ok(false) => {}
                Err(e) => {
                    tracing::warn!(output = %out.display(), "the XDMF sidecar does not match its basis and cannot be rewritten: {e:#}")
                }
            }
            return Ok(Status::UpToDate);
        }
        // Another shard's scene that failed already is left to its own shard.
        if taken && let Some(e) = failure_of(&out, &hash) {
            bail!("failed before: {e}");
        }
        let shard = opts.shard.map(|s| s.to_string());
        let claim = match claim::acquire(&out, opts.lease_s, shard)? {
            claim::Acquired::Held(owner) => {
                outcome.claimed_by = Some(owner.describe());
                return Ok(Status::ClaimedElsewhere);
            }
            claim::Acquired::Mine(c) => c,
        };
        // Another process may have finished it between the check and the claim.
        if up_to_date() {
            return Ok(Status::UpToDate);
        }
        // Temporaries of an earlier owner that was killed (the claim says none is at work).
        if let Some(gone) = claim.took_over() {
            crate::output::remove_temps_of(&out, &gone.host_id, gone.pid);
        }
        crate::output::remove_stale_temps(&out);
        // A refused output path is said with the batch's own option (not `-o` and `--force`).
        if let Err(e) = precompute::run_for(&scene, &out, opts.solver, "--out") {
            let record = Failure {
                source_hash: hash.clone(),
                error: format!("{e:#}").replace('\n', " "),
                host: crate::host::this().name.clone(),
                pid: std::process::id(),
                at_unix: crate::host::unix_now(),
            };
            let text = serde_json::to_vec(&record)?;
            if let Err(w) = crate::output::write_atomically(&failure_path(&out), |p| Ok(std::fs::write(p, &text)?)) {
                tracing::warn!("cannot record the failure beside the output: {w}");
            }
            return Err(e);
        }
        let _ = std::fs::remove_file(failure_path(&out));
        if claim.lost() {
            tracing::warn!(output = %out.display(), "this process lost its claim while computing (it was silent past its lease): another process may have computed the scene too");
        }
        Ok(Status::Done)
    })();
    match result {
        Ok(s) => outcome.status = s,
        Err(e) => outcome.error = Some(format!("{e:#}").replace('\n', " ")),
    }
    outcome.seconds = start.elapsed().as_secs_f64();
    outcome
}

/// One scene's state in the output folder, for `ves batch --status`.
#[derive(Clone, Debug, Serialize)]
pub struct SceneState {
    /// Scene file.
    pub scene: String,
    /// Its output, when the scene loads.
    pub output: Option<String>,
    /// Its shard (1 without sharding).
    pub shard: usize,
    /// Its expected cost, the split's weight ([`shard::expected_cost`], arbitrary units).
    pub expected_cost: f64,
    /// "up-to-date", "claimed" (an owner at work), "failed" (its last attempt failed: `error`;
    /// the next batch tries it again), "left" (no up-to-date output, no live claim: a stale
    /// claim is counted here) or "unreadable" (the scene does not load, or names the output of
    /// another scene).
    pub state: &'static str,
    /// The claim's owner, when there is a claim.
    pub claimed_by: Option<String>,
    /// Whether that owner is at work (false: gone; the next batch takes the scene over).
    pub owner_alive: Option<bool>,
    /// Why an unreadable scene does not load, or why its last attempt failed.
    pub error: Option<String>,
}

/// What is done and what is left across all shards and processes: read from the output folder
/// (outputs and claims), nothing computed or changed.
pub fn status(scenes: &[PathBuf], opts: &BatchOptions) -> Vec<SceneState> {
    let planned = plan(scenes, opts);
    let writers = writers(&planned);
    planned
        .into_iter()
        .map(|p| {
            let mut s = SceneState {
                scene: p.scene.display().to_string(),
                output: p.output.as_ref().map(|o| o.display().to_string()),
                shard: p.shard,
                expected_cost: p.cost,
                state: "left",
                claimed_by: None,
                owner_alive: None,
                error: None,
            };
            let (scene, out) = match (p.loaded, p.output) {
                (Ok(scene), Some(out)) => (scene, out),
                (Err(e), _) => {
                    s.state = "unreadable";
                    s.error = Some(e);
                    return s;
                }
                (Ok(_), None) => return s,
            };
            let key = std::path::absolute(&out).unwrap_or(out.clone());
            if let Some((_, first)) = writers.iter().find(|(o, w)| *o == key && *w != s.scene) {
                s.state = "unreadable";
                s.error = Some(clash(&out, first));
                return s;
            }
            let hash = store::source_hash(&scene).ok();
            let fresh = hash
                .as_deref()
                .is_some_and(|h| out.is_file() && store::stored_source_hash(&out).as_deref() == Some(h));
            if let Some(what) = claim::not_a_claim(&claim::path_of(&out)) {
                s.claimed_by = Some(format!(
                    "{} is {what}, not a claim: remove it",
                    claim::path_of(&out).display()
                ));
                s.owner_alive = Some(false);
            } else if let Some(owner) = claim::holder(&out) {
                s.owner_alive = Some(owner.alive());
                s.claimed_by = Some(owner.describe());
            }
            let failed = hash.as_deref().and_then(|h| failure_of(&out, h));
            s.state = if fresh {
                "up-to-date"
            } else if s.owner_alive == Some(true) {
                "claimed"
            } else if let Some(e) = failed {
                s.error = Some(e);
                "failed"
            } else {
                "left"
            };
            s
        })
        .collect()
}
