//! The viewer's messages, defined once here (the page's `web/src/protocol.js` decodes them).
//!
//! Server → page, binary, little-endian, every array 4-byte aligned:
//! - kind 0, a space's surface: u32 kind, space, nv, nt; f32 rest[3nv]; u32 triangles[3nt];
//!   u8 fixed[nv] (bit c: component c of that vertex is supported); zero bytes to a multiple of
//!   4; when the basis has them, u32 faces[nt] (each triangle's CAD face tag).
//! - kind 1, a drawn frame: u32 kind, space, nv, flags (1: the space has stress, 2: the part's
//!   safety factor is below the minimum), frame seq, last hand-message seq read per hand [2],
//!   vertex of the part's largest von Mises stress (u32::MAX: none); f64 time, pose[7]
//!   (position of the centre of mass, quaternion w x y z; all zero for a supported part), largest
//!   von Mises stress (Pa, NaN: none); f32 u[3nv], the elastic displacement in the part frame.
//!   The page draws rest + k·u (posed: x + R(rest + k·u − centre)) for its deformation scale k:
//!   sending displacements, not positions, keeps sub-micrometre motion exact at any scale (an f32
//!   position near 1 m is rounded by 6e-8 m, which a scale of 2000 would draw as 0.1 mm).
//! - kind 3, the same frame's stress (only to clients that asked for it, see `fields`): u32 kind,
//!   space, nv, frame seq; f32 von Mises[nv], largest principal stress[nv] (Pa).
//! - kind 2, a mode shape: u32 kind, space, mode, nv; f32 frequency (Hz); f32 φ[3nv] scaled to
//!   max |φ| = 1.
//! - kind 4, a static load case (only to the page that asked, see `load`): u32 kind, space, nv,
//!   index (in the hello's `spaces[s].loads`); f64 largest displacement (m) and largest von Mises
//!   stress (Pa) of the whole part; f32 u[3nv] (m), von Mises[nv] (Pa) ([`super::loads::encode`]).
//!
//! Server → page, text: JSON objects `hello` (once) and `status` (≈ 20 Hz).
//! Page → server, text only: `{"type":"hand","hand":0|1,"active":bool,"button":bool,
//! "position":[x,y,z],"seq":n}`, `{"type":"mode","space":s,"index":j}`,
//! `{"type":"fields","stress":bool}` (send the stress frames or not; off at first),
//! `{"type":"load","space":s,"name":"…"}` (send load case `name` of space s once, as kind 4: it
//! must be one the hello listed for that space) and
//! `{"type":"reset"}` (the part back to rest, every hand let go), `{"type":"compute","scene":
//! {…the scene's TOML tables as JSON…}}` and `{"type":"cancel"}` (the set-up panel, when the viewer has a workshop).
//! Server → page, text, about a compute: `{"type":"progress","stage","fraction"}`,
//! `{"type":"computed","summary","scene","seconds"}`, `{"type":"compute_error","message"}`; a
//! new basis then comes as a new hello and its meshes. About a load case the file could not give
//! (to the page that asked): `{"type":"load_error","space","index","message"}`. Anything else —
//! binary, longer than [`MAX_MESSAGE`], not JSON, unknown fields, non-finite or far-away
//! positions — is dropped and counted.

use super::hands::HandCommand;
use crate::basis::Basis;

/// Longest client message accepted, bytes (a hand message is ≈ 120, a scene to compute a few
/// kB).
pub const MAX_MESSAGE: usize = 32 * 1024;

/// Hands the viewer simulates.
pub const HANDS: usize = 2;

fn put_u32(b: &mut Vec<u8>, v: u32) {
    b.extend_from_slice(&v.to_le_bytes());
}

fn put_f32(b: &mut Vec<u8>, v: f32) {
    b.extend_from_slice(&v.to_le_bytes());
}

