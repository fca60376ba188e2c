//! The structure the README promises: no import cycles between the top-level modules of each
//! crate (data flows one way), and a layout table that names every folder of the workspace.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The crates under `ffi/`, one per C library, as paths relative to the workspace (`ffi/gmsh`, …).
fn ffi_crates() -> Vec<String> {
    let mut crates: Vec<String> = std::fs::read_dir(workspace().join("ffi"))
        .expect("ffi/")
        .flatten()
        .filter(|e| e.path().join("Cargo.toml").is_file())
        .map(|e| format!("ffi/{}", e.file_name().to_string_lossy()))
        .collect();
    crates.sort();
    crates
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("source folder").flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Top-level module → modules it names as `crate::name` (unit tests left out: they may reach
/// anywhere).
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(src).expect("inside src");
        let first = rel
            .components()
            .next()
            .expect("a component")
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" || module == "main" {
            continue;
        }
        let text = std::fs::read_to_string(&f).expect("readable source");
        let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
        let deps = graph.entry(module.clone()).or_default();
        for (i, _) in code.match_indices("crate::") {
            let rest = &code[i + 7..];
            // `crate::{a, b::c}` names several modules at once: the first word of each item.
            let names: Vec<String> = match rest.strip_prefix('{') {
                Some(group) => group
                    .split('}')
                    .next()
                    .unwrap_or("")
                    .split(',')
                    .map(|item| {
                        item.trim()
                            .chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect()
                    })
                    .collect(),
                None => vec![rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect()],
            };
            for name in names {
                // Modules only: `crate::Basis` is a type re-exported at the root.
                let is_module = name.starts_with(|c: char| c.is_ascii_lowercase() || c == '_');
                if is_module && name != module && name != "self" {
                    deps.insert(name);
                }
            }
        }
    }
    graph
}

