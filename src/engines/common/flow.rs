//! Spheres entering and leaving a GPU backend's run ([`crate::dem::flow`]). The step runs on
//! the GPU between flow events. At an event, a step that can ([`DeviceFlow`]: wgpu-compute)
//! scans its state on the device for the spheres that leave and those near the inflows, removes
//! the leaving ones on the device (the others keep their stable ids, so their history holds),
//! and the inflows place their spheres on the host against the near ones, exactly as the cpu
//! step does, which the step appends on the device. Otherwise (no room is left, or the step
//! cannot scan) the spheres are read back with their contact history (keyed by stable ids), the
//! flows act on the host as on the cpu, and the step is reopened on the same device over the
//! new spheres (its compiled pipelines are the device's, so reopening allocates and uploads,
//! and compiles nothing), with room for the spheres still to come. A run with no sphere left
//! waits, without a step, for its inflows.

use crate::dem::flow::{Event, FlowCounts, FlowSet, NewSphere};
use crate::dem::model::mass;
use crate::dem::stepper::{Advance, Clock, ExternalLoads, Motion, Snapshot, StageTimes, Stepper};
use crate::dem::walls::WallLoad;
use crate::error::Result;
use crate::particles::Particles;
use glam::Vec3;
use std::time::Instant;

/// A GPU step's part in a flow event without reading every sphere back, where it has one (the
/// defaults: none).
pub(crate) trait DeviceFlow: Stepper {
    /// The spheres that leave by `query` and those near its inflows (`None`: this step cannot
    /// scan, and the event reads every sphere back).
    fn scan(&mut self, _query: &FlowQuery) -> Result<Option<Scan>> {
        Ok(None)
    }

    /// Appends `new` after the spheres there, their stable ids after any the step has given,
    /// with no spin and no history; `false` where the step has no room for them (or its grid
    /// was chosen for other radii) and the event reopens it.
    fn append(&mut self, _new: &[NewSphere]) -> Result<bool> {
        Ok(false)
    }

    /// Removes the spheres at the state indices `rows` (distinct, as a scan gave them), the
    /// others keeping their stable ids (their order is input order still); `false` where the
    /// step cannot, and the event reads the spheres back.
    fn remove(&mut self, _rows: &[u32]) -> Result<bool> {
        Ok(false)
    }

    /// Sums the loads on the mesh walls over the spheres whose centres c lie in `lo <= c < hi`
    /// only: a rank's box, the spheres it owns (its ghosts' loads are their owners'). The
    /// others touch the walls as before.
    fn sum_wall_loads_within(&mut self, bounds: ([f32; 3], [f32; 3]));

    /// This step as one a rank keeps on its device from round to round, where the backend can
    /// (the defaults: it cannot, and a rank opens it again each round).
    fn resident(&mut self) -> Option<&mut dyn ResidentStep> {
        None
    }
}

/// A step that a rank of a run decomposed over ranks (the `distributed` module) keeps on its
/// device from round to round. After a round it writes, on the device, the records of its own
/// spheres near the faces of the rank's box for the neighbouring boxes ([`gather_layer`]); it
/// places the records the neighbours sent ([`place_layer`]: ghosts' states into their rows,
/// ownership as the centres lie now) and lists the spheres that leave and the records of
/// spheres it does not hold; then it takes those out and appends these ([`update`]). The
/// history of the spheres that stay is kept on the device (a contact's springs live where the
/// step put them, not with one sphere). Which sphere each stable id is in the whole run, and
/// whether it is the rank's own, the step holds as the rank names them ([`name`]).
///
/// [`gather_layer`]: Self::gather_layer
/// [`place_layer`]: Self::place_layer
/// [`update`]: Self::update
/// [`name`]: Self::name
pub(crate) trait ResidentStep {
    /// The spheres' states in the order of the step's rows now.
    fn rows(&mut self) -> Result<DeviceRows>;

    /// Names the spheres of stable ids: each one's whole-run id and whether it is the rank's
    /// own.
    fn name(&mut self, names: &[Named]) -> Result<()>;

    /// Forgets the whole-run ids of spheres the step no longer holds.
    fn forget(&mut self, wholes: &[u32]) -> Result<()>;

    /// Whether each stable id's sphere is the rank's own (1) or a ghost (0), up to the last
    /// stable id given.
    fn own_marks(&mut self) -> Result<Vec<u32>>;

    /// Each sphere's contacts with other spheres as the step's history holds them after its
    /// last step, in its input order (ascending stable id); `None` where it keeps no history.
    fn sphere_contacts(&mut self) -> Result<Option<Vec<u32>>>;