/// Kind 0: the surface of space `space`.
pub fn mesh(space: usize, basis: &Basis) -> Vec<u8> {
    let (nv, nt) = (basis.vertex_count(), basis.triangles.len());
    let mut b = Vec::with_capacity(16 + 12 * nv + 12 * nt);
    for v in [0, space as u32, nv as u32, nt as u32] {
        put_u32(&mut b, v);
    }
    for p in basis.rest.iter().flatten() {
        put_f32(&mut b, *p as f32);
    }
    for t in basis.triangles.iter().flatten() {
        put_u32(&mut b, *t);
    }
    b.extend_from_slice(&basis.fixed);
    if let Some(faces) = &basis.surface_faces {
        b.resize(b.len().next_multiple_of(4), 0);
        for f in faces {
            put_u32(&mut b, *f);
        }
    }
    b
}

/// What a frame carries besides the arrays.
pub struct FrameHeader {
    /// Active space.
    pub space: usize,
    /// Frame sequence number.
    pub seq: u32,
    /// The part's safety factor is below the minimum.
    pub alarm: bool,
    /// Last hand message read per hand.
    pub hand_seq: [u32; HANDS],
    /// Session time, s.
    pub time: f64,
    /// Pose (position of the centre of mass, quaternion w x y z; zeros for a held part).
    pub pose: [f64; 7],
    /// The part's largest von Mises stress, Pa, and its vertex.
    pub von_mises_max: Option<(f64, usize)>,
}

/// Bytes before a frame's displacements.
pub const FRAME_HEADER: usize = 8 * 4 + 9 * 8;

/// Kind 1 into `b` (cleared first): the elastic displacement `u` (3 per vertex, part frame);
/// `has_stress` sets flag 1.
pub fn frame(b: &mut Vec<u8>, h: &FrameHeader, u: &[f32], has_stress: bool) {
    b.clear();
    let nv = u.len() / 3;
    let flags = u32::from(has_stress) | (u32::from(h.alarm) << 1);
    let (peak, at) = match h.von_mises_max {
        Some((s, v)) => (s, v as u32),
        None => (f64::NAN, u32::MAX),
    };
    for v in [
        1,
        h.space as u32,
        nv as u32,
        flags,
        h.seq,
        h.hand_seq[0],
        h.hand_seq[1],
        at,
    ] {
        put_u32(b, v);
    }
    for v in std::iter::once(h.time).chain(h.pose).chain([peak]) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in u {
        put_f32(b, *v);
    }
}

/// Kind 3 into `b` (cleared first): the stress of frame `seq` of `space`, von Mises then the
/// largest principal stress (n each).
pub fn stress_frame(b: &mut Vec<u8>, space: usize, seq: u32, von_mises: &[f32], principal: &[f32]) {
    b.clear();
    for v in [3, space as u32, von_mises.len() as u32, seq] {
        put_u32(b, v);
    }
    for v in von_mises.iter().chain(principal) {
        put_f32(b, *v);
    }
}

/// Kind 2: mode `j` of space `space`, scaled to a largest vertex amplitude of 1.
pub fn mode(space: usize, basis: &Basis, j: usize) -> Option<Vec<u8>> {
    let n = basis.vertex_count();
    let lambda = *basis.eigenvalues.get(j)?;
    let phi = basis.phi.get(j * 3 * n..(j + 1) * 3 * n)?;
    let peak = phi
        .chunks_exact(3)
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .fold(0.0f32, f32::max);
    let scale = if peak > 0.0 { 1.0 / peak } else { 0.0 };
    let mut b = Vec::with_capacity(20 + 12 * n);
    for v in [2, space as u32, j as u32, n as u32] {
        put_u32(&mut b, v);
    }
    put_f32(&mut b, (lambda.sqrt() / (2.0 * std::f64::consts::PI)) as f32);
    for v in phi {
        put_f32(&mut b, v * scale);
    }
    Some(b)
}

/// A message from the page, as received.
#[derive(Debug, serde::Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum Raw {
    Hand {
        hand: usize,
        active: bool,
        button: bool,
        position: [f64; 3],
        #[serde(default)]
        seq: u32,
    },
    Mode {
        space: usize,
        index: usize,
    },
    Fields {
        stress: bool,
    },
    Reset {},
    Load {
        space: usize,
        name: String,
    },
    Compute {
        scene: serde_json::Value,
    },
    Cancel {},
}

