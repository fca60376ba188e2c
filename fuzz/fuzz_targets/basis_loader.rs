//! The basis loader on mutated basis files: never panics or aborts; whatever loads is finite
//! and consistent. The input bytes overwrite a window of a valid small basis (a corrupted or
//! truncated file), so the fuzzer explores HDF5 structures, not only "not HDF5".
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

/// A valid basis to corrupt: `VES_FUZZ_BASIS` (default /tmp/ves-fuzz/seed.h5, made by
/// scripts/fuzz with `ves precompute`).
fn seed() -> &'static [u8] {
    static SEED: OnceLock<Vec<u8>> = OnceLock::new();
    SEED.get_or_init(|| {
        let path = std::env::var("VES_FUZZ_BASIS").unwrap_or_else(|_| "/tmp/ves-fuzz/seed.h5".into());
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e} (run scripts/fuzz, which makes it)"))
    })
}

fuzz_target!(|data: &[u8]| {
    // libfuzzer-sys aborts from its panic hook; the loader turns panics of the HDF5 layer
    // (hdf5-metno formats corrupted names unchecked) into errors with catch_unwind, so let
    // panics unwind: one escaping the loader still reaches libfuzzer-sys's own catch and aborts.
    static QUIET: std::sync::Once = std::sync::Once::new();
    QUIET.call_once(|| std::panic::set_hook(Box::new(|_| {})));
    if data.len() < 9 {
        return;
    }
    let base = seed();
    let mut bytes = base.to_vec();
    // First 8 bytes: where to write (and whether to truncate); the rest: what.
    let at = u64::from_le_bytes(data[..8].try_into().unwrap_or([0; 8])) as usize % bytes.len();
    let patch = &data[8..];
    if patch[0] & 1 == 1 {
        bytes.truncate(at.max(1));
    } else {
        let end = (at + patch.len() - 1).min(bytes.len());
        bytes[at..end].copy_from_slice(&patch[1..1 + end - at]);
    }
    let dir = std::env::temp_dir().join(format!("ves-fuzz-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("basis.h5");
    if std::fs::write(&path, &bytes).is_err() {
        return;
    }
    let opts = ves_runtime::basis::LoadOptions::default();
    if let Ok(b) = ves_runtime::basis::load(&path, &opts) {
        assert!(b.rest.iter().flatten().all(|v| v.is_finite()));
        assert!(b.phi.iter().all(|v| v.is_finite()));
        assert!(b.eigenvalues.iter().all(|&l| l > 0.0 && l.is_finite()));
        assert!(b.triangles.iter().flatten().all(|&v| (v as usize) < b.rest.len()));
    }
});
