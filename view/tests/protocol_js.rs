//! The viewer's binary protocol across its two languages: messages encoded here by
//! `view::protocol` are decoded by the page's own `web/src/protocol.js` under Node
//! (`web/test/decode.mjs`), and every decoded value must be the one encoded. The layout
//! constants of both sides must agree, and a message of another version, with a foreign magic
//! or cut short must be refused by the page with a reason.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use ves_format::read::LoadCase;
use ves_runtime::Basis;
use ves_view::protocol::{self, FrameHeader, Kind};

/// A folder of its own under the system's temporary folder, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> Scratch {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("ves-protocol-js-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a scratch folder");
        Scratch(dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Three vertices (node 1 of the file is not a corner vertex: node_index skips it), one
/// triangle on CAD face 5, one mode; values chosen exact in f32.
fn basis() -> Basis {
    let rest = vec![[0.0, 0.0, 0.0], [1.25, 0.0, -0.5], [0.0, 0.75, 2.0]];
    let rows: Vec<f64> = (0..9).map(|k| f64::from(k) * 0.25 - 1.0).collect();
    let mut b = Basis::new(
        "mem",
        "global",
        rest,
        vec![0, 2, 3],
        vec![[0, 1, 2]],
        vec![(2.0 * std::f64::consts::PI * 40.0).powi(2)],
        &rows,
        (0.0, 0.0),
        None,
    )
    .expect("a basis");
    b.fixed = vec![7, 0, 4];
    b.surface_faces = Some(vec![5]);
    b
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap_or_else(|| panic!("not a number: {x}")))
        .collect()
}

fn f32s(v: &Value) -> Vec<f32> {
    f64s(v).into_iter().map(|x| x as f32).collect()
}

fn u64s(v: &Value) -> Vec<u64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_u64().unwrap_or_else(|| panic!("not an integer: {x}")))
        .collect()
}

/// Runs the page's decoder on `messages` (name, bytes); returns its JSON.
fn decode_in_node(messages: &[(&str, Vec<u8>)]) -> Value {
    let scratch = Scratch::new();
    let files: Vec<PathBuf> = messages
        .iter()
        .map(|(name, bytes)| {
            let path = scratch.0.join(format!("{name}.bin"));
            std::fs::write(&path, bytes).expect("write a message");
            path
        })
        .collect();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("web/test/decode.mjs");
    let out = Command::new("node")
        .arg(&script)
        .args(&files)
        .output()
        .expect("node runs (scripts/setup installs Node.js)");
    assert!(
        out.status.success(),
        "node {}: {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object from decode.mjs")
}