/// A checked message from the page.
#[derive(Debug, PartialEq)]
pub enum ClientMessage {
    /// Drive (or let go of) a hand.
    Hand(usize, HandCommand),
    /// Send a mode shape.
    Mode {
        /// Space.
        space: usize,
        /// Mode index.
        index: usize,
    },
    /// Send the stress frames (kind 3) or not.
    Fields {
        /// Stress wanted.
        stress: bool,
    },
    /// The part back to rest, every hand let go.
    Reset,
    /// Send a static load case.
    Load {
        /// Space.
        space: usize,
        /// The case's index in that space's list (the hello's `loads`).
        index: usize,
    },
    /// Compute a basis from this scene (TOML text) and move the session to it.
    Compute {
        /// The scene: its TOML tables and keys as JSON.
        scene: serde_json::Value,
    },
    /// Stop the running compute.
    Cancel,
}

/// Where the part is: positions further than `REACH` diagonals from its centre are refused.
#[derive(Clone, Copy, Debug)]
pub struct Extent {
    /// Centre of the bounding box, m.
    pub centre: [f64; 3],
    /// Its diagonal, m.
    pub diagonal: f64,
}

/// How far from the part a hand may be asked to go, in bounding-box diagonals.
pub const REACH: f64 = 10.0;

impl Extent {
    /// The bounding box of a basis's rest positions.
    pub fn of(basis: &Basis) -> Extent {
        let [lo, hi] = crate::kdtree::bounds(&basis.rest);
        let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
        Extent { centre, diagonal }
    }
}

/// Parses and checks a text message; `Err` says why it was dropped. No space has load cases
/// (see [`parse_with`]).
pub fn parse(text: &str, spaces: usize, extent: Option<&Extent>) -> Result<ClientMessage, String> {
    parse_with(text, spaces, extent, &[])
}

