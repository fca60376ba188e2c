//! The faces of a STEP part as its file states them: each B-rep face's name (the first
//! argument of `ADVANCED_FACE('name', …)`) and its surface when that is a plane or a cylinder,
//! in the order of the solids' shells — the order OpenCASCADE builds the shape in, and so the
//! order gmsh numbers the faces. The faces module believes that order only where every plane and
//! cylinder stated agrees with the face gmsh gave the same number.
//!
//! The file is hostile input: strings, lists and nesting are read with bounds, a reference to a
//! missing or wrong entity makes that face's surface unknown, never a panic.

use std::collections::HashMap;

/// Longest face name kept, characters (longer ones are cut, marked with "…"): a bound on what a
/// hostile file makes every listing carry, far above any CAD system's face names.
const NAME_CHARS: usize = 256;
/// Deepest nesting of a statement's parameters that is read.
const DEPTH: usize = 16;

/// A face's surface as the file states it, in the file's length unit.
#[derive(Clone, Debug, PartialEq)]
pub enum Surface {
    /// `PLANE`: a point on it and its unit normal.
    Plane { point: [f64; 3], normal: [f64; 3] },
    /// `CYLINDRICAL_SURFACE`: a point on its axis, the axis (unit) and the radius.
    Cylinder {
        point: [f64; 3],
        axis: [f64; 3],
        radius: f64,
    },
    /// Anything else (cone, sphere, torus, spline, …), or a surface that did not read.
    Other,
}

/// One face of the file.
#[derive(Clone, Debug, PartialEq)]
pub struct StepFace {
    /// Its entity number (`#74`).
    pub id: u64,
    /// Its name as written (decoded), empty when it has none.
    pub name: String,
    /// Its surface.
    pub surface: Surface,
}

/// The faces of the solids of STEP text, in shell order (each face once); empty when the file
/// has no solid B-rep.
pub fn faces(text: &str) -> Vec<StepFace> {
    let bodies: HashMap<u64, &str> = crate::step_units::statements(text).collect();
    let entity = |id: u64| bodies.get(&id).and_then(|b| Param::entity(b));
    // Solids in the order their representation lists them (the order of the file otherwise).
    let mut solids: Vec<u64> = Vec::new();
    for (_, body) in crate::step_units::statements(text) {
        if let Some((kind, args)) = Param::entity(body)
            && kind.ends_with("SHAPE_REPRESENTATION")
            && let Some(Param::List(items)) = args.get(1)
        {
            for item in items {
                if let Param::Ref(r) = item
                    && entity(*r).is_some_and(|(k, _)| is_solid(&k))
                    && !solids.contains(r)
                {
                    solids.push(*r);
                }
            }
        }
    }
    let mut rest: Vec<u64> = bodies
        .iter()
        .filter(|(id, b)| !solids.contains(id) && Param::entity(b).is_some_and(|(k, _)| is_solid(&k)))
        .map(|(&id, _)| id)
        .collect();
    rest.sort_unstable();
    solids.extend(rest);

    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for solid in solids {
        let Some((_, args)) = entity(solid) else { continue };
        // MANIFOLD_SOLID_BREP('n', #outer); BREP_WITH_VOIDS('n', #outer, (#void, …)).
        let mut shells: Vec<u64> = args.get(1).and_then(Param::reference).into_iter().collect();
        if let Some(Param::List(voids)) = args.get(2) {
            shells.extend(voids.iter().filter_map(Param::reference));
        }
        for shell in shells {
            let Some((_, shell_args)) = entity(shell) else { continue };
            let Some(Param::List(list)) = shell_args.get(1) else {
                continue;
            };
            for face in list.iter().filter_map(Param::reference) {
                if !seen.insert(face) {
                    continue;
                }
                let Some((kind, face_args)) = entity(face) else {
                    continue;
                };
                if kind != "ADVANCED_FACE" && kind != "FACE_SURFACE" {
                    continue;
                }
                let name = match face_args.first() {
                    Some(Param::Str(s)) => s.clone(),
                    _ => String::new(),
                };
                let surface = face_args
                    .get(2)
                    .and_then(Param::reference)
                    .map_or(Surface::Other, |s| surface(&entity, s));
                out.push(StepFace {
                    id: face,
                    name,
                    surface,
                });
            }
        }
    }
    out
}

fn is_solid(kind: &str) -> bool {
    kind == "MANIFOLD_SOLID_BREP" || kind == "BREP_WITH_VOIDS"
}

type Lookup<'a> = dyn Fn(u64) -> Option<(String, Vec<Param>)> + 'a;

fn surface(entity: &Lookup, id: u64) -> Surface {
    let Some((kind, args)) = entity(id) else {
        return Surface::Other;
    };
    let placement = args
        .get(1)
        .and_then(Param::reference)
        .and_then(|p| placement(entity, p));
    match (kind.as_str(), placement) {
        ("PLANE", Some((point, normal))) => Surface::Plane { point, normal },
        ("CYLINDRICAL_SURFACE", Some((point, axis))) => match args.get(2).and_then(Param::number) {
            Some(radius) if radius > 0.0 => Surface::Cylinder { point, axis, radius },
            _ => Surface::Other,
        },
        _ => Surface::Other,
    }
}

