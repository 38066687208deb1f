//! The optix engine's shared ground (cargo feature `optix`): opening the GPU with a compiled
//! pipeline, the limits both layers obey, and the Morton order of the launches.

use super::device::{Device, Pipeline};
use super::{ffi, programs};
use crate::error::{Error, Result};
use crate::morton;
use cudarc::driver::CudaModule;
use std::sync::Arc;

/// Most spheres one launch takes (OptiX's launch width limit is 2^30; the acceleration
/// structure's own limit, 2^29 on driver 580, is read from the device).
pub(crate) const MAX_LAUNCH: u64 = 1 << 30;

/// Largest |coordinate| + box half-width the backend accepts. Measured on the H100 (driver
/// 580, OptiX 9.0): boxes out at 1e12 are found exactly, boxes at 1e14 are silently dropped by
/// the traversal; beyond this bound the backend refuses the set instead.
pub const MAX_COORDINATE: f32 = 1e12;

/// Threads per block of the CUDA kernels.
pub(crate) const BLOCK: u32 = 256;

/// Counters the device programs spread their candidate (and contact) counts over: a power of
/// two, indexed by `i & (COUNTER_SLOTS - 1)` (the `& 255u` of `optix/detect.cu` and
/// `optix/dem.cu`, checked by `tests/optix.rs`).
pub const COUNTER_SLOTS: usize = 256;

/// Why the optix backend cannot run here, if it cannot; else the GPU, in words.
pub fn probe() -> std::result::Result<String, String> {
    let device = Device::open()?;
    Ok(describe(&device))
}

/// Why `auto` should prefer another backend on this GPU (no RT cores), if it should.
pub fn auto_skip() -> Option<String> {
    let device = Device::open().ok()?;
    (device.rtcore_version == 0).then(|| {
        format!(
            "{} has no RT cores: OptiX traverses in software there, slower than wgpu-compute's grid",
            device.name
        )
    })
}

pub(crate) fn describe(device: &Device) -> String {
    let cores = if device.rtcore_version == 0 {
        "no RT cores".to_string()
    } else {
        format!("RT cores v{}", device.rtcore_version)
    };
    format!("{}, OptiX ABI {}, {cores}", device.name, ffi::ABI_VERSION)
}

pub(crate) fn gpu_error(e: impl std::fmt::Display) -> Error {
    Error::Gpu(e.to_string())
}

/// Opens GPU 0 with the pipeline of `unit` (entry points `__raygen__{name}` and
/// `__intersection__{name}`, `payloads` payload words) and the module of the CUDA kernels
/// (`optix/kernels.cu`), compiling both with NVRTC on first use.
pub(crate) fn open_programs(
    unit: programs::Unit,
    name: &str,
    payloads: i32,
) -> Result<(Arc<Device>, Pipeline, Arc<CudaModule>)> {
    let unavailable = |reason: String| Error::BackendUnavailable {
        backend: "optix",
        reason,
    };
    let device = Arc::new(Device::open().map_err(unavailable)?);
    let programs_ptx = programs::ptx(unit).map_err(unavailable)?;
    let kernels_ptx = programs::ptx(programs::Unit::Kernels).map_err(unavailable)?;
    let pipeline = Pipeline::new(&device, programs_ptx, name, payloads).map_err(gpu_error)?;
    let module = device
        .cuda
        .load_module(cudarc::nvrtc::Ptx::from_src(kernels_ptx))
        .map_err(gpu_error)?;
    Ok((device, pipeline, module))
}

/// Indices of `centers` in Morton order (ties by index).
pub(crate) fn morton_order_of(centers: &[[f32; 3]]) -> Vec<u32> {
    morton::order(centers).0
}
