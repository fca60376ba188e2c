//! Helpers shared by the CLI test binaries: run `ves`, make a scene beside a copy of the
//! cantilever's STEP file, precompute a small basis, check the failure contract.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub const GOOD: &str = r#"
name = "beam"
[geometry]
step = "beam.step"
unit = "mm"
[material]
young = 2.1e11
poisson = 0.3
density = 7850.0
[mesh]
size = 0.05
order = 1
[[fixed]]
plane = { axis = "x", value = 0.0 }
[modes]
count = 4
"#;

pub fn ves(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ves"))
        .args(args)
        .output()
        .expect("ves runs")
}

/// What a run said on stderr, without the progress lines a run without a terminal logs
/// (`ves::progress` at INFO): the errors and warnings a test checks.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr)
        .lines()
        .filter(|l| !l.contains(" ves::progress: "))
        .map(|l| format!("{l}\n"))
        .collect()
}

/// The JSON object on the last line of stdout (the `--json` contract).
pub fn last_json(o: &Output) -> serde_json::Value {
    let stdout = String::from_utf8_lossy(&o.stdout);
    serde_json::from_str(stdout.lines().last().expect("a JSON line")).expect("the last line is JSON")
}

/// `pvpython --force-offscreen-rendering tests/paraview/SCRIPT ARGS…`, which must succeed (a
/// missing pvpython fails: scripts/setup installs it); the JSON of its last line.
pub fn pvpython_json(script: &str, args: &[&std::ffi::OsStr]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/paraview")
        .join(script);
    let o = Command::new("pvpython")
        .arg("--force-offscreen-rendering")
        .arg(script)
        .args(args)
        .output()
        .expect("pvpython runs (Debian's paraview: scripts/setup installs it)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_str(String::from_utf8_lossy(&o.stdout).lines().last().expect("JSON line")).expect("JSON")
}

/// A JSON array of numbers.
pub fn numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not a list: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap_or_else(|| panic!("not a number: {x}")))
        .collect()
}

/// The first space's frequencies in a `ves precompute --json` summary.
pub fn frequencies(summary: &serde_json::Value) -> Vec<f64> {
    numbers(&summary["spaces"][0]["frequencies_hz"])
}

/// `ves precompute SCENE -o OUT --json`, which must succeed; its JSON.
pub fn precompute_json(scene: &Path, out: &Path) -> serde_json::Value {
    precompute_json_with(scene, out, &[])
}

/// [`precompute_json`] with more flags.
pub fn precompute_json_with(scene: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    precompute_json_in(scene, out, extra, None)
}

/// [`precompute_json`] with its own mesh cache `cache` (`VES_CACHE_DIR`): no mesh or refinement
/// remembered by another test's run is used.
pub fn precompute_json_cached(scene: &Path, out: &Path, cache: &Path) -> serde_json::Value {
    precompute_json_in(scene, out, &[], Some(cache))
}

