//! The optix backend's device programs compile with NVRTC 13.0 (CI installs it from PyPI, so a
//! broken `.cu` cannot land), and a machine without an NVIDIA driver gets a reason, not a
//! panic. The CUDA copy of the proxy rule (`optix/device.cuh`) decides the boundary cases of
//! `common/rule_cases.rs` exactly as `src/proxy.rs` does (it rounds every step as the cpu:
//! no fused multiply-adds). Its exactness is tested with every other backend in
//! backends_exact.rs.
#![cfg(feature = "optix")]

mod common;

use common::rule_cases::{assert_same_decisions, cases, records};
use cudarc::driver::{CudaContext, LaunchConfig, PushKernelArg};
use mochi::ProxyMode;
use mochi::engines::BackendKind;
use mochi::engines::optix::programs::{self, Unit};

/// Runs `mochi_keep` of `optix/device.cuh` on each case record (`common::rule_cases::records`).
const RULE_KERNEL: &str = r#"
struct MochiCase { float4 a; float4 b; unsigned int i, j, mode, pad; };
extern "C" __global__ void rule_cases(const MochiCase* cases, unsigned int* kept, unsigned int n) {
    unsigned int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) {
        return;
    }
    MochiCase c = cases[k];
    kept[k] = mochi_keep(c.mode, c.i, c.a, c.j, c.b) ? 1u : 0u;
}
"#;

/// A CUDA context on GPU 0, or why there is none.
fn cuda_context() -> Result<std::sync::Arc<CudaContext>, String> {
    // SAFETY: only tries to open the library.
    if !unsafe { cudarc::driver::sys::is_culib_present() } {
        return Err("no NVIDIA driver (libcuda.so) found".into());
    }
    CudaContext::new(0).map_err(|e| format!("opening GPU 0: {e}"))
}

#[test]
fn cuda_rule_matches_the_rust_rule() {
    let ptx = match programs::compile_with_rule("rule_cases.cu", RULE_KERNEL) {
        Ok(ptx) => ptx,
        Err(why) if !programs::nvrtc_present() => {
            assert!(!common::ci(), "CI expects NVRTC: {why}");
            eprintln!("note: the CUDA rule is not tested on this machine: {why}");
            return;
        }
        Err(why) => panic!("{why}"),
    };
    let context = match cuda_context() {
        Ok(context) => context,
        Err(why) => {
            assert!(
                !common::expected(BackendKind::Optix),
                "optix expected here, but the CUDA rule cannot run: {why}"
            );
            eprintln!("note: the CUDA rule is not run on this machine: {why}");
            return;
        }
    };
    let stream = context.default_stream();
    let module = context
        .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
        .unwrap();
    let function = module.load_function("rule_cases").unwrap();
    let cases = cases();
    let n = cases.len() as u32;
    for mode in [ProxyMode::Mochi, ProxyMode::Nns] {
        let input = stream.clone_htod(&records(&cases, mode)).unwrap();
        let mut output = stream.alloc_zeros::<u32>(cases.len()).unwrap();
        let mut launch = stream.launch_builder(&function);
        launch.arg(&input).arg(&mut output).arg(&n);
        // SAFETY: the kernel reads n records of 12 words from `input` and writes n words.
        unsafe { launch.launch(LaunchConfig::for_num_elems(n)) }.unwrap();
        let kept = stream.clone_dtoh(&output).unwrap();
        // No fused multiply-adds: every case, on the boundary or not, as the cpu decides it.
        assert_same_decisions(mode, &cases, &kept, false);
    }
}

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
    let entries: [(Unit, &[&str]); 5] = [
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
        (
            Unit::Granular,
            &["__raygen__granular", "__intersection__granular", "params"],
        ),
        (
            Unit::GranularKernels,
            &["granular_integrate", "permute_rows"],
        ),
    ];
    for (unit, names) in entries {
        let ptx = programs::compile(unit).unwrap_or_else(|e| panic!("{e}"));
        for name in names {
            assert!(ptx.contains(name), "{}: no {name} in the PTX", unit.name());
        }
    }
}

/// Every launch-parameter struct (and history entry) that the host hands the device code has,
/// in CUDA, the size and field offsets of its Rust twin: NVRTC compiles each unit followed by
/// `static_assert`s that the host writes from `offset_of!`.
#[test]
fn shared_structs_lie_where_the_device_code_reads_them() {
    if !programs::nvrtc_present() {
        assert!(!common::ci(), "CI expects NVRTC on the library path");
        eprintln!("note: NVRTC is not installed here; the layouts are not compared");
        return;
    }
    for unit in Unit::ALL {
        let checks = programs::layout_checks(unit);
        assert!(checks.contains("static_assert(sizeof("), "{}", unit.name());
        programs::compile_with_checks(unit, &checks).unwrap_or_else(|e| panic!("{e}"));
    }
    // A wrong offset is caught.
    let wrong = programs::layout_checks(Unit::Granular).replace(
        "GranularLaunch, slots) == ",
        "GranularLaunch, slots) == 4 + ",
    );
    let err = programs::compile_with_checks(Unit::Granular, &wrong).expect_err("a wrong offset");
    assert!(err.to_string().contains("GranularLaunch.slots"), "{err}");
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

/// Every counter index of the device programs (`i & MASKu`) masks to `COUNTER_SLOTS`, the
/// length of the counter buffers the host allocates.
#[test]
fn counter_masks_match_the_counter_buffers() {
    use mochi::engines::optix::COUNTER_SLOTS;
    assert!(COUNTER_SLOTS.is_power_of_two());
    for (name, source) in [
        ("detect.cu", include_str!("../optix/detect.cu")),
        ("dem.cu", include_str!("../optix/dem.cu")),
        ("granular.cu", include_str!("../optix/granular.cu")),
    ] {
        let masks: Vec<usize> = source
            .split("& ")
            .skip(1)
            .filter_map(|rest| {
                let digits =
                    rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
                (digits > 0 && rest[digits..].starts_with('u'))
                    .then(|| rest[..digits].parse().unwrap())
            })
            .collect();
        assert!(!masks.is_empty(), "{name}: no counter index");
        for mask in masks {
            assert_eq!(
                mask,
                COUNTER_SLOTS - 1,
                "{name}: a counter index masked by {mask}"
            );
        }
    }
}

/// An NVRTC failure is a typed compile error carrying the compiler's log, and converts into the
/// crate's one OptiX/CUDA variant; a missing NVRTC is an unavailable backend instead.
#[test]
fn compile_errors_carry_the_nvrtc_log() {
    use mochi::{Error, OptixError};
    let broken = r#"extern "C" __global__ void broken() { undeclared_name = 1; }"#;
    let err = programs::compile_with_rule("broken.cu", broken).expect_err("does not compile");
    if !programs::nvrtc_present() {
        assert!(!common::ci(), "CI expects NVRTC: {err}");
        assert!(matches!(
            Error::from(err),
            Error::BackendUnavailable {
                backend: "optix",
                ..
            }
        ));
        return;
    }
    match &err {
        OptixError::Compile { unit, log } => {
            assert_eq!(unit, "broken.cu");
            assert!(log.contains("undeclared_name"), "{log}");
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(Error::from(err), Error::Optix(_)));
}