    /// The records of the own spheres near the faces of `bounds`, by direction of the
    /// neighbouring box, and the own spheres' largest speed, into `layer` (its lists' buffers
    /// reused).
    fn gather_layer(&mut self, bounds: &LayerBounds, layer: &mut Layer) -> Result<()>;

    /// Places the records of `received` ([`LayerRecord`]s, as [`gather_layer`](Self::gather_layer)
    /// writes them): the states of spheres the step holds into their rows, each the rank's own
    /// where its centre lies in the box of `bounds`; then lists the spheres that leave (ghosts
    /// no record came for, own spheres beyond the box grown by the halo) and marks the own
    /// spheres beyond the box as ghosts.
    fn place_layer(&mut self, bounds: &LayerBounds, received: &[Vec<u8>]) -> Result<Placed>;

    /// Whether the step has room for `coming` once `leaving` spheres have left (rows kept,
    /// radii its grid was chosen for, stable ids).
    fn fits(&self, leaving: usize, coming: &[Arriving]) -> bool;

    /// Removes the spheres of the rows `leaving` (distinct) and appends `coming` with no
    /// history, where it [`fits`](Self::fits) them; returns the stable id of the first
    /// appended (the others follow it).
    fn update(&mut self, leaving: &[u32], coming: &[Arriving]) -> Result<u32>;
}

/// A stable id's sphere as a rank names it ([`ResidentStep::name`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Named {
    pub stable: u32,
    /// Its id in the whole run.
    pub whole: u32,
    pub own: bool,
}

/// Where a rank's box and its halo lie, in `f32` (infinite where no box lies beyond).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LayerBounds {
    /// A centre at or below `near.0` (at or above `near.1`) along an axis lies within the halo
    /// of the box below (above) along it.
    pub near: ([f32; 3], [f32; 3]),
    /// The rank's box: `lo <= c < hi` along every axis.
    pub own: ([f32; 3], [f32; 3]),
    /// The box grown by the halo: an own sphere beyond it leaves the rank.
    pub keep: ([f32; 3], [f32; 3]),
    /// Whether a box lies next to the rank's each way ([`direction`]).
    pub ways: [bool; DIRECTIONS],
}

impl LayerBounds {
    /// Whether the centre `pos + lo` (summed in `f32`, as the device sums it) lies in the box.
    pub fn owns(&self, pos: [f32; 3], lo: [f32; 3]) -> bool {
        (0..3).all(|a| {
            let c = pos[a] + lo[a];
            c >= self.own.0[a] && c < self.own.1[a]
        })
    }
}

/// The index of the direction `d` (each of -1, 0, 1) of a neighbouring box among
/// [`DIRECTIONS`].
pub(crate) fn direction(d: [i32; 3]) -> usize {
    ((d[0] + 1) + 3 * (d[1] + 1) + 9 * (d[2] + 1)) as usize
}

/// The directions of the neighbouring boxes, one index each ([`direction`]; 13: the box itself).
pub(crate) const DIRECTIONS: usize = 27;

/// A round's records for the neighbouring boxes ([`ResidentStep::gather_layer`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Layer {
    /// Each direction's [`LayerRecord`]s as bytes.
    pub lists: Vec<Vec<u8>>,
    /// The own spheres' largest speed \[m/s\].
    pub fastest: f32,
}

/// A sphere as one rank's step sends it to another's: `[x, y, z, r]`, the residual of the
/// centre and the whole-run id, the velocity, `[ωx, ωy, ωz, material]`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct LayerRecord {
    pub pos: [f32; 4],
    pub lo: [f32; 3],
    pub whole: u32,
    pub vel: [f32; 3],
    pub pad: u32,
    pub omega: [f32; 4],
}

/// What placing a round's records left ([`ResidentStep::place_layer`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Placed {
    /// Each sphere that leaves: its row, stable id and 1 where it was the rank's own.
    pub leaving: Vec<[u32; 3]>,
    /// The records of spheres the step does not hold, by their place among those received
    /// (the messages one after the other).
    pub coming: Vec<u32>,
    /// Ghosts that became the rank's own.
    pub made_own: u32,
    /// Own spheres that became ghosts.
    pub made_ghosts: u32,
}

/// A step's spheres row by row: `[x, y, z, r]` (the `f32` centre and radius), the residuals
/// of the centres `[x, y, z, 0]`, `[vx, vy, vz, m]` (the mass as the step's contacts see it),
/// `[ωx, ωy, ωz, material]` and the stable id.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct DeviceRows {
    pub pos: Vec<[f32; 4]>,
    pub lo: Vec<[f32; 4]>,
    pub vel: Vec<[f32; 4]>,
    pub omega: Vec<[f32; 4]>,
    pub ids: Vec<u32>,
}

