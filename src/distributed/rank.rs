//! One rank of a decomposed run. It holds the spheres whose centres lie in its box (in the
//! order of their ids in the whole run, their contact history naming partners by id) and takes
//! the steps in rounds of k steps (k = 1 unless set), each round as
//!
//! 1. **ghosts**: every rank sends each other rank the spheres within the halo of its box: k
//!    cells of the whole run's lattice (a cell is the reach of any pair), and for k > 1 twice
//!    the farthest any sphere can travel in k steps at the fastest sphere's speed and gravity;
//! 2. **steps**: its own spheres and the ghosts, merged in the order of their ids, take k steps
//!    of its engine. A step's force on a sphere depends only on the spheres within a cell of
//!    it, so the ghosts' errors (they miss the spheres beyond the halo) creep inwards by at
//!    most a cell (and their travel) a step and never reach an own sphere within the round.
//!    On the cpu, on the lattice of the whole run, each sphere sums its contacts in an order
//!    its place and the ids decide, so an own sphere's state is the whole run's bit for bit;
//!    a GPU backend's step (on the rank's GPU) sums in its own order, so its run matches the
//!    whole run as two runs of one GPU match. The ghosts' new states are dropped (their owners
//!    have them);
//! 3. **migration**: a sphere whose centre left the box goes to the rank that owns it now,
//!    with its contact history.
//!
//! A clump's spheres are the rank's whose box holds the clump's centre, wherever they lie;
//! they go with their clump, which goes whole, as a ghost too (the `clumps` module), and the
//! halo is deeper by the clumps' span.
//!
//! A GPU step that can stay on its device from round to round (`resident`) takes the three
//! phases there instead, exchanging states alone (not in a run of clumps); other GPU steps are
//! opened again over each round's spheres.
//!
//! Each pair is computed on both of its sides (every engine does so in any run), so no force
//! crosses ranks: only states do.

use super::clumps::{RankClumps, read_clumps};
use super::comm::Comm;
use super::grid::Grid;
use super::pieces::OwnPiece;
use super::record::{Held, SphereRecord, own_pair_ends, partners_by_id, put, read_all, spheres_of};
use super::resident::Resident;
use super::slabs::Slabs;
use crate::clump::ClumpSet;
use crate::dem::StepParams;
use crate::dem::flow::{FlowCounts, FlowSet};
use crate::dem::stepper::{
    Advance, Clock, ExternalLoads, Motion, RankShare, Snapshot, StageTimes, Stepper,
};
use crate::dem::walls::{WallLoad, WallSet};
use crate::engines::common::flow::{Reopen, Room};
use crate::engines::cpu::CpuStepper;
use crate::engines::{BackendChoice, DemSetup, Opened, Options, open_rank_step};
use crate::error::{Error, Result};
use crate::io::{CheckpointPiece, KeptHistory};
use crate::particles::{ContactHistory, FIRST_MESH_WALL, HistoryEntry, LoadEntry, Particles};
use crate::proxy::ProxyMode;
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

/// How a rank steps its spheres and their ghosts.
enum LocalStep {
    /// The cpu step, opened at the first round and given each round's spheres since (its cells
    /// and scratch kept).
    Cpu(Option<Box<CpuStepper>>),
    /// A GPU backend's step, opened again over each round's spheres on the rank's GPU, or
    /// kept there from round to round where the backend can (`resident`; the rank's own
    /// spheres are then read from it when asked). Either sums the walls' loads of the spheres
    /// in the rank's box alone.
    Device {
        reopen: Reopen,
        backend: &'static str,
        resident: Option<Resident>,
    },
}

/// One rank's part of a run decomposed into boxes.
pub struct RankStepper<C: Comm> {
    comm: C,
    grid: Grid,
    params: StepParams,
    mode: ProxyMode,
    walls: WallSet,
    /// The largest sphere of the whole run: every rank bins on the lattice its cells make.
    r_max: f32,
    /// The smallest and largest radius of the whole run and its inflows \[m\].
    radii: (f32, f32),
    /// How far a step looks for a sphere's partners: a cell of the whole run's lattice,
    /// padded for the rounding of the centres \[m\].
    reach: f64,
    /// Steps a round (between two exchanges of ghosts).
    round: u32,
    /// This rank's spheres, by ascending id.
    own: Vec<Held>,
    /// The run's clumps and this rank's (`None`: the run has none).
    clumps: Option<RankClumps>,
    /// The ghosts of the last step.
    ghosts: usize,
    /// The spheres of the whole run.
    total: usize,
    /// The loads on the spheres of the whole run, by id (empty lists: none).
    loads: ExternalLoads,
    /// The step of its spheres and their ghosts.
    local: LocalStep,
    /// Steps taken since t = 0.
    step: u64,
    /// This rank's share of the run so far.
    share: RankShare,
    /// The loads of every rank's own spheres on each mesh wall in the last step, summed over
    /// the ranks.
    wall_loads: Vec<WallLoad>,
    /// The spheres' ways in and out, with what they did since t = 0 (the same on every rank).
    flow: Option<(FlowSet, FlowCounts)>,
    /// Steps between two moves of the grid's faces (0: never).
    rebalance_every: u64,
    /// Rows a GPU step kept from round to round keeps for spheres to come (`None`: as many as
    /// its ghosts, at least a sixteenth of its own spheres, and 1024 more).
    spare_rows: Option<usize>,
    /// Steps since the faces last moved, and this rank's time stepping its spheres since
    /// \[ms\] (laying out, stepping, reading back: not waiting for the others).
    since_rebalance: (u64, f64),
    /// The contacts of the last call that counted them (each contact once).
    counted: u64,
}

impl<C: Comm> RankStepper<C> {
    /// This rank's part of `setup` (the whole run's start, which every rank is given): the
    /// spheres in its box of the run's box cut into a grid of `comm.size()` boxes ([`Grid`]),
    /// stepped on the cpu, ghosts exchanged every step.
    pub fn new(comm: C, setup: &DemSetup) -> Result<Self> {
        Self::opened(comm, setup, None)
    }

    /// [`Self::new`] where `setup`'s spheres come without their contact history, and `kept`
    /// holds the history of those this rank owns as it opens ([`owned_at_opening`]; a history
    /// read for another rank is an error): a resumed run's rank reads no other history.
    pub fn with_own_history(comm: C, setup: &DemSetup, kept: &KeptHistory) -> Result<Self> {
        Self::opened(comm, setup, Some(kept))
    }

