//! `ves bench`.

use anyhow::{Context, Result};
use std::sync::Arc;
use ves_runtime::{LoadOptions, basis, bench};

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    file: super::BasisFile,
}

impl Args {
    pub fn run(self) -> Result<()> {
        // Loading all modes once checks the file and says how many there are.
        let all = basis::load(&self.file.basis, &LoadOptions::default())?;
        let available = all.mode_count();
        // r = 30 and 100 where the file has them (20 and 30 for a nonlinear model, whose step
        // costs O(r⁴)); otherwise every mode it has.
        let nonlinear = all.nonlinear.is_some();
        let sizes = if nonlinear { [20usize, 30] } else { [30, 100] };
        let mut counts: Vec<usize> = sizes.into_iter().filter(|&r| r <= available).collect();
        if counts.is_empty() {
            counts.push(available);
        }
        let mut report = serde_json::Map::new();
        report.insert("nonlinear".into(), nonlinear.into());
        // Steps per timed batch: a nonlinear step is ~100× a linear one.
        let per_batch = if nonlinear { 200 } else { 2000 };
        for r in counts {
            let opts = LoadOptions {
                modes: Some(r),
                surface_only: true,
                ..Default::default()
            };
            let b = basis::load(&self.file.basis, &opts).with_context(|| format!("haptic benchmark with {r} modes"))?;
            let b = Arc::new(b);
            let ns = bench::haptic_step_ns(b.clone(), 201, per_batch);
            report.insert(format!("haptic_step_ns_median_r{r}"), ns.into());
            let (median, p99) = bench::contact_rows_ns(&b);
            report.insert(format!("contact_rows_ns_median_r{r}"), median.into());
            report.insert(format!("contact_rows_ns_p99_r{r}"), p99.into());
            if let Some((force, tangent)) = bench::nonlinear_kernels_ns(&b, 51, 100) {
                report.insert(format!("nonlinear_force_ns_median_r{r}"), force.into());
                report.insert(format!("nonlinear_force_and_tangent_ns_median_r{r}"), tangent.into());
            }
            // Bent far: a tenth of the part's size each way, once a second.
            if let Some(s) = bench::nonlinear_sweep(b.clone(), 51, per_batch, 0.1) {
                report.insert(format!("nonlinear_sweep_step_ns_median_r{r}"), s.step_ns.into());
                report.insert(
                    format!("nonlinear_sweep_iterations_per_step_r{r}"),
                    s.iterations_per_step.into(),
                );
                report.insert(
                    format!("nonlinear_sweep_tangents_per_step_r{r}"),
                    s.tangents_per_step.into(),
                );
            }
            let ns = bench::haptic_press_step_ns(b, 201, per_batch);
            report.insert(format!("haptic_press_step_ns_median_r{r}"), ns.into());
        }
        let field = if available >= 30 {
            basis::load(
                &self.file.basis,
                &LoadOptions {
                    modes: Some(30),
                    ..Default::default()
                },
            )?
        } else {
            all
        };
        report.insert("full_field_modes".into(), field.mode_count().into());
        report.insert("full_field_vertices".into(), field.vertex_count().into());
        report.insert("full_field_ms_median".into(), bench::full_field_ms(&field, 301).into());
        // With modal stress: σ over the same vertices and its von Mises pass (null without).
        let stress = bench::full_field_stress_ms(&field, 301);
        report.insert("full_field_stress_ms_median".into(), stress.map(|s| s.0).into());
        report.insert("von_mises_ms_median".into(), stress.map(|s| s.1).into());
        report.insert("bytes_loaded".into(), field.bytes_loaded.into());
        let v = serde_json::Value::Object(report);
        if self.file.json {
            println!("{v}");
        } else {
            println!("{}", serde_json::to_string_pretty(&v)?);
        }
        Ok(())
    }
}
