//! The VES modal-basis file, version 1 (HDF5; docs/format.md), defined once: its names
//! ([`names`]), one guarded reader ([`read`]) and one writer ([`write`]), and the XDMF sidecar
//! that shows a basis to ParaView ([`xdmf`]).
//!
//! Permissive (MIT OR Apache-2.0): the runtime reads with it, the pipeline writes with it.

pub mod checks;
pub mod element;
#[cfg(feature = "hdf5")]
pub mod file;
pub mod identifier;
pub mod names;
#[cfg(feature = "hdf5")]
pub mod read;
#[cfg(feature = "hdf5")]
pub mod strings;
#[cfg(feature = "hdf5")]
pub mod write;
pub mod xdmf;

pub use element::ElementKind;
pub use identifier::{IdentifierError, check_identifier};
pub use names::{FORMAT, VERSION};
#[cfg(feature = "hdf5")]
pub use read::{BasisReader, Nonlinear, ReadError, SpaceReader, guarded};
#[cfg(feature = "hdf5")]
pub use write::{FileData, LoadData, NonlinearData, PeakRecord, SpaceData, WriteError, write_file};

/// An input that cannot be used: the file (or other input) it came from and what is wrong and
/// what to change, shown as `path: message`. The one error of the readers of files (a basis, a
/// device script) in the format crate and the runtime.
#[derive(Debug, Clone, thiserror::Error)]
// The path as given (a file name may hold terminal escapes): shown, not obeyed.
#[error("{}: {message}", identifier::escape_for_terminal(path))]
pub struct InputError {
    /// The input.
    pub path: String,
    /// What is wrong and what to do.
    pub message: String,
}

/// Material constants and Rayleigh damping (`/material`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Rayleigh α, 1/s.
    pub alpha: f64,
    /// Rayleigh β, s.
    pub beta: f64,
    /// Yield strength, Pa (optional attribute): the runtime's safety factor.
    pub yield_strength: Option<f64>,
}

/// Mass properties of a part that can move as a whole (`rigid/`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidProperties {
    /// kg.
    pub mass: f64,
    /// m.
    pub center: [f64; 3],
    /// kg·m², about the centre of mass.
    pub inertia: [[f64; 3]; 3],
    /// The rigid motions the supports leave free: all six for a free body.
    pub free: FreeMotions,
}

/// The rigid motions a part's supports leave free, as twists about its centre of mass: row
/// `(v, ω)` moves a material point at `x` with velocity `v + ω × (x − c)`. Any basis of the
/// free motions serves (the runtime makes it orthonormal in kinetic energy). A free body has
/// all six; a shaft in two bearings one (its turn about the axis); a plate held only out of
/// plane three.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FreeMotions {
    count: usize,
    twists: [[f64; 6]; 6],
}

impl FreeMotions {
    /// All six: a free body (the identity twists).
    pub fn all() -> FreeMotions {
        FreeMotions {
            count: 6,
            twists: std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 })),
        }
    }

    /// These twists (at most six, each finite); `None` otherwise.
    pub fn new(twists: &[[f64; 6]]) -> Option<FreeMotions> {
        if twists.len() > 6 || twists.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        let mut all = [[0.0; 6]; 6];
        all[..twists.len()].copy_from_slice(twists);
        Some(FreeMotions {
            count: twists.len(),
            twists: all,
        })
    }

    /// How many.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The twists `(v, ω)` about the centre of mass.
    pub fn twists(&self) -> &[[f64; 6]] {
        &self.twists[..self.count]
    }

    /// Whether every rigid motion is free (a free body).
    pub fn is_all(&self) -> bool {
        self.count == 6
    }

    /// The same motions as twists about `to`, these being about `from`: a twist (v, ω) moves
    /// the point `to` with v + ω × (to − from).
    pub fn moved(&self, from: [f64; 3], to: [f64; 3]) -> FreeMotions {
        let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
        let mut out = *self;
        for t in &mut out.twists[..self.count] {
            let w = [t[3], t[4], t[5]];
            t[0] += w[1] * d[2] - w[2] * d[1];
            t[1] += w[2] * d[0] - w[0] * d[2];
            t[2] += w[0] * d[1] - w[1] * d[0];
        }
        out
    }
}

