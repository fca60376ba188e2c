//! Static correction on the ribplate through the runtime: a hand grabs each rib tip (the
//! scene's probes) and pulls sideways until the part settles; the displacement the haptic step
//! reports for the held vertex's contact patch (30 modes + the static correction Gᵢ − Φ̄ᵢΛ⁻¹Φ̄ᵢᵀ
//! from the stored compliance block) must equal the full static solve K u = Wᵀ F of the same mesh
//! for the force the runtime applied, spread over the patch with the file's weights W and read
//! back with them (Σ wₐ uₐ). The full solve is independent of the factor that made the stored blocks:
//! K is assembled from the basis file's own mesh and supports and solved by faer's sparse LU.
//! In each rib's refined VOI space the same holds against the refined mesh's full solve, where
//! the coarse space's discretisation error is also measured.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use ves_pipeline::problem::Discretized;
use ves_pipeline::scene::{CorrectionRegion, Scene, StaticCorrection};
use ves_runtime::Basis;
use ves_runtime::haptic::{Coupling, HandInput, HandOutput, Haptics};
use ves_runtime::integrator::Scheme;
use ves_tests::case_path;

/// The ribplate with its four VOIs, 30 modes and the static correction, precomputed once for
/// both tests (global space = the plain ribplate's mesh, 8 mm).
fn basis_file() -> &'static Path {
    static FILE: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &FILE
        .get_or_init(|| {
            let mut scene = Scene::load(&case_path("ribplate/scene-voi.toml")).expect("scene");
            scene.modes.count = 30;
            scene.static_correction = Some(StaticCorrection {
                region: CorrectionRegion::Surface,
            });
            let dir = tempfile::tempdir().expect("temp dir");
            let path = dir.path().join("ribplate-voi.h5");
            let t = std::time::Instant::now();
            ves_pipeline::precompute::run(&scene, &path, ves_pipeline::modes::SolverChoice::Auto)
                .unwrap_or_else(|e| panic!("{e:#}"));
            println!(
                "precompute of 5 spaces with compliance: {:.1} s",
                t.elapsed().as_secs_f64()
            );
            (dir, path)
        })
        .1
}

/// One space of the file: the runtime's basis and an independent full solver of its mesh.
struct Space {
    basis: Arc<Basis>,
    d: Discretized,
    contact: ves_format::Contact,
    lu: faer::sparse::linalg::solvers::Lu<usize, f64>,
}

fn space(name: &str) -> Space {
    let path = basis_file();
    let basis = ves_runtime::switching::load_spaces(path, None, true)
        .expect("load")
        .into_iter()
        .map(|s| s.basis)
        .find(|b| b.space == name)
        .expect("space in the file");
    assert!(
        basis.compliance.is_some(),
        "{name}: compliance blocks stored and loaded"
    );
    // The space's own mesh, supports and material, read back from the file and assembled.
    let file = ves_format::BasisReader::open(path).expect("open");
    let m = file.material().expect("material");
    let s = file.space(name).expect("space");
    let n = s.node_count;
    let surface = s.surface_triangles().expect("surface");
    let mesh = ves_pipeline::mesh::Mesh {
        nodes: s.nodes(n).expect("nodes"),
        vertex_count: s.vertex_count,
        kind: s.kind,
        tets: s.tets().expect("tets"),
        surface_faces: vec![0; surface.len()],
        surface,
    };
    let mut mask = vec![false; 3 * n];
    for f in s.fixed_dofs().expect("fixed") {
        mask[f as usize] = true;
    }
    let dofs = ves_pipeline::fem::Dofs::from_mask(&mask);
    let contact = s
        .contact()
        .expect("contact")
        .expect("the default contact patches are stored");
    assert!(contact.radius > 0.0);
    let d = Discretized::assemble(mesh, dofs, (&m).into()).expect("assemble");
    // Full K from its stored lower triangle, then a general sparse LU (not the Cholesky the
    // pipeline factors K with to make the blocks).
    let a = &d.system;
    let nf = d.dofs.free_count();
    let mut triplets = Vec::with_capacity(2 * a.k.len());
    for col in 0..nf {
        let range = a.pattern.col_ptr()[col]..a.pattern.col_ptr()[col + 1];
        for (&row, &v) in a.pattern.row_idx()[range.clone()].iter().zip(&a.k[range]) {
            triplets.push(faer::sparse::Triplet::new(row, col, v));
            if row != col {
                triplets.push(faer::sparse::Triplet::new(col, row, v));
            }
        }
    }
    let k = faer::sparse::SparseColMat::<usize, f64>::try_new_from_triplets(nf, nf, &triplets).expect("K");
    let lu = k.sp_lu().expect("K is regular with the supports");
    Space { basis, d, contact, lu }
}

