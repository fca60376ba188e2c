//! The viewer's messages, defined once here and in the page's `web/src/protocol.js`, which
//! decodes them; both follow the one written description, docs/view.md, "The WebSocket
//! protocol", and `runtime/tests/protocol_js.rs` has the page's decoder read what this module
//! encodes.
//!
//! Server → page, binary, little-endian, every array aligned to its element: a [`HEADER`]
//! (u32 [`MAGIC`], [`VERSION`], [`Kind`]) then the kind's fields — a space's surface
//! ([`mesh`]), a drawn frame ([`frame`]), a mode shape ([`mode`]), a frame's stress
//! ([`stress_frame`]), a static load case ([`load_case`]).
//!
//! Server → page, text: JSON objects `hello` (once per basis; its `protocol` is [`VERSION`])
//! and `status` (≈ 20 Hz).
//! Page → server, text only: `{"type":"hand","hand":0|1,"active":bool,"button":bool,
//! "position":[x,y,z],"seq":n}`, `{"type":"mode","space":s,"index":j}`,
//! `{"type":"fields","stress":bool}` (send the stress frames or not; off at first),
//! `{"type":"load","space":s,"name":"…"}` (send load case `name` of space s once, as kind 4: it
//! must be one the hello listed for that space) and
//! `{"type":"reset"}` (the part back to rest, every hand let go), `{"type":"compute","scene":
//! {…the scene's TOML tables as JSON…}}`, `{"type":"cancel"}` (also returns the set-up to the
//! scene served), `{"type":"edit","scene":{…},"seq":n}`, `{"type":"undo"}`, `{"type":"redo"}` and
//! `{"type":"revert"}` (the set-up panel, when the viewer has a workshop).
//! Server → page, text, the set-up every page shows (after the first hello, and at each change):
//! `{"ack","type":"setup","draft","served","summary","edited","undo","redo","history","project"}`
//! (`SetUp::message` in `setup.rs`; `ack`: the `seq` of the last `edit` or `compute` of this
//! connection the server had applied).
//! Server → page, text, about a compute: `{"type":"progress","stage","fraction"}`,
//! `{"type":"computed","summary","scene","seconds","warnings","mesh","live"}`, `{"type":"checked","summary","seconds","warnings"}`, `{"type":"compute_error","message"}`; a
//! new basis then comes as a new hello and its meshes. About a load case the file could not give
//! (to the page that asked): `{"type":"load_error","space","index","message"}`. Anything else —
//! binary, longer than [`MAX_MESSAGE`], not JSON, unknown fields, non-finite or far-away
//! positions — is dropped and counted.

use super::hands::HandCommand;
use ves_format::read::LoadCase;
use ves_runtime::basis::Basis;

/// Longest client message accepted, bytes (a hand message is ≈ 120, a scene to compute a few
/// kB).
pub const MAX_MESSAGE: usize = 32 * 1024;

/// Hands the viewer simulates.
pub const HANDS: usize = 2;

/// First word of every binary message: "VESV" in ASCII, so a page never reads another
/// stream's bytes as a part.
pub const MAGIC: u32 = u32::from_le_bytes(*b"VESV");

/// Version of the binary layouts below, also the hello's `protocol`: a page refuses any other
/// (its server was updated under it: a reload fetches the matching page). Bumped whenever a
/// layout changes; 1 was the unversioned layout without [`MAGIC`].
pub const VERSION: u32 = 2;

/// Bytes of the header every binary message starts with: u32 magic, version, kind. A multiple
/// of 8, so the f64 fields after it stay aligned.
pub const HEADER: usize = 12;

/// What a binary message carries (the header's third word).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Kind {
    /// A space's surface ([`mesh`]).
    Mesh = 0,
    /// A drawn frame ([`frame`]).
    Frame = 1,
    /// A mode shape ([`mode`]).
    Mode = 2,
    /// A frame's stress ([`stress_frame`]).
    Stress = 3,
    /// A static load case ([`load_case`]).
    Load = 4,
}

