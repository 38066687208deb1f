//! What opening any engine's DEM step takes ([`DemSetup`]): the engines' constructors take it
//! with the few settings of their own, and `open.rs` opens every backend's step from it.

use crate::dem::model::StepParams;
use crate::dem::walls::WallSet;

use crate::particles::Particles;
use crate::proxy::ProxyMode;

/// A DEM step to open, on any engine: the spheres, the step's parameters, the proxy mode of
/// its pair search and the walls. The engines' openers validate the spheres.
#[derive(Debug, Clone)]
pub struct DemSetup {
    /// The spheres at the start.
    pub particles: Particles,
    /// The step's parameters.
    pub params: StepParams,
    /// The proxy mode of the step's pair search.
    pub mode: ProxyMode,
    /// The walls (the box's alone by default).
    pub walls: WallSet,
}

impl DemSetup {
    /// `particles` stepped with `params` in `mode`, in the box.
    pub fn new(particles: Particles, params: StepParams, mode: ProxyMode) -> Self {
        DemSetup {
            particles,
            params,
            mode,
            walls: WallSet::default(),
        }
    }

    /// This setup inside `walls`.
    pub fn with_walls(self, walls: WallSet) -> Self {
        DemSetup { walls, ..self }
    }

    /// The setup of a scene's start, and the start's flows.
    pub(crate) fn of_start(
        start: crate::dem::scene::Start,
    ) -> (DemSetup, crate::dem::flow::FlowSet) {
        let crate::dem::scene::Start {
            particles,
            params,
            mode,
            walls,
            flow,
        } = start;
        (
            DemSetup::new(particles, params, mode).with_walls(walls),
            flow,
        )
    }

    /// The spheres, and the rest of the setup (its spheres none).
    pub(crate) fn split(self) -> (Particles, DemSetup) {
        let particles = self.particles;
        let rest = DemSetup {
            particles: Particles::default(),
            ..self
        };
        (particles, rest)
    }

    /// This setup over `particles` instead.
    pub(crate) fn over(&self, particles: Particles) -> DemSetup {
        DemSetup {
            particles,
            params: self.params.clone(),
            mode: self.mode,
            walls: self.walls.clone(),
        }
    }
}