    fn opened(comm: C, setup: &DemSetup, kept: Option<&KeptHistory>) -> Result<Self> {
        let DemSetup {
            particles: whole,
            params,
            mode,
            walls,
        } = setup;
        whole.validate()?;
        let lo = params.box_lo.map(f64::from);
        let hi = params.box_hi.map(f64::from);
        let grid = Grid::cut(lo, hi, comm.size())?;
        let radii = whole.radius_range();
        let r_max = radii.1;
        let reach = reach_of(r_max, params, *mode);
        let own = own_of(whole, &grid, comm.rank(), kept)?;
        let clumps = RankClumps::of(whole, &grid, comm.rank());
        // Every rank opens the same run (and none goes on before all have opened it).
        let mut outgoing = vec![(whole.len() as u64).to_le_bytes().to_vec(); comm.size()];
        outgoing[comm.rank()].clear();
        let counts = comm.exchange(outgoing)?;
        let same = |m: &Vec<u8>| m.is_empty() || m[..] == (whole.len() as u64).to_le_bytes();
        if !counts.iter().all(same) {
            return Err(Error::Usage(
                "the ranks opened runs of different spheres: every rank must open the same".into(),
            ));
        }
        let own_count = own.len() as u64;
        Ok(Self {
            comm,
            grid,
            params: params.clone(),
            mode: *mode,
            walls: walls.clone(),
            r_max,
            radii,
            reach,
            round: 1,
            own,
            clumps,
            ghosts: 0,
            total: whole.len(),
            loads: ExternalLoads::default(),
            local: LocalStep::Cpu(None),
            step: whole.step,
            share: RankShare {
                spheres: own_count,
                ..RankShare::default()
            },
            wall_loads: vec![WallLoad::default(); walls.meshes.len()],
            flow: None,
            rebalance_every: 0,
            spare_rows: None,
            since_rebalance: (0, 0.0),
            counted: 0,
        })
    }

    /// The same rank exchanging ghosts every `steps` steps (at least 1), its halo that many
    /// cells deep and more (the module's rounds): fewer exchanges, more ghosts. Every rank of
    /// a group takes the same.
    pub fn exchanging_every(mut self, steps: u32) -> Result<Self> {
        if steps == 0 {
            return Err(Error::Usage(
                "ranks exchange their ghosts every 1 or more steps".into(),
            ));
        }
        self.round = steps;
        Ok(self)
    }

    /// The same rank stepping on the backend of `choice` (`auto`: the registry's one rule; a
    /// GPU backend on the GPU of the process's local rank), with the backend it runs on. On a
    /// GPU backend it exchanges ghosts as seldom as a halo of a quarter of the thinnest box
    /// allows (at most every 32 steps): each round pays a read-back and a write (of the spheres
    /// near the box's faces, where its step stays on the device; else of every sphere), so a
    /// round is as long as its ghosts let it be.
    pub fn on_backend(mut self, choice: BackendChoice, options: &Options) -> Result<Opened<Self>> {
        let setup = DemSetup {
            particles: Particles::default(),
            params: self.params.clone(),
            mode: self.mode,
            walls: self.walls.clone(),
        };
        let opened = open_rank_step(choice, setup, options)?;
        if let Some(reopen) = opened.value {
            let thinnest = self.grid.thinnest();
            self.round = ((thinnest / (4.0 * self.reach)) as u32).clamp(1, 32);
            let backend = opened.kind.name();
            self.local = LocalStep::Device {
                reopen,
                backend,
                resident: None,
            };
        }
        Ok(Opened {
            value: self,
            kind: opened.kind,
            reason: opened.reason,
        })
    }

    /// Steps a round (between two exchanges of ghosts).
    pub fn steps_between_exchanges(&self) -> u32 {
        self.round
    }

    /// The same rank moving the grid's faces at the end of the first round `steps` steps or
    /// more after the last move (0: never), so that each slab of each axis cut holds an equal
    /// part of the work: on the cpu each rank's time stepping its spheres since the last move,
    /// spread evenly over them, on a GPU backend the spheres themselves, summed over their
    /// places along each axis by every rank alike. On the cpu any faces give the whole run bit
    /// for bit. Every rank of a group takes the same.
    pub fn rebalancing_every(mut self, steps: u64) -> Self {
        self.rebalance_every = steps;
        self
    }

    /// The same rank keeping, on a GPU step it keeps from round to round, rows for `spheres`
    /// more spheres than it opened it over (default: as many as its ghosts, at least a
    /// sixteenth of its own spheres, and 1024 more: the spheres a round brings come in through
    /// the halo, and every row holds a sphere's whole state and contact history on the
    /// device): spheres that enter its box or its halo take them; where they run out, the rank
    /// opens its step again.
    pub fn keeping_rows_for(mut self, spheres: usize) -> Self {
        self.spare_rows = Some(spheres);
        self
    }

    /// The grid of the ranks' boxes now.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Moves the faces ([`rebalancing_every`](Self::rebalancing_every)) and hands on the
    /// spheres whose box changed (every rank together). A step kept on the device stays where
    /// no face moved farther than the halo: every sphere entering a box is a ghost there, and
    /// the next round's exchange, over the new boxes, hands it on with the springs its new
    /// owner kept for it.
    fn rebalance(&mut self) -> Result<()> {
        let busy = std::mem::take(&mut self.since_rebalance).1;
        let centres: Vec<[f64; 3]> = match self.resident_mut() {
            Some(resident) => resident.own_centres()?,
            None => {
                self.settle()?;
                self.own.iter().map(Held::exact_position).collect()
            }
        };
        // A GPU rank's time is mostly its round's fixed costs (the exchange, the launches),
        // which spread over its spheres would give the rank with fewer fewer still: GPU ranks
        // balance their spheres.
        let per_sphere = match self.local {
            LocalStep::Device { .. } => 1.0,
            LocalStep::Cpu(_) => busy / centres.len().max(1) as f64,
        };
        // The work along each axis, one histogram after the other.
        let mut work = vec![0.0f64; 3 * Slabs::BINS];
        for &x in &centres {
            for (a, axis) in self.grid.axes.iter().enumerate() {
                work[a * Slabs::BINS + axis.bin(x)] += per_sphere;
            }
        }
        // Every rank sums the same histograms in the order of the ranks: the same faces.
        let outgoing = vec![bytemuck::cast_slice(&work).to_vec(); self.comm.size()];
        let mut total = vec![0.0f64; 3 * Slabs::BINS];
        for message in self.comm.exchange(outgoing)? {
            if message.len() != total.len() * 8 {
                return Err(Error::Usage("a rank's work is not a histogram".into()));
            }
            let theirs: Vec<f64> = bytemuck::pod_collect_to_vec(&message);
            total.iter_mut().zip(theirs).for_each(|(t, w)| *t += w);
        }
        let along = |a: usize| total[a * Slabs::BINS..(a + 1) * Slabs::BINS].to_vec();
        let grid = self.grid.balanced(&[along(0), along(1), along(2)]);
        let halo = self.resident_mut().map(|r| r.halo());
        let kept = halo.is_some_and(|halo| grid.moved_within(&self.grid, halo));
        self.grid = grid;
        if !kept {
            self.settle()?;
            self.migrate()?;
            self.share.spheres = self.own.len() as u64;
        }
        Ok(())
    }

