//! The static load cases of the spaces served (`spaces/<s>/loads/<name>/` of the basis file,
//! docs/format.md): listed in the hello, and read from the file and sent to a page only when it
//! asks for one (kind 4, [`super::protocol::load_case`]), since each carries a displacement and a stress per vertex.

use crate::Basis;
use ves_format::BasisReader;
use ves_format::read::LoadCase;

/// What the hello says of one load case (its data comes on request).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoadInfo {
    /// Its name (the scene's `[[load]] name`, or `gravity`).
    pub name: String,
    /// `force`, `pressure` or `gravity`.
    pub kind: String,
    /// Sum of the applied nodal loads, N.
    pub total_force: [f64; 3],
    /// Total support reaction, N.
    pub reaction: [f64; 3],
    /// Largest nodal displacement magnitude, m.
    pub max_displacement: f64,
    /// Largest corner-vertex von Mises stress, Pa.
    pub max_von_mises: f64,
}

/// The load cases of one served space, as listed in the hello.
#[derive(Clone, Debug, Default)]
pub struct SpaceLoads {
    /// Each case, in the file's order (the index a page's request resolves to).
    pub cases: Vec<LoadInfo>,
    /// The file's node count when the cases were listed (a request is refused if the file has
    /// since changed under the server).
    pub node_count: usize,
    /// Why the space offers none although its file has a `loads` group (a damaged case).
    pub error: Option<String>,
}

impl SpaceLoads {
    /// The names, in order.
    pub fn names(&self) -> Vec<String> {
        self.cases.iter().map(|c| c.name.clone()).collect()
    }
}

/// Lists (and checks, every array read once) the load cases of `basis`'s space in the file it
/// was loaded from. A basis built in memory has none; a damaged case leaves the space without
/// load cases and says why (the part itself is still served).
pub fn list(basis: &Basis) -> SpaceLoads {
    let Some(path) = &basis.source else {
        return SpaceLoads::default();
    };
    let read = || -> Result<(Vec<LoadInfo>, usize), String> {
        let file = BasisReader::open(path).map_err(|e| e.to_string())?;
        let space = file.space(&basis.space).map_err(|e| e.to_string())?;
        let cases = space.loads().map_err(|e| e.to_string())?;
        Ok((cases.iter().map(info).collect(), space.node_count))
    };
    match read() {
        Ok((cases, node_count)) => SpaceLoads {
            cases,
            node_count,
            error: None,
        },
        Err(e) => SpaceLoads {
            error: Some(e),
            ..SpaceLoads::default()
        },
    }
}

fn info(c: &LoadCase) -> LoadInfo {
    LoadInfo {
        name: c.name.clone(),
        kind: c.kind.clone(),
        total_force: c.total_force,
        reaction: c.reaction,
        max_displacement: c.max_displacement,
        max_von_mises: c.max_von_mises,
    }
}

/// Reads load case `name` of `basis`'s space from its file; `node_count` is the file's node
/// count when the case was listed.
pub fn read(basis: &Basis, name: &str, node_count: usize) -> Result<LoadCase, String> {
    let path = basis.source.as_ref().ok_or("this basis was not loaded from a file")?;
    let file = BasisReader::open(path).map_err(|e| e.to_string())?;
    let space = file.space(&basis.space).map_err(|e| e.to_string())?;
    if space.node_count != node_count {
        return Err(format!(
            "{}: space {:?} now has {} nodes, {node_count} when it was loaded: the file changed",
            path.display(),
            basis.space,
            space.node_count
        ));
    }
    space.load(name).map_err(|e| e.to_string())
}