/// A sphere appended to a step with its state: where it is to the residual, how it moves and
/// turns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Arriving {
    pub sphere: NewSphere,
    /// The residual of its centre \[m\].
    pub residual: [f32; 3],
    /// Its angular velocity \[rad/s\].
    pub spin: [f32; 3],
}

/// Opens a backend's step over the spheres given with the room given for more (where it keeps
/// any), on the device of the first.
pub type Reopen = Box<dyn FnMut(Particles, Room) -> Result<Box<dyn DeviceFlow>> + Send>;

/// Spheres of room a reopened step keeps for those to come, at least.
const SPARE_ROOM: usize = 4096;

/// A GPU backend's step with flows (module docs).
pub struct FlowStep {
    /// The step (`None` while no sphere is in the run).
    step: Option<Box<dyn DeviceFlow>>,
    /// The spheres while there is no step: none, and the step count.
    idle: Particles,
    reopen: Reopen,
    flow: FlowSet,
    /// Steps between flow events.
    every: u32,
    dt: f32,
    /// Each material's density \[kg/m³\].
    densities: Vec<f32>,
    /// At least the largest radius in the step (the boxes near the inflows grow with it).
    r_max: f32,
    counts: FlowCounts,
    /// The step's description, kept for the times it has no step.
    described: String,
    /// Gravity at t = 0 set since the run opened (`None`: the scene's), given to every step
    /// opened again.
    gravity: Option<[f32; 3]>,
}

impl FlowStep {
    /// The step over `particles` that `reopen` opens, with `flow` acting every
    /// [`FlowSet::every`] steps (time step `dt`, each material's density in `densities`).
    pub fn new(
        particles: Particles,
        flow: FlowSet,
        dt: f32,
        densities: Vec<f32>,
        reopen: Reopen,
    ) -> Result<Self> {
        let mut step = FlowStep {
            step: None,
            idle: Particles {
                step: particles.step,
                ..Particles::default()
            },
            reopen,
            every: flow.every(true),
            counts: flow.counted,
            flow,
            dt,
            densities,
            r_max: 0.0,
            described: String::new(),
            gravity: None,
        };
        step.open(particles)?;
        Ok(step)
    }

    /// The step count now.
    fn now(&self) -> u64 {
        self.idle.step
    }

    /// Opens the step over `parts` (none for no spheres), with room for spheres to come where
    /// an inflow brings them.
    fn open(&mut self, parts: Particles) -> Result<()> {
        if parts.is_empty() {
            self.step = None;
            self.idle = parts;
            return Ok(());
        }
        let n = parts.len();
        // Room for what the inflows bring: more spheres, of their radii.
        let room = match (self.flow.smallest_radius(), self.flow.largest_radius()) {
            (Some(a), b) => Room {
                spheres: n + (n / 8).max(SPARE_ROOM),
                radii: (a, b),
                region: self.flow.inflow_bounds(),
            },
            (None, _) => Room::of(&parts),
        }
        .holding(&parts);
        self.r_max = room.radii.1;
        let mut step = (self.reopen)(parts, room)?;
        if let Some(gravity) = self.gravity {
            step.set_gravity(gravity)?;
        }
        self.described = step.describe();
        self.step = Some(step);
        Ok(())
    }

    /// Removes and inserts what the flows say after the step that brought the run to `now`.
    fn flow_event(&mut self) -> Result<()> {
        let started = Instant::now();
        let flowed = self.flow_on_device();
        self.counts.events += 1;
        self.counts.event_ms += started.elapsed().as_secs_f64() * 1e3;
        flowed
    }

