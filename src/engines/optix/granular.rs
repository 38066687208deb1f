//! The granular part of the optix DEM step (docs/method.md, "The optix granular step"): what a
//! run with Hertz–Mindlin or per-pair contacts, friction, rolling resistance or spinning spheres
//! keeps on the GPU besides the frictionless step's state, and how it moves to and from the
//! host. The contacts are resolved by `optix/granular.cu` (the law of `optix/contact.cuh`, twin
//! of `dem::model::contact`), the walls and the integration by `optix/granular_kernels.cu`.
//!
//! Contact history lives in three buffers of `slots` entries per sphere, indexed by stable id
//! (the input index), so the Morton re-sort never moves it. A step reads one and writes
//! another; the third holds the history of the batch's start, untouched until the batch is
//! known good. Each pair is written by its owner only (the sphere whose ray reports it); the
//! host reads owner-only entries back as both sides (the partner's springs negated), the layout
//! of [`ContactHistory`], and uploads both-sided entries as they are (the owner finds its own).
//! Every sphere's contacts are counted even where they do not fit: if any sphere needed more
//! than `slots`, the batch is redone from its start with more slots.
//!
//! Mesh walls (and a box switched off) run here only, whatever the contact law: the
//! integration kernel resolves each sphere's mesh-wall contacts after its box walls'
//! (`optix/mesh_walls.cuh`), from the tables the wgpu engines upload too
//! ([`WallTables`]), and sums the walls' loads in the last step of an advance.

use super::clumps::DeviceClumps;
use super::device::{
    Device, Gas, HistorySlots, LawTable, MeshBuffers, Order, SlotsRead, State, cuda,
};
use super::launches::{
    ClumpStep, GranularBuffers, GranularIntegration, GranularKernels, GranularProgram,
};
use super::programs::GranularLaw;
use crate::clump::ClumpSet;
use crate::dem::model::law::CohesionParams;
use crate::dem::model::{LawParams, StepParams};
use crate::dem::walls::{WallLoad, WallSet};
use crate::engines::common::walls::{WallTables, wall_loads};
use crate::error::{Error, OptixError, Result};
use crate::particles::{ContactHistory, HistoryEntry, LoadEntry, Particles};
use crate::proxy::ProxyMode;
use cudarc::driver::{CudaSlice, CudaStream, DriverError, sys::CUresult};
use std::sync::Arc;

/// History slots per sphere a run starts with, as the cpu step (a dense monodisperse packing
/// has 12 neighbours, plus up to 3 walls; a pair is held by one of its spheres only here).
const FIRST_SLOTS: u32 = 16;

/// The granular step's programs, parameters and buffers.
pub(super) struct Granular {
    program: GranularProgram,
    kernels: GranularKernels,
    /// The step's parameters, but for the history's slots (each launch gives its own).
    params: LawParams,
    /// Every pair of materials' law.
    laws: LawTable,
    /// wx, wy, wz and the material (its bits: `Particles::material`) per sphere, in the
    /// state's order.
    ang: CudaSlice<f32>,
    /// The angular velocities at the batch's start (and the re-sort's scratch).
    ang_spare: CudaSlice<f32>,
    /// Contact torques of the current step, 3 floats per sphere.
    torque: CudaSlice<f32>,
    history: History,
    mesh: MeshBuffers,
    /// The loads on the mesh walls in the last step of the last advance.
    loads: Vec<WallLoad>,
    /// The clumps (none: one unread entry each).
    clumps: DeviceClumps,
}

/// The contact history on the GPU: three buffers, of which a step reads `current` and writes
/// another, while `start` holds the batch's start until the batch is known good (each with the
/// load histories of the Mindlin–Deresiewicz model where `loaded`).
struct History {
    buffers: [HistorySlots; 3],
    loaded: bool,
    start: usize,
    current: usize,
    /// The most contacts a sphere held where that exceeded the slots (0: none did).
    need: CudaSlice<u32>,
    /// Where no contact carries springs: the buffers are empty, and the particles' history
    /// (if any) is given back as it came, as the cpu step does.
    idle: Option<ContactHistory>,
}

