//! The `optix` backend (cargo feature `optix`): the paper's own path on NVIDIA GPUs. Every
//! sphere's proxy box (2·r, or 2·r_max in `nns` mode) is a custom primitive of one OptiX
//! acceleration structure; one point ray per sphere visits every box its centre lies in, and the
//! intersection program applies the proxy-sphere rule and writes the kept pairs without ever
//! reporting a hit (`optix/detect.cu`). Boxes are written by a CUDA kernel (`optix/kernels.cu`);
//! `update` refits the structure instead of rebuilding it.
//!
//! Everything NVIDIA is loaded at run time (CUDA driver and NVRTC through `cudarc`, OptiX
//! through our own FFI of ABI 105), so the crate builds anywhere and a machine without the
//! driver gets a clear "unavailable" instead of a crash. Spheres are launched in Morton order
//! (coherent rays: faster than random order, docs/performance-log/).
//!
//! Layers, as cudarc's: `sys.rs` is the raw OptiX ABI (structs, constants, the function table by
//! named slot, loaded once); `device.rs` and `launches.rs` the safe layer (`device.rs` the owning
//! types: device, pipelines, acceleration structure, state, history and tables; `launches.rs`
//! one typed, length-checked launch per device program and CUDA kernel, with the launch
//! parameters the device code reads); `engine.rs` (the one probe and opened device, limits,
//! Morton order), `detect.rs` (`impl Backend`), `dem.rs` (`impl Stepper`), `granular.rs` and
//! `clumps.rs` (the granular step's state and its clumps') are safe code over it. Only
//! `sys.rs`, `device.rs` and `launches.rs` may use `unsafe`, each block with its reason.

mod clumps;
mod dem;
mod detect;
#[allow(unsafe_code)]
#[deny(clippy::undocumented_unsafe_blocks)]
mod device;
mod engine;
mod granular;
#[allow(unsafe_code)]
#[deny(clippy::undocumented_unsafe_blocks)]
mod launches;
pub mod programs;
#[allow(unsafe_code)]
#[deny(clippy::undocumented_unsafe_blocks)]
mod sys;

pub use dem::OptixStepper;
pub use detect::OptixBackend;
pub use device::COUNTER_SLOTS;
pub use engine::{MAX_COORDINATE, auto_skip, probe};
pub use launches::layout_checks;
