//! `ves faces`.

use anyhow::Result;
use std::path::PathBuf;

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// A STEP or IGES part, or a scene (its part meshed as the scene meshes it).
    input: PathBuf,
    /// Accept a scene whose geometry is a .geo script (gmsh scripts can run shell commands).
    #[arg(long)]
    allow_geo_scripts: bool,
    /// Print the faces as JSON (last line of stdout).
    #[arg(long)]
    json: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let faces = ves_pipeline::faces::list(&self.input, self.allow_geo_scripts)?;
        if self.json {
            return super::print_json(&faces);
        }
        let mm = |p: [f64; 3]| format!("({:.2}, {:.2}, {:.2})", 1e3 * p[0], 1e3 * p[1], 1e3 * p[2]);
        let mut text = format!(
            "{} CAD faces of {} (tags as `faces = [...]` names them; mm)\n",
            faces.len(),
            self.input.display()
        );
        for f in &faces {
            let what = match f.kind {
                "plane" => format!(
                    "plane, normal ({:.3}, {:.3}, {:.3})",
                    f.normal.unwrap_or_default()[0],
                    f.normal.unwrap_or_default()[1],
                    f.normal.unwrap_or_default()[2]
                ),
                "cylinder" => {
                    let a = f.axis.unwrap_or_default();
                    format!(
                        "cylinder{} r = {:.3}, axis ({:.3}, {:.3}, {:.3}) through {}",
                        if f.concave == Some(true) { " (concave)" } else { "" },
                        1e3 * f.radius_m.unwrap_or_default(),
                        a[0],
                        a[1],
                        a[2],
                        mm(f.axis_point_m.unwrap_or_default())
                    )
                }
                _ => "other".to_string(),
            };
            let name = f.name.as_ref().map_or(String::new(), |n| format!("{n:?} "));
            text.push_str(&format!(
                "{:>5}  {name}{what}; area {:.4} mm², centroid {}\n",
                f.tag,
                1e6 * f.area_m2,
                mm(f.centroid_m)
            ));
        }
        super::print_text(&text)
    }
}
