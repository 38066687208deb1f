//! The `wgpu-rq` backend: proxy-sphere boxes in a BLAS of AABBs, one point ray per sphere through
//! WGSL ray queries (Vulkan ray queries, DX12 DXR 1.1, Metal).
//!
//! Build: Morton keys of the centres, a GPU radix sort, the spheres reordered and their proxy
//! boxes written (`wgsl/rq/rq_build.wgsl`), then the BLAS (split into several when the adapter caps
//! the primitives per BLAS) and a TLAS with one instance per BLAS; all in one submission.
//! Detection: `wgsl/rq/rq_pairs.wgsl` applies the rule of [`crate::proxy`] to every candidate.
//! Pairs are counted while written, so a full output buffer is grown and the pass rerun: nothing
//! is ever truncated. wgpu has no refit, so [`Backend::update`](crate::Backend::update) rebuilds.

pub(crate) mod accel;
mod dem;
mod detect;
mod shaders;

pub use dem::RqStepper;
pub use detect::WgpuRqBackend;
pub use shaders::modules as shaders;
