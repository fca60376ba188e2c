//! `ves info`.

use anyhow::Result;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    file: super::BasisFile,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let info = ves_pipeline::store::info(&self.file.basis)?;
        if self.file.json {
            return super::print_json(&info);
        }
        // Text from the file goes to a terminal: control and bidirectional-text characters are
        // shown escaped, never interpreted.
        let esc = ves_format::names::escape_for_terminal;
        println!("{} ({} bytes, {})", info.path, info.bytes, esc(&info.generator));
        for s in &info.spaces {
            let correction = if s.static_correction_vertices > 0 {
                format!(", static correction at {} vertices", s.static_correction_vertices)
            } else {
                String::new()
            };
            let contact = if s.contact_radius_m > 0.0 {
                format!(", hand contact patch {:.1} mm", 1e3 * s.contact_radius_m)
            } else {
                ", hand contact on one vertex".to_string()
            };
            let felt = s.felt_error.as_ref().map_or(String::new(), |f| {
                format!(
                    ", felt error stated at {} vertices (median {:.2} %, 90 % of them ≤ {:.2} %)",
                    f.spread.vertices,
                    100.0 * f.spread.median,
                    100.0 * f.spread.p90
                )
            });
            let supports = s.supports.as_ref().map_or(String::new(), |i| i.text());
            // Which motions a part held in some directions only is free to make.
            let free = if (1..6).contains(&s.rigid_modes_dropped) && !s.free_motions.is_empty() {
                let words: Vec<String> = s.free_motions.iter().map(free_motion_text).collect();
                format!(", free to {}", words.join(" and "))
            } else {
                String::new()
            };
            let supports = format!("{supports}{free}");
            let correction = format!("{contact}{correction}{felt}{supports}");
            let meshing = s
                .meshing_strategy
                .as_deref()
                .map_or(String::new(), |m| format!(", meshed by strategy \"{}\"", esc(m)));
            let error = ves_pipeline::accuracy::summary_text(s.estimated_relative_error.as_deref())
                + &s.nonlinear.map_or(String::new(), |n| n.text());
            println!(
                "  {}: {} nodes ({} vertices), {} tets of order {}, {} modes {:.4}..{:.4} Hz, max residual {:.1e}, {} rigid dropped{correction}{meshing}{error}",
                esc(&s.name),
                s.nodes,
                s.vertices,
                s.tets,
                s.element_order,
                s.modes,
                s.frequencies_hz.first().copied().unwrap_or(0.0),
                s.frequencies_hz.last().copied().unwrap_or(0.0),
                s.max_relative_residual,
                s.rigid_modes_dropped,
            );
            for l in &s.loads {
                let f = l.total_force_n;
                println!(
                    "    load {} ({}): total force [{:.4e}, {:.4e}, {:.4e}] N, max displacement {:.4e} m, max von Mises {:.4e} Pa, reaction balance {:.1e}",
                    esc(&l.name),
                    esc(&l.kind),
                    f[0],
                    f[1],
                    f[2],
                    l.max_displacement_m,
                    l.max_von_mises_pa,
                    l.balance_residual
                );
                if let Some(text) = &l.peak_stress {
                    println!("      {}", esc(text));
                }
            }
        }
        Ok(())
    }
}

/// A free motion in words: "slide along (0, 0, 1)", "turn about (0, 0, 1) through (…) m".
fn free_motion_text(m: &ves_pipeline::rigid_motions::FreeMotion) -> String {
    use ves_pipeline::rigid_motions::FreeMotion;
    // Directions to 4 decimals, points to 10 µm, so that an axis reads as the axis it is
    // ("(1, 0, 0)", not "(1, 1.3e-16, -1.1e-16)").
    let rounded = |d: &[f64; 3], decimals: usize| {
        let r = |x: f64| {
            let t = format!("{:.*}", decimals, x);
            let t = t.trim_end_matches('0').trim_end_matches('.');
            if t == "-0" { "0".to_string() } else { t.to_string() }
        };
        format!("({}, {}, {})", r(d[0]), r(d[1]), r(d[2]))
    };
    let (along, at) = (|d| rounded(d, 4), |p| rounded(p, 5));
    match m {
        FreeMotion::Slide { direction } => format!("slide along {}", along(direction)),
        FreeMotion::Turn { direction, point } => {
            format!("turn about {} through {} m", along(direction), at(point))
        }
        FreeMotion::Screw {
            direction,
            point,
            pitch,
        } => format!(
            "screw about {} through {} m ({:.3e} m per radian)",
            along(direction),
            at(point),
            pitch
        ),
    }
}
