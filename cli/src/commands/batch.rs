//! `ves batch`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::batch::{self, BatchOptions, Status};
use ves_pipeline::modes::SolverChoice;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene files or directories (searched recursively for *.toml). Each scene is done once,
    /// however many names reach it. Links named here are followed; inside a directory, links to
    /// scene files are followed but links to directories are not entered (a link loop cannot
    /// make the search endless): name such a directory here to include it.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Scenes precomputed at once.
    #[arg(short = 'j', long, default_value_t = 1)]
    jobs: usize,
    /// Output directory (default: beside each scene, <name>.h5).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Eigen-solver.
    #[arg(long, default_value = "auto", value_parser = super::solver_parser())]
    solver: SolverChoice,
    /// Accept .geo geometries (gmsh scripts, which can run shell commands): only for scenes you trust.
    #[arg(long)]
    allow_geo_scripts: bool,
    /// Take shard K of N (`2/8`) of the scenes, split by expected cost the same way on every
    /// node; `auto` reads a Slurm job array's task (SLURM_ARRAY_TASK_ID, _COUNT, _MIN, _STEP).
    #[arg(long, value_name = "K/N|auto", allow_hyphen_values = true)]
    shard: Option<String>,
    /// Seconds a claim of this process outlives its silence: another host takes a scene over
    /// when its owner has not renewed the claim for this long (renewed every quarter of it).
    #[arg(long, default_value_t = ves_pipeline::batch::claim::DEFAULT_LEASE_S, value_name = "S", allow_hyphen_values = true, value_parser = lease_seconds)]
    lease: f64,
    /// Do not wait at the end for scenes other processes had claimed (they are reported as
    /// claimed-elsewhere).
    #[arg(long)]
    no_wait: bool,
    /// With --shard: keep to this shard's share (by default a shard done with its share takes
    /// the scenes of other shards that nobody has claimed yet, from the end of their lists).
    #[arg(long)]
    no_steal: bool,
    /// Report what is done, being computed and left, across all shards and processes that
    /// share the outputs; computes nothing.
    #[arg(long)]
    status: bool,
    /// Print the outcomes as JSON (last line of stdout).
    #[arg(long)]
    json: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        anyhow::ensure!(
            (1..=64).contains(&self.jobs),
            "-j {}: give 1 to 64 parallel scenes",
            self.jobs
        );
        anyhow::ensure!(
            !self.solver.is_slepc(),
            "--solver slepc: not available in ves batch (MPI runs one scene at a time); use `mpirun ves precompute` per scene"
        );
        let shard = self.shard.as_deref().map(batch::Shard::parse).transpose()?;
        let scenes = batch::collect(&self.inputs)?;
        let opts = BatchOptions {
            jobs: self.jobs,
            out: self.out,
            solver: self.solver,
            allow_geo_scripts: self.allow_geo_scripts,
            shard,
            lease_s: self.lease,
            wait: !self.no_wait,
            steal: !self.no_steal,
        };
        if self.status {
            return report_status(&batch::status(&scenes, &opts), self.json);
        }
        let outcomes = batch::run(&scenes, &opts)?;
        let count = |s: Status| outcomes.iter().filter(|o| o.status == s).count();
        let (done, fresh, failed) = (count(Status::Done), count(Status::UpToDate), count(Status::Failed));
        let elsewhere = count(Status::ClaimedElsewhere);
        if self.json {
            super::print_json(&outcomes)?;
        } else {
            let mut text = String::new();
            for o in &outcomes {
                let what = match o.status {
                    Status::Done => format!("done in {:.1} s", o.seconds),
                    Status::UpToDate => "up to date".into(),
                    Status::Failed => format!("FAILED: {}", o.error.as_deref().unwrap_or("")),
                    Status::ClaimedElsewhere => {
                        format!("claimed by {}", o.claimed_by.as_deref().unwrap_or("another process"))
                    }
                };
                let from = match (o.shard, shard) {
                    (Some(k), Some(s)) if k != s.index => format!(" (taken from shard {k})"),
                    _ => String::new(),
                };
                text.push_str(&format!("{}{from}: {what}\n", o.scene));
            }
            let shard = shard.map(|s| format!("shard {s}: ")).unwrap_or_default();
            let elsewhere = if elsewhere > 0 {
                format!(", {elsewhere} claimed elsewhere (not waited for)")
            } else {
                String::new()
            };
            text.push_str(&format!(
                "{shard}{done} done, {fresh} up to date, {failed} failed{elsewhere}\n"
            ));
            super::print_text(&text)?;
        }
        if failed > 0 {
            let names: Vec<&str> = outcomes
                .iter()
                .filter(|o| o.status == Status::Failed)
                .map(|o| o.scene.as_str())
                .collect();
            anyhow::bail!("{failed} of {} scenes failed: {}", outcomes.len(), names.join(", "));
        }
        Ok(())
    }
}

/// `ves batch --status`: one line per scene and a count of each state.
fn report_status(states: &[batch::SceneState], json: bool) -> Result<()> {
    let count = |s: &str| states.iter().filter(|x| x.state == s).count();
    if json {
        return super::print_json(&serde_json::json!({
            "scenes": states,
            "up_to_date": count("up-to-date"),
            "claimed": count("claimed"),
            "left": count("left"),
            "failed": count("failed"),
            "unreadable": count("unreadable"),
        }));
    }
    let sharded = states.iter().any(|s| s.shard > 1);
    let mut text = String::new();
    for s in states {
        let shard = if sharded {
            format!(" [shard {}]", s.shard)
        } else {
            String::new()
        };
        let who = match (&s.claimed_by, s.owner_alive) {
            (Some(o), Some(true)) => format!(" (claimed by {o})"),
            (Some(o), _) => format!(" (a stale claim of {o}, gone: the next batch takes it over)"),
            _ => String::new(),
        };
        let why = s.error.as_deref().map(|e| format!(": {e}")).unwrap_or_default();
        text.push_str(&format!("{}{shard}: {}{who}{why}\n", s.scene, s.state));
    }
    text.push_str(&format!(
        "{} up to date, {} being computed, {} failed, {} left, {} unreadable\n",
        count("up-to-date"),
        count("claimed"),
        count("failed"),
        count("left"),
        count("unreadable")
    ));
    super::print_text(&text)
}

/// `--lease`: seconds within [`batch::claim::LEASE_RANGE_S`].
fn lease_seconds(text: &str) -> Result<f64, String> {
    let (lo, hi) = batch::claim::LEASE_RANGE_S;
    match text.trim().parse::<f64>() {
        Ok(s) if (lo..=hi).contains(&s) => Ok(s),
        _ => Err(format!(
            "{:?}: give {lo} to {hi} seconds (a claim is renewed every quarter of it)",
            text.chars().take(40).collect::<String>()
        )),
    }
}
