//! The length unit a STEP file declares for its shapes. OpenCASCADE applies it on import (VES
//! asks for millimetres and scales to metres), so a scene's `geometry.unit` does not apply to a
//! STEP part: this finds the file's own unit so that a scene which says otherwise is told.

use std::collections::HashMap;

/// A length unit as a STEP file declares it.
#[derive(Clone, Debug, PartialEq)]
pub struct StepUnit {
    /// As written: "MILLIMETRE", "METRE", "INCH", …
    pub name: String,
    /// Metres per unit.
    pub metres: f64,
}

/// The `#12 = BODY` statements of STEP text's DATA section: each entity's id and body (none
/// without a DATA section).
pub fn statements(text: &str) -> impl Iterator<Item = (u64, &str)> {
    let data = text.find("DATA;").map_or("", |i| &text[i..]);
    // A `;` inside a quoted name ends nothing (`''` inside one is a quote, which toggles twice).
    let mut quoted = false;
    data.split(move |c| {
        quoted ^= c == '\'';
        c == ';' && !quoted
    })
    .filter_map(|statement| {
        let (id, body) = statement.trim().strip_prefix('#')?.split_once('=')?;
        Some((id.trim().parse().ok()?, body))
    })
}

/// The length unit of the representation contexts in STEP text (Part 21), when all of them
/// agree on one; `None` when the file names none, several, or one this cannot resolve.
pub fn length_unit(text: &str) -> Option<StepUnit> {
    // Only the statements a unit needs are kept.
    let mut entities: HashMap<u64, String> = HashMap::new();
    for (id, body) in statements(text) {
        if body.contains("UNIT") {
            entities.insert(id, body.split_whitespace().collect::<Vec<_>>().concat());
        }
    }
    let mut found: Vec<StepUnit> = Vec::new();
    for body in entities.values() {
        let Some(list) = body.split("GLOBAL_UNIT_ASSIGNED_CONTEXT((").nth(1) else {
            continue;
        };
        let list = list.split(')').next().unwrap_or("");
        for id in refs(list) {
            if let Some(u) = entities.get(&id).filter(|b| b.contains("LENGTH_UNIT"))
                && let Some(u) = resolve(&entities, u, 0)
                && !found.contains(&u)
            {
                found.push(u);
            }
        }
    }
    (found.len() == 1).then(|| found.remove(0))
}

fn refs(list: &str) -> impl Iterator<Item = u64> + '_ {
    list.split(',').filter_map(|r| r.trim().strip_prefix('#')?.parse().ok())
}

fn resolve(entities: &HashMap<u64, String>, body: &str, depth: usize) -> Option<StepUnit> {
    if depth > 4 {
        return None;
    }
    if let Some(rest) = body.split("CONVERSION_BASED_UNIT('").nth(1) {
        let (name, rest) = rest.split_once('\'')?;
        // `…('INCH',#5)` with `#5 = LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),#4)`.
        let measure = refs(rest.trim_start_matches(',').split(')').next()?)
            .next()
            .and_then(|m| entities.get(&m));
        let metres = measure.and_then(|m| {
            let value: f64 = m.split("LENGTH_MEASURE(").nth(1)?.split(')').next()?.parse().ok()?;
            let base = refs(m.rsplit(',').next()?.trim_end_matches(')')).next()?;
            Some(value * resolve(entities, entities.get(&base)?, depth + 1)?.metres)
        });
        let metres = metres.or(match name.to_ascii_uppercase().as_str() {
            "INCH" => Some(0.0254),
            "FOOT" => Some(0.3048),
            _ => None,
        })?;
        return Some(StepUnit {
            name: name.to_ascii_uppercase(),
            metres,
        });
    }
    let args = body.split("SI_UNIT(").nth(1)?.split(')').next()?;
    let (prefix, unit) = args.split_once(',')?;
    if unit != ".METRE." {
        return None;
    }
    let (word, scale) = match prefix {
        "$" => ("", 1.0),
        ".KILO." => ("KILO", 1e3),
        ".DECI." => ("DECI", 1e-1),
        ".CENTI." => ("CENTI", 1e-2),
        ".MILLI." => ("MILLI", 1e-3),
        ".MICRO." => ("MICRO", 1e-6),
        ".NANO." => ("NANO", 1e-9),
        _ => return None,
    };
    Some(StepUnit {
        name: format!("{word}METRE"),
        metres: scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_of(body: &str) -> Option<StepUnit> {
        length_unit(&format!("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n{body}\nENDSEC;\n"))
    }

    #[test]
    fn si_and_conversion_based_units_are_resolved_through_the_context() {
        let mm = "#4=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));\n\
                  #3=(NAMED_UNIT(*)SI_UNIT($,.STERADIAN.)SOLID_ANGLE_UNIT());\n";
        let u = unit_of(&format!("{mm}#9=(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNIT_ASSIGNED_CONTEXT((#4,#3))REPRESENTATION_CONTEXT('',''));")).unwrap();
        assert_eq!((u.name.as_str(), u.metres), ("MILLIMETRE", 1e-3));
        // Inches defined from millimetres, as the AP209 bracket of the corpus does.
        let inch = format!(
            "{mm}#5=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),#4);\n\
             #6=(CONVERSION_BASED_UNIT('INCH',#5)LENGTH_UNIT()NAMED_UNIT(#1));\n\
             #9=(GEOMETRIC_REPRESENTATION_CONTEXT(3)\nGLOBAL_UNIT_ASSIGNED_CONTEXT(( #6 , #3 ))REPRESENTATION_CONTEXT('',''));"
        );
        let u = unit_of(&inch).unwrap();
        assert_eq!(u.name, "INCH");
        assert!((u.metres - 0.0254).abs() < 1e-15);
        let metre = "#4=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT($,.METRE.));\n#9=(GLOBAL_UNIT_ASSIGNED_CONTEXT((#4)));";
        assert_eq!(unit_of(metre).unwrap().metres, 1.0);
        // No context, or contexts that disagree: no claim.
        assert_eq!(unit_of(mm), None);
        let both = format!(
            "{mm}#5=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT($,.METRE.));\n#9=(GLOBAL_UNIT_ASSIGNED_CONTEXT((#4)));\n#10=(GLOBAL_UNIT_ASSIGNED_CONTEXT((#5)));"
        );
        assert_eq!(unit_of(&both), None);
    }

    #[test]
    fn the_corpus_parts_declare_what_their_sources_say() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus");
        for (file, metres) in [
            ("crankshaft.step", 1e-3),
            ("pmi_block_2holes.step", 1e-3),
            ("bracket_ribbed_ap209.step", 0.0254),
        ] {
            let text = std::fs::read_to_string(dir.join(file)).unwrap();
            let u = length_unit(&text).unwrap_or_else(|| panic!("{file}: no unit"));
            assert!((u.metres - metres).abs() < 1e-15, "{file}: {u:?}");
        }
    }
}
