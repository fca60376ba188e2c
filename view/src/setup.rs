//! The set-up the server owns: the scene of the basis served, the edits not yet computed, their
//! undo and redo, and the history of computes. Every page shows this one state (a reload or a
//! second tab shows what is served, never the page's own start), and a project on disk keeps it
//! across restarts (`project.rs`).

use serde::{Deserialize, Serialize};
use serde_json::Value;

/// Edits kept for undo (each a scene of at most [`crate::protocol::MAX_MESSAGE`] bytes).
pub const UNDO_DEPTH: usize = 100;
/// Computes kept in the history.
pub const HISTORY: usize = 200;
/// Computes of the history sent to the pages (the newest).
pub const HISTORY_SHOWN: usize = 20;

/// One compute, as the history keeps it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// When it ended, seconds since 1970 (UTC).
    pub unix_time: u64,
    /// What it changed from the scene served before: dotted keys (`material.young`, `fixed`);
    /// empty for the first compute.
    pub changed: Vec<String>,
    /// "computed", "cancelled" or "failed".
    pub outcome: String,
    /// Its summary line, or why it failed.
    pub summary: String,
    /// From the request to its end, s.
    pub seconds: f64,
}

/// The set-up state. The scenes are the page's: the scene's TOML tables as JSON.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SetUp {
    /// The scene of the basis served; none before the first compute.
    pub served: Option<Value>,
    /// The served scene as the scene file "save scene" gives (TOML).
    pub served_toml: Option<String>,
    /// The served basis's summary line.
    pub summary: Option<String>,
    /// The warnings its compute gave, one line each.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Its mesh (the compute's `mesh`: sizes and the tets' quality histogram), or null.
    #[serde(default)]
    pub mesh: Value,
    /// The scene being edited (equal to `served` when nothing was edited since).
    pub draft: Value,
    undo: Vec<Value>,
    redo: Vec<Value>,
    /// Computes so far, oldest first (at most [`HISTORY`]).
    pub history: Vec<Entry>,
}

impl SetUp {
    /// A set-up whose draft is `start` and which serves nothing yet.
    pub fn new(start: Value) -> SetUp {
        SetUp {
            draft: start,
            ..SetUp::default()
        }
    }

    /// `scene` becomes the draft (undoable). False when it is the draft already.
    pub fn edit(&mut self, scene: Value) -> bool {
        if same(&scene, &self.draft) {
            return false;
        }
        push_bounded(&mut self.undo, std::mem::replace(&mut self.draft, scene), UNDO_DEPTH);
        self.redo.clear();
        true
    }

    /// The draft before the last edit. False when there is none.
    pub fn undo(&mut self) -> bool {
        let Some(before) = self.undo.pop() else {
            return false;
        };
        push_bounded(&mut self.redo, std::mem::replace(&mut self.draft, before), UNDO_DEPTH);
        true
    }

    /// The edit last undone. False when there is none.
    pub fn redo(&mut self) -> bool {
        let Some(after) = self.redo.pop() else {
            return false;
        };
        push_bounded(&mut self.undo, std::mem::replace(&mut self.draft, after), UNDO_DEPTH);
        true
    }

    /// The draft back to the scene served, as an edit (undo brings the edits back). False when
    /// nothing is served or nothing was edited.
    pub fn revert(&mut self) -> bool {
        match self.served.clone() {
            Some(s) => self.edit(s),
            None => false,
        }
    }

    /// Whether the draft differs from the scene served.
    pub fn edited(&self) -> bool {
        !self.served.as_ref().is_some_and(|s| same(s, &self.draft))
    }

    /// `scene` (saved as `toml`) is served from now on, with `summary` and its compute's
    /// `warnings`.
    pub fn serve(&mut self, scene: Value, toml: String, summary: String, warnings: Vec<String>) {
        self.served = Some(scene);
        self.served_toml = Some(toml);
        self.summary = Some(summary);
        self.warnings = warnings;
    }

    /// Adds a compute to the history.
    pub fn record(&mut self, entry: Entry) {
        push_bounded(&mut self.history, entry, HISTORY);
    }

    /// The computes in the history that made a basis (cancelled and failed ones left out).
    pub fn computes(&self) -> usize {
        self.history.iter().filter(|e| e.outcome == "computed").count()
    }

    /// The message every page gets: `{"type":"setup","draft","served","served_toml","summary",
    /// "warnings","mesh","edited","undo","redo","history","project"}` (`undo` and `redo` count the steps
    /// available; `history` is the newest [`HISTORY_SHOWN`] computes).
    pub fn message(&self, project: Option<&str>) -> Value {
        let shown = &self.history[self.history.len().saturating_sub(HISTORY_SHOWN)..];
        serde_json::json!({
            "type": "setup",
            "draft": self.draft,
            "served": self.served,
            "served_toml": self.served_toml,
            "summary": self.summary,
            "warnings": self.warnings,
            "mesh": self.mesh,
            "edited": self.edited(),
            "undo": self.undo.len(),
            "redo": self.redo.len(),
            "history": shown,
            "project": project,
        })
    }
}