impl Default for FreeMotions {
    fn default() -> FreeMotions {
        FreeMotions::all()
    }
}

/// A 3×3 static compliance block (K⁻¹)ᵢᵢ, m/N.
pub type Block3 = [[f64; 3]; 3];

/// Static compliance as stored: node indices and one block per node.
pub type Compliance = (Vec<u32>, Vec<Block3>);

/// What a hand feels wrong at surface vertices (`felt/`), along each vertex's outward normal,
/// for its contact patch there: the share of the exact compliance the stored modes miss and the
/// mesh's own relative error of that exact compliance. With the static correction stored the
/// truncation is 0 (the runtime adds the missing part at any mode count) and every vertex a
/// hand can touch is listed; without it, only the sampled points.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FeltErrors {
    /// The modes the truncation was measured with (all the space's).
    pub modes: u32,
    /// Corner vertices, strictly ascending.
    pub nodes: Vec<u32>,
    /// The modes' share missed, in [0, 1], parallel to `nodes`.
    pub truncation: Vec<f64>,
    /// The mesh's relative error, finite and ≥ 0, parallel to `nodes`.
    pub mesh_error: Vec<f64>,
}

impl FeltErrors {
    /// What a hand feels wrong in all at entry k: a + e − a·e (both make the part too stiff).
    pub fn total(&self, k: usize) -> f64 {
        let (a, e) = (self.truncation[k], self.mesh_error[k]);
        a + e - a * e
    }
}

/// The hand's contact patches (`contact/`): for each surface vertex (centre), the nodes its force
/// is spread over and their weights (summing to 1). The runtime applies a hand's force F at
/// centre k as wₐ F on each node a and reads the displacement Σ wₐ uₐ; the compliance blocks,
/// when stored, are Wₖ K⁻¹ Wₖᵀ for these patches.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Contact {
    /// Patch radius, m.
    pub radius: f64,
    /// The centres (corner vertices), ascending.
    pub centres: Vec<u32>,
    /// `nodes[offsets[k]..offsets[k + 1]]` is centre k's patch; `centres.len() + 1` entries.
    pub offsets: Vec<u32>,
    /// Node indices (corner vertices and mid-edge nodes).
    pub nodes: Vec<u32>,
    /// Weights, parallel to `nodes`.
    pub weights: Vec<f64>,
}

impl Contact {
    /// Centre k's nodes and weights.
    pub fn patch(&self, k: usize) -> (&[u32], &[f64]) {
        let (lo, hi) = (self.offsets[k] as usize, self.offsets[k + 1] as usize);
        (&self.nodes[lo..hi], &self.weights[lo..hi])
    }

    /// Checks what a reader relies on: offsets from 0 to the number of nodes, ascending centres
    /// that are corner vertices (below `vertex_count`), node indices below `node_count`, and per
    /// patch finite weights summing to 1, each within [`Contact::weight_range`] of its node.
    pub fn check(&self, kind: crate::ElementKind, vertex_count: usize, node_count: usize) -> Result<(), ContactError> {
        if !(self.radius.is_finite() && self.radius >= 0.0) {
            return Err(ContactError::Radius { radius: self.radius });
        }
        if self.offsets.len() != self.centres.len() + 1
            || self.offsets.first() != Some(&0)
            || self.offsets.last().map(|&o| o as usize) != Some(self.nodes.len())
            || self.offsets.windows(2).any(|w| w[0] > w[1])
        {
            return Err(ContactError::Offsets {
                nodes: self.nodes.len(),
                patches: self.centres.len(),
            });
        }
        if self.weights.len() != self.nodes.len() {
            return Err(ContactError::Weights {
                weights: self.weights.len(),
                nodes: self.nodes.len(),
            });
        }
        if self.centres.windows(2).any(|w| w[0] >= w[1]) {
            return Err(ContactError::Centres);
        }
        if let Some(&centre) = self.centres.iter().find(|&&v| v as usize >= vertex_count) {
            return Err(ContactError::NotCorner { centre, vertex_count });
        }
        if let Some(&node) = self.nodes.iter().find(|&&v| v as usize >= node_count) {
            return Err(ContactError::Node { node, node_count });
        }
        for k in 0..self.centres.len() {
            let (nodes, w) = self.patch(k);
            for (&a, &x) in nodes.iter().zip(w) {
                let (lo, hi) = Contact::weight_range(kind, a as usize >= vertex_count);
                if !(x >= lo - WEIGHT_TOLERANCE && x <= hi + WEIGHT_TOLERANCE) {
                    return Err(ContactError::WeightRange {
                        weight: x,
                        node: a,
                        patch: k,
                        centre: self.centres[k],
                        range: (lo, hi),
                    });
                }
            }
            let sum: f64 = w.iter().sum();
            if (sum - 1.0).abs() > WEIGHT_TOLERANCE {
                return Err(ContactError::Sum { patch: k, sum });
            }
        }
        Ok(())
    }

