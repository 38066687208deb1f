//! The engines: one folder per backend holding its device-resident state (buffers, structure
//! build, shaders and their binding constants), with detection ([`crate::Backend`]) and the DEM
//! step ([`crate::dem::Stepper`]) as thin layers over it; and the registry that knows which
//! engines this build has, which can run here, and the one `auto` rule that detection,
//! simulation and rendering share (docs/ARCHITECTURE.md).

pub mod cpu;
mod flow_step;
mod gpu_detect;
mod gpu_flow;
mod gpu_granular;
mod gpu_readback;
mod gpu_state;
mod gpu_step;
mod gpu_walls;
mod open;
#[cfg(feature = "optix")]
pub mod optix;
mod registry;
mod setup;
pub mod wgpu_compute;
pub mod wgpu_rq;

pub use gpu_step::KernelSet;
pub use open::{open, open_choice, open_scene, open_setup, open_stepper};
pub(crate) use registry::open_auto;
pub use registry::{BackendChoice, BackendKind, Opened, Options, RebuildPolicy};
pub use setup::DemSetup;