/// [`parse`] where `loads[s]` names the load cases of space s (a space beyond `loads` has none):
/// a load request must name one of them.
pub fn parse_with(
    text: &str,
    spaces: usize,
    extent: Option<&Extent>,
    loads: &[Vec<String>],
) -> Result<ClientMessage, String> {
    if text.len() > MAX_MESSAGE {
        return Err(format!("{} bytes (at most {MAX_MESSAGE})", text.len()));
    }
    let raw: Raw = serde_json::from_str(text).map_err(|e| e.to_string())?;
    match raw {
        Raw::Hand {
            hand,
            active,
            button,
            position,
            seq,
        } => {
            if hand >= HANDS {
                return Err(format!("hand {hand} (0 or 1)"));
            }
            let Some(extent) = extent else {
                return Err("no part to touch yet".into());
            };
            let d2: f64 = (0..3).map(|k| (position[k] - extent.centre[k]).powi(2)).sum();
            // NaN is refused too.
            if d2.is_nan() || d2.sqrt() > REACH * extent.diagonal {
                return Err(format!("position {position:?} is not finite or is far from the part"));
            }
            Ok(ClientMessage::Hand(
                hand,
                HandCommand {
                    position,
                    button,
                    active,
                    seq,
                },
            ))
        }
        Raw::Mode { space, index } if space < spaces => Ok(ClientMessage::Mode { space, index }),
        Raw::Mode { space, .. } => Err(format!("space {space} of {spaces}")),
        Raw::Fields { stress } => Ok(ClientMessage::Fields { stress }),
        Raw::Reset {} => Ok(ClientMessage::Reset),
        Raw::Load { space, .. } if space >= spaces => Err(format!("load case of space {space} of {spaces}")),
        Raw::Load { space, name } => match loads.get(space).and_then(|l| l.iter().position(|n| *n == name)) {
            Some(index) => Ok(ClientMessage::Load { space, index }),
            // Not echoed whole: a hostile page's name may be 32 kB.
            None => Err(format!(
                "no load case {:?} in space {space}",
                name.chars().take(40).collect::<String>()
            )),
        },
        Raw::Compute { scene } => Ok(ClientMessage::Compute { scene }),
        Raw::Cancel {} => Ok(ClientMessage::Cancel),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const E: Extent = Extent {
        centre: [0.5, 0.05, 0.025],
        diagonal: 1.0,
    };

    #[test]
    fn good_messages_parse_and_bad_ones_are_refused_with_a_reason() {
        let ok = parse(
            r#"{"type":"hand","hand":1,"active":true,"button":false,"position":[1,0.05,0.05],"seq":7}"#,
            1,
            Some(&E),
        );
        assert_eq!(
            ok,
            Ok(ClientMessage::Hand(
                1,
                HandCommand {
                    position: [1.0, 0.05, 0.05],
                    button: false,
                    active: true,
                    seq: 7
                }
            ))
        );
        assert_eq!(
            parse(r#"{"type":"mode","space":0,"index":3}"#, 1, Some(&E)),
            Ok(ClientMessage::Mode { space: 0, index: 3 })
        );
        assert_eq!(
            parse(r#"{"type":"fields","stress":true}"#, 1, Some(&E)),
            Ok(ClientMessage::Fields { stress: true })
        );
        assert_eq!(parse(r#"{"type":"reset"}"#, 1, Some(&E)), Ok(ClientMessage::Reset));
        let bad = [
            r#"{"type":"hand","hand":2,"active":true,"button":true,"position":[1,0,0]}"#,
            r#"{"type":"hand","hand":0,"active":true,"button":true,"position":[1e300,0,0]}"#,
            r#"{"type":"hand","hand":0,"active":true,"button":true,"position":[1,0]}"#,
            r#"{"type":"hand","hand":0,"active":true,"button":true,"position":[1,0,0],"x":1}"#,
            r#"{"type":"mode","space":1,"index":0}"#,
            r#"{"type":"quit"}"#,
            r#"{"type":"reset","all":true}"#,
            "not json",
            "[]",
        ];
        for b in bad {
            assert!(parse(b, 1, Some(&E)).is_err(), "{b}");
        }
        let long = format!(r#"{{"type":"load","space":0,"name":"{}"}}"#, "x".repeat(40_000));
        assert!(parse(&long, 1, Some(&E)).unwrap_err().contains("bytes"));
        let long = format!(
            r#"{{"type":"mode","space":0,"index":0,"pad":"{}"}}"#,
            "x".repeat(40_000)
        );
        assert!(parse(&long, 1, Some(&E)).unwrap_err().contains("bytes"));
        // JSON has no NaN; a string in its place is refused by the parser.
        assert!(
            parse(
                r#"{"type":"hand","hand":0,"active":true,"button":true,"position":["NaN",0,0]}"#,
                1,
                Some(&E)
            )
            .is_err()
        );
    }

    /// A load request names a case the hello listed for that space; anything else (an unknown
    /// or foreign name, another space, a missing or mistyped field, an extra field) is refused.
    #[test]
    fn a_load_request_must_name_a_listed_case_of_a_served_space() {
        let loads = vec![vec!["tip".to_string(), "gravity".to_string()], Vec::new()];
        let parse = |t: &str| parse_with(t, 2, Some(&E), &loads);
        assert_eq!(
            parse(r#"{"type":"load","space":0,"name":"gravity"}"#),
            Ok(ClientMessage::Load { space: 0, index: 1 })
        );
        let bad = [
            r#"{"type":"load","space":0,"name":"nope"}"#,
            r#"{"type":"load","space":1,"name":"tip"}"#,
            r#"{"type":"load","space":2,"name":"tip"}"#,
            r#"{"type":"load","space":-1,"name":"tip"}"#,
            r#"{"type":"load","space":0,"name":"TIP"}"#,
            r#"{"type":"load","space":0,"name":"tip\u0000"}"#,
            r#"{"type":"load","space":0,"name":"../tip"}"#,
            r#"{"type":"load","space":0,"name":7}"#,
            r#"{"type":"load","space":0}"#,
            r#"{"type":"load","name":"tip"}"#,
            r#"{"type":"load","space":0,"name":"tip","index":0}"#,
            r#"{"type":"load","space":1e99,"name":"tip"}"#,
            r#"{"type":"load","space":0,"name":null}"#,
        ];
        for b in bad {
            assert!(parse(b).is_err(), "{b}");
        }
        // The reason quotes at most 40 characters of a long name.
        let long = format!(r#"{{"type":"load","space":0,"name":"{}"}}"#, "y".repeat(20_000));
        let why = parse(&long).unwrap_err();
        assert!(why.len() < 120, "{why}");
        // Without a list, no space has load cases.
        assert!(super::parse(r#"{"type":"load","space":0,"name":"tip"}"#, 2, Some(&E)).is_err());
    }
}