    /// The range of a contact weight wₐ = ∫ Nₐ p dA / ∫ p dA: with a pressure p ≥ 0 it is an
    /// average of the shape function Nₐ over the patch, so it lies within Nₐ's range on a
    /// surface triangle: [0, 1] for a 3-node triangle's corners and a 6-node triangle's mid-edge
    /// nodes (4 L₁L₂), [−1/8, 1] for a 6-node triangle's corners (L(2L − 1), least at L = 1/4).
    /// The runtime multiplies the hand's force by each weight: a weight of 1e9 in a patch that
    /// still sums to 1 makes a 12.5 mm pull feel 6e-10 N instead of 6.3 N.
    pub fn weight_range(kind: crate::ElementKind, mid_edge: bool) -> (f64, f64) {
        match kind {
            crate::ElementKind::Tet10 if !mid_edge => (-0.125, 1.0),
            _ => (0.0, 1.0),
        }
    }
}

/// A contact group a reader cannot rely on: what is wrong with it (the caller names the file).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ContactError {
    /// The radius is not a length.
    #[error("radius {radius} is not a length ≥ 0")]
    Radius {
        /// The radius stored, m.
        radius: f64,
    },
    /// The offsets do not split the nodes into one run per centre.
    #[error("offsets do not split {nodes} nodes into {patches} patches")]
    Offsets {
        /// Nodes stored.
        nodes: usize,
        /// Centres stored.
        patches: usize,
    },
    /// Not one weight per node.
    #[error("{weights} weights for {nodes} nodes")]
    Weights {
        /// Weights stored.
        weights: usize,
        /// Nodes stored.
        nodes: usize,
    },
    /// The centres are not strictly ascending.
    #[error("centres are not ascending")]
    Centres,
    /// A centre that is not a corner vertex.
    #[error("centre {centre} is not a corner vertex (of {vertex_count})")]
    NotCorner {
        /// The centre.
        centre: u32,
        /// Corner vertices of the space.
        vertex_count: usize,
    },
    /// A node index beyond the space's nodes.
    #[error("node {node} of {node_count}")]
    Node {
        /// The index.
        node: u32,
        /// Nodes of the space.
        node_count: usize,
    },
    /// A weight outside its node's shape-function range ([`Contact::weight_range`]).
    #[error(
        "weight {weight:e} of node {node} in patch {patch} (centre {centre}) is outside [{}, {}]: a weight is the \
         node's shape function averaged over the patch's pressure", .range.0, .range.1
    )]
    WeightRange {
        /// The weight.
        weight: f64,
        /// Its node.
        node: u32,
        /// The patch.
        patch: usize,
        /// The patch's centre.
        centre: u32,
        /// The range allowed.
        range: (f64, f64),
    },
    /// A patch whose weights do not sum to 1.
    #[error("the weights of patch {patch} sum to {sum}, not 1")]
    Sum {
        /// The patch.
        patch: usize,
        /// The sum.
        sum: f64,
    },
}

