//! Volume-of-interest switching (README, volumes of interest): one simulation per modal space of a part, the
//! one whose VOI holds the haptic point(s) active. At a switch the new space takes over the
//! state through the precomputed transfer matrix (q_new = T q_old, the mass-weighted
//! projection), and for a short window both spaces run and the force sent to the device is
//! blended from the old model's to the new one's, so the hand feels no step where the two
//! discretisations differ. Hysteresis (enter a box only well inside it, leave it only well
//! outside) keeps the choice from flickering at a border. All simulations are built up front:
//! a switch allocates nothing in the haptic thread.

use crate::basis::Basis;
use crate::haptic::{Coupling, HandInput, HandOutput, Haptics};
use crate::integrator::Scheme;
use std::sync::Arc;
use std::time::Instant;

/// How switching behaves.
#[derive(Clone, Copy, Debug)]
pub struct SwitchConfig {
    /// Hysteresis half-width, m: enter a VOI when at least this far inside its box, leave it
    /// when this far outside.
    pub margin: f64,
    /// Haptic steps over which the device force is blended from the old space to the new.
    pub blend_steps: usize,
    /// A grabbing hand counts at the vertex it holds (so a pull out of the box keeps the space
    /// that resolves the pulled point until the grab ends); off, it counts at its position.
    pub hold_grabs: bool,
}

impl Default for SwitchConfig {
    fn default() -> Self {
        SwitchConfig {
            margin: 2e-3,
            blend_steps: 100,
            hold_grabs: true,
        }
    }
}

/// Why a set of spaces cannot be switched between.
#[derive(Debug, thiserror::Error)]
pub enum SwitchError {
    /// No spaces given.
    #[error("no modal space to simulate")]
    Empty,
    /// A VOI space has no transfer matrix from another space.
    #[error("no transfer matrix from space {from:?} to {to:?}; precompute the scene again with this version of ves")]
    MissingTransfer {
        /// Source space.
        from: String,
        /// Target space.
        to: String,
    },
    /// A transfer matrix has the wrong size.
    #[error("transfer {from:?} → {to:?} has {len} values, expected {expected}")]
    BadTransfer {
        /// Source space.
        from: String,
        /// Target space.
        to: String,
        /// Values found.
        len: usize,
        /// Values expected.
        expected: usize,
    },
}

/// One space: its basis and the transfer matrices *into* it, indexed by source space.
pub struct SpaceInput {
    /// The basis (global space first).
    pub basis: Arc<Basis>,
    /// `transfers[from]`: row-major `r × r_from` (None for `from` = itself).
    pub transfers: Vec<Option<Vec<f64>>>,
}

/// Simulations of every space of a part, switched by where the hands are.
pub struct Switcher {
    sims: Vec<Haptics>,
    transfers: Vec<Vec<Option<Vec<f64>>>>,
    active: usize,
    /// (old space, steps of blending left).
    fading: Option<(usize, usize)>,
    old_out: Vec<HandOutput>,
    /// Per hand, where it acts while it holds a grab (the grabbed vertex's rest position): a
    /// held grab keeps the space that resolves the point it pulls, wherever the hand goes.
    held: Vec<Option<[f64; 3]>>,
    cfg: SwitchConfig,
    /// Switches so far.
    pub switches: u64,
    /// Time the last switch took in the haptic thread (transfer and hand hand-over), ns.
    pub last_switch_ns: u64,
    /// Longest switch so far, ns.
    pub max_switch_ns: u64,
}

impl Switcher {
    /// Builds one simulation per space (all allocation happens here).
    pub fn new(
        spaces: Vec<SpaceInput>,
        coupling: Coupling,
        dt: f64,
        scheme: Scheme,
        hands: usize,
        cfg: SwitchConfig,
    ) -> Result<Switcher, SwitchError> {
        if spaces.is_empty() {
            return Err(SwitchError::Empty);
        }
        let r: Vec<usize> = spaces.iter().map(|s| s.basis.mode_count()).collect();
        for (to, s) in spaces.iter().enumerate() {
            for from in 0..spaces.len() {
                if from == to {
                    continue;
                }
                let name = |i: usize| spaces[i].basis.space.clone();
                match s.transfers.get(from).and_then(|t| t.as_ref()) {
                    None => {
                        return Err(SwitchError::MissingTransfer {
                            from: name(from),
                            to: name(to),
                        });
                    }
                    Some(t) if t.len() != r[to] * r[from] => {
                        return Err(SwitchError::BadTransfer {
                            from: name(from),
                            to: name(to),
                            len: t.len(),
                            expected: r[to] * r[from],
                        });
                    }
                    Some(_) => {}
                }
            }
        }
        let sims = spaces
            .iter()
            .map(|s| Haptics::new(s.basis.clone(), coupling, dt, scheme, hands))
            .collect();
        Ok(Switcher {
            sims,
            transfers: spaces.into_iter().map(|s| s.transfers).collect(),
            active: 0,
            fading: None,
            old_out: vec![HandOutput::default(); hands],
            held: vec![None; hands],
            cfg,
            switches: 0,
            last_switch_ns: 0,
            max_switch_ns: 0,
        })
    }

