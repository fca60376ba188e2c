//! The file contracts live in the repository and stay true to the code: every name of the basis
//! file (`format/src/names.rs`) is documented in docs/format.md, the scene keys documented in
//! docs/scene.md are exactly the keys the parser (`pipeline/src/scene.rs`) accepts, and no file
//! points to design notes outside the repository.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(workspace().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// Values of the `pub const NAME: &str = "...";` items of a Rust source.
fn str_constants(src: &str) -> Vec<(String, String)> {
    src.lines()
        .filter_map(|l| {
            let rest = l.trim().strip_prefix("pub const ")?;
            let (name, rest) = rest.split_once(": &str = \"")?;
            let (value, _) = rest.split_once("\";")?;
            Some((name.to_string(), value.to_string()))
        })
        .collect()
}

/// The inline code spans of a Markdown text (fenced blocks left out).
fn code_spans(md: &str) -> Vec<String> {
    let mut outside_fences = String::new();
    let mut fenced = false;
    for line in md.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced {
            outside_fences.push_str(line);
            outside_fences.push('\n');
        }
    }
    outside_fences
        .split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// Whether `word` occurs in `text` with no identifier character on either side.
fn contains_token(text: &str, word: &str) -> bool {
    let ident = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
    text.match_indices(word)
        .any(|(i, _)| !ident(text[..i].chars().next_back()) && !ident(text[i + word.len()..].chars().next()))
}

/// Names of `names.rs` that no code span of `doc` shows.
fn undocumented_names(names_rs: &str, doc: &str) -> Vec<String> {
    let spans = code_spans(doc);
    str_constants(names_rs)
        .into_iter()
        .filter(|(_, value)| !spans.iter().any(|s| contains_token(s, value)))
        .map(|(name, value)| format!("{name} = {value:?}"))
        .collect()
}

#[test]
fn every_basis_file_name_is_in_the_format_doc() {
    let names = read("format/src/names.rs");
    assert!(
        str_constants(&names).len() >= 40,
        "names.rs: the parser found only {} string constants",
        str_constants(&names).len()
    );
    let missing = undocumented_names(&names, &read("docs/format.md"));
    assert!(missing.is_empty(), "docs/format.md does not name {missing:?}");
}

/// A serde struct or enum of the scene parser.
#[derive(Default, Debug)]
struct Item {
    is_enum: bool,
    /// Struct: (TOML key, Rust type). Enum: (TOML value, "").
    members: Vec<(String, String)>,
}

/// The `Deserialize` structs and enums of a source (before its tests), with serde's renames.
fn serde_items(src: &str) -> BTreeMap<String, Item> {
    let code = src.split("#[cfg(test)]").next().unwrap_or(src);
    let mut items = BTreeMap::new();
    let mut lines = code.lines().peekable();
    while let Some(line) = lines.next() {
        if !(line.starts_with("#[derive(") && line.contains("Deserialize")) {
            continue;
        }
        let mut lowercase = false;
        let mut header = String::new();
        for l in lines.by_ref() {
            if l.starts_with("#[") {
                lowercase |= l.contains("rename_all = \"lowercase\"");
            } else {
                header = l.to_string();
                break;
            }
        }
        let decl = header.trim_start_matches("pub ");
        let (is_enum, rest) = match (decl.strip_prefix("struct "), decl.strip_prefix("enum ")) {
            (Some(r), _) => (false, r),
            (_, Some(r)) => (true, r),
            _ => panic!("scene.rs: unexpected item after a derive: {header:?}"),
        };
        let name = rest.trim_end_matches('{').trim().to_string();
        let mut item = Item {
            is_enum,
            ..Item::default()
        };
        let mut rename: Option<String> = None;
        for l in lines.by_ref() {
            if l.starts_with('}') {
                break;
            }
            let t = l.trim();
            if let Some(r) = t.strip_prefix("#[serde(rename = \"") {
                rename = r.split('"').next().map(str::to_string);
            } else if t.starts_with("///") || t.starts_with("#[") || t.is_empty() {
            } else if is_enum {
                let variant = t.trim_end_matches(',');
                let key = rename.take().unwrap_or_else(|| {
                    if lowercase {
                        variant.to_lowercase()
                    } else {
                        variant.to_string()
                    }
                });
                item.members.push((key, String::new()));
            } else if let Some((field, ty)) = t.trim_start_matches("pub ").split_once(": ") {
                let key = rename.take().unwrap_or_else(|| field.to_string());
                item.members.push((key, ty.trim_end_matches(',').to_string()));
            }
        }
        items.insert(name, item);
    }
    items
}

