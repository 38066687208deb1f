//! The optix engine's shared ground (cargo feature `optix`): the one opened GPU (probed once
//! per process, reused by every open), the limits both layers obey, and the Morton order of the
//! launches.

use super::device::Device;
use super::sys;
use crate::error::{Error, OptixError, Result};
use crate::morton;
use std::sync::{Arc, OnceLock};

/// Most spheres one launch takes (OptiX's launch width limit is 2^30; the acceleration
/// structure's own limit, 2^29 on driver 580, is read from the device).
pub(crate) const MAX_LAUNCH: u64 = 1 << 30;

/// Largest |coordinate| + box half-width the backend accepts. Measured on the H100 (driver
/// 580, OptiX 9.0): boxes out at 1e12 are found exactly, boxes at 1e14 are silently dropped by
/// the traversal; beyond this bound the backend refuses the set instead.
pub const MAX_COORDINATE: f32 = 1e12;

/// GPU 0 with its CUDA and OptiX contexts, opened on first use: the probe, `auto`'s check for RT
/// cores and every backend and stepper share it (and its one stream), so a process creates one
/// context. A failure is kept too: the machine does not change while mochi runs.
pub(crate) fn device() -> std::result::Result<Arc<Device>, OptixError> {
    static DEVICE: OnceLock<std::result::Result<Arc<Device>, OptixError>> = OnceLock::new();
    DEVICE.get_or_init(|| Device::open().map(Arc::new)).clone()
}

/// Why the optix backend cannot run here, if it cannot; else the GPU, in words.
pub fn probe() -> std::result::Result<String, String> {
    device().map(|d| describe(&d)).map_err(|e| e.to_string())
}

/// Why `auto` should prefer another backend on this GPU (no RT cores), if it should.
pub fn auto_skip() -> Option<String> {
    let device = device().ok()?;
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
    format!("{}, OptiX ABI {}, {cores}", device.name, sys::ABI_VERSION)
}

/// The shared device, or why the backend cannot run here ([`Error::BackendUnavailable`]: no
/// driver, no OptiX of our ABI, or GPU 0 would not open).
pub(crate) fn open_device() -> Result<Arc<Device>> {
    device().map_err(|e| Error::BackendUnavailable {
        backend: "optix",
        reason: e.to_string(),
    })
}

/// Indices of `centers` in Morton order (ties by index).
pub(crate) fn morton_order_of(centers: &[[f32; 3]]) -> Vec<u32> {
    morton::order(centers).0
}