impl History {
    /// The buffer the next step writes: neither the one it reads nor the batch's start.
    fn next(&self) -> usize {
        if self.current == self.start {
            (self.start + 1) % 3
        } else {
            3 - self.current - self.start
        }
    }

    /// The buffer the next step reads, the one it writes and the overflow counter.
    fn step_buffers(&mut self) -> (&HistorySlots, &mut HistorySlots, &mut CudaSlice<u32>) {
        let (read, write) = (self.current, self.next());
        let [old, new] = self
            .buffers
            .get_disjoint_mut([read, write])
            .expect("a step reads and writes different buffers");
        (old, new, &mut self.need)
    }

    fn slots(&self) -> u32 {
        self.buffers[0].slots()
    }
}

impl Granular {
    /// Uploads the angular velocities, the materials and the contact history of `particles`
    /// (`order`: the input index of each state position) for a step with `params` inside
    /// `walls`, whose materials [`check_materials`] passed.
    pub fn new(
        device: &Arc<Device>,
        particles: &Particles,
        params: &StepParams,
        order: &[u32],
        walls: &WallSet,
    ) -> Result<Self> {
        let n = order.len() as u32;
        let stream = &device.stream;
        let alloc = cuda("allocating the granular state");
        let ang_rows: Vec<f32> = order
            .iter()
            .flat_map(|&i| {
                let [x, y, z] = particles.angular_velocities[i as usize];
                [x, y, z, f32::from_bits(particles.material(i as usize))]
            })
            .collect();
        let ang = if ang_rows.is_empty() {
            stream.alloc_zeros::<f32>(4)
        } else {
            stream.clone_htod(&ang_rows)
        }
        .map_err(&alloc)?;
        let zeros = |len: usize| stream.alloc_zeros::<f32>(len.max(4)).map_err(&alloc);
        let loaded = params.friction.keeps_load();
        let table = params.materials.clone();
        let laws = LawTable::upload(stream, &table, CohesionParams::of(params))?;
        let keeps = params.friction.has_history();
        let r_max = particles.radius_range().1;
        let law = GranularLaw {
            loaded,
            cohesive: params.adheres(),
        };
        let params = LawParams::new(params, n, 0).reaching(params, r_max);
        let history = if keeps {
            upload_history(device, &particles.history, n, loaded)?
        } else {
            let empty = three(|| HistorySlots::empty(stream, 0, 0, false))?;
            History {
                idle: Some(particles.history.clone()),
                ..History::on_device(device, empty, false)?
            }
        };
        let reach = r_max + params.reach;
        let tables = WallTables::new(walls, &table, reach, u32::MAX as u64, "optix")?;
        Ok(Self {
            mesh: MeshBuffers::upload(stream, &tables)?,
            loads: vec![WallLoad::default(); walls.meshes.len()],
            program: GranularProgram::new(device, law)?,
            kernels: GranularKernels::load(device, law)?,
            params,
            laws,
            ang_spare: zeros(4 * n as usize)?,
            torque: zeros(3 * n as usize)?,
            ang,
            history,
            clumps: DeviceClumps::upload(stream, &particles.clumps)?,
        })
    }

    /// History slots per sphere (0 where no contact carries springs).
    pub fn slots(&self) -> u32 {
        self.history.slots()
    }

    /// The step's parameters with the history's slots.
    fn law(&self) -> LawParams {
        self.params.with_history(self.slots(), 0)
    }

