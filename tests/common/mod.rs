//! Shared by the GPU tests: CI runs them on lavapipe and must fail, not skip, without an adapter.
#![allow(dead_code)] // each test file uses the part it needs

pub mod rule_cases;

use mochi::gpu::{self, Gpu, Need};

/// True when running under CI (`CI=true`), where every GPU test must find an adapter.
pub fn ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Whether this run must test backend `kind` (a missing one fails it): under CI every backend
/// but optix (CI machines have no NVIDIA GPU); optix where `MOCHI_EXPECT_OPTIX=1`.
pub fn expected(kind: mochi::engines::BackendKind) -> bool {
    match kind {
        mochi::engines::BackendKind::Optix => {
            std::env::var("MOCHI_EXPECT_OPTIX").is_ok_and(|v| v == "1")
        }
        _ => ci(),
    }
}

/// Whether an adapter for `need` exists. Without one: a panic under CI, else a printed note
/// saying that `what` is not tested on this machine, and `false`.
pub fn adapter_for(need: Need, what: &str) -> bool {
    match gpu::probe(need) {
        Ok(_) => true,
        Err(why) => {
            assert!(!ci(), "CI expects a GPU adapter for {what}: {why}");
            eprintln!("note: {what} is not tested on this machine: {why}");
            false
        }
    }
}

/// An open compute device, or `None` as [`adapter_for`] decides.
pub fn open_gpu(what: &str) -> Option<Gpu> {
    adapter_for(Need::Compute, what)
        .then(|| Gpu::open(Need::Compute).expect("a probed adapter opens"))
}

/// Like [`open_gpu`], with the device's `max_compute_workgroups_per_dimension` lowered to `max`
/// (the device then rejects any dispatch wider than that).
pub fn open_gpu_lowered(what: &str, max: u32) -> Option<Gpu> {
    adapter_for(Need::Compute, what).then(|| {
        Gpu::open_limited(Need::Compute, |limits| {
            limits.max_compute_workgroups_per_dimension = max;
        })
        .expect("a probed adapter opens")
    })
}

/// The largest difference of one coordinate between the same sphere in `a` and in `b` [m].
pub fn largest_gap(a: &mochi::dem::Particles, b: &mochi::dem::Particles) -> f32 {
    assert_eq!(a.len(), b.len());
    a.positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| (0..3).map(|i| (p[i] - q[i]).abs()).fold(0.0, f32::max))
        .fold(0.0, f32::max)
}