impl Space {
    /// Kept surface vertex nearest `at` (it carries a compliance block).
    fn vertex_near(&self, at: [f64; 3]) -> usize {
        let b = &self.basis;
        let d = |v: u32| (0..3).map(|c| (b.rest[v as usize][c] - at[c]).powi(2)).sum::<f64>();
        b.surface_vertices
            .iter()
            .copied()
            .min_by(|&x, &y| d(x).total_cmp(&d(y)))
            .expect("surface") as usize
    }

    /// Full static solve: displacement of kept vertex `i`'s contact patch under force `f` (N)
    /// spread over it.
    fn exact(&self, i: usize, f: [f64; 3]) -> [f64; 3] {
        use faer::linalg::solvers::SolveCore;
        let node = self.basis.node_index[i];
        let k = self
            .contact
            .centres
            .binary_search(&node)
            .expect("a surface vertex has a patch");
        let (nodes, weights) = self.contact.patch(k);
        assert!(nodes.len() > 1, "a rib tip's patch spreads over several nodes");
        let free = |a: u32, c: usize| self.d.dofs.free_of[3 * a as usize + c];
        let mut x = faer::Mat::<f64>::zeros(self.d.dofs.free_count(), 1);
        for (&a, &w) in nodes.iter().zip(weights) {
            for (c, fc) in f.iter().enumerate() {
                if free(a, c) != u32::MAX {
                    x[(free(a, c) as usize, 0)] += w * fc;
                }
            }
        }
        self.lu.solve_in_place_with_conj(faer::Conj::No, x.as_mut());
        let mut u = [0.0; 3];
        for (&a, &w) in nodes.iter().zip(weights) {
            for (c, uc) in u.iter_mut().enumerate() {
                if free(a, c) != u32::MAX {
                    *uc += w * x[(free(a, c) as usize, 0)];
                }
            }
        }
        u
    }

    /// The runtime's answer: grab vertex `i`, pull the hand 0.2 mm along `dir` and hold until
    /// the reported vertex position stops moving. Returns (displacement the haptic step reports
    /// for the held vertex, force on the part), m and N.
    fn settled(&self, i: usize, dir: [f64; 3], correction: bool) -> ([f64; 3], [f64; 3]) {
        let coupling = Coupling {
            stiffness: 1e4,
            damping: 20.0,
            max_force: 1e3,
        };
        let mut h = Haptics::new(self.basis.clone(), coupling, 1e-3, Scheme::Exact, 1);
        h.set_static_correction(correction);
        let rest = self.basis.rest[i];
        let mut out = [HandOutput::default()];
        let hand = |pull: f64| {
            [HandInput {
                position: std::array::from_fn(|c| rest[c] + pull * dir[c]),
                velocity: [0.0; 3],
                button: true,
            }]
        };
        h.step(&hand(0.0), &mut out); // the grab, on the vertex itself
        assert_eq!(out[0].vertex as usize, i, "the hand holds the probe's vertex");
        let mut last = [f64::NAN; 3];
        for k in 1..=200_000 {
            h.step(&hand(2e-4), &mut out);
            let u: [f64; 3] = std::array::from_fn(|c| out[0].vertex_position[c] - rest[c]);
            if k % 1000 == 0 {
                let change = norm(std::array::from_fn(|c| u[c] - last[c]));
                if change < 1e-13 * norm(u) {
                    assert_eq!(out[0].vertex as usize, i);
                    return (u, out[0].force.map(|v| -v));
                }
                last = u;
            }
        }
        panic!("{}: the held vertex never settled", self.basis.space);
    }
}