    /// Resolves every contact of `state` (forces into `force`, torques into the step's torque
    /// accumulator, the pairs' new history).
    pub fn resolve(
        &mut self,
        gas: &Gas,
        mode: ProxyMode,
        state: &State,
        force: &mut CudaSlice<f32>,
        contacts: &mut CudaSlice<u32>,
        candidates: &mut CudaSlice<u64>,
    ) -> Result<()> {
        let law = self.law();
        let (old, new, _) = self.history.step_buffers();
        let buffers = GranularBuffers {
            state,
            ang: &self.ang,
            force,
            torque: &mut self.torque,
            contacts,
            candidates,
            old,
            new,
            laws: &self.laws,
            clumps: (&self.clumps.of, self.clumps.components()),
        };
        self.program.launch(gas, mode, law, buffers)?;
        Ok(())
    }

    /// Walls, gravity at `step` and one integration step of `state` and the angular
    /// velocities (each clump's, which places its components); completes the new history,
    /// which the next step reads.
    pub fn integrate(
        &mut self,
        state: &mut State,
        (force, external): (&mut CudaSlice<f32>, &CudaSlice<f32>),
        step: u32,
    ) -> Result<()> {
        let law = self.law();
        let components = self.clumps.components();
        let written = self.history.next();
        let (old, new, need) = self.history.step_buffers();
        let b = GranularIntegration {
            ang: &mut self.ang,
            force,
            torque: &mut self.torque,
            old,
            new,
            need,
            laws: &self.laws,
            external,
            clump_rows: (&mut self.clumps.rows, components),
        };
        self.kernels
            .integrate(state, b, &law, step, &mut self.mesh)?;
        if self.clumps.any() {
            let c = &mut self.clumps;
            let clumps = ClumpStep {
                count: c.count(),
                bodies: &mut c.bodies,
                shapes: &c.shapes,
                parts: &c.parts,
                rows: &c.rows,
            };
            let accumulators = (&mut self.ang, force, &mut self.torque);
            self.kernels.advance_clumps(
                state,
                accumulators,
                (external, &self.laws),
                clumps,
                &law,
                step,
            )?;
        }
        self.history.current = written;
        Ok(())
    }

    /// Sums the loads on the mesh walls in step `step` (the last of the advance to come), from
    /// zero.
    pub fn sum_loads_in(&mut self, stream: &Arc<CudaStream>, step: u64) -> Result<()> {
        if self.mesh.params.walls > 0 {
            self.mesh.params.loads_step = step as u32;
            self.mesh.clear_loads(stream, true)?;
        }
        Ok(())
    }

    /// Sums the loads of the spheres whose centres lie in `lo <= c < hi` only (a rank's box).
    pub fn sum_loads_within(&mut self, (lo, hi): ([f32; 3], [f32; 3])) {
        (self.mesh.params.own_lo, self.mesh.params.own_hi) = (lo, hi);
    }

    /// Reads the loads summed in the last advance, refusing one in which some sphere came
    /// within its radius of more triangles of one wall than the step keeps.
    pub fn read_loads(&mut self, stream: &Arc<CudaStream>) -> Result<()> {
        let walls = self.mesh.params.walls as usize;
        if walls > 0 {
            let words = self.mesh.read_loads(stream)?;
            let lanes = self.mesh.params.load_lanes as usize;
            self.loads = wall_loads(&words, walls, lanes, "optix")?;
        }
        Ok(())
    }

    /// The loads on each mesh wall in the last step of the last advance.
    pub fn loads(&self) -> &[WallLoad] {
        &self.loads
    }

    /// Reorders the angular velocities as the state (`order[p]`: the position whose sphere
    /// goes to p).
    pub fn permute(&mut self, order: &Order) -> Result<()> {
        let n = self.params.n;
        self.kernels
            .permute_rows(&self.ang, order, &mut self.ang_spare, n)?;
        std::mem::swap(&mut self.ang, &mut self.ang_spare);
        Ok(())
    }

    /// Whether a batch can overflow the history slots, so that it must be able to start over.
    pub fn may_start_over(&self) -> bool {
        self.history.idle.is_none()
    }

