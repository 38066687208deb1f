//! Spheres entering and leaving a GPU backend's run ([`crate::dem::flow`]): the step runs on
//! the GPU between flow events; at each event the spheres are read back (with their contact
//! history, keyed by stable ids), the flows remove and insert on the host exactly as the cpu
//! step does, and the step is reopened on the same device over the new spheres (its compiled
//! pipelines are the device's, so reopening allocates and uploads, and compiles nothing).
//! A run with no sphere left waits, without a step, for its inflows.

use crate::dem::flow::{FlowCounts, FlowSet};
use crate::dem::stepper::{Advance, Clock, StageTimes, Stepper};
use crate::dem::walls::WallLoad;
use crate::error::Result;
use crate::particles::Particles;
use std::time::Instant;

/// Opens a backend's step over the spheres given, on the device of the first.
pub type Reopen = Box<dyn FnMut(Particles) -> Result<Box<dyn Stepper>> + Send>;

/// A GPU backend's step with flows (module docs).
pub struct FlowStep {
    /// The step (`None` while no sphere is in the run).
    step: Option<Box<dyn Stepper>>,
    /// The spheres while there is no step: none, and the step count.
    idle: Particles,
    reopen: Reopen,
    flow: FlowSet,
    /// Steps between flow events.
    every: u32,
    dt: f32,
    density: f32,
    counts: FlowCounts,
    /// The step's description, kept for the times it has no step.
    described: String,
}

impl FlowStep {
    /// The step over `particles` that `reopen` opens, with `flow` acting every
    /// [`FlowSet::every`] steps (time step `dt`, particle `density`).
    pub fn new(
        particles: Particles,
        flow: FlowSet,
        dt: f32,
        density: f32,
        mut reopen: Reopen,
    ) -> Result<Self> {
        let every = flow.every(true);
        let idle = Particles {
            step: particles.step,
            ..Particles::default()
        };
        let step = if particles.is_empty() {
            None
        } else {
            Some(reopen(particles)?)
        };
        let described = step.as_ref().map(|s| s.describe()).unwrap_or_default();
        Ok(FlowStep {
            step,
            idle,
            reopen,
            flow,
            every,
            dt,
            density,
            counts: FlowCounts::default(),
            described,
        })
    }

    /// The step count now.
    fn now(&self) -> u64 {
        self.idle.step
    }

    /// Removes and inserts what the flows say after the step that brought the run to `now`.
    fn flow_event(&mut self) -> Result<()> {
        let started = Instant::now();
        let flowed = self.flow_on_host();
        self.counts.events += 1;
        self.counts.event_ms += started.elapsed().as_secs_f64() * 1e3;
        flowed
    }

    /// [`flow_event`](Self::flow_event)'s work.
    fn flow_on_host(&mut self) -> Result<()> {
        let mut parts = match &mut self.step {
            Some(step) => step.particles()?,
            None => self.idle.clone(),
        };
        let changed = self.flow.apply(
            &mut parts,
            self.every,
            self.dt,
            self.density,
            &mut self.counts,
        )?;
        if !changed {
            return Ok(());
        }
        if parts.is_empty() {
            self.step = None;
            self.idle = parts;
        } else {
            let step = (self.reopen)(parts)?;
            self.described = step.describe();
            self.step = Some(step);
        }
        Ok(())
    }
}

impl Stepper for FlowStep {
    fn describe(&self) -> String {
        let what = if self.described.is_empty() {
            "a GPU backend (no sphere yet)"
        } else {
            &self.described
        };
        format!("{what}, spheres flowing every {} steps", self.every)
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        let end = self.now() + steps as u64;
        let mut done = Advance {
            steps,
            contacts: 0,
            times: StageTimes::default(),
            clock: Clock::None,
        };
        while self.now() < end {
            let every = self.every as u64;
            let event = (self.now() / every + 1) * every;
            let run = event.min(end) - self.now();
            match &mut self.step {
                Some(step) => {
                    let advance = step.advance(run as u32)?;
                    done.contacts = advance.contacts;
                    done.times.add(&advance.times);
                    done.clock = advance.clock;
                }
                None => done.contacts = 0,
            }
            self.idle.step += run;
            if FlowSet::due_after(self.now(), self.every) {
                self.flow_event()?;
            }
        }
        Ok(done)
    }

    fn particles(&mut self) -> Result<Particles> {
        match &mut self.step {
            Some(step) => step.particles(),
            None => Ok(self.idle.clone()),
        }
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.step
            .as_ref()
            .map(|s| s.wall_loads())
            .unwrap_or_default()
    }

    fn flow_counts(&self) -> Option<FlowCounts> {
        Some(self.counts)
    }

    fn refits(&self) -> bool {
        self.step.as_ref().is_some_and(|s| s.refits())
    }

    fn grid_build(&self) -> Option<&'static str> {
        self.step.as_ref().and_then(|s| s.grid_build())
    }
}