    /// Index of the active space.
    pub fn active(&self) -> usize {
        self.active
    }

    /// The simulation of space `i`.
    pub fn sim(&self, i: usize) -> &Haptics {
        &self.sims[i]
    }

    /// Every space's simulation, global first.
    pub fn sims(&self) -> &[Haptics] {
        &self.sims
    }

    /// Mutable access to every simulation (e.g. to make the part a free body in each).
    pub fn sims_mut(&mut self) -> &mut [Haptics] {
        &mut self.sims
    }

    /// Whether the force is being blended after a switch.
    pub fn blending(&self) -> bool {
        self.fading.is_some()
    }

    /// The space the hands ask for: the current VOI while every hand stays within its box
    /// widened by the margin; otherwise the first VOI whose box shrunk by the margin holds every
    /// hand; otherwise the global space (index 0). A hand counts where it acts: at the vertex it
    /// holds while it holds a grab (pulling a rib out of its box keeps the rib's space until the
    /// grab ends), else at its position. A hand without a position (non-finite: no device
    /// there, as an unused hand of `ves view`) does not count; with none, the active space stays.
    pub fn wanted(&self, inputs: &[HandInput]) -> usize {
        let at = |k: usize, h: &HandInput| {
            let p = self
                .held
                .get(k)
                .copied()
                .flatten()
                .filter(|_| h.button && self.cfg.hold_grabs)
                .unwrap_or(h.position);
            p.iter().all(|v| v.is_finite()).then_some(p)
        };
        if !inputs.iter().enumerate().any(|(k, h)| at(k, h).is_some()) {
            return self.active;
        }
        let holds = |b: &[[f64; 3]; 2], grow: f64| {
            inputs
                .iter()
                .enumerate()
                .filter_map(|(k, h)| at(k, h))
                .all(|p| (0..3).all(|c| p[c] >= b[0][c] - grow && p[c] <= b[1][c] + grow))
        };
        // Each space's VOI is its basis's (None for the global space).
        let voi = |i: usize| self.sims[i].basis().voi;
        if let Some(b) = &voi(self.active)
            && holds(b, self.cfg.margin)
        {
            return self.active;
        }
        (0..self.sims.len())
            .find(|&i| voi(i).as_ref().is_some_and(|b| holds(b, -self.cfg.margin)))
            .unwrap_or(0)
    }

    /// One haptic step: switch if the hands ask for another space, step the active space (and
    /// the old one while blending), write the forces.
    pub fn step(&mut self, inputs: &[HandInput], outputs: &mut [HandOutput]) {
        let want = self.wanted(inputs);
        if want != self.active {
            self.switch_to(want);
        }
        self.sims[self.active].step(inputs, outputs);
        if let Some((old, left)) = self.fading {
            let n = self.old_out.len().min(inputs.len());
            self.sims[old].step(&inputs[..n], &mut self.old_out[..n]);
            // Weight of the new model rises linearly to 1 over the window.
            let w = 1.0 - left as f64 / (self.cfg.blend_steps as f64 + 1.0);
            for (o, p) in outputs.iter_mut().zip(&self.old_out[..n]) {
                for c in 0..3 {
                    o.force[c] = w * o.force[c] + (1.0 - w) * p.force[c];
                }
            }
            self.fading = (left > 1).then_some((old, left - 1));
        }
        let sim = &self.sims[self.active];
        for (k, held) in self.held.iter_mut().enumerate() {
            *held = sim.grabbed_vertex(k).map(|v| sim.basis().rest[v as usize]);
        }
    }

    /// Back to the start: every space at rest, hands let go, the global space active.
    pub fn reset(&mut self) {
        for sim in &mut self.sims {
            sim.reset();
        }
        self.active = 0;
        self.fading = None;
        self.held.fill(None);
    }

    fn switch_to(&mut self, to: usize) {
        let t0 = Instant::now();
        let from = self.active;
        let (a, b) = if from < to {
            let (l, r) = self.sims.split_at_mut(to);
            (&l[from], &mut r[0])
        } else {
            let (l, r) = self.sims.split_at_mut(from);
            (&r[0], &mut l[to])
        };
        if let Some(t) = self.transfers[to][from].as_deref() {
            b.transfer_from(a, t);
        }
        self.active = to;
        self.fading = (self.cfg.blend_steps > 0).then_some((from, self.cfg.blend_steps));
        self.switches += 1;
        self.last_switch_ns = t0.elapsed().as_nanos() as u64;
        self.max_switch_ns = self.max_switch_ns.max(self.last_switch_ns);
    }
}