    /// The event on the device where the step can take it there, else [`round_trip`].
    fn flow_on_device(&mut self) -> Result<()> {
        let event = Event {
            step: self.now(),
            every: self.every,
            dt: self.dt,
        };
        let query = FlowQuery {
            near: self
                .flow
                .reach(event, self.r_max)
                .into_iter()
                .flatten()
                .collect(),
            outflows: self.flow.outflows.clone(),
            floor: self.flow.floor,
        };
        let Some(step) = &mut self.step else {
            return self.round_trip();
        };
        // Inflowing clumps are made on the host.
        if self.flow.clumps.is_some() {
            return self.round_trip();
        }
        if query == FlowQuery::default() {
            return Ok(());
        }
        let Some(scan) = step.scan(&query)? else {
            return self.round_trip();
        };
        if !scan.leaving.is_empty() {
            let rows: Vec<u32> = scan.leaving.iter().map(|s| s.row).collect();
            if !step.remove(&rows)? {
                return self.round_trip();
            }
            // Weighed as the cpu's flows weigh them: by the density of each one's material.
            for s in &scan.leaving {
                self.counts.removed += 1;
                let density = self.densities[s.material as usize];
                self.counts.removed_mass += mass(density, s.radius) as f64;
            }
        }
        let near = |lo: Vec3, hi: Vec3| -> Vec<(Vec3, f32)> {
            let inside = |c: &Vec3| c.cmpge(lo).all() && c.cmple(hi).all();
            scan.near
                .iter()
                .filter(|(c, _)| inside(c))
                .copied()
                .collect()
        };
        let new = self.flow.insert(event, self.r_max, near, &mut self.counts);
        if new.is_empty() || step.append(&new)? {
            let largest = new.iter().map(|s| s.radius).fold(0.0, f32::max);
            self.r_max = self.r_max.max(largest);
            return Ok(());
        }
        // No room (or other radii): reopened with them.
        self.counts.read_backs += 1;
        let mut parts = step.particles()?;
        for s in &new {
            parts.push_of(s.centre, s.velocity, s.radius, s.material)?;
        }
        self.open(parts)
    }

    /// The event on the host: every sphere read back, the flows applied, the step reopened.
    fn round_trip(&mut self) -> Result<()> {
        let mut parts = match &mut self.step {
            Some(step) => {
                self.counts.read_backs += 1;
                step.particles()?
            }
            None => self.idle.clone(),
        };
        let changed = self.flow.apply(
            &mut parts,
            self.every,
            self.dt,
            &self.densities,
            &mut self.counts,
        )?;
        if changed { self.open(parts) } else { Ok(()) }
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

    fn step(&self) -> u64 {
        self.now()
    }

    fn particles(&mut self) -> Result<Particles> {
        match &mut self.step {
            Some(step) => step.particles(),
            None => Ok(self.idle.clone()),
        }
    }

    fn snapshot(&mut self) -> Result<Snapshot> {
        match &mut self.step {
            Some(step) => step.snapshot(),
            None => Ok(Snapshot::of(self.idle.clone())),
        }
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        match &mut self.step {
            Some(step) => step.set_motion(motion),
            None => motion.apply(&mut self.idle),
        }
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        self.gravity = Some(gravity);
        match &mut self.step {
            Some(step) => step.set_gravity(gravity),
            None => Ok(()),
        }
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        // Its spheres enter and leave: no load stays with its sphere.
        match loads.is_empty() {
            true => Ok(()),
            false => Err(super::rows::not_fixed()),
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

/// What a flow event asks of the state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlowQuery {
    /// Boxes (lo, hi) whose spheres are listed (around the inflows that insert).
    pub near: Vec<(Vec3, Vec3)>,
    /// Boxes whose spheres leave.
    pub outflows: Vec<(Vec3, Vec3)>,
    /// Centres below this height leave.
    pub floor: Option<f32>,
}

/// A sphere that leaves, as the scan found it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leaving {
    /// Its state index.
    pub row: u32,
    /// Its radius \[m\].
    pub radius: f32,
    /// Its material.
    pub material: u8,
}

/// What the scan found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scan {
    /// Every sphere that leaves, in no order.
    pub leaving: Vec<Leaving>,
    /// Centre and radius of every other sphere in a box of [`FlowQuery::near`], in no order.
    pub near: Vec<(Vec3, f32)>,
}

/// What an engine's state has room for: rows for `spheres` spheres (at least the
/// particles'), and a grid and walls for radii over the range `radii` (at least the
/// particles'); the rest for spheres appended later (the flow events of a device step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Room {
    /// Spheres.
    pub spheres: usize,
    /// Smallest and largest radius \[m\].
    pub radii: (f32, f32),
    /// Where spheres will come (the inflows' regions: a grid build is chosen for them too).
    pub region: Option<([f32; 3], [f32; 3])>,
}

impl Room {
    /// Room for `particles` and nothing more.
    pub fn of(particles: &Particles) -> Room {
        Room {
            spheres: particles.len(),
            radii: particles.radius_range(),
            region: None,
        }
    }

    /// This room, grown to hold `particles` (the radii of none count for nothing).
    pub fn holding(self, particles: &Particles) -> Room {
        let (a, b) = particles.radius_range();
        let radii = match (particles.is_empty(), self.radii) {
            (true, radii) => radii,
            (false, (0.0, 0.0)) => (a, b),
            (false, (lo, hi)) => (lo.min(a), hi.max(b)),
        };
        Room {
            spheres: self.spheres.max(particles.len()),
            radii,
            ..self
        }
    }
}