    /// Starts a batch from `state`, which [`Self::start_over`] can go back to: keeps a copy of
    /// it in `spare` and of the angular velocities, and clears the overflow counter.
    pub fn begin_batch(
        &mut self,
        stream: &Arc<CudaStream>,
        state: &State,
        spare: &mut State,
    ) -> Result<()> {
        let copy = cuda("keeping the batch's start");
        stream
            .memcpy_dtod(&state.pos, &mut spare.pos)
            .map_err(&copy)?;
        stream
            .memcpy_dtod(&state.lo, &mut spare.lo)
            .map_err(&copy)?;
        stream
            .memcpy_dtod(&state.vel, &mut spare.vel)
            .map_err(&copy)?;
        stream
            .memcpy_dtod(&self.ang, &mut self.ang_spare)
            .map_err(&copy)?;
        self.clumps.keep_start(stream)?;
        stream.memset_zeros(&mut self.history.need).map_err(&copy)?;
        if self.mesh.params.walls > 0 {
            // A batch redone sums the loads of its steps once.
            self.mesh.clear_loads(stream, false)?;
        }
        self.history.start = self.history.current;
        Ok(())
    }

    /// After a batch: the most contacts a sphere needed, where that exceeded the slots.
    pub fn overflow(&self, stream: &Arc<CudaStream>) -> Result<Option<u32>> {
        let need = stream
            .clone_dtoh(&self.history.need)
            .map_err(cuda("reading the history counter"))?[0];
        Ok((need > self.slots()).then_some(need))
    }

    /// Goes back to the batch's start (`spare`, as [`Self::begin_batch`] kept it) with room
    /// for `need` contacts per sphere and a quarter more; [`Error::TooLarge`] where the GPU's
    /// memory cannot hold that.
    pub fn start_over(
        &mut self,
        device: &Device,
        state: &mut State,
        spare: &State,
        need: u32,
    ) -> Result<()> {
        let stream = &device.stream;
        let copy = cuda("going back to the batch's start");
        stream
            .memcpy_dtod(&spare.pos, &mut state.pos)
            .map_err(&copy)?;
        stream
            .memcpy_dtod(&spare.lo, &mut state.lo)
            .map_err(&copy)?;
        stream
            .memcpy_dtod(&spare.vel, &mut state.vel)
            .map_err(&copy)?;
        stream
            .memcpy_dtod(&self.ang_spare, &mut self.ang)
            .map_err(&copy)?;
        self.clumps.restore_start(stream)?;
        let h = &mut self.history;
        let (old_slots, loaded) = (h.slots(), h.loaded);
        let SlotsRead {
            counts,
            entries,
            loads,
        } = h.buffers[h.start].read(stream)?;
        let n = counts.len() as u32;
        // Room for this sphere and some more, rather than a redo per extra contact.
        let slots = need.saturating_add(need / 4);
        let entries = relayout(&entries, old_slots as usize, slots as usize);
        let loads = relayout(&loads, old_slots as usize, slots as usize);
        // The old buffers go first, their memory back to the GPU (freed on the stream), as it
        // is the new ones' too.
        h.buffers = three(|| HistorySlots::empty(stream, 0, 0, false))?;
        stream
            .synchronize()
            .map_err(cuda("freeing the contact history"))?;
        let loads = loaded.then_some(&loads[..]);
        self.history = upload(device, n, slots, &counts, &entries, loads)?;
        Ok(())
    }

    /// Ends a batch that did not overflow: its last history is the next batch's start.
    pub fn end_batch(&mut self) {
        self.history.start = self.history.current;
    }

    /// The angular velocities and the materials (in input order, `ids[p]` the input index of
    /// state position p) and the contact history, both sides of each pair.
    /// Sets gravity at t = 0 from the next step on.
    pub(super) fn set_gravity(&mut self, gravity: [f32; 3]) {
        self.params.gravity = gravity.into();
    }

    /// Whether the integration reads the external loads.
    pub(super) fn set_external(&mut self, on: bool) {
        self.params.loaded = on as u32;
    }

