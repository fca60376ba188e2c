//! A project on disk: the set-up of one part ([`SetUp`]: the scene served, the edits, undo and
//! redo, the history of computes) in `project.json`, and the basis served last in `basis.h5`, in
//! a folder of its own (`ves view PART.step` puts it beside the part as `PART.ves`). Opening the
//! part again resumes there: the same basis served at once, the same edits in the panel.
//!
//! The folder is read as hostile input like any file: `project.json` is bounded in size and
//! parsed strictly, the basis goes through the runtime's checked loader, and nothing in either
//! names another file. A project of another part (its key differs) is set aside, not resumed.

use crate::setup::SetUp;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The project's state file.
pub const STATE: &str = "project.json";
/// The basis served last.
pub const BASIS: &str = "basis.h5";
/// What `project.json` says it is.
const FORMAT: &str = "ves-project";
/// Its version.
const VERSION: u32 = 1;
/// Largest `project.json` read, bytes: 100 undo steps and 100 redo of at most 32 KiB each,
/// and the history, fit well within.
const MAX_STATE: u64 = 16 << 20;

/// `project.json`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct State {
    format: String,
    version: u32,
    /// The part's file name.
    part: String,
    /// What the part's content was (a fingerprint the caller makes): another part's project is
    /// not resumed.
    key: String,
    setup: SetUp,
}

/// Why a project cannot be used (the viewer runs on without one, saying so).
#[derive(Debug, thiserror::Error)]
pub enum ProjectError {
    /// Its folder cannot be made or written.
    #[error("{}: {error}; the set-up is not kept (give --project DIR in a folder you can write)", dir.display())]
    Folder {
        /// The folder.
        dir: PathBuf,
        /// Why.
        error: std::io::Error,
    },
}

/// An open project.
#[derive(Debug)]
pub struct Project {
    dir: PathBuf,
    part: String,
    key: String,
}

/// What an opened project had.
#[derive(Debug)]
pub struct Resumed {
    /// The set-up as it was left.
    pub setup: SetUp,
    /// The basis served then, if it is there and was computed from `setup.served`.
    pub basis: Option<PathBuf>,
}

/// What opening a project found.
#[derive(Debug)]
pub struct Opened {
    /// The project.
    pub project: Project,
    /// Its state, when it is this part's.
    pub resumed: Option<Resumed>,
    /// One line for the user when a state was there but not resumed (another part's, unreadable;
    /// it is set aside as `project.json.old`).
    pub notice: Option<String>,
}

/// What opening a project did, in words for the user: "new", "resumed (2 computes before)"
/// (its basis served), or its set-up resumed with its scene computed again. `resumed`: the
/// computes in the history of a set-up resumed; `served`: whether its basis is served.
pub fn resumed_words(resumed: Option<usize>, served: bool) -> String {
    match (resumed, served) {
        (Some(1), true) => "resumed (1 compute before)".into(),
        (Some(n), true) => format!("resumed ({n} computes before)"),
        (Some(_), false) => "its set-up resumed; its scene is computed again".into(),
        (None, _) => "new".into(),
    }
}

impl Project {
    /// Opens (or makes) the project in `dir` for the part named `part` whose content gives `key`.
    pub fn open(dir: &Path, part: &str, key: &str) -> Result<Opened, ProjectError> {
        let folder = |error| ProjectError::Folder {
            dir: dir.to_path_buf(),
            error,
        };
        std::fs::create_dir_all(dir).map_err(folder)?;
        let project = Project {
            dir: dir.to_path_buf(),
            part: part.to_string(),
            key: key.to_string(),
        };
        // Writable, or said now rather than at the first compute.
        let probe = dir.join(".ves-write-probe");
        std::fs::write(&probe, b"").map_err(folder)?;
        let _ = std::fs::remove_file(&probe);
        let path = dir.join(STATE);
        let (resumed, notice) = match read_state(&path) {
            Ok(None) => (None, None),
            Ok(Some(s)) if s.key == key => {
                let basis = dir.join(BASIS);
                let basis = (s.setup.served.is_some() && basis.is_file()).then_some(basis);
                (Some(Resumed { setup: s.setup, basis }), None)
            }
            Ok(Some(s)) => (
                None,
                Some(format!("it was made for another {} (the part changed since)", s.part)),
            ),
            Err(why) => (None, Some(why)),
        };
        let notice = notice.map(|why| {
            // Set aside, not overwritten: it may be the only copy of someone's set-up.
            let _ = std::fs::rename(&path, dir.join(format!("{STATE}.old")));
            let _ = std::fs::remove_file(dir.join(BASIS));
            format!(
                "{}: {why}; it was set aside as {STATE}.old and the set-up starts afresh",
                path.display()
            )
        });
        Ok(Opened {
            project,
            resumed,
            notice,
        })
    }

