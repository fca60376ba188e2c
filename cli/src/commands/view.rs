//! `ves view`: the part in a browser, with the mouse as a haptic hand. Given a scene or a
//! geometry file, the page also sets the part up and computes its basis (the workshop).

use super::session::Settings;
use crate::workshop::PartWorkshop;
use anyhow::{Context, Result};
use std::io::Write;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use ves_pipeline::scene::{Scene, SceneOptions};
use ves_view::{self as view, ViewConfig, Workshop};

/// What `ves view` was given: a basis to serve, or a part to set up (its project's basis, if
/// it had one; else the first basis to come).
type Opened = (Option<Vec<ves_runtime::switching::SpaceInput>>, Option<view::Studio>);

/// Arguments.
#[derive(clap::Args)]
pub struct Args {
    /// A basis file (.h5), a scene (.toml: the page can change it and compute again) or a
    /// geometry file (.step, .stp, .iges, .igs, .brep: the page sets the part up).
    basis: PathBuf,
    /// Accept a scene whose geometry is a .geo file: a gmsh script, which can run shell
    /// commands. Only for scenes you trust.
    #[arg(long)]
    allow_geo_scripts: bool,
    /// Port to serve on (0: any free port; the URL printed says which).
    #[arg(long, default_value_t = 8765)]
    port: u16,
    /// Address to listen on. Loopback by default: anything else lets other machines drive the
    /// session.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    host: IpAddr,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    duration: Option<f64>,
    /// Gravity on a free part, m/s² along −z. Off by default here: with it, a part nobody holds
    /// falls out of view before the page opens (ves session's default is 9.81).
    #[arg(long, default_value_t = 0.0)]
    gravity: f64,
    #[command(flatten)]
    settings: Settings,
    /// At the end, print the statistics (session and server) as JSON.
    #[arg(long)]
    json: bool,
    /// Do not serve instant bases. By default, when only supports, material or modes change,
    /// the page gets an instant basis first (the previous basis's mesh, modes from a few block
    /// solves, each frequency with a bound) while the converged compute runs; this waits for
    /// the converged one alone (docs/view.md).
    #[arg(long)]
    no_instant: bool,
    /// Where the set-up is kept (the scene served, edits, undo, the history of computes, the
    /// basis served last): a part opened again resumes there. Default for a geometry file:
    /// PART.ves beside it; a scene keeps a project only when given one. A part opened in the
    /// page keeps its own under VES_PROJECTS_DIR (default ~/.local/share/ves/projects).
    #[arg(long, conflicts_with = "no_project")]
    project: Option<PathBuf>,
    /// Keep no project (nor one for a part opened in the page): the set-up lives as long as the
    /// server.
    #[arg(long)]
    no_project: bool,
}

impl Args {
    pub fn run(self) -> Result<()> {
        let mut cfg = self.settings.config(self.duration.unwrap_or(f64::INFINITY), "view")?;
        // 1000 g: beyond it a free part leaves the view within one drawn frame, and products
        // with the part's mass and the step could leave the range of the frames' f32.
        if !self.gravity.is_finite() || self.gravity.abs() > 1e4 {
            anyhow::bail!(
                "--gravity {:e}: must be finite and within ±1e4 m/s² (e.g. 9.81)",
                self.gravity
            );
        }
        if let Some((g, _)) = cfg.free_body.as_mut() {
            *g = [0.0, 0.0, -self.gravity];
        }
        let (spaces, studio) = self.open()?;
        if !self.host.is_loopback() {
            tracing::warn!(
                "--host {}: the viewer is reachable from other machines, and anyone who opens it can drive the session",
                self.host
            );
        }
        let name = self.basis.file_name().map_or_else(
            || self.basis.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let cfg = ViewConfig {
            addr: SocketAddr::new(self.host, self.port),
            session: cfg,
            name,
            limits: view::Limits::default(),
            face_kinds: Some(face_kinds),
        };
        let stop = Arc::new(AtomicBool::new(false));
        // Ctrl-C ends the session and prints the statistics; SIGTERM and SIGHUP end the
        // process at once, its work folder removed (ves_pipeline::workdir).
        ves_pipeline::workdir::stop_on_interrupt(stop.clone());
        let stats = view::serve_studio(spaces, studio, &cfg, stop, |addr| {
            // The URL on stdout, flushed: scripts and tests wait for this line.
            let host = if addr.ip().is_unspecified() {
                "127.0.0.1".to_string()
            } else {
                addr.ip().to_string()
            };
            let host = if addr.is_ipv6() && !addr.ip().is_unspecified() {
                format!("[{host}]")
            } else {
                host
            };
            println!("ves view: http://{host}:{}/  (Ctrl-C stops)", addr.port());
            let _ = std::io::stdout().flush();
        })
        .map_err(|e| anyhow::anyhow!(e))
        .with_context(|| self.basis.display().to_string())?;
        super::session::warn_refused(&stats.session);
        if self.json {
            println!("{}", serde_json::to_string(&stats)?);
        }
        Ok(())
    }

    /// What the file given is: a basis to serve, or a part to set up and compute.
    fn open(&self) -> Result<Opened> {
        let p = &self.basis;
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let solver = ves_pipeline::modes::SolverChoice::Auto;
        match ext.as_str() {
            "toml" => {
                let options = SceneOptions {
                    allow_geo_scripts: self.allow_geo_scripts,
                };
                let scene = Scene::load_with(p, options)?;
                let workshop = PartWorkshop::for_scene(&scene, options, solver)?.instant(!self.no_instant);
                let key = [scene.toml.as_bytes(), &read_part(&scene.geometry)?];
                self.studio(workshop, &scene.geometry, &key, self.project.clone())
            }
            "step" | "stp" | "iges" | "igs" | "brep" => {
                ves_pipeline::input::open(p)?;
                let workshop = PartWorkshop::for_geometry(p, solver)?.instant(!self.no_instant);
                let beside = std::path::absolute(p)?.with_extension("ves");
                self.studio(workshop, p, &[&read_part(p)?], self.project.clone().or(Some(beside)))
            }
            "geo" => anyhow::bail!(
                "{}: a .geo file is a gmsh script and can run shell commands; export the part as STEP, or name it in a scene and pass --allow-geo-scripts if you trust it",
                p.display()
            ),
            _ => Ok((Some(self.settings.spaces(p)?), None)),
        }
    }
}

impl Args {
    /// The studio of `workshop`: its project in `dir` (unless --no-project), keyed by the
    /// fingerprint of `key` (the part's bytes, and the scene's text for a scene), resumed with
    /// its basis when it had one.
    fn studio(
        &self,
        workshop: PartWorkshop,
        part: &std::path::Path,
        key: &[&[u8]],
        dir: Option<PathBuf>,
    ) -> Result<Opened> {
        let none = |workshop: PartWorkshop| {
            let studio = view::Studio {
                workshop: Arc::new(workshop),
                project: None,
                setup: None,
                uploads: self.uploads(None),
            };
            Ok((None, Some(studio)))
        };
        let Some(dir) = dir.filter(|_| !self.no_project) else {
            return none(workshop);
        };
        let dir = std::path::absolute(&dir)?;
        let name = part
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let key = project_key(key);
        let opened = match view::Project::open(&dir, &name, &key) {
            Ok(o) => o,
            // A folder that cannot be written (a read-only share): the part is still set up.
            Err(e) => {
                tracing::warn!("{e}");
                return none(workshop);
            }
        };
        if let Some(n) = &opened.notice {
            tracing::warn!("{n}");
        }
        let (setup, basis) = match opened.resumed {
            Some(r) => (Some(r.setup), r.basis),
            None => (None, None),
        };
        // The basis served last, served again at once; one that cannot be read is computed again.
        let spaces = basis.as_ref().and_then(|b| {
            ves_runtime::switching::load_spaces(b, None, true)
                .map_err(|e| tracing::warn!("{}: {e}; its scene is computed again", b.display()))
                .ok()
        });
        if let (Some(_), Some(b)) = (&spaces, &basis) {
            // Instant bases are made from the project's basis, as from one computed.
            workshop.served_from_project(b);
        }
        // Said on every start: which folder holds the set-up, and whether it was resumed.
        eprintln!(
            "ves view: project {}: {}",
            dir.display(),
            view::project::resumed_words(setup.as_ref().map(view::setup::SetUp::computes), spaces.is_some())
        );
        let studio = view::Studio {
            workshop: Arc::new(workshop),
            project: Some(opened.project),
            setup,
            uploads: self.uploads(Some((dir.clone(), key))),
        };
        Ok((spaces, Some(studio)))
    }