    /// The clumps as the device holds them now.
    pub(super) fn read_clumps(&self, stream: &Arc<CudaStream>) -> Result<ClumpSet> {
        self.clumps.read(stream)
    }

    /// Whether the run has clumps.
    pub(super) fn has_clumps(&self) -> bool {
        self.clumps.any()
    }

    /// Whether the step turns its spheres.
    pub(super) fn turns(&self) -> bool {
        self.params.turns != 0
    }

    /// The angular velocities on the device: x, y, z and the material's bits per sphere, in
    /// the step's order.
    pub(super) fn spin_mut(&mut self) -> &mut CudaSlice<f32> {
        &mut self.ang
    }

    pub fn read_back(&self, stream: &Arc<CudaStream>, ids: &[u32]) -> Result<ReadBack> {
        let read = cuda("reading the angular velocities back");
        let rows = stream.clone_dtoh(&self.ang).map_err(&read)?;
        let mut w = vec![[0.0f32; 3]; ids.len()];
        let mut materials = vec![0u8; ids.len()];
        for (row, &id) in rows.chunks_exact(4).zip(ids) {
            w[id as usize] = [row[0], row[1], row[2]];
            // Uploaded from a u8 and never written since.
            materials[id as usize] = row[3].to_bits() as u8;
        }
        let h = &self.history;
        let history = match &h.idle {
            Some(given) => given.clone(),
            None => {
                let read = h.buffers[h.current].read(stream)?;
                both_sides(&read, h.slots() as usize)?
            }
        };
        Ok(ReadBack {
            angular_velocities: w,
            materials,
            history,
        })
    }
}

/// What the granular step reads back besides the frictionless step's state, in input order.
pub(super) struct ReadBack {
    pub angular_velocities: Vec<[f32; 3]>,
    /// Each sphere's material.
    pub materials: Vec<u8>,
    pub history: ContactHistory,
}

impl History {
    /// Buffers `buffers` (the first holding the history; load histories where `loaded`) with a
    /// cleared overflow counter.
    fn on_device(device: &Device, buffers: [HistorySlots; 3], loaded: bool) -> Result<Self> {
        let need = device
            .stream
            .alloc_zeros::<u32>(1)
            .map_err(cuda("allocating the history counter"))?;
        Ok(Self {
            buffers,
            loaded,
            start: 0,
            current: 0,
            need,
            idle: None,
        })
    }
}

/// Refuses materials the step would read past the table with: a sphere's beyond the table's
/// materials, the box's or a mesh wall's column beyond its rigid wall's.
pub(super) fn check_materials(
    particles: &Particles,
    params: &StepParams,
    walls: &WallSet,
) -> Result<()> {
    let table = &params.materials;
    particles.check_materials(table.count)?;
    let rigid = table.column_of_rigid_wall();
    let columns = walls.meshes.iter().map(|w| w.column(table));
    match std::iter::once(params.box_column).chain(columns).max() {
        Some(column) if column > rigid => Err(Error::InvalidConfig {
            what: "optix".into(),
            reason: format!(
                "a wall has material {column} but the scene has {} materials",
                table.count
            ),
        }),
        _ => Ok(()),
    }
}

/// Three buffers made by `make`.
fn three(
    make: impl Fn() -> std::result::Result<HistorySlots, OptixError>,
) -> std::result::Result<[HistorySlots; 3], OptixError> {
    Ok([make()?, make()?, make()?])
}

/// `history` (by stable id, both sides of each pair, as the cpu step keeps it) on the GPU for
/// `n` spheres, with the slots it needs and at least [`FIRST_SLOTS`], and load histories
/// beside the entries where `loaded` (zero where `history` has none).
fn upload_history(
    device: &Device,
    history: &ContactHistory,
    n: u32,
    loaded: bool,
) -> Result<History> {
    let slots = FIRST_SLOTS.max(history.most() as u32);
    if history.is_empty() {
        check_room(device, n, slots, loaded)?;
        let empty = || HistorySlots::empty(&device.stream, n, slots, loaded);
        let buffers = three(empty).map_err(|e| out_of_room(device, e, n, slots, loaded))?;
        return History::on_device(device, buffers, loaded);
    }
    let (counts, entries, loads) = layout(history, n as usize, slots as usize);
    let loads = loaded.then_some(&loads[..]);
    upload(device, n, slots, &counts, &entries, loads)
}