fn push_bounded<T>(list: &mut Vec<T>, item: T, depth: usize) {
    if list.len() >= depth {
        list.remove(0);
    }
    list.push(item);
}

/// The keys in which `after` differs from `before`, dotted (`material.young`); tables are
/// compared key by key, anything else (arrays: `fixed`, `faces`) as a whole.
pub fn changes(before: &Value, after: &Value) -> Vec<String> {
    let mut out = Vec::new();
    diff("", before, after, &mut out);
    out
}

/// Equal as scenes: numbers by value (the page sends 7850 where the starting scene has 7850.0,
/// which JSON keeps apart), the rest exactly.
fn same(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => x.as_f64() == y.as_f64(),
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
        }
        (Value::Array(x), Value::Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(v, w)| same(v, w)),
        _ => a == b,
    }
}

fn diff(at: &str, a: &Value, b: &Value, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Object(a), Value::Object(b)) => {
            let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let path = if at.is_empty() { k.clone() } else { format!("{at}.{k}") };
                match (a.get(k), b.get(k)) {
                    (Some(x), Some(y)) => diff(&path, x, y, out),
                    _ => out.push(path),
                }
            }
        }
        _ if !same(a, b) => out.push(if at.is_empty() { "scene".into() } else { at.into() }),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn undo_after_two_edits_returns_the_first_and_redo_the_second() {
        let mut s = SetUp::new(json!({"modes": {"count": 12}}));
        assert!(s.edit(json!({"modes": {"count": 20}})));
        assert!(s.edit(json!({"modes": {"count": 30}})));
        assert!(!s.edit(json!({"modes": {"count": 30}})), "the same scene is no edit");
        assert!(s.undo());
        assert_eq!(s.draft, json!({"modes": {"count": 20}}));
        assert!(s.undo());
        assert_eq!(s.draft, json!({"modes": {"count": 12}}));
        assert!(!s.undo(), "nothing before the start");
        assert!(s.redo());
        assert_eq!(s.draft, json!({"modes": {"count": 20}}));
        // A new edit drops what was undone.
        assert!(s.edit(json!({"modes": {"count": 8}})));
        assert!(!s.redo());
    }

    #[test]
    fn revert_returns_to_the_served_scene_and_is_undone_like_an_edit() {
        let mut s = SetUp::new(json!({"a": 1}));
        assert!(!s.revert(), "nothing served yet");
        assert!(s.edited());
        s.serve(json!({"a": 1}), "a = 1".into(), "12 modes".into(), vec![]);
        assert!(!s.edited());
        s.edit(json!({"a": 2}));
        assert!(s.edited());
        assert!(s.revert());
        assert_eq!(s.draft, json!({"a": 1}));
        assert!(s.undo());
        assert_eq!(s.draft, json!({"a": 2}));
    }

    #[test]
    fn undo_and_history_are_bounded() {
        let mut s = SetUp::new(json!(0));
        for i in 1..=(UNDO_DEPTH + 10) {
            s.edit(json!(i));
        }
        let mut steps = 0;
        while s.undo() {
            steps += 1;
        }
        assert_eq!(steps, UNDO_DEPTH);
        assert_eq!(s.draft, json!(10), "the oldest edits went first");
        for i in 0..(HISTORY + 5) {
            s.record(Entry {
                unix_time: i as u64,
                changed: vec![],
                outcome: "computed".into(),
                summary: String::new(),
                seconds: 1.0,
            });
        }
        assert_eq!(s.history.len(), HISTORY);
        assert_eq!(s.history[0].unix_time, 5);
        let m = s.message(None);
        assert_eq!(m["history"].as_array().map(Vec::len), Some(HISTORY_SHOWN));
        assert_eq!(m["history"][HISTORY_SHOWN - 1]["unix_time"], json!(HISTORY + 4));
    }

    #[test]
    fn changes_name_the_keys_that_differ() {
        let a = json!({"material": {"young": 2e11, "poisson": 0.3}, "fixed": [{"faces": [1]}], "modes": {"count": 12}});
        let b = json!({"material": {"young": 7e10, "poisson": 0.3}, "fixed": [{"faces": [1, 2]}], "stress": {"enabled": true}, "modes": {"count": 12}});
        assert_eq!(changes(&a, &b), ["fixed", "material.young", "stress"]);
        assert!(changes(&a, &a).is_empty());
        assert_eq!(changes(&json!(1), &json!(2)), ["scene"]);
        // The page's 7850 is the starting scene's 7850.0.
        let page = json!({"material": {"density": 7850}, "damping": {"alpha": 0}});
        let start = json!({"material": {"density": 7850.0}, "damping": {"alpha": 0.0}});
        assert!(changes(&start, &page).is_empty());
        let mut s = SetUp::new(start.clone());
        s.serve(start, String::new(), String::new(), vec![]);
        assert!(!s.edit(page) && !s.edited());
    }
}