    /// The same rank with spheres entering and leaving by `flow` (from its counts on), as
    /// the cpu step's flows do it: at each flow event every rank gathers the whole run, takes
    /// the same event on it and keeps the spheres of its box (ids renumbered as the event
    /// leaves the spheres: in their order), so that the run stays the whole run bit for bit
    /// on the cpu. Every rank of a group takes the same.
    pub fn with_flow(mut self, flow: FlowSet) -> Result<Self> {
        if flow.is_empty() {
            return Ok(self);
        }
        // The lattice of the whole run, sized for what the inflows bring as well.
        self.r_max = self.r_max.max(flow.largest_radius());
        let smallest = flow.smallest_radius().unwrap_or(self.radii.0);
        self.radii = (self.radii.0.min(smallest), self.r_max);
        self.reach = reach_of(self.r_max, &self.params, self.mode).max(self.reach);
        let counted = flow.counted;
        self.flow = Some((flow, counted));
        Ok(self)
    }

    /// The flow event after the round that brought the run to its step, where one is due
    /// ([`with_flow`](Self::with_flow); every rank together).
    fn flow_event(&mut self) -> Result<()> {
        let gpu = matches!(self.local, LocalStep::Device { .. });
        let Some(every) = self.flow.as_ref().map(|(flow, _)| flow.every(gpu)) else {
            return Ok(());
        };
        if !FlowSet::due_after(self.step, every) {
            return Ok(());
        }
        let started = Instant::now();
        // The event changes the spheres on the host: a step kept on the device is let go.
        self.settle()?;
        let mut whole = self
            .collect(true)?
            .ok_or_else(|| Error::Usage("the run was not gathered here".into()))?;
        let Some((flow, counts)) = &mut self.flow else {
            return Ok(());
        };
        let (dt, densities) = (self.params.dt, &self.params.materials.densities);
        flow.apply(&mut whole, every, dt, densities, counts)?;
        counts.events += 1;
        counts.event_ms += started.elapsed().as_secs_f64() * 1e3;
        self.total = whole.len();
        self.own = own_of(&whole, &self.grid, self.comm.rank(), None)?;
        self.clumps = RankClumps::of(&whole, &self.grid, self.comm.rank());
        self.share.spheres = self.own.len() as u64;
        Ok(())
    }

    /// Steps to the next flow event (none: `u32::MAX`).
    fn steps_to_flow_event(&self) -> u32 {
        let gpu = matches!(self.local, LocalStep::Device { .. });
        match &self.flow {
            Some((flow, _)) => {
                let every = flow.every(gpu) as u64;
                (every - self.step % every) as u32
            }
            None => u32::MAX,
        }
    }

    /// The spheres this rank owns now.
    pub fn own_spheres(&self) -> usize {
        match &self.local {
            LocalStep::Device {
                resident: Some(r), ..
            } => r.own_spheres(),
            _ => self.own.len(),
        }
    }

    /// The ghosts this rank held in its last step.
    pub fn ghost_spheres(&self) -> usize {
        self.ghosts
    }

    /// This rank and the ranks of its group.
    pub fn comm(&self) -> &C {
        &self.comm
    }

    /// How far beyond its box a rank holds ghosts for a round of `steps` steps (the module's
    /// first phase; every rank together).
    fn halo(&self, steps: u32) -> Result<f64> {
        let fastest = self
            .own
            .iter()
            .map(|h| h.sphere.speed())
            .fold(0.0, f64::max);
        self.halo_at(steps, fastest)
    }

    /// [`halo`](Self::halo) where this rank's fastest sphere moves at `fastest` \[m/s\].
    /// A clump's components lie up to its span beyond its owner's box, and a ghost clump
    /// missing a contact is wrong at once in all its components: with clumps the halo is a
    /// span deeper, and each step of the round two spans more.
    fn halo_at(&self, steps: u32, fastest: f64) -> Result<f64> {
        let span = self.clumps.as_ref().map_or(0.0, |c| c.span);
        let reach = steps as f64 * (self.reach + 2.0 * span) + span;
        if steps == 1 {
            return Ok(reach);
        }
        let fastest = self.max_over_ranks(fastest)?;
        let gravity = glam::Vec3::from(self.params.gravity).length() as f64;
        let round = steps as f64 * self.params.dt as f64;
        let travel = round * (fastest + gravity * round);
        Ok(reach + 2.0 * travel)
    }

    /// The external loads on the spheres of the whole run's ids `ids`, in that order.
    fn loads_of(&self, ids: &[u32]) -> ExternalLoads {
        let rows = |all: &[[f32; 3]]| match all.is_empty() {
            true => Vec::new(),
            false => ids.iter().map(|&id| all[id as usize]).collect(),
        };
        ExternalLoads {
            forces: rows(&self.loads.forces),
            torques: rows(&self.loads.torques),
        }
    }

    /// The step kept on the device (none: the rank holds its spheres).
    fn resident_mut(&mut self) -> Option<&mut Resident> {
        match &mut self.local {
            LocalStep::Device { resident, .. } => resident.as_mut(),
            LocalStep::Cpu(_) => None,
        }
    }

    /// The step kept on the device, taken out of the rank (none: the rank holds its spheres).
    fn take_resident(&mut self) -> Option<Resident> {
        match &mut self.local {
            LocalStep::Device { resident, .. } => resident.take(),
            LocalStep::Cpu(_) => None,
        }
    }

    /// Reads the rank's own spheres, with their contacts, from a step kept on the device, which
    /// is then let go (the next round opens one again): before anything but a round reads or
    /// changes them.
    fn settle(&mut self) -> Result<()> {
        if let Some(mut resident) = self.take_resident() {
            self.own = resident.held()?;
        }
        Ok(())
    }