/// History `counts` and `entries` (`slots` per sphere) of `n` spheres on the GPU, with the
/// load histories `loads` beside them (`None`: none kept).
fn upload(
    device: &Device,
    n: u32,
    slots: u32,
    counts: &[u32],
    entries: &[HistoryEntry],
    loads: Option<&[LoadEntry]>,
) -> Result<History> {
    let loaded = loads.is_some();
    check_room(device, n, slots, loaded)?;
    let stream = &device.stream;
    let room = |e| out_of_room(device, e, n, slots, loaded);
    let start = HistorySlots::upload(stream, slots, counts, entries, loads).map_err(room)?;
    let empty = || HistorySlots::empty(stream, n, slots, loaded);
    let [a, b] = [empty().map_err(room)?, empty().map_err(room)?];
    History::on_device(device, [start, a, b], loaded)
}

/// [`Error::TooLarge`] unless the GPU has room for the three history buffers of `n` spheres
/// with `slots` slots each (with load histories where `loaded`).
fn check_room(device: &Device, n: u32, slots: u32, loaded: bool) -> Result<()> {
    let needed = 3 * HistorySlots::bytes(n, slots, loaded);
    let free = device.free_memory()?;
    if needed <= free {
        return Ok(());
    }
    Err(too_large(device, n, slots, needed, free))
}

fn too_large(device: &Device, n: u32, slots: u32, needed: u64, free: u64) -> Error {
    Error::TooLarge {
        what: format!(
            "bytes of GPU memory for the contact history of {n} spheres with {slots} contacts \
             each (three buffers) on {}, whose free memory is the limit",
            device.name
        ),
        got: needed,
        limit: free,
    }
}

/// An allocation that failed for want of memory as [`Error::TooLarge`]; other errors as they
/// are.
fn out_of_room(device: &Device, e: OptixError, n: u32, slots: u32, loaded: bool) -> Error {
    match e {
        OptixError::Cuda {
            error: DriverError(CUresult::CUDA_ERROR_OUT_OF_MEMORY),
            ..
        } => too_large(
            device,
            n,
            slots,
            3 * HistorySlots::bytes(n, slots, loaded),
            device.free_memory().unwrap_or(0),
        ),
        e => e.into(),
    }
}

/// The counts, the entries (`slots` per sphere, which must hold the most any sphere has) and
/// their load histories (zero where `history` keeps none) of `history` for `n` spheres.
fn layout(
    history: &ContactHistory,
    n: usize,
    slots: usize,
) -> (Vec<u32>, Vec<HistoryEntry>, Vec<LoadEntry>) {
    let mut counts = vec![0u32; n];
    let mut entries = vec![HistoryEntry::default(); n * slots];
    let mut loads = vec![LoadEntry::default(); n * slots];
    for (i, count) in counts.iter_mut().enumerate() {
        let (held, held_loads) = (history.of(i), history.loads_of(i));
        entries[i * slots..i * slots + held.len()].copy_from_slice(held);
        loads[i * slots..i * slots + held_loads.len()].copy_from_slice(held_loads);
        *count = held.len() as u32;
    }
    (counts, entries, loads)
}

/// `entries` of `from` slots per sphere in `to` ≥ `from` slots per sphere.
fn relayout<T: Copy + Default>(entries: &[T], from: usize, to: usize) -> Vec<T> {
    let n = entries.len() / from.max(1);
    let mut out = vec![T::default(); n * to];
    for (i, held) in entries.chunks_exact(from.max(1)).enumerate() {
        out[i * to..i * to + from].copy_from_slice(held);
    }
    out
}