/// `AXIS2_PLACEMENT_3D('', #location, #axis, #ref)`: its origin and unit axis (z when unset).
fn placement(entity: &Lookup, id: u64) -> Option<([f64; 3], [f64; 3])> {
    let (kind, args) = entity(id)?;
    if kind != "AXIS2_PLACEMENT_3D" {
        return None;
    }
    let point = triple(entity, args.get(1)?.reference()?, "CARTESIAN_POINT")?;
    let axis = match args.get(2) {
        Some(Param::Ref(r)) => triple(entity, *r, "DIRECTION")?,
        _ => [0.0, 0.0, 1.0],
    };
    let norm = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
    (norm > 0.0).then(|| (point, axis.map(|a| a / norm)))
}

fn triple(entity: &Lookup, id: u64, kind: &str) -> Option<[f64; 3]> {
    let (k, args) = entity(id)?;
    let Some(Param::List(xyz)) = args.get(1).filter(|_| k == kind) else {
        return None;
    };
    let v: Vec<f64> = xyz.iter().filter_map(Param::number).collect();
    match v.as_slice() {
        &[x, y, z] if v.iter().all(|c| c.is_finite()) => Some([x, y, z]),
        _ => None,
    }
}

/// One parameter of a STEP statement.
#[derive(Clone, Debug, PartialEq)]
enum Param {
    Str(String),
    Ref(u64),
    Num(f64),
    List(Vec<Param>),
    /// `$`, `*`, an enumeration (`.T.`) or a typed value (`LENGTH_MEASURE(1.)`).
    Other,
}

impl Param {
    fn reference(&self) -> Option<u64> {
        match self {
            Param::Ref(r) => Some(*r),
            _ => None,
        }
    }

    fn number(&self) -> Option<f64> {
        match self {
            Param::Num(x) => Some(*x),
            _ => None,
        }
    }

    /// A simple entity's type and parameters (`TYPE(…)`); `None` for a complex entity
    /// (`(A(…) B(…))`) or text that does not read.
    fn entity(body: &str) -> Option<(String, Vec<Param>)> {
        let body = body.trim();
        let open = body.find('(')?;
        let kind = body[..open].trim();
        if kind.is_empty() || !kind.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
            return None;
        }
        let mut chars = body[open..].chars().peekable();
        match list(&mut chars, 0)? {
            Param::List(args) => Some((kind.to_ascii_uppercase(), args)),
            _ => None,
        }
    }
}

type Chars<'a> = std::iter::Peekable<std::str::Chars<'a>>;

fn skip_space(chars: &mut Chars) {
    while chars.peek().is_some_and(|c| c.is_whitespace()) {
        chars.next();
    }
}

/// `( p, p, … )`, the opening parenthesis next.
fn list(chars: &mut Chars, depth: usize) -> Option<Param> {
    if depth > DEPTH || chars.next() != Some('(') {
        return None;
    }
    let mut items = Vec::new();
    loop {
        skip_space(chars);
        if chars.peek() == Some(&')') {
            chars.next();
            return Some(Param::List(items));
        }
        items.push(param(chars, depth)?);
        skip_space(chars);
        match chars.next()? {
            ',' => continue,
            ')' => return Some(Param::List(items)),
            _ => return None,
        }
    }
}

fn param(chars: &mut Chars, depth: usize) -> Option<Param> {
    match *chars.peek()? {
        '(' => list(chars, depth + 1),
        '\'' => {
            chars.next();
            let mut raw = String::new();
            loop {
                match chars.next()? {
                    '\'' if chars.peek() == Some(&'\'') => {
                        chars.next();
                        raw.push('\'');
                    }
                    '\'' => break,
                    c => raw.push(c),
                }
            }
            Some(Param::Str(decode(&raw)))
        }
        '#' => {
            chars.next();
            let mut digits = String::new();
            while let Some(c) = chars.peek().copied().filter(char::is_ascii_digit) {
                digits.push(c);
                chars.next();
            }
            digits.parse().ok().map(Param::Ref)
        }
        c if c == '-' || c == '+' || c.is_ascii_digit() => {
            let mut number = String::new();
            while let Some(c) = chars
                .peek()
                .copied()
                .filter(|c| c.is_ascii_alphanumeric() || "+-.".contains(*c))
            {
                number.push(c);
                chars.next();
            }
            number.parse().ok().map(Param::Num)
        }
        _ => {
            // `$`, `*`, `.ENUM.` or `TYPED(…)`.
            while chars.peek().is_some_and(|&c| c != ',' && c != ')' && c != '(') {
                chars.next();
            }
            if chars.peek() == Some(&'(') {
                list(chars, depth + 1)?;
            }
            Some(Param::Other)
        }
    }
}