/// Every dotted key path the parser accepts under `item` (tables included), and the accepted
/// values of the keys whose type is an enum.
fn key_paths(
    items: &BTreeMap<String, Item>,
    item: &str,
    prefix: &str,
    keys: &mut BTreeSet<String>,
    values: &mut BTreeMap<String, Vec<String>>,
) {
    for (key, ty) in &items[item].members {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        keys.insert(path.clone());
        let inner = ty
            .split(|c: char| !(c.is_alphanumeric() || c == '_'))
            .find(|w| items.contains_key(*w));
        if let Some(inner) = inner {
            if items[inner].is_enum {
                values.insert(path, items[inner].members.iter().map(|(v, _)| v.clone()).collect());
            } else {
                key_paths(items, inner, &path, keys, values);
            }
        }
    }
}

/// The rows of the "## Keys" table: first cell's key → the whole row.
fn documented_keys(scene_md: &str) -> BTreeMap<String, String> {
    let section = scene_md
        .split("\n## Keys")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("docs/scene.md has a `## Keys` section");
    section
        .lines()
        .filter_map(|l| {
            let key = l.strip_prefix("| `")?.split('`').next()?;
            Some((key.to_string(), l.to_string()))
        })
        .collect()
}

/// What is wrong between the parser and the doc's key table, one line each.
fn scene_contract_gaps(scene_rs: &str, scene_md: &str) -> Vec<String> {
    let items = serde_items(scene_rs);
    let (mut keys, mut values) = (BTreeSet::new(), BTreeMap::new());
    key_paths(&items, "RawScene", "", &mut keys, &mut values);
    let doc = documented_keys(scene_md);
    let mut gaps = Vec::new();
    for k in &keys {
        if !doc.contains_key(k) {
            gaps.push(format!(
                "key `{k}` is accepted by scene.rs but not in docs/scene.md's table"
            ));
        }
    }
    for k in doc.keys() {
        if !keys.contains(k) {
            gaps.push(format!(
                "key `{k}` is in docs/scene.md's table but scene.rs does not accept it"
            ));
        }
    }
    for (k, vals) in &values {
        for v in vals {
            if doc.get(k).is_some_and(|row| !row.contains(&format!("`\"{v}\"`"))) {
                gaps.push(format!("value \"{v}\" of `{k}` is not in its row of docs/scene.md"));
            }
        }
    }
    let extensions = scene_rs
        .lines()
        .find(|l| l.starts_with("const GEOMETRY_EXTENSIONS"))
        .and_then(|l| l.split_once("= ["))
        .map(|(_, list)| {
            list.split('"')
                .skip(1)
                .step_by(2)
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .unwrap_or_default();
    if extensions.is_empty() {
        gaps.push("scene.rs: GEOMETRY_EXTENSIONS not found".into());
    }
    for e in extensions {
        if doc
            .get("geometry.step")
            .is_some_and(|row| !row.contains(&format!("`.{e}`")))
        {
            gaps.push(format!("geometry extension .{e} is not in the `geometry.step` row"));
        }
    }
    gaps
}

/// The scene parser's serde items: scene.rs and the material table it takes from material.rs.
fn scene_sources() -> String {
    let code = |path: &str| read(path).split("#[cfg(test)]").next().unwrap_or_default().to_string();
    code("pipeline/src/scene.rs") + "\n" + &code("numerics/src/material.rs")
}

#[test]
fn the_scene_doc_lists_exactly_the_keys_the_parser_accepts() {
    let scene_rs = scene_sources();
    let items = serde_items(&scene_rs);
    let (mut keys, mut values) = (BTreeSet::new(), BTreeMap::new());
    key_paths(&items, "RawScene", "", &mut keys, &mut values);
    // The parser of this test must see the scene's real shape, not an empty set.
    for k in [
        "name",
        "geometry.unit",
        "fixed.box.min",
        "voi.box.max",
        "mesh.refinement",
        "stress.enabled",
    ] {
        assert!(keys.contains(k), "scene.rs parsed without `{k}`: {keys:?}");
    }
    assert_eq!(values["geometry.unit"], ["m", "mm"]);
    assert_eq!(values["mesh.refinement"], ["uniform", "local"]);
    let gaps = scene_contract_gaps(&scene_rs, &read("docs/scene.md"));
    assert!(gaps.is_empty(), "scene contract out of date:\n{}", gaps.join("\n"));
}

/// The checks above fail when the doc drops a name or lists a key the parser does not take.
#[test]
fn the_checks_catch_a_missing_name_and_an_invented_key() {
    let names = read("format/src/names.rs");
    let format_md = read("docs/format.md");
    let without = format_md.replace("`modes/relative_residuals`", "`residuals`");
    assert_eq!(
        undocumented_names(&names, &without),
        ["RELATIVE_RESIDUALS = \"modes/relative_residuals\""]
    );

    let scene_rs = scene_sources();
    let scene_md = read("docs/scene.md");
    let row = scene_md
        .lines()
        .find(|l| l.starts_with("| `mesh.max_dofs`"))
        .expect("max_dofs row");
    let dropped = scene_md.replace(&format!("{row}\n"), "");
    assert_eq!(
        scene_contract_gaps(&scene_rs, &dropped),
        ["key `mesh.max_dofs` is accepted by scene.rs but not in docs/scene.md's table"]
    );
    let invented = scene_md.replace(
        &format!("{row}\n"),
        &format!("{row}\n| `gravity.g` | [x, y, z] | m/s² | none | |\n"),
    );
    assert_eq!(
        scene_contract_gaps(&scene_rs, &invented),
        ["key `gravity.g` is in docs/scene.md's table but scene.rs does not accept it"]
    );
    let no_local = scene_md.replace("`\"local\"`", "local");
    assert_eq!(
        scene_contract_gaps(&scene_rs, &no_local),
        ["value \"local\" of `mesh.refinement` is not in its row of docs/scene.md"]
    );
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if p.is_dir() {
            if !(name.starts_with('.') || name == "target" || name == "node_modules") {
                sources(&p, out);
            }
        } else if p.extension().is_some_and(|x| x == "rs" || x == "md") {
            out.push(p);
        }
    }
}

#[test]
fn nothing_points_to_design_notes_outside_the_repository() {
    // Spelt in pieces so that this file does not match itself.
    let needle = ["DES", "IGN"].concat();
    let mut files = Vec::new();
    sources(&workspace(), &mut files);
    assert!(files.len() > 50, "only {} .rs/.md files found", files.len());
    let hits: Vec<String> = files
        .iter()
        .flat_map(|f| {
            let text = std::fs::read_to_string(f).unwrap_or_default();
            let rel = f.strip_prefix(workspace()).unwrap_or(f).display().to_string();
            text.lines()
                .enumerate()
                .filter(|(_, l)| l.contains(needle.as_str()))
                .map(|(i, l)| format!("{rel}:{}: {}", i + 1, l.trim()))
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(
        hits.is_empty(),
        "references to design notes that are not in the repository (point to docs/format.md, \
         docs/scene.md or the relevant docs/ page):\n{}",
        hits.join("\n")
    );
}