/// Loads every space of a basis file with its transfer matrices, ready for [`Switcher::new`].
#[cfg(feature = "hdf5")]
pub fn load_spaces(
    path: &std::path::Path,
    modes: Option<usize>,
    surface_only: bool,
) -> Result<Vec<SpaceInput>, crate::basis::LoadError> {
    let file = ves_format::BasisReader::open(path)?;
    let names = file.space_names()?;
    let mut bases = Vec::with_capacity(names.len());
    for n in &names {
        let opts = crate::basis::LoadOptions {
            space: Some(n.clone()),
            modes,
            surface_only,
        };
        bases.push(Arc::new(crate::basis::load_space(&file, &opts)?));
    }
    let mut out = Vec::with_capacity(bases.len());
    for (to, b) in bases.iter().enumerate() {
        let space = file.space(&b.space)?;
        let mut transfers = vec![None; bases.len()];
        for (from, a) in bases.iter().enumerate() {
            if from != to {
                transfers[from] = space.transfer(&a.space, b.mode_count(), a.mode_count())?;
            }
        }
        out.push(SpaceInput {
            basis: b.clone(),
            transfers,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An unused hand (non-finite position) neither blocks a switch into a volume of interest
    /// nor forces one out; with no hand at all the active space stays. (`ves view` parks its
    /// second hand that way, and the first could never enter a VOI.)
    #[test]
    fn an_absent_hand_does_not_count() {
        let sw = two_spaces(2);
        let at = |p: [f64; 3]| HandInput {
            position: p,
            ..Default::default()
        };
        let (inside, outside, absent) = (at([0.005, 0.005, 0.0]), at([0.02, 0.02, 0.0]), at([f64::NAN; 3]));
        assert_eq!(sw.wanted(&[inside, absent]), 1);
        assert_eq!(sw.wanted(&[absent, inside]), 1);
        assert_eq!(sw.wanted(&[inside, outside]), 0);
        assert_eq!(sw.wanted(&[absent, absent]), 0, "none present: the active space stays");
    }

    fn two_spaces(hands: usize) -> Switcher {
        let global = Arc::new(crate::basis::stretch_grid(1.0, 100.0, 0.0));
        let mut local = crate::basis::stretch_grid(1.0, 100.0, 0.0);
        local.space = "voi".into();
        local.voi = Some([[0.0, 0.0, -0.01], [0.01, 0.01, 0.01]]);
        let spaces = vec![
            SpaceInput {
                basis: global,
                transfers: vec![None, Some(vec![1.0])],
            },
            SpaceInput {
                basis: Arc::new(local),
                transfers: vec![Some(vec![1.0]), None],
            },
        ];
        Switcher::new(
            spaces,
            Coupling::default(),
            1e-3,
            Scheme::Exact,
            hands,
            SwitchConfig::default(),
        )
        .unwrap()
    }

    /// A hand that grabbed inside a volume of interest keeps that space while it holds, however
    /// far it pulls out of the box; letting go returns to the global space. Before, the switch
    /// followed the hand: pulling a rib upward dropped the session to the coarse space mid-pull.
    #[test]
    fn a_held_grab_keeps_its_space_until_released() {
        let mut sw = two_spaces(1);
        let mut out = [HandOutput::default()];
        let hand = |p: [f64; 3], button| HandInput {
            position: p,
            button,
            ..Default::default()
        };
        for _ in 0..10 {
            sw.step(&[hand([0.005, 0.005, 0.0], true)], &mut out);
        }
        assert_eq!(sw.active(), 1, "grabbed inside the box");
        let v = sw.sim(1).grabbed_vertex(0).expect("a grab");
        // Pulled 5 cm out of a 1 cm box, button held: the same space, the same vertex.
        for _ in 0..50 {
            sw.step(&[hand([0.05, 0.05, 0.0], true)], &mut out);
            assert_eq!(sw.active(), 1);
        }
        assert_eq!(sw.sim(1).grabbed_vertex(0), Some(v));
        assert!(
            out[0].force.iter().any(|f| f.abs() > 1.0),
            "still pulling: {:?}",
            out[0].force
        );
        // Let go out there: back to the global space at the next step.
        sw.step(&[hand([0.05, 0.05, 0.0], false)], &mut out);
        sw.step(&[hand([0.05, 0.05, 0.0], false)], &mut out);
        assert_eq!(sw.active(), 0);
        // Without a grab the hand's own position rules: out of the box is the global space.
        sw.step(&[hand([0.05, 0.05, 0.0], true)], &mut out);
        assert_eq!(sw.active(), 0);
    }

    /// Reset brings every space to rest, lets go of the hands and makes the global space
    /// active, whatever happened before.
    #[test]
    fn reset_returns_to_rest() {
        let mut sw = two_spaces(1);
        let mut out = [HandOutput::default()];
        let pull = HandInput {
            position: [0.03, 0.005, 0.0],
            button: true,
            ..Default::default()
        };
        let grab = HandInput {
            position: [0.005, 0.005, 0.0],
            button: true,
            ..Default::default()
        };
        sw.step(&[grab], &mut out);
        for _ in 0..30 {
            sw.step(&[pull], &mut out);
        }
        assert_eq!(sw.active(), 1);
        assert!(sw.sim(1).state().q[0].abs() > 0.0);
        sw.reset();
        assert_eq!(sw.active(), 0);
        for i in 0..2 {
            assert!(
                sw.sim(i)
                    .state()
                    .q
                    .iter()
                    .chain(&sw.sim(i).state().v)
                    .all(|&x| x == 0.0)
            );
            assert_eq!(sw.sim(i).grabbed_vertex(0), None);
        }
    }
}