    /// A round of `steps` steps of the step kept on the device, which holds the round's own
    /// spheres and ghosts: its steps, then the exchange that leaves it holding the next round's
    /// ([`Resident::exchange`]: the ghosts and the migration of the module's phases, by
    /// states alone). Returns as [`take_round`](Self::take_round).
    fn resident_round(
        &mut self,
        mut resident: Resident,
        steps: u32,
        count: bool,
        started: Instant,
    ) -> Result<(u64, StageTimes, Vec<WallLoad>)> {
        let loads = match self.loads.is_empty() {
            true => ExternalLoads::default(),
            false => self.loads_of(&resident.ids()),
        };
        let step = &mut resident.step;
        step.set_gravity(self.params.gravity)?;
        step.set_external_loads(&loads)?;
        let opened = Instant::now();
        let mut times = step.advance(steps)?.times;
        let stepped = Instant::now();
        self.step = step.step();
        let wall_loads = step.wall_loads();
        self.ghosts = resident.ghosts();
        self.share.spheres = resident.own_spheres() as u64;
        self.share.ghosts = self.ghosts as u64;
        let count = count.then_some(self.mode);
        // The next round's halo, at the speeds the round ends with.
        let round = self.round;
        let halo = |fastest: f64| self.halo_at(round, fastest);
        let exchanged = resident.exchange(&self.comm, &self.grid, halo, count)?;
        let touching = exchanged.touching.unwrap_or(0);
        match exchanged.settled {
            Some(own) => self.own = own,
            None => {
                // The walls' loads of the spheres in the box, as the exchange left them (the
                // faces may have moved since the last).
                let (lo, hi) = self.grid.bounds_of(self.comm.rank());
                (resident.step).sum_wall_loads_within((lo.map(|x| x as f32), hi.map(|x| x as f32)));
                if let LocalStep::Device { resident: kept, .. } = &mut self.local {
                    *kept = Some(resident);
                }
            }
        }
        let ms = |from: Instant, to: Instant| (to - from).as_secs_f64() * 1e3;
        let share = &mut self.share;
        share.rounds += 1;
        share.steps += steps as u64;
        share.open_ms += ms(started, opened);
        share.step_ms += ms(opened, stepped);
        share.read_back_ms += exchanged.read_ms;
        share.exchange_ms += stepped.elapsed().as_secs_f64() * 1e3 - exchanged.read_ms;
        self.since_rebalance.0 += steps as u64;
        self.since_rebalance.1 += ms(started, stepped) + exchanged.read_ms;
        let engine = times.total_ms();
        times.build_ms += (started.elapsed().as_secs_f64() * 1e3 - engine).max(0.0);
        Ok((touching, times, wall_loads))
    }

    /// One round of `steps` steps: ghosts, the steps, migration (the module's three phases);
    /// returns, where `count` asks, each own sphere's contacts with spheres after it, summed
    /// (each contact of two own spheres counted by both; 0 where not asked: a GPU step's are
    /// found on the host), and the round's phase times (the exchanges and the opening of a GPU
    /// step counted as the build's).
    fn take_round(&mut self, steps: u32, count: bool) -> Result<(u64, StageTimes, Vec<WallLoad>)> {
        let started = Instant::now();
        if let Some(resident) = self.take_resident() {
            return self.resident_round(resident, steps, count, started);
        }
        let halo = self.halo(steps)?;
        let (outgoing, clumps_out) = self.ghosts_out(steps, halo);
        let mut ghosts = read_all(&self.comm.exchange(outgoing)?)?;
        ghosts.par_sort_unstable_by_key(|h| h.sphere.id);
        self.ghosts = ghosts.len();
        let ghost_clumps = match self.clumps.is_some() {
            true => read_clumps(&self.comm.exchange(clumps_out)?)?,
            false => Vec::new(),
        };

        let ghosts_in = Instant::now();
        let (mut local, ids, own_at) = self.merged(&ghosts)?;
        let local_clumps = match &self.clumps {
            Some(clumps) => {
                let found = clumps.local(&ghost_clumps, &ids)?;
                local.clumps = found.set.clone();
                Some(found)
            }
            None => None,
        };
        let loads = self.loads_of(&ids);
        let gravity = self.params.gravity;
        // When the engine had the round's spheres, and when it had stepped them.
        let (mut opened, mut stepped) = (Instant::now(), Instant::now());
        let meshes = self.walls.meshes.len();
        let (after, mut times, touching, wall_loads) = match &mut self.local {
            // No sphere here: nothing to step.
            _ if local.is_empty() => {
                let after = Particles {
                    step: local.step + steps as u64,
                    ..local
                };
                let loads = vec![WallLoad::default(); meshes];
                (after, StageTimes::default(), 0, loads)
            }
            LocalStep::Cpu(kept) => {
                let stepper = match kept.take() {
                    Some(mut stepper) => {
                        stepper.replace_particles(local)?;
                        kept.insert(stepper)
                    }
                    None => {
                        let setup = DemSetup {
                            particles: local,
                            params: self.params.clone(),
                            mode: self.mode,
                            walls: self.walls.clone(),
                        };
                        let opened = CpuStepper::open(setup)?.sized_for(self.r_max, self.mode);
                        kept.insert(Box::new(opened))
                    }
                };
                stepper.set_gravity(gravity)?;
                stepper.set_external_loads(&loads)?;
                let mut counted = vec![false; ids.len()];
                own_at.iter().for_each(|&at| counted[at] = true);
                stepper.count_wall_loads_of(Some(counted));
                opened = Instant::now();
                let times = stepper.advance(steps)?.times;
                stepped = Instant::now();
                let touching = stepper.touching();
                let own_touching = own_at.iter().map(|&at| touching[at] as u64).sum();
                let wall_loads = stepper.wall_loads();
                (stepper.particles()?, times, own_touching, wall_loads)
            }
            LocalStep::Device { reopen, .. } => {
                // Kept on the device from now on, room made for the spheres to come (a step
                // of clumps is opened again each round: no room to spare).
                let ghosts = local.len() - own_at.len();
                let spare = match local_clumps {
                    Some(_) => 0,
                    None => (self.spare_rows).unwrap_or(ghosts.max(own_at.len() / 16) + 1024),
                };
                let room = Room {
                    spheres: local.len() + spare,
                    radii: self.radii,
                    region: None,
                }
                .holding(&local);
                give_back_freed_memory();
                let mut stepper = reopen(local, room)?;
                // The walls' loads of the spheres this rank owns, not of its ghosts.
                let (lo, hi) = self.grid.bounds_of(self.comm.rank());
                stepper.sum_wall_loads_within((lo.map(|x| x as f32), hi.map(|x| x as f32)));
                // A step kept on the device exchanges spheres alone, not clumps.
                if stepper.resident().is_some() && local_clumps.is_none() {
                    let resident = Resident::new(stepper, &ids, &own_at)?;
                    self.own.clear();
                    return self.resident_round(resident, steps, count, started);
                }
                stepper.set_gravity(gravity)?;
                stepper.set_external_loads(&loads)?;
                opened = Instant::now();
                let times = stepper.advance(steps)?.times;
                stepped = Instant::now();
                let after = stepper.particles()?;
                let own_touching = match count {
                    true => own_pair_ends(&after, &own_at, self.mode)?,
                    false => 0,
                };
                let wall_loads = stepper.wall_loads();
                (after, times, own_touching, wall_loads)
            }
        };
        self.step = after.step;

        let exchanged = Instant::now();
        let by_id = partners_by_id(&ids);
        self.own = own_at
            .iter()
            .map(|&at| Held::of(&after, at, ids[at], by_id))
            .collect();
        if let (Some(clumps), Some(local)) = (&mut self.clumps, &local_clumps) {
            clumps.take_own(&after.clumps, local);
        }
        let read_back = Instant::now();
        self.migrate()?;
        let ms = |from: Instant, to: Instant| (to - from).as_secs_f64() * 1e3;
        let share = &mut self.share;
        share.rounds += 1;
        share.steps += steps as u64;
        share.ghosts = self.ghosts as u64;
        share.spheres = self.own.len() as u64;
        share.exchange_ms += ms(started, ghosts_in) + read_back.elapsed().as_secs_f64() * 1e3;
        share.open_ms += ms(ghosts_in, opened);
        share.step_ms += ms(opened, stepped);
        share.read_back_ms += ms(stepped, read_back);
        self.since_rebalance.0 += steps as u64;
        self.since_rebalance.1 += ms(ghosts_in, read_back);
        // The stage times of the engine's steps, and all else of the round as the build's.
        let engine = ms(started, exchanged) - times.total_ms();
        times.build_ms += engine.max(0.0) + exchanged.elapsed().as_secs_f64() * 1e3;
        Ok((touching, times, wall_loads))
    }