#[test]
fn the_page_decodes_what_the_server_encodes() {
    let basis = basis();
    let pose = [0.5, -0.25, 2.0, 0.6, 0.0, 0.8, 0.0];
    let header = FrameHeader {
        space: 1,
        seq: 4_000_000_000,
        alarm: true,
        hand_seq: [17, 0xffff_fffe],
        time: 12.375,
        pose,
        von_mises_max: Some((2.5e6, 2)),
    };
    let u = [1.5e-6f32, -2.0, 0.125, 3.0, 0.0, -7.5e-3, 0.5, 0.25, -0.125];
    let mut frame = Vec::new();
    protocol::frame(&mut frame, &header, &u, true);
    let held = FrameHeader {
        space: 0,
        seq: 1,
        alarm: false,
        hand_seq: [0, 0],
        time: 0.0,
        pose: [0.0; 7],
        von_mises_max: None,
    };
    let mut frame_held = Vec::new();
    protocol::frame(&mut frame_held, &held, &u[..6], false);
    let (vm, p1) = ([1.0e6f32, 2.5, 0.0], [-3.0e5f32, 0.5, 8.0]);
    let mut stress = Vec::new();
    protocol::stress_frame(&mut stress, 2, 99, &vm, &p1);
    let case = LoadCase {
        name: "tip".into(),
        kind: "force".into(),
        total_force: [0.0, 0.0, -1.0],
        reaction: [0.0, 0.0, 1.0],
        balance_residual: 0.0,
        max_displacement: 1.5e-3,
        max_von_mises: 2.31e7,
        displacement: (0..12).map(|k| f64::from(k) * 0.5).collect(),
        von_mises: vec![10.0, 20.0, 30.0, 40.0],
        stress: vec![0.0; 18],
        peak: None,
        regular_peak: None,
    };
    let mut no_faces = basis.clone();
    no_faces.surface_faces = None;
    let messages = [
        ("mesh", protocol::mesh(3, &basis)),
        ("mesh_no_faces", protocol::mesh(0, &no_faces)),
        ("frame", frame.clone()),
        ("frame_held", frame_held),
        ("stress", stress),
        ("mode", protocol::mode(1, &basis, 0).expect("mode 0")),
        ("load", protocol::load_case(2, 5, &basis, &case).expect("the case fits")),
    ];
    let got = decode_in_node(&messages);
    let m = &got["messages"];

    // Kind 0: the surface, its supports and its CAD faces.
    let mesh = &m[0];
    assert_eq!(mesh["kind"], Kind::Mesh as u32, "{mesh}");
    assert_eq!((mesh["space"].as_u64(), mesh["vertices"].as_u64()), (Some(3), Some(3)));
    let rest: Vec<f32> = basis.rest.iter().flatten().map(|&x| x as f32).collect();
    assert_eq!(f32s(&mesh["rest"]), rest);
    assert_eq!(u64s(&mesh["triangles"]), [0, 1, 2]);
    assert_eq!(u64s(&mesh["fixed"]), [7, 0, 4]);
    assert_eq!(u64s(&mesh["faces"]), [5]);
    assert_eq!(m[1]["faces"], Value::Null, "no faces in the basis: none decoded");
    assert_eq!(u64s(&m[1]["fixed"]), [7, 0, 4]);

    // Kind 1: every header field and the displacements.
    let f = &m[2];
    assert_eq!(f["kind"], Kind::Frame as u32);
    assert_eq!(
        [&f["space"], &f["vertices"], &f["seq"], &f["peakVertex"]].map(|v| v.as_u64()),
        [Some(1), Some(3), Some(4_000_000_000), Some(2)]
    );
    assert_eq!(u64s(&f["handSeq"]), [17, 0xffff_fffe]);
    assert_eq!(
        (f["hasStress"].as_bool(), f["alarm"].as_bool()),
        (Some(true), Some(true))
    );
    assert_eq!(
        (f["time"].as_f64(), f["peakVonMises"].as_f64()),
        (Some(12.375), Some(2.5e6))
    );
    assert_eq!(f64s(&f["pose"]), pose);
    assert_eq!(f32s(&f["u"]), u);
    // A held part (zero pose) and no stress peak.
    let h = &m[3];
    assert_eq!(h["pose"], Value::Null, "{h}");
    assert_eq!(
        (h["peakVertex"].as_i64(), h["peakVonMises"].as_str()),
        (Some(-1), Some("NaN"))
    );
    assert_eq!(
        (h["hasStress"].as_bool(), h["alarm"].as_bool()),
        (Some(false), Some(false))
    );
    assert_eq!(f32s(&h["u"]), u[..6]);

    // Kind 3: the stress of a frame.
    let s = &m[4];
    assert_eq!(s["kind"], Kind::Stress as u32);
    assert_eq!((s["space"].as_u64(), s["seq"].as_u64()), (Some(2), Some(99)));
    assert_eq!(
        (f32s(&s["vonMises"]), f32s(&s["principal"])),
        (vm.to_vec(), p1.to_vec())
    );

    // Kind 2: a mode shape, scaled to a largest amplitude of 1, and its frequency.
    let md = &m[5];
    assert_eq!(md["kind"], Kind::Mode as u32);
    assert_eq!(
        [&md["space"], &md["mode"], &md["vertices"]].map(|v| v.as_u64()),
        [Some(1), Some(0), Some(3)]
    );
    let hz = (basis.eigenvalues[0].sqrt() / (2.0 * std::f64::consts::PI)) as f32;
    assert_eq!(md["frequency"].as_f64().map(|x| x as f32), Some(hz));
    let phi = &basis.phi[..9];
    let peak = phi
        .chunks_exact(3)
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .fold(0.0f32, f32::max);
    assert_eq!(
        f32s(&md["phi"]),
        phi.iter().map(|v| v * (1.0 / peak)).collect::<Vec<_>>()
    );

    // Kind 4: a load case at the kept vertices (nodes 0, 2, 3 of the file).
    let l = &m[6];
    assert_eq!(l["kind"], Kind::Load as u32);
    assert_eq!(
        [&l["space"], &l["index"], &l["vertices"]].map(|v| v.as_u64()),
        [Some(2), Some(5), Some(3)]
    );
    assert_eq!(
        (l["maxDisplacement"].as_f64(), l["maxVonMises"].as_f64()),
        (Some(1.5e-3), Some(2.31e7))
    );
    assert_eq!(f32s(&l["u"]), [0.0, 0.5, 1.0, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5]);
    assert_eq!(f32s(&l["vm"]), [10.0, 30.0, 40.0]);

    // One layout on both sides.
    assert_eq!(got["magic"].as_u64(), Some(u64::from(protocol::MAGIC)));
    assert_eq!(got["version"].as_u64(), Some(u64::from(protocol::VERSION)));
    assert_eq!(got["header"].as_u64(), Some(protocol::HEADER as u64));
    let at = |kind: &str, field: &str| got["layout"][kind][field].as_u64().map(|v| v as usize);
    assert_eq!(at("frame", "seq"), Some(protocol::FRAME_SEQ));
    assert_eq!(at("frame", "time"), Some(protocol::FRAME_TIME));
    assert_eq!(at("frame", "u"), Some(protocol::FRAME_HEADER));
    assert_eq!(at("load", "u"), Some(protocol::LOAD_HEADER));
    for (kind, first_array) in [("mesh", "rest"), ("stress", "vonMises"), ("mode", "frequency")] {
        assert_eq!(at(kind, first_array), Some(protocol::SHORT_HEADER), "{kind}");
    }
    assert_eq!(frame.len(), protocol::FRAME_HEADER + 4 * u.len());
}

