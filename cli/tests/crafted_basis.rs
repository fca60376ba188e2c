//! Crafted basis files (issue "Nothing lost, nobody in"), made with h5py from a good basis: data
//! kept outside the file, values physics forbids, names that drive a terminal, linked spaces that
//! multiply the work. Each must end in one line naming the file and the dataset, exit status 1,
//! and nothing read from elsewhere written anywhere.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The good scene with exact static compliance stored (the blocks the runtime feels).
fn basis_with_compliance() -> (tempfile::TempDir, PathBuf) {
    let scene = GOOD.replace("[modes]", "[static_correction]\nregion = \"surface\"\n[modes]");
    let (dir, path) = workdir(&scene);
    let basis = dir.path().join("beam.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    (dir, basis)
}

/// Copies `basis` to `name` beside it and runs `edit` (Python, h5py) on the copy with `f` the
/// file opened read-write, `g` its global space and `np` numpy.
fn craft(basis: &Path, name: &str, edit: &str) -> PathBuf {
    let copy = basis.with_file_name(name);
    std::fs::copy(basis, &copy).unwrap();
    let script = format!(
        "import sys, h5py, numpy as np\nf = h5py.File(sys.argv[1], 'r+')\ng = f['spaces/global']\n{edit}\nf.close()\n"
    );
    let o = Command::new("python3")
        .arg("-c")
        .arg(&script)
        .arg(&copy)
        .output()
        .expect("python3 runs");
    assert!(o.status.success(), "crafting {name}: {}", stderr(&o));
    copy
}

/// Runs `args` and checks the file is refused: exit 1, one line, naming the file and each of
/// `what`.
fn refused(args: &[&str], file: &Path, what: &[&str]) -> std::process::Output {
    let o = ves(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{args:?} accepted it: {err}");
    assert!(
        err.contains(file.to_str().unwrap()),
        "{args:?} does not name the file: {err}"
    );
    for w in what {
        assert!(err.contains(w), "{args:?} does not say {w:?}: {err}");
    }
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    o
}

/// A script that presses the first surface vertex for a moment.
fn press_script(dir: &Path) -> String {
    let script = dir.join("hand.csv");
    std::fs::write(&script, "0,1,0.05,0.05\n0.01,1,0.05,0.05\n").unwrap();
    format!("script:{}", script.display())
}

/// `mesh/nodes` rebuilt with external raw storage passed `info`, `bench`, `session` and
/// `export`, and `ves export --vtu` copied the other file (e.g. /etc/passwd) into the .vtu.
/// Likewise a virtual dataset, an external link, and a filter the writer never uses.
#[test]
fn data_kept_outside_the_file_is_refused_before_it_is_read() {
    let (dir, basis) = good_basis();
    let secret = dir.path().join("secret.txt");
    std::fs::write(&secret, "SECRET-LINE ".repeat(100_000)).unwrap();
    let other = dir.path().join("other.h5");
    std::fs::copy(&basis, &other).unwrap();
    let s = secret.to_str().unwrap();
    let o = other.to_str().unwrap();
    let external = craft(
        &basis,
        "external.h5",
        &format!(
            "n = g['mesh/nodes'].shape\ndel g['mesh/nodes']\n\
             g.create_dataset('mesh/nodes', shape=n, dtype='<f8', external=[({s:?}, 0, n[0] * 24)])"
        ),
    );
    let virtual_ = craft(
        &basis,
        "virtual.h5",
        &format!(
            "n = g['mesh/nodes'].shape\ndel g['mesh/nodes']\nl = h5py.VirtualLayout(shape=n, dtype='<f8')\n\
             l[:] = h5py.VirtualSource({o:?}, 'spaces/global/mesh/nodes', shape=n)\n\
             g.create_virtual_dataset('mesh/nodes', l)"
        ),
    );
    let elink = craft(
        &basis,
        "elink.h5",
        &format!("del g['mesh/nodes']\ng['mesh/nodes'] = h5py.ExternalLink({o:?}, '/spaces/global/mesh/nodes')"),
    );
    let filter = craft(
        &basis,
        "fletcher.h5",
        "v = g['mesh/nodes'][...]\ndel g['mesh/nodes']\ng.create_dataset('mesh/nodes', data=v, fletcher32=True)",
    );
    let device = press_script(dir.path());
    for (file, why) in [
        (&external, "external file"),
        (&virtual_, "Virtual"),
        (&elink, "link into another file"),
        (&filter, "Fletcher32"),
    ] {
        let f = file.to_str().unwrap();
        let vtu = dir
            .path()
            .join(format!("{}-vtu", file.file_stem().unwrap().to_str().unwrap()));
        let v = vtu.to_str().unwrap();
        for args in [
            vec!["info", f],
            vec!["bench", f],
            vec!["export", f, "--vtu", v],
            vec!["session", f, "--device", &device, "--duration", "0.01"],
        ] {
            refused(&args, file, &["mesh/nodes", why]);
        }
        let written: Vec<_> = std::fs::read_dir(&vtu)
            .map(|d| d.flatten().collect())
            .unwrap_or_default();
        assert!(written.is_empty(), "{f}: export wrote {written:?}");
    }
    // The good file still passes, and its export holds its own data.
    let o = ves(&["info", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let vtu = dir.path().join("good-vtu");
    let o = ves(&["export", basis.to_str().unwrap(), "--vtu", vtu.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read(vtu.join("global.vtu")).unwrap();
    assert!(!text.windows(6).any(|w| w == b"SECRET"));
}

/// Values physics forbids were accepted: negative, huge or antisymmetric compliance (the felt
/// force was 0 instead of 1.5 N), β = 1e300 (every runtime step quarantined, exit 0), negative
/// frequencies or ones that disagree with the eigenvalues, eigenvalues out of order, all-zero
/// (degenerate) triangles and tets, a default space the file does not hold.
#[test]
fn values_physics_forbids_are_refused_naming_the_dataset() {
    let (dir, basis) = basis_with_compliance();
    // k: the most compliant block (a free vertex; blocks of supported vertices are zero).
    let blocks = |expr: &str| {
        format!(
            "b = g['compliance/blocks']\nv = b[...]\nk = int(np.argmax(np.trace(v, axis1=1, axis2=2)))\n{expr}\nb[...] = v"
        )
    };
    let cases = [
        ("negative.h5", blocks("v[k] = -v[k]"), "compliance/blocks"),
        ("huge.h5", blocks("v[k] = v[k] * 1e20"), "no elastic part is so soft"),
        (
            "antisymmetric.h5",
            blocks("v[k, 0, 1] = v[k, 0, 0]\nv[k, 1, 0] = -v[k, 0, 0]"),
            "not symmetric",
        ),
        (
            "beta.h5",
            "f['material'].attrs['rayleigh_beta'] = 1e300".to_string(),
            "rayleigh_beta",
        ),
        (
            "negative_hz.h5",
            "d = g['modes/frequencies_hz']\nd[...] = -d[...]".to_string(),
            "modes/frequencies_hz",
        ),
        (
            "wrong_hz.h5",
            "d = g['modes/frequencies_hz']\nd[...] = 1.5 * d[...]".to_string(),
            "modes/frequencies_hz",
        ),
        (
            "descending.h5",
            "d = g['modes/eigenvalues']\nd[...] = d[...][::-1]".to_string(),
            "ascending",
        ),
        (
            "zero_triangles.h5",
            "d = g['mesh/surface_triangles']\nd[...] = 0".to_string(),
            "mesh/surface_triangles",
        ),
        (
            "degenerate_tet.h5",
            "d = g['mesh/tets']\nv = d[...]\nv[0, 1] = v[0, 0]\nd[...] = v".to_string(),
            "mesh/tets",
        ),
        (
            "default.h5",
            "f.attrs['default_space'] = 'nowhere'".to_string(),
            "default_space",
        ),
    ];
    let device = press_script(dir.path());
    for (name, edit, why) in &cases {
        let file = craft(&basis, name, edit);
        let f = file.to_str().unwrap();
        let dataset = if name.starts_with("beta") { "rayleigh_beta" } else { why };
        refused(&["info", f], &file, &[why, dataset]);
        // The runtime reads no tets.
        if *name != "degenerate_tet.h5" {
            refused(
                &["session", f, "--device", &device, "--duration", "0.01"],
                &file,
                &[why],
            );
        }
    }
    let o = ves(&["info", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout_of(&o).contains("static correction at"), "{}", stdout_of(&o));
}

fn stdout_of(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// 2000 hard-linked spaces took 31 s and 660 MB before refusing; spaces that are soft links to one
/// another multiplied the reading work the same way.
#[test]
fn linked_spaces_cannot_multiply_the_work() {
    let (_dir, basis) = good_basis();
    let hard = craft(
        &basis,
        "hard2000.h5",
        "for i in range(2000):\n    f['spaces/s%d' % i] = g",
    );
    let t = std::time::Instant::now();
    refused(&["info", hard.to_str().unwrap()], &hard, &["2001 spaces"]);
    assert!(t.elapsed().as_secs_f64() < 10.0, "{:?}", t.elapsed());
    let few_hard = craft(&basis, "hard3.h5", "for i in range(3):\n    f['spaces/s%d' % i] = g");
    refused(
        &["info", few_hard.to_str().unwrap()],
        &few_hard,
        &["spaces/global", "hard links"],
    );
    let soft = craft(
        &basis,
        "soft.h5",
        "for i in range(40):\n    f['spaces/s%02d' % i] = h5py.SoftLink('/spaces/global')",
    );
    refused(&["info", soft.to_str().unwrap()], &soft, &["share data"]);
}

/// `ves info` printed terminal escape sequences from space names verbatim.
#[test]
fn names_from_the_file_never_reach_the_terminal_raw() {
    let (_dir, basis) = good_basis();
    // ESC ] 0 ; … BEL sets the terminal's title, ESC [ 2 J clears the screen.
    let evil = r"'\x1b]0;owned\x07\x1b[2J'";
    let renamed = craft(
        &basis,
        "renamed.h5",
        &format!("f.move('spaces/global', 'spaces/' + {evil})\nf.attrs['default_space'] = {evil}"),
    );
    let f = renamed.to_str().unwrap();
    for args in [vec!["info", f], vec!["bench", f]] {
        let o = refused(&args, &renamed, &["/spaces", "space name"]);
        assert!(
            !o.stderr.contains(&0x1b) && !o.stdout.contains(&0x1b),
            "{args:?}: raw escape printed"
        );
    }
    let bidi = craft(&basis, "bidi.h5", "f.move('spaces/global', 'spaces/glob\\u202eal')");
    let o = refused(&["info", bidi.to_str().unwrap()], &bidi, &["space name"]);
    assert!(!stderr(&o).contains('\u{202E}'), "{}", stderr(&o));
    // Other text from the file is printed escaped.
    let generator = craft(&basis, "generator.h5", "f.attrs['generator'] = 'ves \\x1b[31mred'");
    let o = ves(&["info", generator.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!o.stdout.contains(&0x1b), "{}", stdout_of(&o));
    assert!(stdout_of(&o).contains("\\u{1b}[31mred"), "{}", stdout_of(&o));
}

/// `ves verify` on a crafted basis failed with a Python TypeError that did not name the file.
#[test]
fn verify_checks_the_basis_first_and_names_it() {
    let (_dir, basis) = good_basis();
    let zero = craft(&basis, "zero.h5", "d = g['mesh/surface_triangles']\nd[...] = 0");
    let hz = craft(&basis, "hz.h5", "d = g['modes/frequencies_hz']\nd[...] = -d[...]");
    for (file, why) in [(&zero, "mesh/surface_triangles"), (&hz, "modes/frequencies_hz")] {
        refused(
            &["verify", file.to_str().unwrap(), "--against", "scikit-fem"],
            file,
            &[why],
        );
    }
}

/// A dataset declared at 1 GB but never written, in a file made sparse to pass the file-size
/// check: `ves info` allocated the whole of it (4 GB asked in the reported case) and aborted.
#[test]
fn a_dataset_never_written_in_a_sparse_file_is_refused_before_it_is_read() {
    let (_dir, basis) = common::good_basis();
    let crafted = craft(
        &basis,
        "sparse.h5",
        "del g['mesh/tets']\ng.create_dataset('mesh/tets', shape=(62_500_000, 4), dtype='u4', chunks=(65536, 4))",
    );
    // Apparent size 5 GiB, a few kilobytes on disk.
    std::fs::OpenOptions::new()
        .write(true)
        .open(&crafted)
        .and_then(|f| f.set_len(5 << 30))
        .expect("sparse");
    let path = crafted.to_str().unwrap();
    refused(&["info", path], &crafted, &["mesh/tets", "never written"]);
    let out = crafted.with_file_name("vtu");
    refused(
        &["export", path, "--vtu", out.to_str().unwrap()],
        &crafted,
        &["never written"],
    );
}

/// The good scene with a tip load case (the default contact patch is stored too).
fn basis_with_load() -> (tempfile::TempDir, PathBuf) {
    let tip = "[[load]]\nname = \"tip\"\nplane = { axis = \"x\", value = 1.0 }\nforce = [0.0, 0.0, -1000.0]\n";
    let (dir, path) = workdir(&format!("{GOOD}{tip}"));
    let basis = dir.path().join("beam.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    (dir, basis)
}

/// Issue 40: values and groups the reader let through. Contact weights of ±1e9 that still sum
/// to 1 (the felt force fell from 6.3 N to 6e-10 N), `contact` or `loads` stored as a dataset
/// (read as absent), an inverted `fixed_mask`, load data of 1e300 (the page sent `inf`) and a
/// `max_displacement` never compared with the data: `ves info` accepted some, `ves export` and
/// the runtime's loader (`ves session`) all. Each is refused by all three, naming the dataset,
/// and export writes nothing; so are a felt-error table out of order, a share above 1 and
/// datasets of unequal length.
#[test]
fn every_reader_refuses_damaged_contact_loads_and_mask() {
    let (dir, basis) = basis_with_load();
    let cases = [
        (
            "weights.h5",
            "w = g['contact/weights']\nv = w[...]\no = g['contact/offsets'][...]\n\
             k = next(k for k in range(len(o) - 1) if o[k + 1] - o[k] >= 2)\n\
             v[o[k]] += 1e9\nv[o[k] + 1] -= 1e9\nw[...] = v",
            &["contact", "outside [0, 1]"][..],
        ),
        (
            "contact_dataset.h5",
            "del g['contact']\ng['contact'] = np.zeros(3)",
            &["contact", "not a group"],
        ),
        (
            "loads_dataset.h5",
            "del g['loads']\ng['loads'] = np.zeros(3)",
            &["loads", "not a group"],
        ),
        (
            "inverted_mask.h5",
            "d = g['mesh/fixed_mask']\nd[...] = 1 - d[...]",
            &["mesh/fixed_mask", "mesh/fixed_dofs"],
        ),
        (
            "huge_load.h5",
            "c = g['loads/tip']\nd = c['displacement']\nv = d[...]\nv[-1] = [1e300, 0.0, 0.0]\nd[...] = v\n\
             c.attrs['max_displacement'] = 1e300",
            &["loads/tip/displacement", "single precision"],
        ),
        (
            "felt_order.h5",
            "d = g['felt/nodes']\nv = d[...]\nv[0], v[-1] = v[-1], v[0]\nd[...] = v",
            &["felt/nodes", "ascending"],
        ),
        (
            "felt_share.h5",
            "d = g['felt/truncation']\nv = d[...]\nv[0] = 2.0\nd[...] = v",
            &["felt/truncation", "outside [0, 1]"],
        ),
        (
            "felt_extent.h5",
            "n = len(g['felt/mesh_error'])\ndel g['felt/mesh_error']\ng['felt/mesh_error'] = np.zeros(n + 1)",
            &["felt/", "mesh errors"],
        ),
        (
            "wrong_max.h5",
            "c = g['loads/tip']\nc.attrs['max_displacement'] = 2 * c.attrs['max_displacement']",
            &["loads/tip", "max_displacement"],
        ),
    ];
    let device = press_script(dir.path());
    for (name, edit, why) in cases {
        refused_by_every_reader(&craft(&basis, name, edit), dir.path(), &device, why);
    }
    let o = ves(&["info", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A 1 MB file whose `contact/nodes` is 2e8 deflated zeros (800 MB of values) made `ves info`
/// allocate them all (2.4 GB with the weights). It is refused before the values are read: under
/// a 600 MB address-space limit, in one line naming the dataset.
#[test]
fn a_compressed_contact_dataset_is_refused_before_it_is_allocated() {
    let (dir, basis) = basis_with_load();
    let file = craft(
        &basis,
        "zeros.h5",
        "del g['contact/nodes']\nn = 200_000_000\nstep = 1 << 22\n\
         d = g.create_dataset('contact/nodes', shape=(n,), dtype='<u4', chunks=(1 << 20,), compression='gzip')\n\
         z = np.zeros(step, dtype='<u4')\nfor i in range(0, n, step):\n    d[i:i + step] = z[:min(step, n - i)]",
    );
    let f = file.to_str().unwrap();
    let vtu = dir.path().join("zeros-vtu");
    for args in [vec!["info", f], vec!["export", f, "--vtu", vtu.to_str().unwrap()]] {
        let o = Command::new("prlimit")
            .arg("--as=600000000")
            .arg(env!("CARGO_BIN_EXE_ves"))
            .args(&args)
            .output()
            .expect("prlimit runs");
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(f) && err.contains("contact/nodes"), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    }
    assert!(!vtu.exists());
}

/// `transfer/<from>` was never validated: an entry of 1e9 (a switch of space multiplied the
/// state by it) and `transfer` stored as a dataset passed `ves info`; the first passed
/// `ves session` too. Both are refused by info, export and session, naming the dataset.
#[test]
fn a_damaged_transfer_is_refused_by_every_reader() {
    let voi = "[[voi]]\nname = \"tip\"\nbox = { min = [0.8, -0.1, -0.1], max = [1.1, 0.2, 0.2] }\nsize = 0.02\n";
    let (dir, path) = workdir(&format!("{GOOD}{voi}"));
    let basis = dir.path().join("beam.h5");
    let o = ves(&["precompute", path.to_str().unwrap(), "-o", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let device = press_script(dir.path());
    for (name, edit, why) in [
        (
            "big.h5",
            "d = g['transfer/tip']\nv = d[...]\nv[0, 0] = 1e9\nd[...] = v",
            &["transfer/tip", "1e9", "row 0, column 0"][..],
        ),
        (
            "dataset.h5",
            "t = f['spaces/tip']\ndel t['transfer']\nt['transfer'] = np.zeros(3)",
            &["transfer", "not a group"],
        ),
    ] {
        refused_by_every_reader(&craft(&basis, name, edit), dir.path(), &device, why);
    }
    let o = ves(&["info", basis.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `ves info`, `ves export` (writing nothing) and `ves session` each refuse `file`, naming it and
/// `why`.
fn refused_by_every_reader(file: &Path, dir: &Path, device: &str, why: &[&str]) {
    let f = file.to_str().unwrap();
    let vtu = dir.join(format!("{}-vtu", file.file_name().unwrap().to_string_lossy()));
    refused(&["info", f], file, why);
    refused(&["export", f, "--vtu", vtu.to_str().unwrap()], file, why);
    assert!(!vtu.exists(), "{f}: export wrote {}", vtu.display());
    refused(&["session", f, "--device", device, "--duration", "0.01"], file, why);
}