/// Offset of a frame's sequence number (after the header's space, nv and flags).
pub const FRAME_SEQ: usize = HEADER + 3 * 4;

/// Offset of a frame's time (after the header's 7 u32 fields).
pub const FRAME_TIME: usize = HEADER + 7 * 4;

/// Bytes before a frame's displacements: the header, 7 u32 and 9 f64 fields.
pub const FRAME_HEADER: usize = FRAME_TIME + 9 * 8;

/// Bytes before a load case's arrays: the header, 3 u32 and 2 f64 fields.
pub const LOAD_HEADER: usize = HEADER + 3 * 4 + 2 * 8;

/// Bytes before a mesh's, a mode's and a stress frame's arrays (but a mode's f32 frequency).
pub const SHORT_HEADER: usize = HEADER + 3 * 4;

fn put_u32(b: &mut Vec<u8>, v: u32) {
    b.extend_from_slice(&v.to_le_bytes());
}

fn put_f32(b: &mut Vec<u8>, v: f32) {
    b.extend_from_slice(&v.to_le_bytes());
}

/// Starts a message of `kind` in `b` (cleared first).
fn begin(b: &mut Vec<u8>, kind: Kind) {
    b.clear();
    for v in [MAGIC, VERSION, kind as u32] {
        put_u32(b, v);
    }
}

