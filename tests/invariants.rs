//! Invariants of the assembled system on real meshes.

use ves_pipeline::linsolve::sym_matvec;
use ves_pipeline::problem::discretize;
use ves_pipeline::rigid_motions::rigid_motions;
use ves_tests::load_case;

#[test]
fn stiffness_annihilates_rigid_motions_of_a_free_body() {
    let scene = load_case("bracket");
    let d = discretize(&scene, None).expect("bracket discretizes");
    assert!(d.dofs.fixed.is_empty());
    assert_eq!(d.rigid, 6);
    let n = d.dofs.free_count();
    let mut y = vec![0.0; n];
    let kmax = d.system.k.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let c = d.system.mass.center;
    for (r, u) in rigid_motions(&d.mesh.nodes, c, d.mesh.diameter()).iter().enumerate() {
        sym_matvec(&d.system.pattern, &d.system.k, u, &mut y);
        let worst = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let unorm = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(worst < 1e-10 * kmax * unorm, "rigid motion {r}: |K u| = {worst:e}");
    }
}

#[test]
fn tet10_mid_edge_nodes_follow_gmsh_edge_order() {
    // The cantilever is a box: every edge is straight, so each mid-edge node must sit at the
    // midpoint of the edge our shape functions assign to it.
    let scene = load_case("cantilever");
    let d = discretize(&scene, None).expect("cantilever discretizes");
    assert_eq!(d.mesh.kind, ves_pipeline::fem::element::Kind::Tet10);
    assert!(d.mesh.vertex_count < d.mesh.nodes.len());
    for e in 0..d.mesh.tet_count() {
        let t = d.mesh.tet(e);
        assert!(
            t[..4].iter().all(|&v| (v as usize) < d.mesh.vertex_count),
            "corners are numbered first"
        );
        assert!(t[4..].iter().all(|&v| (v as usize) >= d.mesh.vertex_count));
        for (k, (a, b)) in ves_pipeline::fem::element::tet10::EDGES.iter().enumerate() {
            let (pa, pb, pm) = (
                d.mesh.nodes[t[*a] as usize],
                d.mesh.nodes[t[*b] as usize],
                d.mesh.nodes[t[4 + k] as usize],
            );
            for c in 0..3 {
                assert!((pm[c] - (pa[c] + pb[c]) / 2.0).abs() < 1e-9, "tet {e} edge {k}");
            }
        }
    }
}

#[test]
fn surface_triangles_close_the_part_and_face_outwards() {
    // Σ area·n = 0 for a closed surface, and the divergence theorem gives the volume:
    // V = Σ (1/3) x_c · n A over outward faces.
    let scene = load_case("bracket");
    let d = discretize(&scene, None).expect("bracket discretizes");
    let mut sum = [0.0f64; 3];
    let mut vol = 0.0;
    for f in &d.mesh.surface {
        let [a, b, c] = f.map(|i| d.mesh.nodes[i as usize]);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n2 = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        for k in 0..3 {
            sum[k] += n2[k] / 2.0;
            vol += (a[k] + b[k] + c[k]) / 3.0 * n2[k] / 2.0 / 3.0;
        }
    }
    let tets: f64 = d.system.mass.mass / scene.material.density;
    assert!(sum.iter().all(|s| s.abs() < 1e-12), "open surface: {sum:?}");
    assert!((vol - tets).abs() < 1e-9 * tets, "outward volume {vol} vs tets {tets}");
}