/// `ves precompute SCENE -o OUT --json EXTRA…`, in the mesh cache `cache` when given, which
/// must succeed; its JSON.
fn precompute_json_in(scene: &Path, out: &Path, extra: &[&str], cache: Option<&Path>) -> serde_json::Value {
    let mut command = Command::new(env!("CARGO_BIN_EXE_ves"));
    command
        .args([
            "precompute",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ])
        .args(extra);
    if let Some(cache) = cache {
        command.env("VES_CACHE_DIR", cache);
    }
    let o = command.output().expect("ves runs");
    assert!(
        o.status.success(),
        "{}: {}",
        scene.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    last_json(&o)
}

/// `ves session BASIS --device script:SCRIPT --json`, which must succeed; its JSON.
pub fn session_json(basis: &Path, script: &Path) -> serde_json::Value {
    session_json_with(basis, script, &[])
}

/// [`session_json`] with more flags.
pub fn session_json_with(basis: &Path, script: &Path, extra: &[&str]) -> serde_json::Value {
    let device = format!("script:{}", script.display());
    let mut args = vec!["session", basis.to_str().unwrap(), "--device", &device, "--json"];
    args.extend_from_slice(extra);
    let o = ves(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    last_json(&o)
}

/// A directory holding the cantilever STEP file as `beam.step` and `scene` as `scene.toml`.
pub fn workdir(scene: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let step = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/cantilever/cantilever.step");
    std::fs::copy(step, dir.path().join("beam.step")).expect("copy step");
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, scene).expect("write scene");
    (dir, path)
}

/// A directory with the good scene precomputed into `beam.h5`.
pub fn good_basis() -> (tempfile::TempDir, PathBuf) {
    let (dir, path) = workdir(GOOD);
    let basis = dir.path().join("beam.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (dir, basis)
}

/// Runs `ves precompute` on a bad scene and checks the contract for failures.
pub fn fails(scene: &str, expect: &[&str]) {
    let (dir, path) = workdir(scene);
    let out = dir.path().join("out.h5");
    std::fs::write(&out, b"previous result").expect("sentinel");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let stderr = stderr(&o);
    assert!(!o.status.success(), "should fail: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected, got: {stderr}");
    for e in expect {
        assert!(lines[0].contains(e), "{:?} should mention {e:?}", lines[0]);
    }
    assert_eq!(
        std::fs::read(&out).expect("sentinel kept"),
        b"previous result",
        "existing output overwritten"
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .collect();
    assert_eq!(leftovers.len(), 3, "files left behind: {leftovers:?}");
}

/// Asserts that a run failed and that its message mentions `what`.
pub fn assert_refused(o: &Output, what: &str) {
    let e = stderr(o);
    assert!(
        !o.status.success() && e.contains(what),
        "expected a refusal mentioning {what:?}: {e}"
    );
}

/// The number written right after `marker` in `text` (the size an error message advises).
pub fn number_after(text: &str, marker: &str) -> f64 {
    text.split(marker)
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.trim_end_matches([',', ';']).parse().ok())
        .unwrap_or_else(|| panic!("no number after {marker:?} in {text}"))
}

/// The corpus block (`pmi_block_2holes.step`, which names every face "PartBody") written to
/// `dir/name` with each face named by its place in the file's shell: "f1" … "f30".
pub fn block_with_named_faces(dir: &Path, name: &str) -> PathBuf {
    let step = Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases/corpus/pmi_block_2holes.step");
    let text = std::fs::read_to_string(step).expect("the corpus block");
    let shell = text
        .split("CLOSED_SHELL(")
        .nth(1)
        .and_then(|s| s.split(")) ;").next())
        .expect("its shell");
    let order: Vec<&str> = shell.split('(').nth(1).expect("its faces").split(',').collect();
    assert_eq!(order.len(), 30);
    let mut named = text.clone();
    for (k, id) in order.iter().enumerate() {
        let from = format!("{id}=ADVANCED_FACE('PartBody'");
        assert_eq!(named.matches(&from).count(), 1, "{from}");
        named = named.replace(&from, &format!("{id}=ADVANCED_FACE('f{}'", k + 1));
    }
    write_file(dir, name, &named)
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write a test file");
    path
}

/// `mkfifo path`.
pub fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    assert_eq!(
        unsafe { libc::mkfifo(c.as_ptr(), 0o600) },
        0,
        "mkfifo {}",
        path.display()
    );
}

/// `ves view INPUT --port PORT --duration SECONDS --json`, its stdin closed, stdout piped, with
/// `env` set: the process, its stdout after the URL line (the `--json` statistics come there at
/// the end), and the loopback URL it printed.
pub fn start_view(
    input: &Path,
    port: &str,
    seconds: &str,
    env: &[(&str, &Path)],
    stderr: std::process::Stdio,
) -> (
    std::process::Child,
    std::io::BufReader<std::process::ChildStdout>,
    String,
) {
    use std::io::BufRead;
    let mut server = Command::new(env!("CARGO_BIN_EXE_ves"))
        .args([
            "view",
            input.to_str().expect("a UTF-8 test path"),
            "--port",
            port,
            "--duration",
            seconds,
            "--json",
        ])
        .envs(env.iter().copied())
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(stderr)
        .spawn()
        .expect("ves view starts");
    let mut out = std::io::BufReader::new(server.stdout.take().expect("stdout"));
    let mut line = String::new();
    out.read_line(&mut line).expect("the URL line");
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://127.0.0.1:"))
        .unwrap_or_else(|| panic!("no loopback URL in {line:?}"))
        .to_string();
    (server, out, url)
}

/// `ves export BASIS --vtu DIR`, then meshio reads the files against the basis (h5py):
/// `tests/vtk/vtu_check.py` must print "ok".
pub fn export_vtu_and_check(basis: &Path, dir: &Path) {
    let o = ves(&["export", basis.to_str().unwrap(), "--vtu", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let check = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vtk/vtu_check.py");
    let o = Command::new("python3")
        .args([check.to_str().unwrap(), dir.to_str().unwrap(), basis.to_str().unwrap()])
        .output()
        .expect("python3");
    assert!(
        o.status.success() && String::from_utf8_lossy(&o.stdout).contains("ok"),
        "{}",
        stderr(&o)
    );
}