    /// The messages of the module's first phase, one a rank: the own spheres within `halo` of
    /// its box for a round of `steps` steps, and the own clumps any of whose components are
    /// (each with every component).
    fn ghosts_out(&self, steps: u32, halo: f64) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
        let ranks = self.comm.size();
        let owner = self.comm.rank();
        let components = self.clumps.as_ref().map_or(0, RankClumps::components);
        let (in_clumps, free) =
            (self.own).split_at(self.own.partition_point(|h| h.sphere.id < components));
        // A ghost's state after its first step is dropped unless the round goes on; then its
        // contacts must be its own.
        let put_ghost = |message: &mut Vec<u8>, held: &Held| {
            let history = match steps {
                1 => (&[][..], &[][..]),
                _ => (&held.contacts[..], &held.loads[..]),
            };
            put(message, &held.sphere, history);
        };
        // The own clumps, each with its components (consecutive in the own spheres).
        let mut groups = Vec::with_capacity(self.clumps.as_ref().map_or(0, |c| c.own.len()));
        if let Some(clumps) = &self.clumps {
            let mut at = 0;
            for clump in &clumps.own {
                let n = clumps.ids_of(clump.index).len();
                groups.push((Some(clump), &in_clumps[at..at + n]));
                at += n;
            }
        }
        groups.extend(free.iter().map(|held| (None, std::slice::from_ref(held))));
        // Each thread's messages for the ranks whose halos its spheres lie in, then joined
        // (the ghosts are sorted by id where they come).
        let empty = || (vec![Vec::new(); ranks], vec![Vec::new(); ranks]);
        let grid = &self.grid;
        (groups.par_iter())
            .fold(empty, |(mut spheres, mut clumps), &(clump, group)| {
                let mut to: Vec<usize> = (group.iter())
                    .flat_map(|h| grid.ghost_ranks(h.exact_position(), owner, halo))
                    .collect();
                if group.len() > 1 {
                    to.sort_unstable();
                    to.dedup();
                }
                for r in to {
                    group
                        .iter()
                        .for_each(|held| put_ghost(&mut spheres[r], held));
                    if let Some(c) = clump {
                        clumps[r].extend_from_slice(bytemuck::bytes_of(c));
                    }
                }
                (spheres, clumps)
            })
            .reduce(empty, |(mut s, mut c), (more_s, more_c)| {
                s.iter_mut().zip(more_s).for_each(|(a, m)| a.extend(m));
                c.iter_mut().zip(more_c).for_each(|(a, m)| a.extend(m));
                (s, c)
            })
    }

    /// Sends each own sphere whose centre lies beyond this rank's box, with its contacts, to
    /// the rank that owns it, and takes those sent here (every rank together).
    fn migrate(&mut self) -> Result<()> {
        let rank = self.comm.rank();
        // Where each own clump goes (by ascending index): its components go with it.
        let clumps_to: Vec<(u32, usize)> = (self.clumps.iter())
            .flat_map(|c| c.own.iter().map(|c| (c.index, self.grid.owner(c.position))))
            .collect();
        let goes_to = |held: &Held| match self
            .clumps
            .as_ref()
            .and_then(|c| c.clump_of(held.sphere.id))
        {
            None => Ok(self.grid.owner(held.exact_position())),
            Some(k) => match clumps_to.binary_search_by_key(&k, |&(index, _)| index) {
                Ok(at) => Ok(clumps_to[at].1),
                Err(_) => Err(Error::Usage(
                    "a clump's sphere is on a rank without its clump".into(),
                )),
            },
        };
        let mut outgoing = vec![Vec::new(); self.comm.size()];
        let mut staying = Vec::with_capacity(self.own.len());
        for held in std::mem::take(&mut self.own) {
            match goes_to(&held)? {
                r if r == rank => staying.push(held),
                r => put(
                    &mut outgoing[r],
                    &held.sphere,
                    (&held.contacts, &held.loads),
                ),
            }
        }
        staying.extend(read_all(&self.comm.exchange(outgoing)?)?);
        staying.par_sort_unstable_by_key(|h| h.sphere.id);
        self.own = staying;
        if let Some(clumps) = &mut self.clumps {
            let mut outgoing = vec![Vec::new(); self.comm.size()];
            let mut staying = Vec::with_capacity(clumps.own.len());
            for (clump, &(_, r)) in std::mem::take(&mut clumps.own).iter().zip(&clumps_to) {
                match r == rank {
                    true => staying.push(*clump),
                    false => outgoing[r].extend_from_slice(bytemuck::bytes_of(clump)),
                }
            }
            staying.extend(read_clumps(&self.comm.exchange(outgoing)?)?);
            staying.sort_unstable_by_key(|c| c.index);
            clumps.own = staying;
        }
        Ok(())
    }

    /// The 8 bytes of `x` from every other rank (every rank together).
    fn of_other_ranks(&self, x: [u8; 8]) -> Result<Vec<[u8; 8]>> {
        let mut outgoing = vec![x.to_vec(); self.comm.size()];
        outgoing[self.comm.rank()].clear();
        let mut values = Vec::new();
        for message in self.comm.exchange(outgoing)? {
            if message.is_empty() {
                continue;
            }
            let bytes = message
                .as_slice()
                .try_into()
                .map_err(|_| Error::Usage("a rank's number is not 8 bytes".into()))?;
            values.push(bytes);
        }
        Ok(values)
    }

    /// The sum of `x` over the ranks (every rank together).
    fn sum_over_ranks(&self, x: u64) -> Result<u64> {
        let others = self.of_other_ranks(x.to_le_bytes())?;
        Ok(x + others.into_iter().map(u64::from_le_bytes).sum::<u64>())
    }

    /// `loads` summed over the ranks, in the order of the ranks (every rank together).
    fn loads_over_ranks(&self, loads: &[WallLoad]) -> Result<Vec<WallLoad>> {
        let rows: Vec<[f64; 6]> = loads
            .iter()
            .map(|l| std::array::from_fn(|k| if k < 3 { l.force[k] } else { l.torque[k - 3] }))
            .collect();
        let outgoing = vec![bytemuck::cast_slice(&rows).to_vec(); self.comm.size()];
        let mut sum = vec![WallLoad::default(); loads.len()];
        for message in self.comm.exchange(outgoing)? {
            if message.len() != rows.len() * 48 {
                return Err(Error::Usage("a rank's wall loads are not the run's".into()));
            }
            let theirs: Vec<[f64; 6]> = bytemuck::pod_collect_to_vec(&message);
            for (s, t) in sum.iter_mut().zip(theirs) {
                s.add(&WallLoad {
                    force: [t[0], t[1], t[2]],
                    torque: [t[3], t[4], t[5]],
                });
            }
        }
        Ok(sum)
    }

    /// The largest `x` of the ranks (every rank together).
    fn max_over_ranks(&self, x: f64) -> Result<f64> {
        let others = self.of_other_ranks(x.to_le_bytes())?;
        Ok(others.into_iter().map(f64::from_le_bytes).fold(x, f64::max))
    }

    /// This rank's spheres and `ghosts` (by ascending id) merged in the order of their ids (a
    /// sphere then meets its neighbours in the order the whole run's step does), as one set of
    /// spheres whose history names partners by their place in it; with the id of each sphere of
    /// it and the places of the own ones.
    fn merged(&self, ghosts: &[Held]) -> Result<(Particles, Vec<u32>, Vec<usize>)> {
        let n = self.own.len() + ghosts.len();
        // Each sphere, and whether it is an own one.
        let mut spheres: Vec<(&Held, bool)> = Vec::with_capacity(n);
        let (mut a, mut b) = (0, 0);
        while a < self.own.len() || b < ghosts.len() {
            let take_own = b == ghosts.len()
                || (a < self.own.len() && self.own[a].sphere.id < ghosts[b].sphere.id);
            match take_own {
                true => {
                    spheres.push((&self.own[a], true));
                    a += 1;
                }
                false => {
                    spheres.push((&ghosts[b], false));
                    b += 1;
                }
            }
        }
        let ids: Vec<u32> = spheres.iter().map(|(h, _)| h.sphere.id).collect();
        // The place of each id, by ascending id.
        let mut places: Vec<(u32, u32)> = (0..n as u32).map(|at| (ids[at as usize], at)).collect();
        places.par_sort_unstable();
        if places.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(Error::Usage(
                "a sphere is both owned and a ghost here".into(),
            ));
        }
        let place_of = |id: u32| {
            let k = places.binary_search_by_key(&id, |&(id, _)| id).ok()?;
            Some(places[k].1)
        };
        let mut local = spheres_of(&spheres, |(h, _)| &h.sphere, self.step);
        // The spheres' contacts, partners by place, each with its load history where it has
        // one; a partner sphere beyond the ghosts is beyond reach (the step would drop it).
        let kept: Vec<((u32, HistoryEntry), Option<LoadEntry>)> = (spheres.par_iter().enumerate())
            .flat_map_iter(|(at, &(held, _))| {
                held.contacts.iter().enumerate().filter_map(move |(k, e)| {
                    let partner = match e.partner >= FIRST_MESH_WALL {
                        true => Some(e.partner),
                        false => place_of(e.partner),
                    }?;
                    let contact = (at as u32, HistoryEntry { partner, ..*e });
                    Some((contact, held.loads.get(k).copied()))
                })
            })
            .collect();
        let contacts: Vec<(u32, HistoryEntry)> = kept.iter().map(|&(c, _)| c).collect();
        let loads: Vec<LoadEntry> = kept.iter().filter_map(|&(_, l)| l).collect();
        let own_at: Vec<usize> = (spheres.iter().enumerate())
            .filter(|(_, (_, own))| *own)
            .map(|(at, _)| at)
            .collect();
        if self.params.friction.has_history() {
            local.history = ContactHistory::from_contacts_with_loads(n, &contacts, &loads)?;
        }
        Ok((local, ids, own_at))
    }

    /// The whole run's spheres, on rank 0 (`None` on the others): every rank sends its own.
    pub fn gather(&mut self) -> Result<Option<Particles>> {
        self.collect(false)
    }

    /// The whole run's spheres on rank 0, or on every rank where `everywhere`. A step kept on
    /// the device is read, not let go.
    fn collect(&mut self, everywhere: bool) -> Result<Option<Particles>> {
        let kept = self.resident_mut().map(|r| r.held()).transpose()?;
        let own = kept.as_deref().unwrap_or(&self.own);
        let mut outgoing = vec![Vec::new(); self.comm.size()];
        for (r, message) in outgoing.iter_mut().enumerate() {
            if everywhere || r == 0 {
                for held in own {
                    put(message, &held.sphere, (&held.contacts, &held.loads));
                }
            }
        }
        let received = self.comm.exchange(outgoing)?;
        let clumps = self.collect_clumps(everywhere)?;
        if !everywhere && self.comm.rank() != 0 {
            return Ok(None);
        }
        let mut all = read_all(&received)?;
        all.par_sort_unstable_by_key(|h| h.sphere.id);
        if (all.par_iter().enumerate()).any(|(k, h)| h.sphere.id as usize != k) {
            return Err(Error::Usage("the ranks' spheres are not the run's".into()));
        }
        let mut whole = spheres_of(&all, |h| &h.sphere, self.step);
        let contacts: Vec<(u32, HistoryEntry)> = (all.par_iter())
            .flat_map_iter(|h| h.contacts.iter().map(move |&e| (h.sphere.id, e)))
            .collect();
        let loads: Vec<LoadEntry> = (all.par_iter())
            .flat_map_iter(|h| h.loads.iter().copied())
            .collect();
        if self.params.friction.has_history() {
            whole.history = ContactHistory::from_contacts_with_loads(all.len(), &contacts, &loads)?;
        }
        whole.clumps = clumps.unwrap_or_default();
        Ok(Some(whole))
    }

    /// The run's clumps on rank 0, or on every rank where `everywhere` (`None` on the others,
    /// and where the run has none): every rank sends its own (every rank together).
    fn collect_clumps(&self, everywhere: bool) -> Result<Option<ClumpSet>> {
        let Some(clumps) = &self.clumps else {
            return Ok(None);
        };
        let own: &[u8] = bytemuck::cast_slice(&clumps.own);
        let outgoing = (0..self.comm.size())
            .map(|r| match everywhere || r == 0 {
                true => own.to_vec(),
                false => Vec::new(),
            })
            .collect();
        let received = self.comm.exchange(outgoing)?;
        if !everywhere && self.comm.rank() != 0 {
            return Ok(None);
        }
        let all = read_clumps(&received)?;
        let each_once = all.iter().enumerate().all(|(k, c)| c.index as usize == k);
        if !each_once || all.len() != clumps.count() {
            return Err(Error::Usage("the ranks' clumps are not the run's".into()));
        }
        Ok(Some(clumps.set_of(all.iter())))
    }
}

