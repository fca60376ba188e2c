//! The static load cases of the spaces served (`spaces/<s>/loads/<name>/` of the basis file,
//! docs/format.md): listed in the hello, and read from the file and sent to a page only when it
//! asks for one (kind 4, [`encode`]), since each carries a displacement and a stress per vertex.

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

/// Bytes before a load case's arrays.
pub const LOAD_HEADER: usize = 4 * 4 + 2 * 8;

/// Kind 4, load case `index` (in the hello's list) of space `space`: u32 kind, space, nv, index;
/// f64 largest displacement (m), largest von Mises stress (Pa) of the whole part (the file's
/// attributes); f32 u[3nv] (the static displacement of each drawn vertex, m), von Mises[nv]
/// (Pa). `None` if the case does not fit the basis (a vertex's node beyond the case's arrays).
pub fn encode(space: usize, index: usize, basis: &Basis, case: &LoadCase) -> Option<Vec<u8>> {
    let nv = basis.vertex_count();
    let mut b = Vec::with_capacity(LOAD_HEADER + 16 * nv);
    for v in [4, space as u32, nv as u32, index as u32] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in [case.max_displacement, case.max_von_mises] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for &node in &basis.node_index {
        let u = case.displacement.get(3 * node as usize..3 * node as usize + 3)?;
        for c in u {
            b.extend_from_slice(&(*c as f32).to_le_bytes());
        }
    }
    for &node in &basis.node_index {
        let s = *case.von_mises.get(node as usize)?;
        b.extend_from_slice(&(s as f32).to_le_bytes());
    }
    Some(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arrays are the kept vertices' rows of the case, in f32, after the whole part's maxima.
    #[test]
    fn a_load_case_is_encoded_for_the_kept_vertices() {
        let rest = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let mut basis = Basis::new(
            "mem",
            "global",
            rest,
            vec![0, 2, 3],
            vec![[0, 1, 2]],
            vec![1.0],
            &[1.0; 9],
            (0.0, 0.0),
            None,
        )
        .expect("a basis");
        let case = LoadCase {
            name: "tip".into(),
            kind: "force".into(),
            total_force: [0.0, 0.0, -1.0],
            reaction: [0.0, 0.0, 1.0],
            balance_residual: 0.0,
            max_displacement: 3.0,
            max_von_mises: 40.0,
            displacement: (0..12).map(f64::from).collect(),
            von_mises: vec![10.0, 20.0, 30.0, 40.0],
            stress: vec![0.0; 18],
        };
        let b = encode(1, 2, &basis, &case).expect("fits");
        let u32s = |at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let f32s = |at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        assert_eq!([u32s(0), u32s(4), u32s(8), u32s(12)], [4, 1, 3, 2]);
        assert_eq!(f64::from_le_bytes(b[24..32].try_into().expect("8 bytes")), 40.0);
        let u: Vec<f32> = (0..9).map(|k| f32s(LOAD_HEADER + 4 * k)).collect();
        assert_eq!(u, [0.0, 1.0, 2.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]);
        let vm: Vec<f32> = (0..3).map(|k| f32s(LOAD_HEADER + 36 + 4 * k)).collect();
        assert_eq!(vm, [10.0, 30.0, 40.0]);
        assert_eq!(b.len(), LOAD_HEADER + 16 * 3);
        // A case shorter than the basis's nodes (a file changed under the server) is refused.
        basis.node_index[2] = 4;
        assert!(encode(0, 0, &basis, &case).is_none());
    }
}
