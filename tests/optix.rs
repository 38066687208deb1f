//! The optix backend's device programs compile with NVRTC 13.0 (CI installs it from PyPI, so a
//! broken `.cu` cannot land), and a machine without an NVIDIA driver gets a reason, not a
//! panic. Its exactness is tested with every other backend in backends_exact.rs.
#![cfg(feature = "optix")]

mod common;

use mochi::backend::BackendKind;
use mochi::backend::optix::programs::{self, Unit};

#[test]
fn device_programs_compile_with_nvrtc() {
    if !programs::nvrtc_present() {
        assert!(
            !common::ci(),
            "CI expects NVRTC (libnvrtc.so.13) on the library path: scripts/test.sh installs it"
        );
        eprintln!("note: NVRTC is not installed here; the device programs are not compiled");
        return;
    }
    let entries: [(Unit, &[&str]); 3] = [
        (
            Unit::Detect,
            &["__raygen__detect", "__intersection__detect", "params"],
        ),
        (
            Unit::Kernels,
            &["proxy_boxes", "dem_boxes", "dem_integrate", "dem_permute"],
        ),
        (
            Unit::Dem,
            &["__raygen__dem", "__intersection__dem", "params"],
        ),
    ];
    for (unit, names) in entries {
        let ptx = programs::compile(unit).unwrap_or_else(|e| panic!("{e}"));
        for name in names {
            assert!(ptx.contains(name), "{}: no {name} in the PTX", unit.name());
        }
    }
}

#[test]
fn optix_is_available_or_says_why() {
    match BackendKind::Optix.probe() {
        Ok(device) => {
            assert!(device.contains("OptiX ABI 105"), "{device}");
            let backend = BackendKind::Optix.open().expect("a probed device opens");
            assert_eq!(backend.info().name, "optix");
        }
        Err(why) => {
            assert!(
                !common::expected(BackendKind::Optix),
                "optix expected here: {why}"
            );
            assert!(!why.is_empty());
            let err = BackendKind::Optix
                .open()
                .err()
                .expect("open fails as probe did");
            assert!(err.to_string().contains("optix"), "{err}");
        }
    }
}