fn norm(u: [f64; 3]) -> f64 {
    u.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn rel(u: [f64; 3], exact: [f64; 3]) -> f64 {
    norm(std::array::from_fn(|c| u[c] - exact[c])) / norm(exact)
}

fn probes() -> Vec<([f64; 3], [f64; 3])> {
    let scene = Scene::load(&case_path("ribplate/scene-voi.toml")).expect("scene");
    assert_eq!(scene.probes.len(), 4, "one probe per rib");
    scene.probes.iter().map(|p| (p.at, p.force)).collect()
}

/// The stored blocks are (K⁻¹)ᵢᵢ computed in f64 and the runtime adds Gᵢᵢ − ΦᵢΛ⁻¹Φᵢᵀ to a modal
/// part ΦᵢΛ⁻¹ΦᵢᵀF built from the same f32 rows, so the two cancel to rounding: the corrected
/// static response is exact up to the two solvers' rounding (measured 5.6e-13 to 1.0e-11).
const EXACT: f64 = 1e-9;

#[test]
fn rib_tip_displacement_through_the_runtime_is_the_full_solve_with_correction() {
    let _serial = ves_tests::serial();
    let global = space("global");
    for (k, (at, dir)) in probes().into_iter().enumerate() {
        let i = global.vertex_near(at);
        let (u, f) = global.settled(i, dir, true);
        let e_corr = rel(u, global.exact(i, f));
        let (u_modal, f_modal) = global.settled(i, dir, false);
        let e_modal = rel(u_modal, global.exact(i, f_modal));
        println!(
            "rib {}: force {:.3} N, |u| {:.4e} m; 30 modes alone error {:.2} %, with static correction {e_corr:.1e}",
            k + 1,
            norm(f),
            norm(u),
            100.0 * e_modal
        );
        assert!(norm(f) > 0.1, "the hand loads the rib: {f:?}");
        assert!(e_corr < EXACT, "rib {}: corrected error {e_corr}", k + 1);
        assert!(e_modal > 1e-3, "30 modes alone should miss some compliance: {e_modal}");
    }
}

/// Each rib's VOI space: the runtime's corrected tip response equals the full solve on the
/// refined mesh; the coarse global space, even corrected, carries its discretisation error
/// against it (the refined mesh is softer at the tip).
#[test]
fn rib_tip_in_its_voi_space_through_the_runtime_against_the_refined_full_solve() {
    let _serial = ves_tests::serial();
    let global = space("global");
    for (k, (at, dir)) in probes().into_iter().enumerate() {
        let name = format!("rib{}", k + 1);
        let refined = space(&name);
        let i = refined.vertex_near(at);
        let (u, f) = refined.settled(i, dir, true);
        let fine = refined.exact(i, f);
        let e_corr = rel(u, fine);
        let ig = global.vertex_near(at);
        let (rf, rg) = (refined.basis.rest[i], global.basis.rest[ig]);
        let gap = norm(std::array::from_fn(|c| rf[c] - rg[c]));
        let coarse = global.exact(ig, f);
        println!(
            "{name}: force {:.3} N, refined |u| {:.4e} m; VOI space corrected {e_corr:.1e}; \
             coarse full solve {:.2} % off (tip vertices {:.2} mm apart)",
            norm(f),
            norm(fine),
            100.0 * rel(coarse, fine),
            1e3 * gap
        );
        assert!(e_corr < EXACT, "{name}: corrected error {e_corr}");
        assert!(norm(coarse) < norm(fine), "{name}: refinement must soften the tip");
    }
}
