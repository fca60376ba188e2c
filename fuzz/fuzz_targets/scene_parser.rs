//! The scene parser on arbitrary text: never panics; an error is one line naming the file;
//! whatever parses is valid.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;
use ves_pipeline::scene::Scene;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    // Geometry paths resolve beside the scene file; a missing file is itself an error path.
    match Scene::parse(Path::new("/tmp/ves-fuzz/scene.toml"), text) {
        Ok(s) => {
            assert!(s.material.young > 0.0 && s.material.young.is_finite());
            assert!(s.material.poisson > -1.0 && s.material.poisson < 0.5);
            assert!(s.mesh.size > 0.0 && s.mesh.size.is_finite());
            assert!(matches!(s.mesh.order, 1 | 2));
            assert!(s.modes.count >= 1 && s.modes.count <= 2000);
        }
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "multi-line error: {m}");
            assert!(m.contains("scene.toml"), "error without the file: {m}");
        }
    }
});
