//! The static load cases of the spaces served (`spaces/<s>/loads/<name>/` of the basis file,
//! docs/format.md): listed in the hello, and read from the file and sent to a page only when it
//! asks for one (kind 4, [`super::protocol::load_case`]), since each carries a displacement and a stress per vertex.

use std::path::PathBuf;
use ves_format::read::LoadCase;
use ves_format::{BasisReader, ReadError};
use ves_runtime::Basis;

/// Why a load case a page asked for cannot be sent.
#[derive(Debug, thiserror::Error)]
pub enum LoadsError {
    /// The basis served was built in memory.
    #[error("this basis was not loaded from a file")]
    NoFile,
    /// The file cannot give it (damaged, gone, or no such case).
    #[error(transparent)]
    Read(#[from] ReadError),
    /// The file's space is not the one the cases were listed from.
    #[error(
        "{}: space {space:?} now has {now} nodes, {then} when it was loaded: the file changed",
        path.display()
    )]
    Changed {
        /// The basis file.
        path: PathBuf,
        /// The space.
        space: String,
        /// Its nodes now.
        now: usize,
        /// Its nodes when the cases were listed.
        then: usize,
    },
    /// The basis served changed between the request and its answer.
    #[error("the basis changed; choose the load case again")]
    BasisChanged,
    /// The case read does not fit the basis served.
    #[error("load case {name:?} does not fit the basis served: the file changed")]
    DoesNotFit {
        /// The case.
        name: String,
    },
    /// The task reading it panicked or was cancelled.
    #[error("reading the load case failed: {0}")]
    Failed(tokio::task::JoinError),
}

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
    /// The largest von Mises peak as studied on meshes refined around it, when the file has it.
    pub peak: Option<Peak>,
    /// The largest studied peak that is not singular, when the largest is.
    pub regular_peak: Option<Peak>,
}

/// A studied von Mises peak as the hello sends it (the file's `peak_*` attributes).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Peak {
    /// `converging`, `slow`, `singular` or `unsettled`.
    pub verdict: String,
    /// Its value on the basis's mesh, Pa.
    pub value: f64,
    /// The value's estimated error, Pa (null: none stated).
    pub error: Option<f64>,
    /// The value with the element size there halved, then quartered, Pa.
    pub refined: [f64; 2],
    /// Where it is, m.
    pub position: [f64; 3],
}

impl From<&ves_format::PeakRecord> for Peak {
    fn from(p: &ves_format::PeakRecord) -> Peak {
        Peak {
            verdict: p.verdict.clone(),
            value: p.value,
            error: p.error,
            refined: p.refined,
            position: p.position,
        }
    }
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
    let read = || -> Result<(Vec<LoadInfo>, usize), ReadError> {
        let file = BasisReader::open(path)?;
        let space = file.space(&basis.space)?;
        let cases = space.loads()?;
        Ok((cases.iter().map(info).collect(), space.node_count))
    };
    match read() {
        Ok((cases, node_count)) => SpaceLoads {
            cases,
            node_count,
            error: None,
        },
        Err(e) => SpaceLoads {
            error: Some(e.to_string()),
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
        peak: c.peak.as_ref().map(Peak::from),
        regular_peak: c.regular_peak.as_ref().map(Peak::from),
    }
}

/// Reads load case `name` of `basis`'s space from its file; `node_count` is the file's node
/// count when the case was listed.
pub fn read(basis: &Basis, name: &str, node_count: usize) -> Result<LoadCase, LoadsError> {
    let path = basis.source.as_ref().ok_or(LoadsError::NoFile)?;
    let file = BasisReader::open(path)?;
    let space = file.space(&basis.space)?;
    if space.node_count != node_count {
        return Err(LoadsError::Changed {
            path: path.clone(),
            space: basis.space.clone(),
            now: space.node_count,
            then: node_count,
        });
    }
    Ok(space.load(name)?)
}