impl<C: Comm + Send> RankStepper<C> {
    /// This rank's own spheres, each with its contacts counted (in `contacts`), in no set
    /// order. A step kept on the device is read, not let go.
    fn own_records(&mut self) -> Result<Vec<SphereRecord>> {
        match self.resident_mut() {
            Some(resident) => resident.seen(),
            None => Ok((self.own.iter())
                .map(|h| SphereRecord {
                    contacts: h.contacts.len() as u32,
                    ..h.sphere
                })
                .collect()),
        }
    }

    /// The whole run's spheres without their springs, each with its contacts counted, on rank
    /// 0 (`None` on the others): every rank sends its own spheres' records alone.
    pub fn gather_snapshot(&mut self) -> Result<Option<Snapshot>> {
        self.collect_snapshot(false)
    }

    /// [`gather_snapshot`](Self::gather_snapshot) on rank 0, or on every rank where
    /// `everywhere`. A step kept on the device is read, not let go.
    fn collect_snapshot(&mut self, everywhere: bool) -> Result<Option<Snapshot>> {
        let own = self.own_records()?;
        let size = self.comm.size();
        let outgoing = (0..size)
            .map(|r| match everywhere || r == 0 {
                true => bytemuck::cast_slice(&own).to_vec(),
                false => Vec::new(),
            })
            .collect();
        let received = self.comm.exchange(outgoing)?;
        let clumps = self.collect_clumps(everywhere)?;
        if !everywhere && self.comm.rank() != 0 {
            return Ok(None);
        }
        let record = std::mem::size_of::<SphereRecord>();
        if received.iter().any(|m| m.len() % record != 0) {
            return Err(Error::Usage("a rank's message ends inside a sphere".into()));
        }
        // Each record in the place of its id: every id of the run once.
        let mut all = vec![<SphereRecord as bytemuck::Zeroable>::zeroed(); self.total];
        let mut seen = vec![false; self.total];
        for m in &received {
            for bytes in m.chunks_exact(record) {
                let s: SphereRecord = bytemuck::pod_read_unaligned(bytes);
                let id = s.id as usize;
                if seen.get(id) != Some(&false) {
                    return Err(Error::Usage("the ranks' spheres are not the run's".into()));
                }
                (all[id], seen[id]) = (s, true);
            }
        }
        if seen.contains(&false) {
            return Err(Error::Usage("the ranks' spheres are not the run's".into()));
        }
        let mut particles = spheres_of(&all, |s| s, self.step);
        particles.clumps = clumps.unwrap_or_default();
        Ok(Some(Snapshot {
            particles,
            contacts: all.iter().map(|s| s.contacts).collect(),
        }))
    }