/// A STEP string's text: `\X2\…\X0\` (UTF-16 hex) and `\X\hh` (ISO 8859-1) decoded, control
/// characters dropped, at most [`NAME_CHARS`] characters.
fn decode(raw: &str) -> String {
    let mut out = String::new();
    let mut rest = raw;
    while let Some(i) = rest.find('\\') {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        if let Some(after) = rest.strip_prefix("\\X2\\") {
            let end = after.find("\\X0\\").unwrap_or(after.len());
            let units: Vec<u16> = after.as_bytes()[..end]
                .chunks(4)
                .filter_map(|c| u16::from_str_radix(std::str::from_utf8(c).ok()?, 16).ok())
                .collect();
            out.extend(char::decode_utf16(units).map(|c| c.unwrap_or('\u{fffd}')));
            rest = after.get(end + 4..).unwrap_or("");
        } else if let Some(after) = rest.strip_prefix("\\X\\")
            && let Some(byte) = after.get(..2).and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(char::from(byte));
            rest = &after[2..];
        } else {
            out.push('\\');
            rest = &rest[1..];
        }
    }
    out.push_str(rest);
    let clean: String = out.chars().filter(|c| !c.is_control()).collect();
    let clean = clean.trim();
    if clean.chars().count() > NAME_CHARS {
        clean.chars().take(NAME_CHARS - 1).chain(['…']).collect()
    } else {
        clean.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(data: &str) -> String {
        format!("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n{data}\nENDSEC;\nEND-ISO-10303-21;\n")
    }

    #[test]
    fn faces_come_in_shell_order_with_names_and_surfaces() {
        let text = step(
            "#1=CARTESIAN_POINT('',(0.,0.,5.));\n#2=DIRECTION('',(0.,0.,2.));\n\
             #3=AXIS2_PLACEMENT_3D('',#1,#2,$);\n#4=PLANE('',#3);\n\
             #5=CYLINDRICAL_SURFACE('',#3,2.5E0);\n#6=SPHERICAL_SURFACE('',#3,1.);\n\
             #10=ADVANCED_FACE('top; it''s \\X2\\00E9\\X0\\',(#99),#4,.T.);\n\
             #11=ADVANCED_FACE('',(#99),#5,.F.);\n#12=ADVANCED_FACE('ball',(#99),#6,.T.);\n\
             #20=CLOSED_SHELL('',(#12,#10,#11,#10));\n#21=MANIFOLD_SOLID_BREP('body',#20);\n\
             #22=ADVANCED_BREP_SHAPE_REPRESENTATION('',(#21,#3),#30);",
        );
        let f = faces(&text);
        assert_eq!(f.iter().map(|f| f.id).collect::<Vec<_>>(), [12, 10, 11]);
        assert_eq!(f[1].name, "top; it's é");
        assert_eq!(f[0].surface, Surface::Other);
        assert_eq!(
            f[1].surface,
            Surface::Plane {
                point: [0.0, 0.0, 5.0],
                normal: [0.0, 0.0, 1.0]
            }
        );
        assert!(matches!(f[2].surface, Surface::Cylinder { radius, .. } if radius == 2.5));
    }

    #[test]
    fn hostile_text_gives_no_faces_or_unknown_surfaces_never_a_panic() {
        for data in [
            "#20=CLOSED_SHELL('',(#10));\n#21=MANIFOLD_SOLID_BREP('b',#20);\n#10=ADVANCED_FACE('x',(#1),#77,.T.);",
            "#21=MANIFOLD_SOLID_BREP('b',#21);",
            "#21=MANIFOLD_SOLID_BREP('b',#20);\n#20=CLOSED_SHELL('',(#10,#20,#21));\n#10=ADVANCED_FACE('unterminated,(#1),#77,.T.);",
            "#21=MANIFOLD_SOLID_BREP('b',#20);\n#20=CLOSED_SHELL('',((((((((((((((((((((((((#1)))))))))))))))))))))))));",
            "#21=MANIFOLD_SOLID_BREP('b',#20);\n#20=CLOSED_SHELL('',(#10));\n#10=ADVANCED_FACE('\\X2\\D800zz\\X0\\',(#1),#4,.T.);\n\
             #4=PLANE('',#3);\n#3=AXIS2_PLACEMENT_3D('',#1,#2,$);\n#1=CARTESIAN_POINT('',(1.,NaN,2.));",
        ] {
            let f = faces(&step(data));
            assert!(f.iter().all(|f| f.surface == Surface::Other), "{data}: {f:?}");
        }
        let long = "x".repeat(1000);
        assert_eq!(decode(&long).chars().count(), NAME_CHARS);
    }

    #[test]
    fn the_pmi_block_lists_its_thirty_faces() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus");
        let text = std::fs::read_to_string(dir.join("pmi_block_2holes.step")).unwrap();
        let f = faces(&text);
        assert_eq!(f.len(), 30);
        let planes = f.iter().filter(|f| matches!(f.surface, Surface::Plane { .. })).count();
        let cylinders = f
            .iter()
            .filter(|f| matches!(f.surface, Surface::Cylinder { .. }))
            .count();
        // As the file's faces state (counted by a script apart): 19 on a PLANE, 9 on a
        // CYLINDRICAL_SURFACE (bores, halves sharing one surface, and fillets), 2 on cones.
        assert_eq!((planes, cylinders), (19, 9));
        assert!(f.iter().all(|f| f.name == "PartBody"));
    }
}