    /// The project's folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes `setup` (replacing the file whole: a crash leaves the old one or the new one).
    pub fn save(&self, setup: &SetUp) -> std::io::Result<()> {
        let state = State {
            format: FORMAT.into(),
            version: VERSION,
            part: self.part.clone(),
            key: self.key.clone(),
            setup: setup.clone(),
        };
        let text = serde_json::to_vec_pretty(&state).map_err(std::io::Error::other)?;
        replace(&self.dir.join(STATE), |f| f.write_all(&text))
    }

    /// Removes what the project wrote, and its folder when nothing else is in it: a project
    /// made for a part whose first compute failed keeps nothing worth resuming.
    pub fn discard(&self) {
        for f in [STATE, BASIS] {
            let _ = std::fs::remove_file(self.dir.join(f));
        }
        let _ = std::fs::remove_dir(&self.dir);
    }

    /// Keeps a copy of the basis `from` as the project's basis.
    pub fn keep_basis(&self, from: &Path) -> std::io::Result<()> {
        replace(&self.dir.join(BASIS), |f| {
            std::io::copy(&mut std::fs::File::open(from)?, f).map(|_| ())
        })
    }
}

/// `project.json`, if there: `Err` says in words why it cannot be used.
fn read_state(path: &Path) -> Result<Option<State>, String> {
    use std::io::Read;
    let file = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e.to_string()),
    };
    let mut text = Vec::new();
    file.take(MAX_STATE + 1)
        .read_to_end(&mut text)
        .map_err(|e| e.to_string())?;
    if text.len() as u64 > MAX_STATE {
        return Err(format!("larger than {} MiB", MAX_STATE >> 20));
    }
    let state: State = serde_json::from_slice(&text).map_err(|e| format!("not a VES project ({e})"))?;
    if state.format != FORMAT || state.version != VERSION {
        return Err(format!(
            "a {} version {} file, not {FORMAT} version {VERSION}",
            state.format, state.version
        ));
    }
    Ok(Some(state))
}

/// Writes `path` through a temporary beside it, flushed, then renamed over it.
fn replace(path: &Path, write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>) -> std::io::Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let done = std::fs::File::create(&tmp).and_then(|mut f| {
        write(&mut f)?;
        f.sync_all()
    });
    match done.and_then(|()| std::fs::rename(&tmp, path)) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ves-project-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn a_saved_set_up_resumes_with_its_basis_and_another_part_s_is_set_aside() {
        let dir = tmp("resume");
        let opened = Project::open(&dir, "lever.stp", "k1").expect("open");
        assert!(opened.resumed.is_none() && opened.notice.is_none());
        let mut s = SetUp::new(json!({"modes": {"count": 12}}));
        s.serve(
            json!({"modes": {"count": 12}}),
            "[modes]".into(),
            "12 modes".into(),
            vec!["a wall one element thick".into()],
        );
        s.edit(json!({"modes": {"count": 20}}));
        opened.project.save(&s).expect("save");
        let basis = dir.join("made.h5");
        std::fs::write(&basis, b"basis bytes").expect("basis");
        opened.project.keep_basis(&basis).expect("keep");

        let again = Project::open(&dir, "lever.stp", "k1").expect("open again");
        let r = again.resumed.expect("resumed");
        assert_eq!(r.setup, s);
        assert_eq!(
            std::fs::read(r.basis.expect("its basis")).ok().as_deref(),
            Some(&b"basis bytes"[..])
        );

        let other = Project::open(&dir, "lever.stp", "k2").expect("open for another part");
        assert!(other.resumed.is_none());
        assert!(other.notice.is_some_and(|n| n.contains("another lever.stp")));
        assert!(dir.join("project.json.old").is_file() && !dir.join(BASIS).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_damaged_or_foreign_state_is_set_aside_not_read() {
        let dir = tmp("damaged");
        std::fs::create_dir_all(&dir).expect("dir");
        for junk in [
            &b"{not json"[..],
            br#"{"format":"ves-project","version":2,"part":"p","key":"k","setup":{"draft":null,"served":null,"served_toml":null,"summary":null,"undo":[],"redo":[],"history":[]}}"#,
            br#"{"format":"other","version":1,"part":"p","key":"k","setup":{}}"#,
        ] {
            std::fs::write(dir.join(STATE), junk).expect("write");
            let o = Project::open(&dir, "p", "k").expect("open");
            assert!(o.resumed.is_none(), "{}", String::from_utf8_lossy(junk));
            assert!(o.notice.is_some());
            assert_eq!(std::fs::read(dir.join("project.json.old")).ok().as_deref(), Some(junk));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