/// The history of spheres holding `counts[i]` entries of `entries[i·slots..]` (and their load
/// histories, where `read` has them) in the cpu's layout ([`ContactHistory::from_owner_rows`]).
fn both_sides(read: &SlotsRead, slots: usize) -> Result<ContactHistory> {
    let (counts, entries) = (&read.counts, &read.entries);
    let load = |at: usize| read.loads.get(at).copied().unwrap_or_default();
    let row = |i: usize| {
        let held = (counts[i] as usize).min(slots);
        (i * slots..i * slots + held).map(|at| (entries[at], load(at)))
    };
    ContactHistory::from_owner_rows(counts.len(), !read.loads.is_empty(), row)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::FIRST_WALL;

    fn entry(partner: u32, x: f32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: [x, 0.0, -x],
            rolling: [0.0, x, 0.0],
        }
    }

    #[test]
    fn owner_only_entries_read_back_as_both_sides() {
        // Sphere 0 owns its contacts with 1 and 2, sphere 2 holds a box wall and sphere 1 a
        // mesh wall (walls are never mirrored); 2 slots each.
        let e = HistoryEntry::default();
        let mesh_wall = crate::particles::FIRST_MESH_WALL + 1;
        let entries = [
            entry(1, 1.0),
            entry(2, 2.0),
            entry(mesh_wall, 4.0),
            e,
            entry(FIRST_WALL + 4, 3.0),
            e,
        ];
        let read = |counts: &[u32], entries: &[HistoryEntry]| SlotsRead {
            counts: counts.to_vec(),
            entries: entries.to_vec(),
            loads: Vec::new(),
        };
        let h = both_sides(&read(&[2, 1, 1], &entries), 2).unwrap();
        assert_eq!(h.of(0), &[entry(1, 1.0), entry(2, 2.0)]);
        // A sphere's contacts come in the order of their owners.
        assert_eq!(h.of(1), &[entry(0, -1.0), entry(mesh_wall, 4.0)]);
        assert_eq!(h.of(2), &[entry(0, -2.0), entry(FIRST_WALL + 4, 3.0)]);
        // Both-sided already (an upload read back before any step): nothing is doubled.
        let (counts, entries, _) = layout(&h, 3, 4);
        assert_eq!(counts, [2, 2, 2]);
        assert_eq!(both_sides(&read(&counts, &entries), 4).unwrap(), h);
        // More slots: the same history.
        let wider = relayout(&entries, 4, 7);
        assert_eq!(wider.len(), 21);
        assert_eq!(both_sides(&read(&counts, &wider), 7).unwrap(), h);
    }

    #[test]
    fn load_histories_read_back_on_both_sides_with_their_reversal_negated() {
        let load = LoadEntry {
            reversal: [0.5, -0.25, 0.0],
            normal: 2.0,
        };
        let read = SlotsRead {
            counts: vec![1, 0],
            entries: vec![entry(1, 1.0), HistoryEntry::default()],
            loads: vec![load, LoadEntry::default()],
        };
        let h = both_sides(&read, 1).unwrap();
        assert_eq!(h.loads_of(0), &[load]);
        assert_eq!(h.of(1), &[entry(0, -1.0)]);
        let mirrored = LoadEntry {
            reversal: [-0.5, 0.25, -0.0],
            normal: 2.0,
        };
        assert_eq!(h.loads_of(1), &[mirrored]);
        let (_, _, loads) = layout(&h, 2, 2);
        assert_eq!(
            loads,
            [load, LoadEntry::default(), mirrored, LoadEntry::default()]
        );
        assert_eq!(relayout(&loads, 2, 3)[3], mirrored);
    }

    #[test]
    fn a_partner_out_of_range_is_refused() {
        let read = SlotsRead {
            counts: vec![1],
            entries: vec![entry(5, 1.0)],
            loads: Vec::new(),
        };
        assert!(both_sides(&read, 1).is_err());
    }
}