/// Rounding allowed on a contact weight's range and on a patch's sum (the integration's rounding
/// is far below it).
pub const WEIGHT_TOLERANCE: f64 = 1e-6;

#[cfg(test)]
mod contact_tests {
    use super::Contact;
    use crate::ElementKind::{Tet4, Tet10};

    /// A damage and a word its refusal must contain.
    type Damage = (&'static str, fn(&mut Contact));

    /// Two patches of a 10-node mesh of 4 corner vertices and 6 nodes: a corner's share may be
    /// negative (down to −1/8), a mid-edge node's may not.
    fn good() -> Contact {
        Contact {
            radius: 0.005,
            centres: vec![0, 2],
            offsets: vec![0, 3, 4],
            nodes: vec![0, 1, 5, 2],
            weights: vec![0.625, -0.125, 0.5, 1.0],
        }
    }

    /// What a reader relies on is checked: each damage alone is refused, naming what is wrong.
    #[test]
    fn a_damaged_contact_group_is_refused() {
        assert_eq!(good().check(Tet10, 4, 6), Ok(()));
        let cases: [Damage; 11] = [
            ("node 6 of 6", |c| c.nodes[2] = 6),
            ("not a corner vertex", |c| c.centres[1] = 4),
            ("offsets", |c| c.offsets = vec![0, 4, 3]),
            ("offsets", |c| {
                c.offsets.pop();
            }),
            ("weights for", |c| c.weights.truncate(3)),
            ("sum to", |c| c.weights[0] = 0.7),
            ("not ascending", |c| c.centres = vec![2, 0]),
            ("radius", |c| c.radius = f64::NAN),
            // Issue 40: ±1e9 summing to 1 divided the felt force by 1e10.
            ("outside [-0.125, 1]", |c| {
                c.weights[0] += 1e9;
                c.weights[1] -= 1e9;
            }),
            // A mid-edge node's shape function 4 L₁L₂ is never negative.
            ("outside [0, 1]", |c| {
                c.weights[2] = -0.125;
                c.weights[1] = 0.5;
            }),
            ("outside", |c| c.weights[3] = f64::INFINITY),
        ];
        for (says, damage) in cases {
            let mut c = good();
            damage(&mut c);
            let e = c.check(Tet10, 4, 6).expect_err(says).to_string();
            assert!(e.contains(says), "{e:?} should say {says:?}");
        }
        // The sum alone, as the check was, lets the ±1e9 patch through.
        let mut c = good();
        c.weights[0] += 1e9;
        c.weights[1] -= 1e9;
        assert!((c.weights[..3].iter().sum::<f64>() - 1.0).abs() < 1e-6);
        // With 4-node tets every node is a corner of a 3-node triangle: no share is negative.
        let e = good().check(Tet4, 6, 6).unwrap_err().to_string();
        assert!(e.contains("outside [0, 1]"), "{e}");
        let mut rounded = good();
        rounded.weights[3] = 1.0 + 1e-9;
        assert_eq!(rounded.check(Tet10, 4, 6), Ok(()), "rounding is allowed");
    }
}

#[cfg(test)]
mod free_motion_tests {
    use super::FreeMotions;

    /// A turn about the axis through a along z, given about the origin, moved to c: the same
    /// turn, its point c moving with ω × (c − a).
    #[test]
    fn a_turn_moved_to_another_point_is_the_same_turn() {
        let (a, c) = ([1.0, 2.0, 0.0], [0.5, -1.0, 3.0]);
        // About the origin: v = ω × (0 − a) with ω = e_z.
        let at_origin = FreeMotions::new(&[[a[1], -a[0], 0.0, 0.0, 0.0, 1.0]]).expect("one twist");
        let moved = at_origin.moved([0.0; 3], c);
        let want = [-(c[1] - a[1]), c[0] - a[0], 0.0, 0.0, 0.0, 1.0];
        assert_eq!(moved.twists(), &[want]);
    }
}