/// A cycle in the graph, if any (depth-first search).
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(n) {
            Some(2) => return None,
            Some(1) => {
                let start = path.iter().position(|p| p == n).unwrap_or(0);
                let mut cycle = path[start..].to_vec();
                cycle.push(n.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(n.to_string(), 1);
        path.push(n.to_string());
        for m in graph.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, graph, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in graph.keys() {
        if let Some(c) = visit(n, graph, &mut state, &mut Vec::new()) {
            return Some(c);
        }
    }
    None
}

#[test]
fn no_import_cycles_between_modules() {
    let ffi = ffi_crates();
    assert!(ffi.len() >= 4, "ffi crates found: {ffi:?}");
    for krate in ["numerics", "pipeline", "runtime", "view", "format", "cli"]
        .into_iter()
        .chain(ffi.iter().map(String::as_str))
    {
        let graph = module_graph(&workspace().join(krate).join("src"));
        // The format and the wrappers are small: one or two modules are no sign of a wrong path.
        assert!(
            graph.len() > 1 || krate == "format" || krate.starts_with("ffi/"),
            "{krate}: modules found"
        );
        if let Some(cycle) = find_cycle(&graph) {
            panic!("{krate}: import cycle {}", cycle.join(" → "));
        }
    }
}

/// The layers pipeline/README.md states, lowest first: `- layer N, what: `a` `b` …` lines.
fn stated_layers(readme: &str) -> BTreeMap<String, usize> {
    let mut layer = BTreeMap::new();
    for line in readme.lines().filter(|l| l.starts_with("- layer ")) {
        let n: usize = line[8..]
            .split(|c: char| !c.is_ascii_digit())
            .next()
            .and_then(|d| d.parse().ok())
            .expect("a layer number");
        let names = line.split_once(':').map_or("", |(_, rest)| rest);
        for name in names.split('`').skip(1).step_by(2) {
            layer.insert(name.to_string(), n);
        }
    }
    layer
}

/// Imports that reach into a higher layer, as `from (layer) → to (layer)`, and modules the
/// list leaves out.
fn layer_violations(graph: &BTreeMap<String, BTreeSet<String>>, layer: &BTreeMap<String, usize>) -> Vec<String> {
    let mut bad = Vec::new();
    for (from, deps) in graph {
        let Some(&lf) = layer.get(from) else {
            bad.push(format!("{from} is in no layer"));
            continue;
        };
        for to in deps {
            match layer.get(to) {
                Some(&lt) if lt > lf => bad.push(format!("{from} ({lf}) → {to} ({lt})")),
                None => bad.push(format!("{to} is in no layer")),
                _ => {}
            }
        }
    }
    bad
}

#[test]
fn modules_import_only_from_their_layer_or_below() {
    for (krate, least) in [("numerics", 8), ("pipeline", 20), ("runtime", 13)] {
        let readme = std::fs::read_to_string(workspace().join(krate).join("README.md")).expect("README.md");
        let layer = stated_layers(&readme);
        assert!(
            layer.len() >= least,
            "{krate}/README.md states the layers of every module: {layer:?}"
        );
        let graph = module_graph(&workspace().join(krate).join("src"));
        let bad = layer_violations(&graph, &layer);
        assert!(bad.is_empty(), "imports against {krate}/README.md's layers: {bad:?}");
    }
}

/// A grouped import names each of its modules.
#[test]
fn grouped_imports_are_read() {
    let dir = std::env::temp_dir().join(format!("ves-structure-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join("a.rs"), "use crate::{b::X, c, self};\n").expect("write");
    std::fs::write(dir.join("b.rs"), "").expect("write");
    let g = module_graph(&dir);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(
        g["a"],
        ["b", "c"].map(String::from).into_iter().collect::<BTreeSet<_>>()
    );
}

#[test]
fn layer_check_finds_a_planted_upward_import() {
    let layer = stated_layers("- layer 1, base: `memory`\n- layer 3, solvers: `linsolve`\n- layer 4, x: `mesh`\n");
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    g.entry("linsolve".into()).or_default().insert("memory".into());
    assert!(layer_violations(&g, &layer).is_empty());
    g.entry("linsolve".into()).or_default().insert("mesh".into());
    assert_eq!(layer_violations(&g, &layer), ["linsolve (3) → mesh (4)"]);
}

/// The library crates carry no application: no web server, terminal drawing or argument
/// parsing among their dependencies, optional or not (the server is ves-view, which only the
/// `ves` binary's crate uses).
#[test]
fn libraries_carry_no_application_dependencies() {
    let root = workspace();
    let application = [
        "axum",
        "hyper",
        "tokio",
        "clap",
        "indicatif",
        "tracing-subscriber",
        "ves-cli",
        "ves-view",
    ];
    let mut bad = Vec::new();
    let ffi = ffi_crates();
    for krate in ["format", "numerics", "pipeline", "runtime", "python"]
        .into_iter()
        .chain(ffi.iter().map(String::as_str))
    {
        let toml = std::fs::read_to_string(root.join(krate).join("Cargo.toml")).expect("Cargo.toml");
        let mut section = String::new();
        for line in toml.lines() {
            let line = line.trim();
            if line.starts_with('[') {
                section = line.to_string();
                continue;
            }
            if line.starts_with('#') || !section.ends_with("dependencies]") || section.contains("dev-") {
                continue;
            }
            let name = line.split(['=', ' ']).next().unwrap_or("");
            // Optional or not: the web server is a crate of its own (ves-view).
            if application.contains(&name) {
                bad.push(format!("{krate}: {name}"));
            }
        }
    }
    assert!(bad.is_empty(), "application dependencies of library crates: {bad:?}");
}

#[test]
fn cycle_finder_finds_a_planted_cycle() {
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    g.entry("mesh".into()).or_default().insert("fem".into());
    g.entry("fem".into()).or_default().insert("store".into());
    assert!(find_cycle(&g).is_none());
    g.entry("store".into()).or_default().insert("mesh".into());
    assert_eq!(
        find_cycle(&g).expect("cycle"),
        ["fem", "store", "mesh", "fem"].map(String::from)
    );
}

#[test]
fn readme_layout_names_every_folder() {
    let root = workspace();
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    // Folders git ignores (build output, `scripts/run`'s out/) are not part of the layout.
    let ignored: Vec<String> = std::fs::read_to_string(root.join(".gitignore"))
        .unwrap_or_default()
        .lines()
        .map(|l| l.trim().trim_matches('/').to_string())
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    let mut missing = Vec::new();
    for e in std::fs::read_dir(&root).expect("workspace").flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if e.path().is_dir()
            && !name.starts_with('.')
            && !ignored.contains(&name)
            && !readme.contains(&format!("`{name}/"))
        {
            missing.push(name);
        }
    }
    for sub in ["numerics/src", "pipeline/src", "runtime/src", "view/src", "cli/src"] {
        for e in std::fs::read_dir(root.join(sub)).expect("src").flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if e.path().is_dir() && !readme.contains(&format!("{name}/")) {
                missing.push(format!("{sub}/{name}"));
            }
        }
    }
    assert!(missing.is_empty(), "README.md's layout table does not name {missing:?}");
}

/// `unsafe` code outside the FFI crates stands in one module per crate (`os.rs`: the libc
/// calls behind safe functions; the format crate's `file.rs`, its one module that touches the
/// OS) and the C ABI's exported functions (`capi.rs`); unit tests (a `mod tests` at the end of
/// a file) are left out.
#[test]
fn unsafe_code_lives_in_one_module_per_crate() {
    let root = workspace();
    let mut offenders = Vec::new();
    for krate in ["format", "numerics", "pipeline", "runtime", "view", "cli"] {
        let mut files = Vec::new();
        rust_files(&root.join(krate).join("src"), &mut files);
        for f in &files {
            let name = f.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name == "os.rs" || name == "capi.rs" || name == "file.rs" && krate == "format" {
                continue;
            }
            let text = std::fs::read_to_string(f).expect("source");
            let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
            for (i, line) in code.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                if code.contains("unsafe ") || code.contains("unsafe{") {
                    offenders.push(format!("{}:{}: {}", f.display(), i + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "unsafe outside os.rs and capi.rs:\n{}",
        offenders.join("\n")
    );
}

/// C declarations (`extern "C" { … }` blocks) live in the `src/sys.rs` of the `ffi/` crate of
/// their library, apart from its safe layer; calls into `-sys` crates of C libraries only in
/// `ffi/` too. Exported C functions (`extern "C" fn`) are the C ABI's, allowed anywhere.
#[test]
fn c_declarations_live_only_in_ffi() {
    let root = workspace();
    let ffi = ffi_crates();
    let mut offenders = Vec::new();
    let crates = [
        "format", "numerics", "pipeline", "runtime", "view", "tests", "cli", "python", "fuzz",
    ]
    .into_iter()
    .chain(ffi.iter().map(String::as_str));
    for krate in crates {
        let in_ffi = krate.starts_with("ffi/");
        let mut files = Vec::new();
        rust_files(&root.join(krate), &mut files);
        for f in files
            .iter()
            .filter(|f| !f.components().any(|c| c.as_os_str() == "target"))
        {
            let sys_rs = f == &root.join(krate).join("src").join("sys.rs");
            let text = std::fs::read_to_string(f).expect("source");
            for (i, line) in text.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                let declares = code.contains("extern \"C\" {") || code.contains("extern \"C\"{");
                let sys_crate = code
                    .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .any(|w| w.contains(concat!("_sys", "::")) && !w.starts_with("libfuzzer_sys"));
                if (declares && !sys_rs) || (sys_crate && !in_ffi) {
                    offenders.push(format!("{}:{}: {}", f.display(), i + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "C declarations outside ffi/*/src/sys.rs:\n{}",
        offenders.join("\n")
    );
}

/// One `ffi/` crate's manifest, as far as the licence split needs it.
struct Manifest {
    name: String,
    links: Option<String>,
    license: String,
    /// Path dependencies of every kind (normal, build, dev, per target), relative to the workspace.
    path_deps: Vec<String>,
    /// Every dependency's package name.
    dep_names: Vec<String>,
}

fn manifest(krate: &str) -> Manifest {
    let path = workspace().join(krate).join("Cargo.toml");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let doc: toml::Table = text.parse().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let package = doc.get("package").and_then(|p| p.as_table()).expect("[package]");
    let string = |key: &str| package.get(key).and_then(|v| v.as_str()).map(String::from);
    let license = match package.get("license") {
        // `license.workspace = true`: the workspace's.
        Some(toml::Value::Table(_)) => workspace_license(),
        Some(v) => v.as_str().unwrap_or("").to_string(),
        None => String::new(),
    };
    let mut tables = Vec::new();
    for kind in ["dependencies", "build-dependencies", "dev-dependencies"] {
        tables.extend(doc.get(kind).and_then(|t| t.as_table()));
        for target in doc
            .get("target")
            .and_then(|t| t.as_table())
            .into_iter()
            .flat_map(|t| t.values())
        {
            tables.extend(target.get(kind).and_then(|t| t.as_table()));
        }
    }
    let (mut path_deps, mut dep_names) = (Vec::new(), Vec::new());
    for (key, spec) in tables.into_iter().flatten() {
        let package_name = spec.get("package").and_then(|p| p.as_str()).unwrap_or(key);
        dep_names.push(package_name.to_string());
        if let Some(p) = spec.get("path").and_then(|p| p.as_str()) {
            // Normalise `ffi/metis/../gmsh` to `ffi/gmsh` (paths stay inside the workspace).
            let mut parts: Vec<&str> = krate.split('/').collect();
            for c in p.split('/') {
                match c {
                    ".." => {
                        parts.pop();
                    }
                    "." | "" => {}
                    c => parts.push(c),
                }
            }
            path_deps.push(parts.join("/"));
        }
    }
    Manifest {
        name: string("name").expect("package.name"),
        links: string("links"),
        license,
        path_deps,
        dep_names,
    }
}

fn workspace_license() -> String {
    let text = std::fs::read_to_string(workspace().join("Cargo.toml")).expect("Cargo.toml");
    let doc: toml::Table = text.parse().expect("workspace Cargo.toml");
    doc.get("workspace")
        .and_then(|w| w.get("package"))
        .and_then(|p| p.get("license"))
        .and_then(|l| l.as_str())
        .expect("workspace.package.license")
        .to_string()
}

/// gmsh is GPL: only ves-gmsh loads it, and the other C wrappers (and the permissive crates,
/// format and runtime) reach it through no path dependency, however indirect, so they build
/// and are licensed without it.
#[test]
fn only_ves_gmsh_depends_on_gmsh() {
    let root = workspace();
    let ffi = ffi_crates();
    let gmsh: Vec<&str> = ffi
        .iter()
        .map(String::as_str)
        .filter(|k| {
            let sys = root.join(k).join("src/sys.rs");
            std::fs::read_to_string(sys).is_ok_and(|t| t.contains("\"libgmsh.so"))
        })
        .collect();
    assert_eq!(gmsh, ["ffi/gmsh"], "the crates that load gmsh");
    assert_eq!(manifest("ffi/gmsh").name, "ves-gmsh");
    assert!(manifest("ffi/gmsh").license.contains("GPL"), "ves-gmsh links gmsh: GPL");
    let others = ffi.iter().filter(|k| k.as_str() != "ffi/gmsh").map(String::as_str);
    for krate in others.chain(["format", "runtime", "numerics"]) {
        // Every crate reachable through path dependencies, the crate itself first.
        let mut reached = vec![krate.to_string()];
        let mut next = 0;
        while next < reached.len() {
            let m = manifest(&reached[next]);
            assert!(
                m.links.as_deref() != Some("gmsh") && !m.dep_names.iter().any(|d| d.contains("gmsh")),
                "{krate} reaches gmsh: {} ({}) links it or depends on it",
                reached[next],
                m.name
            );
            for d in m.path_deps {
                if !reached.contains(&d) {
                    reached.push(d);
                }
            }
            next += 1;
        }
        let own = manifest(krate);
        assert!(
            !own.license.contains("GPL"),
            "{krate}: licence {} without gmsh",
            own.license
        );
        // Nor does it link or load gmsh by hand, from its build script, an `extern` block or a
        // library of its own.
        let mut files = vec![root.join(krate).join("build.rs")];
        rust_files(&root.join(krate).join("src"), &mut files);
        for f in files.iter().filter(|f| f.is_file()) {
            let text = std::fs::read_to_string(f).expect("source");
            assert!(
                !text.contains("rustc-link-lib=gmsh")
                    && !text.contains("name = \"gmsh\"")
                    && !text.contains("\"libgmsh.so"),
                "{} links gmsh",
                f.display()
            );
        }
    }
}
