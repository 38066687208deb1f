//! The discrete-element simulation, backend-independent (docs/method.md, "The DEM step"): per
//! time step (1) maintain the acceleration structure, (2) find every touching pair and resolve
//! its contact force in the same pass, (3) walls, gravity and integration. [`walls`] holds the
//! mesh walls' geometry and motion, [`flow`] the spheres' ways in and out. [`model`] holds the
//! physics, [`scene`] the scene files, [`Stepper`] the step every engine implements
//! (the `engines` registry opens one, where the backend's data lives).

pub mod clump_spec;
pub mod contacts;
pub mod equipment;
pub mod flow;
pub mod material_spec;
pub mod model;
pub mod scene;
pub mod stepper;
pub mod walls;

/// Positions as an `f32` centre and its residual ([`Particles::position_residuals`]).
pub use crate::particles::position;
pub use crate::particles::{
    ContactHistory, Energies, FIRST_MESH_WALL, FIRST_WALL, HistoryEntry, Particles,
};
pub use model::{Material, StepParams};
pub use stepper::{
    Advance, Clock, ExternalLoads, Motion, RankShare, Snapshot, StageTimes, Stepper,
};
