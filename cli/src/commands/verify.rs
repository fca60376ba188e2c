//! `ves verify`.

use anyhow::Result;
use std::path::PathBuf;
use ves_pipeline::verify::{self, Against, ToleranceOverrides, VerifyReport};

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (TOML, version 1) or basis file (HDF5).
    input: PathBuf,
    /// Reference solver.
    #[arg(long, default_value = "all", value_parser = against())]
    against: Against,
    /// Modes compared (default: the scene's count).
    #[arg(long)]
    modes: Option<usize>,
    /// Largest relative frequency difference (default: 1e-6 for scikit-fem; CalculiX 1e-3
    /// with 10-node tets, 0.1 with 4-node: its mass integration differs).
    #[arg(long)]
    tol_freq: Option<f64>,
    /// Smallest MAC of an isolated mode (default 0.999; CalculiX 4-node 0.99).
    #[arg(long)]
    min_mac: Option<f64>,
    /// Largest principal angle of a group of close frequencies, rad (default 1e-3; CalculiX 1e-2).
    #[arg(long)]
    max_angle: Option<f64>,
    /// Largest relative difference of the static displacement at the load node (default 1e-6).
    #[arg(long)]
    tol_static: Option<f64>,
    /// Also compare nodal stresses with CalculiX: our recovery from its mode shapes against
    /// its own nodal stress of the same shapes.
    #[arg(long)]
    stress: bool,
    /// Largest relative stress difference (L2 over corner vertices, CalculiX's averaging;
    /// default 1e-2). The gap with the volume-weighted averaging a basis stores is reported too.
    #[arg(long)]
    tol_stress: Option<f64>,
    /// Largest relative max-norm difference of a load case's static displacement with
    /// CalculiX (default 1e-6 on straight-sided elements, 1e-3 on curved 10-node tets).
    #[arg(long)]
    tol_load: Option<f64>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// No progress lines on stderr (they are shown only on a terminal anyway).
    #[arg(long, short)]
    quiet: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let tol = ToleranceOverrides {
            freq: self.tol_freq,
            mac: self.min_mac,
            angle: self.max_angle,
            static_rel: self.tol_static,
            stress: self.tol_stress,
            load: self.tol_load,
        };
        // Each step and reference solver is announced with its size and expected time, above a
        // spinner with the elapsed time (a reference can take many minutes on a fine mesh).
        let visible = !self.quiet;
        let report = {
            let _watching = ves_pipeline::progress::watch(crate::terminal::Terminal::on_stderr(visible));
            verify::verify_input(&self.input, self.against, self.modes, &tol, self.stress)?
        };
        if self.json {
            super::print_json(&report)?;
        } else {
            print_table(&report);
        }
        if !report.pass {
            return Err(super::VerifyFailed.into());
        }
        Ok(())
    }
}

/// `--against`: the registry's names with their descriptions (as `--help` lists them), or `all`.
fn against() -> impl clap::builder::TypedValueParser<Value = Against> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    let each = verify::REFERENCES
        .iter()
        .map(|r| PossibleValue::new(r.name()).help(r.about()));
    let all = PossibleValue::new(verify::reference::ALL).help("Every available reference");
    PossibleValuesParser::new(each.chain([all])).try_map(|name| name.parse::<Against>())
}

fn print_table(report: &VerifyReport) {
    println!(
        "{}: {} nodes, {} tets (order {}), {} unknowns",
        report.input, report.nodes, report.tets, report.element_order, report.dofs
    );
    for r in &report.references {
        println!(
            "\n{} ({:.1} s): {}",
            r.solver,
            r.seconds,
            if r.pass { "PASS" } else { "FAIL" }
        );
        let stress = r.max_stress_rel_diff.is_some();
        println!(
            "  mode   ref     ours (Hz)      reference (Hz)   rel. diff      MAC          group  angle (rad){}",
            if stress { "  stress diff (volume-weighted)" } else { "" }
        );
        for m in &r.modes {
            println!(
                "  {:>4} {:>5} {:>14.6} {:>18.6} {:>12.2e} {:>14.10} {:>6} {:.2e}{}",
                m.mode + 1,
                m.reference_mode + 1,
                m.ours_hz,
                m.reference_hz,
                m.rel_diff,
                m.mac,
                m.group,
                m.group_angle_rad,
                match (m.stress_rel_diff, m.stress_rel_diff_volume_weighted) {
                    (Some(a), Some(v)) => format!("    {a:.2e} ({v:.2e})"),
                    _ => String::new(),
                }
            );
        }
        let st = r
            .static_rel_diff
            .map_or("n/a (free body)".to_string(), |s| format!("{s:.2e}"));
        let groups = r
            .max_group_angle_rad
            .map_or("no groups of close frequencies".to_string(), |a| {
                format!("max group angle {a:.2e} rad")
            });
        let stress = r.max_stress_rel_diff.map_or(String::new(), |s| {
            format!(", stress {s:.2e} (tolerance {:.0e})", r.tolerances.stress)
        });
        println!(
            "  max rel. freq. diff {:.2e}, min MAC (isolated) {:.10}, {groups}, static {st}{stress}",
            r.max_rel_freq_diff, r.min_mac_isolated
        );
    }
    for s in &report.skipped {
        println!("\n{}: SKIPPED ({})", s.solver, s.reason);
    }
    if !report.loads.is_empty() {
        println!(
            "\nload cases against {} (same mesh, same nodal loads{}):",
            report.loads_solver.unwrap_or("the reference"),
            report.loads_seconds.map_or(String::new(), |t| format!(", {t:.1} s"))
        );
        println!("  load                 kind      max |u| (m)   rel. diff (max norm)  reaction diff  tolerance");
        for l in &report.loads {
            println!(
                "  {:<20} {:<9} {:>12.6e} {:>12.2e} {:>20.2e}   {:.0e} {}",
                ves_format::names::escape_for_terminal(&l.name),
                l.kind,
                l.max_displacement_m,
                l.displacement_rel_diff,
                l.reaction_rel_diff,
                l.tolerance,
                if l.pass { "PASS" } else { "FAIL" }
            );
        }
    }
}
