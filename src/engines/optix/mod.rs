//! The `optix` backend (cargo feature `optix`): the paper's own path on NVIDIA GPUs. Every
//! sphere's proxy box (2·r, or 2·r_max in `nns` mode) is a custom primitive of one OptiX
//! acceleration structure; one point ray per sphere visits every box its centre lies in, and the
//! intersection program applies the proxy-sphere rule and writes the kept pairs without ever
//! reporting a hit (`optix/detect.cu`). Boxes are written by a CUDA kernel (`optix/kernels.cu`);
//! `update` refits the structure instead of rebuilding it.
//!
//! Everything NVIDIA is loaded at run time (CUDA driver and NVRTC through `cudarc`, OptiX
//! through our own FFI of ABI 105 in `ffi.rs`), so the crate builds anywhere and a machine without
//! the driver gets a clear "unavailable" instead of a crash. Spheres are launched in Morton
//! order (coherent rays: faster than random order, docs/PERFORMANCE.md).

// The one place of the crate that calls foreign code: every unsafe block says why it holds.
#![allow(unsafe_code)]

mod dem;
mod detect;
pub(crate) mod device;
mod engine;
mod ffi;
pub mod programs;

pub use dem::OptixStepper;
pub use detect::OptixBackend;
pub use engine::{COUNTER_SLOTS, MAX_COORDINATE, auto_skip, probe};