    /// [`Stepper::advance`], the contacts of its last step counted where `count` says (else
    /// those counted last: a GPU rank reads its history's partners, or every sphere back).
    fn advance_counting(&mut self, steps: u32, count: bool) -> Result<Advance> {
        let mut times = StageTimes::default();
        let mut touching = 0;
        let mut left = steps;
        let mut loads = Vec::new();
        while left > 0 {
            let round = left.min(self.round).min(self.steps_to_flow_event());
            // The call's contacts are its last step's.
            let last = count && round == left;
            let (own, round_times, round_loads) = self.take_round(round, last)?;
            touching = own;
            loads = round_loads;
            times.add(&round_times);
            left -= round;
            self.flow_event()?;
            if self.rebalance_every > 0 && self.since_rebalance.0 >= self.rebalance_every {
                self.rebalance()?;
            }
        }
        // Each contact of two spheres is counted by both.
        if count && steps > 0 {
            self.counted = self.sum_over_ranks(touching)? / 2;
        }
        let contacts = self.counted;
        if steps > 0 && !loads.is_empty() {
            self.wall_loads = self.loads_over_ranks(&loads)?;
        }
        Ok(Advance {
            steps,
            contacts,
            times,
            clock: Clock::Wall,
        })
    }
}

/// Every rank of a group steps together: a call of one is a call of all, with the same
/// arguments (the rows of the whole run, by id).
impl<C: Comm + Send> Stepper for RankStepper<C> {
    fn describe(&self) -> String {
        let backend = match &self.local {
            LocalStep::Cpu(_) => "cpu",
            LocalStep::Device { backend, .. } => backend,
        };
        let every = match self.round {
            1 => "every step".to_string(),
            k => format!("every {k} steps"),
        };
        format!(
            "{backend}, rank {} of {} ({}, ghosts exchanged {every})",
            self.comm.rank(),
            self.comm.size(),
            self.grid.describe()
        )
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        self.advance_counting(steps, true)
    }

    fn advance_uncounted(&mut self, steps: u32) -> Result<Advance> {
        self.advance_counting(steps, false)
    }

    fn step(&self) -> u64 {
        self.step
    }

    fn rank_shares(&mut self) -> Result<Vec<RankShare>> {
        let mut outgoing = vec![bytemuck::bytes_of(&self.share).to_vec(); self.comm.size()];
        outgoing[self.comm.rank()].clear();
        let mut shares = Vec::with_capacity(self.comm.size());
        for (r, message) in self.comm.exchange(outgoing)?.into_iter().enumerate() {
            shares.push(match r == self.comm.rank() {
                true => self.share,
                false => bytemuck::try_pod_read_unaligned(&message)
                    .map_err(|_| Error::Usage("a rank's share is not one".into()))?,
            });
        }
        Ok(shares)
    }

    fn steps_a_round(&self) -> u32 {
        self.round
    }

    /// A run of clumps writes whole frames (its clumps' frame beside its spheres').
    fn write_pieces(&mut self, dir: &Path) -> Result<Option<Vec<u64>>> {
        if self.clumps.is_some() {
            return Ok(None);
        }
        let own = self.own_records()?;
        let at = (self.step, &self.params);
        super::pieces::write_pieces(&self.comm, own, at, dir).map(Some)
    }

    /// A run of clumps writes whole checkpoints (a piece holds spheres alone).
    fn write_checkpoint_pieces(&mut self, folder: &Path) -> Result<Option<Vec<CheckpointPiece>>> {
        if self.clumps.is_some() {
            return Ok(None);
        }
        let kept = self.resident_mut().map(|r| r.own_piece()).transpose()?;
        let own = match kept {
            Some(piece) => piece,
            None => OwnPiece::of_held(&self.own, self.step),
        };
        super::pieces::write_checkpoint_pieces(&self.comm, &own, folder).map(Some)
    }