/// Kind 0, the surface of space `space`: u32 space, nv, nt; f32 rest[3nv]; u32 triangles[3nt];
/// u8 fixed[nv] (bit c: component c supported); zero bytes to a multiple of 4; when the basis
/// has them, u32 faces[nt] (each triangle's CAD face tag).
pub fn mesh(space: usize, basis: &Basis) -> Vec<u8> {
    let (nv, nt) = (basis.vertex_count(), basis.triangles.len());
    let mut b = Vec::with_capacity(SHORT_HEADER + 13 * nv + 16 * nt + 3);
    begin(&mut b, Kind::Mesh);
    for v in [space as u32, nv as u32, nt as u32] {
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

/// Kind 1 into `b` (cleared first), a drawn frame: u32 space, nv, flags (1: `has_stress`, 2:
/// alarm), seq, hand_seq[2], vertex of the largest von Mises stress (u32::MAX: none); f64
/// time, pose[7], largest von Mises stress (NaN: none); f32 u[3nv], the elastic displacement
/// `u` (3 per vertex, part frame).
pub fn frame(b: &mut Vec<u8>, h: &FrameHeader, u: &[f32], has_stress: bool) {
    begin(b, Kind::Frame);
    let nv = u.len() / 3;
    let flags = u32::from(has_stress) | (u32::from(h.alarm) << 1);
    let (peak, at) = match h.von_mises_max {
        Some((s, v)) => (s, v as u32),
        None => (f64::NAN, u32::MAX),
    };
    for v in [
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

/// The sequence number of an encoded frame (`None`: too short to be one).
pub fn frame_seq(f: &[u8]) -> Option<u32> {
    let word = f.get(FRAME_SEQ..FRAME_SEQ + 4)?;
    Some(u32::from_le_bytes(word.try_into().ok()?))
}

/// Whether two encoded frames draw the same: equal but for their sequence number and time.
pub fn frames_draw_the_same(a: &[u8], b: &[u8]) -> bool {
    let (seq, time) = (FRAME_SEQ..FRAME_SEQ + 4, FRAME_TIME..FRAME_TIME + 8);
    a.len() == b.len()
        && a.len() >= FRAME_HEADER
        && a[..seq.start] == b[..seq.start]
        && a[seq.end..time.start] == b[seq.end..time.start]
        && a[time.end..] == b[time.end..]
}

/// Kind 3 into `b` (cleared first), the stress of frame `seq` of `space`: u32 space, nv, seq;
/// f32 von Mises[nv], then the largest principal stress[nv] (Pa).
pub fn stress_frame(b: &mut Vec<u8>, space: usize, seq: u32, von_mises: &[f32], principal: &[f32]) {
    begin(b, Kind::Stress);
    for v in [space as u32, von_mises.len() as u32, seq] {
        put_u32(b, v);
    }
    for v in von_mises.iter().chain(principal) {
        put_f32(b, *v);
    }
}

/// Kind 2, mode `j` of space `space`: u32 space, mode, nv; f32 frequency (Hz), φ[3nv] scaled
/// to a largest vertex amplitude of 1.
pub fn mode(space: usize, basis: &Basis, j: usize) -> Option<Vec<u8>> {
    let n = basis.vertex_count();
    let lambda = *basis.eigenvalues.get(j)?;
    let phi = basis.phi.get(j * 3 * n..(j + 1) * 3 * n)?;
    let peak = phi
        .chunks_exact(3)
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .fold(0.0f32, f32::max);
    let scale = if peak > 0.0 { 1.0 / peak } else { 0.0 };
    let mut b = Vec::with_capacity(SHORT_HEADER + 4 + 12 * n);
    begin(&mut b, Kind::Mode);
    for v in [space as u32, j as u32, n as u32] {
        put_u32(&mut b, v);
    }
    put_f32(&mut b, (lambda.sqrt() / (2.0 * std::f64::consts::PI)) as f32);
    for v in phi {
        put_f32(&mut b, v * scale);
    }
    Some(b)
}

/// Kind 4, load case `index` (in the hello's list) of space `space`: u32 space, nv, index; f64
/// largest displacement (m), largest von Mises stress (Pa) of the whole part (the file's
/// attributes); f32 u[3nv] (the static displacement of each drawn vertex, m), von Mises[nv]
/// (Pa). `None` if the case does not fit the basis (a vertex's node beyond the case's arrays).
pub fn load_case(space: usize, index: usize, basis: &Basis, case: &LoadCase) -> Option<Vec<u8>> {
    let nv = basis.vertex_count();
    let mut b = Vec::with_capacity(LOAD_HEADER + 16 * nv);
    begin(&mut b, Kind::Load);
    for v in [space as u32, nv as u32, index as u32] {
        put_u32(&mut b, v);
    }
    for v in [case.max_displacement, case.max_von_mises] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for &node in &basis.node_index {
        let u = case.displacement.get(3 * node as usize..3 * node as usize + 3)?;
        for c in u {
            put_f32(&mut b, *c as f32);
        }
    }
    for &node in &basis.node_index {
        let s = *case.von_mises.get(node as usize)?;
        put_f32(&mut b, s as f32);
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
        #[serde(default)]
        seq: u32,
    },
    Cancel {},
    Edit {
        scene: serde_json::Value,
        #[serde(default)]
        seq: u32,
    },
    Undo {},
    Redo {},
    Revert {},
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
        /// The page's number for this edit of the set-up (see `Edit`).
        seq: u32,
    },
    /// Stop the running compute (and bring the set-up back to the scene served).
    Cancel,
    /// The set-up panel's scene was edited: it is the draft every page shows from now on.
    Edit {
        /// The scene: its TOML tables and keys as JSON.
        scene: serde_json::Value,
        /// The page's number for it, counted from 1 on each connection: the set-up messages this
        /// connection gets after it carry `"ack": seq`, so a page knows which of its edits the
        /// state it is shown already holds.
        seq: u32,
    },
    /// The set-up as it was before the last edit.
    Undo,
    /// The edit last undone, again.
    Redo,
    /// The set-up back to the scene served (an edit: undo brings the edits back).
    Revert,
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
        let [lo, hi] = ves_runtime::kdtree::bounds(&basis.rest);
        let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
        let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
        Extent { centre, diagonal }
    }
}

/// Why a client's text message was dropped.
#[derive(Debug, thiserror::Error)]
pub enum MessageError {
    /// Longer than [`MAX_MESSAGE`].
    #[error("{len} bytes (at most {MAX_MESSAGE})")]
    TooLong {
        /// Its length, bytes.
        len: usize,
    },
    /// Not JSON, or not a message of the protocol (an unknown type or field, a missing one).
    #[error("{0}")]
    Malformed(serde_json::Error),
    /// A hand beyond [`HANDS`].
    #[error("hand {hand} (0 or 1)")]
    NoHand {
        /// The hand asked for.
        hand: usize,
    },
    /// A hand message before any part is served.
    #[error("no part to touch yet")]
    NoPart,
    /// A hand position that is not finite or lies beyond [`REACH`] diagonals from the part.
    #[error("position {position:?} is not finite or is far from the part")]
    FarAway {
        /// The position asked for, m.
        position: [f64; 3],
    },
    /// A mode of a space not served.
    #[error("space {space} of {spaces}")]
    NoSpace {
        /// The space asked for.
        space: usize,
        /// Spaces served.
        spaces: usize,
    },
    /// A load case of a space not served.
    #[error("load case of space {space} of {spaces}")]
    NoLoadSpace {
        /// The space asked for.
        space: usize,
        /// Spaces served.
        spaces: usize,
    },
    /// A load case the hello did not list for that space.
    #[error("no load case {name:?} in space {space}")]
    NoLoadCase {
        /// The name asked for, its first 40 characters (a hostile page's name may be 32 kB).
        name: String,
        /// The space.
        space: usize,
    },
}

/// Parses and checks a text message; `Err` says why it was dropped. No space has load cases
/// (see [`parse_with`]).
pub fn parse(text: &str, spaces: usize, extent: Option<&Extent>) -> Result<ClientMessage, MessageError> {
    parse_with(text, spaces, extent, &[])
}

/// [`parse`] where `loads[s]` names the load cases of space s (a space beyond `loads` has none):
/// a load request must name one of them.
pub fn parse_with(
    text: &str,
    spaces: usize,
    extent: Option<&Extent>,
    loads: &[Vec<String>],
) -> Result<ClientMessage, MessageError> {
    if text.len() > MAX_MESSAGE {
        return Err(MessageError::TooLong { len: text.len() });
    }
    let raw: Raw = serde_json::from_str(text).map_err(MessageError::Malformed)?;
    match raw {
        Raw::Hand {
            hand,
            active,
            button,
            position,
            seq,
        } => {
            if hand >= HANDS {
                return Err(MessageError::NoHand { hand });
            }
            let Some(extent) = extent else {
                return Err(MessageError::NoPart);
            };
            let d2: f64 = (0..3).map(|k| (position[k] - extent.centre[k]).powi(2)).sum();
            // NaN is refused too.
            if d2.is_nan() || d2.sqrt() > REACH * extent.diagonal {
                return Err(MessageError::FarAway { position });
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
        Raw::Mode { space, .. } => Err(MessageError::NoSpace { space, spaces }),
        Raw::Fields { stress } => Ok(ClientMessage::Fields { stress }),
        Raw::Reset {} => Ok(ClientMessage::Reset),
        Raw::Load { space, .. } if space >= spaces => Err(MessageError::NoLoadSpace { space, spaces }),
        Raw::Load { space, name } => match loads.get(space).and_then(|l| l.iter().position(|n| *n == name)) {
            Some(index) => Ok(ClientMessage::Load { space, index }),
            // Not echoed whole: a hostile page's name may be 32 kB.
            None => Err(MessageError::NoLoadCase {
                name: name.chars().take(40).collect(),
                space,
            }),
        },
        Raw::Compute { scene, seq } => Ok(ClientMessage::Compute { scene, seq }),
        Raw::Cancel {} => Ok(ClientMessage::Cancel),
        Raw::Edit { scene, seq } => Ok(ClientMessage::Edit { scene, seq }),
        Raw::Undo {} => Ok(ClientMessage::Undo),
        Raw::Redo {} => Ok(ClientMessage::Redo),
        Raw::Revert {} => Ok(ClientMessage::Revert),
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
            ok.ok(),
            Some(ClientMessage::Hand(
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
            parse(r#"{"type":"mode","space":0,"index":3}"#, 1, Some(&E)).ok(),
            Some(ClientMessage::Mode { space: 0, index: 3 })
        );
        assert_eq!(
            parse(r#"{"type":"fields","stress":true}"#, 1, Some(&E)).ok(),
            Some(ClientMessage::Fields { stress: true })
        );
        assert_eq!(
            parse(r#"{"type":"reset"}"#, 1, Some(&E)).ok(),
            Some(ClientMessage::Reset)
        );
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
        assert!(parse(&long, 1, Some(&E)).unwrap_err().to_string().contains("bytes"));
        let long = format!(
            r#"{{"type":"mode","space":0,"index":0,"pad":"{}"}}"#,
            "x".repeat(40_000)
        );
        assert!(parse(&long, 1, Some(&E)).unwrap_err().to_string().contains("bytes"));
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
            parse(r#"{"type":"load","space":0,"name":"gravity"}"#).ok(),
            Some(ClientMessage::Load { space: 0, index: 1 })
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
        let why = parse(&long).unwrap_err().to_string();
        assert!(why.len() < 120, "{why}");
        // Without a list, no space has load cases.
        assert!(super::parse(r#"{"type":"load","space":0,"name":"tip"}"#, 2, Some(&E)).is_err());
    }

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
            peak: None,
            regular_peak: None,
        };
        let b = load_case(1, 2, &basis, &case).expect("fits");
        let u32s = |at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let f32s = |at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        assert_eq!(
            [u32s(0), u32s(4), u32s(8), u32s(12), u32s(16), u32s(20)],
            [MAGIC, VERSION, Kind::Load as u32, 1, 3, 2]
        );
        let f64s = |at: usize| f64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"));
        assert_eq!([f64s(LOAD_HEADER - 16), f64s(LOAD_HEADER - 8)], [3.0, 40.0]);
        let u: Vec<f32> = (0..9).map(|k| f32s(LOAD_HEADER + 4 * k)).collect();
        assert_eq!(u, [0.0, 1.0, 2.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]);
        let vm: Vec<f32> = (0..3).map(|k| f32s(LOAD_HEADER + 36 + 4 * k)).collect();
        assert_eq!(vm, [10.0, 30.0, 40.0]);
        assert_eq!(b.len(), LOAD_HEADER + 16 * 3);
        // A case shorter than the basis's nodes (a file changed under the server) is refused.
        basis.node_index[2] = 4;
        assert!(load_case(0, 0, &basis, &case).is_none());
    }

    /// A frame is told from the next one at rest by its sequence number and time only, both
    /// read where the page reads them.
    #[test]
    fn frames_differ_only_in_seq_and_time_at_rest() {
        let mut h = FrameHeader {
            space: 0,
            seq: 7,
            alarm: false,
            hand_seq: [1, 2],
            time: 0.5,
            pose: [0.0; 7],
            von_mises_max: None,
        };
        let u = [0.25f32; 6];
        let (mut a, mut b) = (Vec::new(), Vec::new());
        frame(&mut a, &h, &u, false);
        assert_eq!(a.len(), FRAME_HEADER + 4 * u.len());
        assert_eq!(frame_seq(&a), Some(7));
        assert_eq!(
            f64::from_le_bytes(a[FRAME_TIME..FRAME_TIME + 8].try_into().expect("8")),
            0.5
        );
        (h.seq, h.time) = (8, 0.75);
        frame(&mut b, &h, &u, false);
        assert!(frames_draw_the_same(&a, &b));
        h.hand_seq[1] = 3;
        frame(&mut b, &h, &u, false);
        assert!(!frames_draw_the_same(&a, &b));
        assert_eq!(frame_seq(&a[..FRAME_SEQ + 3]), None);
    }
}