/// What the page refuses, and says why: another version, another magic, a message cut short,
/// a hello of another version (or of the unversioned protocol).
#[test]
fn the_page_refuses_another_version_with_a_reason() {
    let basis = basis();
    let mut frame = Vec::new();
    let header = FrameHeader {
        space: 0,
        seq: 1,
        alarm: false,
        hand_seq: [0, 0],
        time: 0.0,
        pose: [0.0; 7],
        von_mises_max: None,
    };
    protocol::frame(&mut frame, &header, &[0.0; 9], false);
    let mut newer = frame.clone();
    newer[4..8].copy_from_slice(&(protocol::VERSION + 1).to_le_bytes());
    let mut foreign = protocol::mesh(0, &basis);
    foreign[0..4].copy_from_slice(&1u32.to_le_bytes());
    let cut = frame[..frame.len() - 4].to_vec();
    let got = decode_in_node(&[
        ("newer", newer),
        ("foreign", foreign),
        ("cut", cut),
        ("tiny", vec![1, 2]),
    ]);
    let m = &got["messages"];
    let newer_version = format!("version {} of the viewer protocol", protocol::VERSION + 1);
    for (i, why) in [
        newer_version.as_str(),
        "wrong magic",
        "cut short",
        "shorter than its header",
    ]
    .iter()
    .enumerate()
    {
        assert_eq!(m[i]["refused"].as_bool(), Some(true), "{}", m[i]);
        let said = m[i]["error"].as_str().unwrap_or_default();
        assert!(said.contains(why), "message {i}: {said:?} should say {why:?}");
    }
    assert!(m[0]["error"].as_str().is_some_and(|e| e.contains("reload the page")));
    // Another version or magic: every message after it will be too (the page stops); a message
    // cut short is dropped alone.
    let foreign: Vec<_> = (0..4).map(|i| m[i]["foreign"].as_bool()).collect();
    assert_eq!(foreign, [Some(true), Some(true), Some(false), Some(true)]);
    let hello = &got["hello"];
    assert_eq!(hello["current"], Value::Null, "the same version is served");
    for k in ["other", "none"] {
        let said = hello[k].as_str().unwrap_or_default();
        assert!(said.contains("reload the page"), "{k}: {said:?}");
    }
    assert!(hello["none"].as_str().is_some_and(|e| e.contains("version 1")));
}
