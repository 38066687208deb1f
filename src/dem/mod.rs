//! The discrete-element simulation (docs/method.md, "The DEM step"): per time step (1) maintain
//! the acceleration structure, (2) find every touching pair and resolve its contact force in the
//! same pass, (3) walls, gravity and integration. [`model`] holds the physics; each backend has a
//! [`Stepper`] that runs the steps where its data lives (the GPU for GPU backends).

pub mod cpu;
mod gpu_step;
pub mod model;
mod open;
#[cfg(feature = "optix")]
pub mod optix;
pub mod scene;
pub mod stepper;
pub mod wgpu_compute;
pub mod wgpu_rq;

pub use crate::particles::Particles;
pub use gpu_step::ForceAtomics;
pub use model::{Material, StepParams};
pub use open::{open_choice, open_stepper};
pub use stepper::{Advance, Clock, StageTimes, Stepper};
