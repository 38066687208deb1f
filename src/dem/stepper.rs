//! The [`Stepper`] trait that every backend's DEM step implements.

use super::flow::FlowCounts;
use super::walls::WallLoad;
use crate::error::Result;
use crate::particles::Particles;

/// Time spent per phase of the step, summed over the steps of one [`Stepper::advance`] \[ms\].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Maintaining the acceleration structure (binning, sorting, building).
    pub build_ms: f64,
    /// Collision detection with the contact forces resolved in the same pass.
    pub dcd_ms: f64,
    /// Walls, gravity and integration.
    pub update_ms: f64,
}

impl StageTimes {
    /// All three phases.
    pub fn total_ms(&self) -> f64 {
        self.build_ms + self.dcd_ms + self.update_ms
    }

    /// Adds `other` to these sums.
    pub fn add(&mut self, other: &StageTimes) {
        self.build_ms += other.build_ms;
        self.dcd_ms += other.dcd_ms;
        self.update_ms += other.update_ms;
    }
}

/// How the stage times were taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    /// GPU timestamps: time on the device itself.
    Gpu,
    /// Host wall-clock time around each phase.
    Wall,
    /// Not measured (a GPU without timestamps).
    None,
}

/// What one [`Stepper::advance`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Advance {
    /// Steps taken.
    pub steps: u32,
    /// Touching pairs found in the last step.
    pub contacts: u64,
    /// Phase times summed over the steps.
    pub times: StageTimes,
    /// How `times` were measured.
    pub clock: Clock,
}

/// One backend's DEM step: keeps the particles (on the GPU for GPU backends) and advances them.
/// `Send`, as the detection `Backend` is, so that a caller may step it on another thread (Python
/// releases its interpreter lock while it steps).
pub trait Stepper: Send {
    /// Backend name and device, in words.
    fn describe(&self) -> String;

    /// Takes `steps` time steps.
    fn advance(&mut self, steps: u32) -> Result<Advance>;

    /// The particles now, in input order (a read-back on GPU backends).
    fn particles(&mut self) -> Result<Particles>;

    /// The force and torque the spheres exerted on each mesh wall in the last step, in the
    /// scene's order of walls (default: none, for a step without mesh walls).
    fn wall_loads(&self) -> Vec<WallLoad> {
        Vec::new()
    }

    /// What the inflows and outflows did since the step opened (default: `None`, a step
    /// without them).
    fn flow_counts(&self) -> Option<FlowCounts> {
        None
    }

    /// Whether this step refits its acceleration structure between rebuilds, and so obeys the
    /// engines' `Options::rebuild` (default: no; grids re-bin and `wgpu-rq` rebuilds every
    /// step).
    fn refits(&self) -> bool {
        false
    }

    /// The grid build this step chose, in words (`dense` or `sorted`), where the backend has a
    /// choice (`wgpu-compute`); default `None`.
    fn grid_build(&self) -> Option<&'static str> {
        None
    }
}