    /// Where the projects of parts opened in the page (**open a part…**) are kept, each in a
    /// folder named by the part and its content's key: `VES_PROJECTS_DIR`, else
    /// `$XDG_DATA_HOME/ves/projects`, else `~/.local/share/ves/projects`; none with --no-project.
    /// The command-line part opened again in the page (`own`: its project's folder and key, the
    /// same bytes) goes back to its own project.
    fn uploads(&self, own: Option<(PathBuf, String)>) -> Option<view::ProjectFor> {
        if self.no_project {
            return None;
        }
        let var = |v: &str| std::env::var_os(v).map(PathBuf::from).filter(|p| p.is_absolute());
        let home = var("VES_PROJECTS_DIR")
            .or_else(|| var("XDG_DATA_HOME").map(|d| d.join("ves/projects")))
            .or_else(|| var("HOME").map(|h| h.join(".local/share/ves/projects")))?;
        Some(Arc::new(move |name: &str, bytes: &[u8]| {
            let key = project_key(&[bytes]);
            let file = std::path::Path::new(name);
            let dir = match &own {
                Some((dir, own_key)) if *own_key == key => dir.clone(),
                _ => home.join(format!("{}-{}", crate::workshop::safe_stem(file), &key[..12])),
            };
            let part = file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            view::Project::open(&dir, &part, &key)
                .map_err(|view::project::ProjectError::Folder { dir, error }| {
                    tracing::warn!(
                        "{}: {error}; the part opened in the page is set up without a project (set VES_PROJECTS_DIR to a folder you can write)",
                        dir.display()
                    )
                })
                .ok()
        }))
    }
}

/// A project's key: the fingerprint of the part's bytes (and a scene's text).
fn project_key(parts: &[&[u8]]) -> String {
    let mut f = ves_pipeline::fingerprint::Fingerprint::default();
    for p in parts {
        f.field(p);
    }
    format!("{:016x}", f.value())
}

/// The part's bytes, for its project's key.
fn read_part(p: &std::path::Path) -> Result<Vec<u8>> {
    std::fs::read(p).with_context(|| format!("{}: cannot read the part", p.display()))
}

/// What each CAD face of a surface is, for the page's hover ([`ves_pipeline::faces`]), named
/// as the part's STEP file names them where its numbering is confirmed to be gmsh's.
fn face_kinds(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    faces: &[u32],
    part: Option<&std::path::Path>,
) -> serde_json::Value {
    let mut listed = ves_pipeline::faces::of_surface(vertices, triangles, faces);
    if let Some(text) = part.and_then(ves_pipeline::faces::step_text) {
        // A basis of another part (served while a new one computes) is not named: said nowhere,
        // as the hover then shows that basis' own faces by number.
        let _ = ves_pipeline::faces::name_from_step(&mut listed, &text);
    }
    serde_json::to_value(listed).unwrap_or_default()
}