    fn flow_counts(&self) -> Option<FlowCounts> {
        self.flow.as_ref().map(|(_, counts)| *counts)
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.wall_loads.clone()
    }

    fn particles(&mut self) -> Result<Particles> {
        self.collect(true)?
            .ok_or_else(|| Error::Usage("the run was not gathered here".into()))
    }

    fn snapshot(&mut self) -> Result<Snapshot> {
        self.collect_snapshot(true)?
            .ok_or_else(|| Error::Usage("the run was not gathered here".into()))
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        motion.check(self.total)?;
        self.settle()?;
        // A clump's components keep the motion they have (as a run of one process checks).
        let components = self.clumps.as_ref().map_or(0, RankClumps::components);
        let changed = (self.own.iter().take_while(|h| h.sphere.id < components)).any(|h| {
            let (i, s) = (h.sphere.id as usize, &h.sphere);
            motion.positions.is_some_and(|x| x[i] != h.exact_position())
                || motion.velocities.is_some_and(|v| v[i] != s.velocity)
                || motion.angular_velocities.is_some_and(|w| w[i] != s.spin)
        });
        if self.sum_over_ranks(changed as u64)? > 0 {
            return Err(crate::dem::stepper::clump_motion_refused());
        }
        for held in &mut self.own {
            let (i, s) = (held.sphere.id as usize, &mut held.sphere);
            if let Some(x) = motion.positions {
                let parts = x[i].map(crate::particles::position::split);
                s.position = parts.map(|p| p.0);
                s.residual = parts.map(|p| p.1);
            }
            if let Some(v) = motion.velocities {
                s.velocity = v[i];
            }
            if let Some(w) = motion.angular_velocities {
                s.spin = w[i];
            }
        }
        // A sphere put in another rank's box goes there before the next step.
        self.migrate()
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        self.params.gravity = gravity;
        Ok(())
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        loads.check(self.total)?;
        if loads.turns() && !self.params.friction.turns() {
            return Err(crate::engines::common::rows::no_spin());
        }
        if self.flow.is_some() && !loads.is_empty() {
            return Err(crate::engines::common::rows::not_fixed());
        }
        self.loads = loads.clone();
        Ok(())
    }
}

/// How far a step looks for a sphere's partners in a run of spheres up to `r_max`: a cell of
/// the whole run's lattice (as far as any pair reaches), padded for the `f32` rounding of the
/// centres the narrow phase compares \[m\].
fn reach_of(r_max: f32, params: &StepParams, mode: ProxyMode) -> f64 {
    let cell = mode.cell_size(r_max) + params.reach_margin(r_max);
    let (lo, hi) = (params.box_lo, params.box_hi);
    let far = lo.iter().chain(&hi).fold(0.0f32, |m, x| m.max(x.abs()));
    cell as f64 * (1.0 + 1e-4) + 1e-6 * far as f64
}

/// Hands the memory this process freed back to the system (glibc keeps freed blocks, and
/// raises the size it maps on its own once large blocks are freed, so a rank that let the whole
/// run go or a round's spheres go would open its step on top of them): a rank's peak is its
/// step's opening, which then starts from what the rank holds. Nothing elsewhere.
pub(crate) fn give_back_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only returns free memory of the allocator to the system; it
    // touches no block in use.
    #[allow(unsafe_code)]
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Whether each sphere of `whole` lies in box `rank` of `grid` (a clump's component: whether
/// its clump's centre does), by place.
fn owned_by(whole: &Particles, grid: &Grid, rank: usize) -> Vec<bool> {
    let clump_of = whole.clumps.owners();
    let clumps = &whole.clumps.clumps;
    (0..whole.len())
        .into_par_iter()
        .map(|i| {
            let x = match clump_of.get(i) {
                Some(&k) => clumps[k as usize].body.position.to_array(),
                None => whole.exact_position(i),
            };
            grid.owner(x) == rank
        })
        .collect()
}

/// Which spheres of `whole`, stepped in the box `box_lo`..`box_hi`, rank `rank` of `ranks` owns
/// as it opens the run ([`RankStepper::new`]), by place: the spheres whose contact history it
/// needs (those of the others come with them as ghosts).
pub fn owned_at_opening(
    whole: &Particles,
    (box_lo, box_hi): ([f32; 3], [f32; 3]),
    (rank, ranks): (usize, usize),
) -> Result<Vec<bool>> {
    let grid = Grid::cut(box_lo.map(f64::from), box_hi.map(f64::from), ranks)?;
    Ok(owned_by(whole, &grid, rank))
}

/// The spheres of `whole` whose centres lie in box `rank` of `grid` (a clump's component: whose
/// clump's centre does), with their contacts (`whole`'s, or those of `kept`, read for the
/// spheres this rank owns), by ascending id (their places in `whole`).
fn own_of(
    whole: &Particles,
    grid: &Grid,
    rank: usize,
    kept: Option<&KeptHistory>,
) -> Result<Vec<Held>> {
    let owned = owned_by(whole, grid, rank);
    // The own places, then their records, each collected into a vector of its length (a
    // rank's records are the larger part of its memory once it has let the whole run go).
    let mut places = Vec::with_capacity(owned.iter().filter(|&&o| o).count());
    places.extend((0..whole.len()).filter(|&i| owned[i]));
    let places = places.into_par_iter();
    let Some(kept) = kept else {
        return Ok(places
            .map(|i| Held::of(whole, i, i as u32, |e| *e))
            .collect());
    };
    if let Some(i) =
        (0..whole.len()).position(|i| owned[i] && !kept.kept.get(i).copied().unwrap_or(false))
    {
        return Err(Error::Usage(format!(
            "sphere {i} is rank {rank}'s, but its contact history was read for another rank"
        )));
    }
    // Each owner's contacts, in their order, at the places `order` lists from `first[owner]`.
    let mut order: Vec<u32> = (0..kept.contacts.len() as u32).collect();
    order.par_sort_by_key(|&k| kept.contacts[k as usize].0);
    let first = |i: usize| order.partition_point(|&k| (kept.contacts[k as usize].0 as usize) < i);
    Ok(places
        .map(|i| {
            let ks = &order[first(i)..first(i + 1)];
            let contacts = ks.iter().map(|&k| kept.contacts[k as usize].1).collect();
            let loads = match kept.loads.is_empty() {
                true => Vec::new(),
                false => ks.iter().map(|&k| kept.loads[k as usize]).collect(),
            };
            Held::with_history(whole, i, contacts, loads)
        })
        .collect())
}
