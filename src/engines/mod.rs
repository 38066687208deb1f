//! The engines: one folder per backend holding its device-resident state (buffers, structure
//! build, shaders and their binding constants), with detection ([`crate::Backend`]) and the DEM
//! step ([`crate::dem::Stepper`]) as thin layers over it; and the registry that knows which
//! engines this build has, which can run here, and the one `auto` rule that detection,
//! simulation and rendering share (docs/ARCHITECTURE.md).

pub(crate) mod common;
pub mod cpu;
mod open;
#[cfg(feature = "optix")]
pub mod optix;
mod registry;
mod setup;
pub mod wgpu;

pub(crate) use open::open_rank_step;
pub use open::{open, open_choice, open_scene, open_setup, open_stepper};
pub(crate) use registry::open_auto;
pub use registry::{BackendChoice, BackendKind, Opened, Options, RebuildPolicy};
pub use setup::DemSetup;
pub use wgpu::step::KernelSet;
