//! The launches of the optix engine's device programs and CUDA kernels over the owners of
//! `device.rs`: one typed launch function per program and kernel, with the launch parameters
//! the device code reads (each checked against its CUDA twin by [`layout_checks`]). A launch
//! function takes the typed buffers, checks their lengths against the count the device code
//! indexes, builds the launch parameters from them and launches; nothing outside this file and
//! `device.rs` holds a raw device pointer.

use super::device::{
    COUNTER_SLOTS, Device, Gas, HistorySlots, LAW_WORDS, LaunchParamSets, LaunchParams, LawTable,
    MeshBuffers, Order, Pipeline, Result, State, check_len, cuda, per_sphere,
};
use super::programs::{self, GranularLaw, Unit};
use crate::dem::model::law::CohesionParams;
use crate::dem::model::{LawParams, PairBridge, PairLaw, TableLaw};
use crate::engines::common::clumps::{ClumpBodyRow, ClumpShapeRow, clump_rows_fields};
use crate::engines::common::walls::MeshWallRow;
use crate::error::OptixError;
use crate::particles::{HistoryEntry, LoadEntry};
use crate::proxy::ProxyMode;
use cudarc::driver::{CudaFunction, CudaSlice, CudaStream, DevicePtr, DeviceRepr, PushKernelArg};
use std::sync::Arc;

/// Launch parameters of `optix/detect.cu`; keep in sync with `DetectParams` there.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DetectParams {
    spheres: u64,
    ids: u64,
    pairs: u64,
    pair_count: u64,
    candidates: u64,
    handle: u64,
    n: u32,
    capacity: u32,
    mode: u32,
    _pad: u32,
}
const _: () = assert!(size_of::<DetectParams>() == 64);

/// The buffers of one detection launch.
pub struct DetectBuffers<'a> {
    /// x, y, z, r per sphere, in the order of the structure's primitives.
    pub spheres: &'a CudaSlice<f32>,
    /// Input index of each sorted sphere.
    pub ids: &'a CudaSlice<u32>,
    /// Kept pairs, 2 words each; the launch writes at most `capacity` of them.
    pub pairs: &'a mut CudaSlice<u32>,
    /// Pairs found (may exceed the capacity).
    pub pair_count: &'a mut CudaSlice<u32>,
    /// Boxes visited, spread over [`COUNTER_SLOTS`] counters.
    pub candidates: &'a mut CudaSlice<u64>,
}

/// The detection programs of `optix/detect.cu`: one point ray per sphere that writes the kept
/// pairs.
pub struct DetectProgram {
    pipeline: Pipeline,
    params: LaunchParams<DetectParams>,
}

impl DetectProgram {
    /// Compiles (NVRTC, once per process) and links the programs on `device`.
    pub fn new(device: &Arc<Device>) -> Result<Self> {
        let ptx = programs::ptx(Unit::Detect)?;
        Ok(Self {
            pipeline: Pipeline::new(device, ptx, "detect", 1)?,
            params: LaunchParams::new(device)?,
        })
    }

    /// One point ray for each of the `n` spheres of `gas` in `mode`, writing up to `capacity`
    /// pairs (0: count only).
    pub fn launch(
        &mut self,
        gas: &Gas,
        mode: ProxyMode,
        capacity: u32,
        b: DetectBuffers<'_>,
    ) -> Result<()> {
        const LAUNCH: &str = "optix/detect.cu";
        let n = gas.primitives;
        check_len(LAUNCH, "spheres", b.spheres, 4 * n as usize)?;
        check_len(LAUNCH, "ids", b.ids, n as usize)?;
        check_len(LAUNCH, "pairs", b.pairs, 2 * capacity as usize)?;
        check_len(LAUNCH, "pair_count", b.pair_count, 1)?;
        check_len(LAUNCH, "candidates", b.candidates, COUNTER_SLOTS)?;
        let device = &self.pipeline.device;
        let params = DetectParams {
            spheres: device.ptr(b.spheres),
            ids: device.ptr(b.ids),
            pairs: device.ptr_mut(b.pairs),
            pair_count: device.ptr_mut(b.pair_count),
            candidates: device.ptr_mut(b.candidates),
            handle: gas.handle,
            n,
            capacity,
            mode: mode.code(),
            _pad: 0,
        };
        let on_device = self.params.set(&device.stream, params)?;
        // SAFETY: the parameters were built just now from the borrowed buffers, whose lengths
        // cover what detect.cu indexes for n rays over n primitives (spheres and ids by ray and
        // primitive index < n, pairs below capacity, counters & 255).
        unsafe { self.pipeline.launch(on_device, n) }
    }
}

// SAFETY: `#[repr(C)]` plain data laid out as `LawParams` in optix/physics.cuh (checked by
// `layout_checks`).
unsafe impl DeviceRepr for LawParams {}

/// Launch parameters of `optix/dem.cu`; keep in sync with `DemLaunch` there.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DemLaunch {
    pos: u64,
    vel: u64,
    force: u64,
    contacts: u64,
    candidates: u64,
    handle: u64,
    n: u32,
    mode: u32,
    _pad: [u32; 2],
    dem: LawParams,
}
const _: () = assert!(size_of::<DemLaunch>() == 192);

/// The buffers of one DEM contact launch.
pub struct DemBuffers<'a> {
    /// x, y, z, r per sphere, in the order of the structure's primitives.
    pub pos: &'a CudaSlice<f32>,
    /// vx, vy, vz, mass per sphere.
    pub vel: &'a CudaSlice<f32>,
    /// 3 floats per sphere, summed with atomics.
    pub force: &'a mut CudaSlice<f32>,
    /// Touching pairs, spread over [`COUNTER_SLOTS`] counters.
    pub contacts: &'a mut CudaSlice<u32>,
    /// Boxes visited, spread over [`COUNTER_SLOTS`] counters.
    pub candidates: &'a mut CudaSlice<u64>,
}

/// The DEM programs of `optix/dem.cu`: one point ray per sphere that resolves its contacts.
pub struct DemProgram {
    pipeline: Pipeline,
    params: LaunchParams<DemLaunch>,
}

impl DemProgram {
    /// Compiles (NVRTC, once per process) and links the programs on `device`.
    pub fn new(device: &Arc<Device>) -> Result<Self> {
        let ptx = programs::ptx(Unit::Dem)?;
        Ok(Self {
            pipeline: Pipeline::new(device, ptx, "dem", 5)?,
            params: LaunchParams::new(device)?,
        })
    }

    /// One point ray for each of the `n` spheres of `gas` in `mode`, adding contact forces.
    pub fn launch(
        &mut self,
        gas: &Gas,
        mode: ProxyMode,
        dem: LawParams,
        b: DemBuffers<'_>,
    ) -> Result<()> {
        const LAUNCH: &str = "optix/dem.cu";
        let n = gas.primitives;
        check_len(LAUNCH, "pos", b.pos, 4 * n as usize)?;
        check_len(LAUNCH, "vel", b.vel, 4 * n as usize)?;
        check_len(LAUNCH, "force", b.force, 3 * n as usize)?;
        check_len(LAUNCH, "contacts", b.contacts, COUNTER_SLOTS)?;
        check_len(LAUNCH, "candidates", b.candidates, COUNTER_SLOTS)?;
        let device = &self.pipeline.device;
        let params = DemLaunch {
            pos: device.ptr(b.pos),
            vel: device.ptr(b.vel),
            force: device.ptr_mut(b.force),
            contacts: device.ptr_mut(b.contacts),
            candidates: device.ptr_mut(b.candidates),
            handle: gas.handle,
            n,
            mode: mode.code(),
            _pad: [0; 2],
            dem,
        };
        let on_device = self.params.set(&device.stream, params)?;
        // SAFETY: the parameters were built just now from the borrowed buffers, whose lengths
        // cover what dem.cu indexes for n rays over n primitives (rows by ray and primitive
        // index < n, counters & 255).
        unsafe { self.pipeline.launch(on_device, n) }
    }
}

/// [`LawParams`] with the address of the material table: the law as the granular programs and
/// kernels read it (`MochiLaw` in `optix/contact.cuh`), made by each launch from the step's
/// parameters and the [`LawTable`] it borrows.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DeviceLaw {
    dem: LawParams,
    laws: u64,
    cohesion: CohesionParams,
    /// `MochiLaw` is 16-byte aligned (its parameters' `sphere_law` is): its size, too.
    _pad: u32,
}
const _: () = assert!(size_of::<DeviceLaw>() == 160);

// SAFETY: `#[repr(C)]` plain data laid out as `MochiLaw` in optix/contact.cuh (checked by
// `layout_checks`).
unsafe impl DeviceRepr for DeviceLaw {}

impl DeviceLaw {
    /// `dem` reading `table`, checked to hold the laws of its columns.
    fn reading(
        launch: &'static str,
        stream: &Arc<CudaStream>,
        dem: &LawParams,
        table: &LawTable,
    ) -> Result<Self> {
        if table.columns != dem.columns {
            return Err(OptixError::BufferTooShort {
                launch,
                buffer: "material laws",
                len: table.words.len(),
                needed: (dem.columns * (dem.columns - 1)) as usize * LAW_WORDS,
            });
        }
        Ok(Self {
            dem: *dem,
            laws: table.words.device_ptr(stream).0,
            cohesion: table.cohesion,
            _pad: 0,
        })
    }
}

/// Launch parameters of `optix/granular.cu`; keep in sync with `GranularLaunch` there.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GranularLaunch {
    pos: u64,
    vel: u64,
    ang: u64,
    ids: u64,
    force: u64,
    torque: u64,
    contacts: u64,
    candidates: u64,
    old_count: u64,
    old_entries: u64,
    new_count: u64,
    new_entries: u64,
    old_loads: u64,
    new_loads: u64,
    handle: u64,
    clump_of: u64,
    n: u32,
    mode: u32,
    components: u32,
    /// `g` starts a 16-byte line, as `MochiLaw`'s alignment asks.
    _pad: [u32; 1],
    g: DeviceLaw,
}
const _: () = assert!(size_of::<GranularLaunch>() == 304);

/// The buffers of one granular contact launch.
pub struct GranularBuffers<'a> {
    /// Positions, velocities and stable ids, in the order of the structure's primitives.
    pub state: &'a State,
    /// wx, wy, wz and the material (its bits) per sphere.
    pub ang: &'a CudaSlice<f32>,
    /// 3 floats per sphere, summed with atomics.
    pub force: &'a mut CudaSlice<f32>,
    /// 3 floats per sphere, summed with atomics.
    pub torque: &'a mut CudaSlice<f32>,
    /// Touching pairs, spread over [`COUNTER_SLOTS`] counters.
    pub contacts: &'a mut CudaSlice<u32>,
    /// Boxes visited, spread over [`COUNTER_SLOTS`] counters.
    pub candidates: &'a mut CudaSlice<u64>,
    /// The last step's contact history.
    pub old: &'a HistorySlots,
    /// This step's, written by the owners of the pairs.
    pub new: &'a mut HistorySlots,
    /// The material table.
    pub laws: &'a LawTable,
    /// Each component's clump by stable id, below the components' count.
    pub clumps: (&'a CudaSlice<u32>, u32),
}

/// The granular DEM programs of `optix/granular.cu`: one point ray per sphere that resolves
/// its contacts with friction, history and rolling resistance.
pub struct GranularProgram {
    pipeline: Pipeline,
    params: LaunchParamSets<GranularLaunch>,
    /// Compiled for the Mindlin–Deresiewicz model (its history buffers hold load histories).
    loaded: bool,
}

impl GranularProgram {
    /// Compiles (NVRTC, once per process) and links the programs on `device`, those of the
    /// Mindlin–Deresiewicz model where `law.loaded` (the history buffers must then hold load
    /// histories), with the cohesion laws where `law.cohesive`.
    pub fn new(device: &Arc<Device>, law: GranularLaw) -> Result<Self> {
        let loaded = law.loaded;
        let ptx = programs::ptx(Unit::Granular(law))?;
        Ok(Self {
            pipeline: Pipeline::new(device, ptx, "granular", 9)?,
            params: LaunchParamSets::default(),
            loaded,
        })
    }

    /// One point ray for each of the `n` spheres of `gas` in `mode`, adding contact forces and
    /// torques and writing the pairs' new history (`law.slots` per sphere where it keeps any).
    pub fn launch(
        &mut self,
        gas: &Gas,
        mode: ProxyMode,
        law: LawParams,
        b: GranularBuffers<'_>,
    ) -> Result<()> {
        const LAUNCH: &str = "optix/granular.cu";
        let n = gas.primitives;
        let rows = 4 * n as usize;
        check_len(LAUNCH, "pos", &b.state.pos, rows)?;
        check_len(LAUNCH, "vel", &b.state.vel, rows)?;
        check_len(LAUNCH, "ids", &b.state.ids, n as usize)?;
        check_len(LAUNCH, "ang", b.ang, rows)?;
        check_len(LAUNCH, "force", b.force, 3 * n as usize)?;
        check_len(LAUNCH, "torque", b.torque, 3 * n as usize)?;
        check_len(LAUNCH, "contacts", b.contacts, COUNTER_SLOTS)?;
        check_len(LAUNCH, "candidates", b.candidates, COUNTER_SLOTS)?;
        let (history_n, slots) = (if law.keeps() { n } else { 0 }, law.slots);
        b.old.check(LAUNCH, history_n, slots, self.loaded)?;
        b.new.check(LAUNCH, history_n, slots, self.loaded)?;
        let device = &self.pipeline.device;
        let params = GranularLaunch {
            pos: device.ptr(&b.state.pos),
            vel: device.ptr(&b.state.vel),
            ang: device.ptr(b.ang),
            ids: device.ptr(&b.state.ids),
            force: device.ptr_mut(b.force),
            torque: device.ptr_mut(b.torque),
            contacts: device.ptr_mut(b.contacts),
            candidates: device.ptr_mut(b.candidates),
            old_count: device.ptr(&b.old.counts),
            old_entries: device.ptr(&b.old.entries),
            new_count: device.ptr_mut(&mut b.new.counts),
            new_entries: device.ptr_mut(&mut b.new.entries),
            old_loads: b.old.loads_ptr(device),
            new_loads: b.new.loads_ptr_mut(device),
            handle: gas.handle,
            clump_of: device.ptr(b.clumps.0),
            n,
            mode: mode.code(),
            components: b.clumps.1,
            _pad: [0; 1],
            g: DeviceLaw::reading(LAUNCH, &device.stream, &law, b.laws)?,
        };
        let on_device = self.params.set(device, params)?;
        // SAFETY: the parameters were built just now from the borrowed buffers, whose lengths
        // cover what granular.cu indexes for n rays over n primitives (rows by ray and
        // primitive index < n, history by stable id < n with `slots` entries each where the
        // law keeps springs, counters & 255; the material table of its columns, whose rows cover
        // every material the angular velocity rows name: checked when they were uploaded).
        unsafe { self.pipeline.launch(on_device, n) }
    }
}

/// The CUDA kernels of `optix/granular_kernels.cu`, each behind a typed, length-checked launch.
pub struct GranularKernels {
    stream: Arc<CudaStream>,
    integrate: CudaFunction,
    permute_rows: CudaFunction,
    advance_clumps: CudaFunction,
    /// Compiled for the Mindlin–Deresiewicz model (its history buffers hold load histories).
    loaded: bool,
}

/// What one integration of the granular step reads and writes besides the state.
pub struct GranularIntegration<'a> {
    /// wx, wy, wz and the material (its bits) per sphere. integrated in place.
    pub ang: &'a mut CudaSlice<f32>,
    /// Contact forces of the step (3 floats per sphere), cleared.
    pub force: &'a mut CudaSlice<f32>,
    /// Contact torques of the step (3 floats per sphere), cleared.
    pub torque: &'a mut CudaSlice<f32>,
    /// The last step's contact history (the walls' springs).
    pub old: &'a HistorySlots,
    /// This step's: the walls' entries are appended to the pairs'.
    pub new: &'a mut HistorySlots,
    /// Raised to the most contacts a sphere holds where that exceeds the slots.
    pub need: &'a mut CudaSlice<u32>,
    /// The material table.
    pub laws: &'a LawTable,
    /// The external loads by input index (force, then torque: 8 floats per sphere), read
    /// where the law's `loaded` is 1.
    pub external: &'a CudaSlice<f32>,
    /// Where each clump's component (the first stable ids, as many as the second) is noted.
    pub clump_rows: (&'a mut CudaSlice<u32>, u32),
}

/// What the clumps' step reads and writes besides the state.
pub struct ClumpStep<'a> {
    /// The clumps' states ([`ClumpBodyRow`](crate::engines::common::clumps::ClumpBodyRow)s
    /// as words), advanced.
    pub bodies: &'a mut CudaSlice<u32>,
    /// The kinds' rows as words.
    pub shapes: &'a CudaSlice<u32>,
    /// The kinds' components (4 floats each).
    pub parts: &'a CudaSlice<f32>,
    /// Each component's state row, by stable id.
    pub rows: &'a CudaSlice<u32>,
    /// The clumps.
    pub count: u32,
}

impl GranularKernels {
    /// Compiles (NVRTC, once per process) and loads the kernels on `device`, those of the
    /// Mindlin–Deresiewicz model where `law.loaded`, with the cohesion laws where
    /// `law.cohesive`.
    pub fn load(device: &Device, law: GranularLaw) -> Result<Self> {
        let loaded = law.loaded;
        let ptx = programs::ptx(Unit::GranularKernels(law))?;
        let module = device
            .cuda
            .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
            .map_err(cuda("loading optix/granular_kernels.cu"))?;
        let function = |name| {
            module
                .load_function(name)
                .map_err(cuda("loading a kernel of optix/granular_kernels.cu"))
        };
        Ok(Self {
            stream: device.stream.clone(),
            integrate: function("granular_integrate")?,
            permute_rows: function("permute_rows")?,
            advance_clumps: function("advance_clumps")?,
            loaded,
        })
    }

    /// Walls, gravity at `step` and one integration step (rotation included) of the `g.n()`
    /// spheres of `state`, in place; clears the accumulators and completes the new history.
    pub fn integrate(
        &self,
        state: &mut State,
        b: GranularIntegration<'_>,
        law: &LawParams,
        step: u32,
        mesh: &mut MeshBuffers,
    ) -> Result<()> {
        const LAUNCH: &str = "granular_integrate";
        let (n, slots) = (law.n, law.slots);
        if n == 0 {
            return Ok(());
        }
        let rows = 4 * n as usize;
        check_len(LAUNCH, "pos", &state.pos, rows)?;
        check_len(LAUNCH, "lo", &state.lo, rows)?;
        check_len(LAUNCH, "vel", &state.vel, rows)?;
        check_len(LAUNCH, "ids", &state.ids, n as usize)?;
        check_len(LAUNCH, "ang", b.ang, rows)?;
        check_len(LAUNCH, "force", b.force, 3 * n as usize)?;
        check_len(LAUNCH, "torque", b.torque, 3 * n as usize)?;
        check_len(LAUNCH, "need", b.need, 1)?;
        if law.loaded != 0 {
            check_len(LAUNCH, "external", b.external, 8 * n as usize)?;
        }
        let (clump_rows, components) = b.clump_rows;
        check_len(LAUNCH, "clump_rows", clump_rows, components as usize)?;
        let history_n = if law.keeps() { n } else { 0 };
        b.old.check(LAUNCH, history_n, slots, self.loaded)?;
        b.new.check(LAUNCH, history_n, slots, self.loaded)?;
        let g = DeviceLaw::reading(LAUNCH, &self.stream, law, b.laws)?;
        let old = b.old;
        let HistorySlots {
            counts: new_counts,
            entries: new_entries,
            loads: new_loads,
            ..
        } = b.new;
        let mut launch = self.stream.launch_builder(&self.integrate);
        launch
            .arg(&mut state.pos)
            .arg(&mut state.lo)
            .arg(&mut state.vel)
            .arg(b.ang)
            .arg(b.force)
            .arg(b.torque)
            .arg(&state.ids)
            .arg(b.external)
            .arg(&old.counts)
            .arg(&old.entries)
            .arg(new_counts)
            .arg(new_entries);
        match (&old.loads, new_loads) {
            (Some(old_loads), Some(new_loads)) => launch.arg(old_loads).arg(new_loads),
            // Never read without MOCHI_LOAD_HISTORY: any buffer will do for the pointers.
            _ => launch.arg(&old.entries).arg(&old.counts),
        };
        launch
            .arg(b.need)
            .arg(&g)
            .arg(&step)
            .arg(&mesh.params)
            .arg(&mesh.walls)
            .arg(&mesh.grid)
            .arg(&mesh.tris)
            .arg(&mut mesh.loads)
            .arg(clump_rows)
            .arg(&components);
        // SAFETY: the arguments match granular_integrate's signature; the state, ang, force
        // and torque hold g.n() rows, ids g.n() entries below n (a permutation of the input
        // indices), external two rows per sphere where the law reads it, the history buffers g.n() spheres of `slots` entries where g keeps springs
        // (checked above; the kernel reads them only then), with load histories of as many
        // slots where the kernel was compiled for them (checked above), need one word; the
        // material table has g's columns (checked above) and rows for every material the
        // angular velocity rows name, its columns every wall's (checked when they were
        // uploaded); the mesh buffers hold what MeshBuffers::upload made of one WallTables
        // (rows, grids whose offsets and triangle indices stay within them, triangles, and the
        // loads of every lane and wall); clump_rows an entry for each of the first
        // `components` stable ids (checked above).
        unsafe { launch.launch(per_sphere(n)) }.map_err(cuda("launching granular_integrate"))?;
        Ok(())
    }

    /// One step of each clump of `c` after [`integrate`](Self::integrate) of the same step
    /// (`step`, the same `law`): its components' forces and torques summed (and cleared), its
    /// body advanced, its components placed in `state` and given its motion (`ang`).
    #[allow(clippy::too_many_arguments)]
    pub fn advance_clumps(
        &self,
        state: &mut State,
        (ang, force, torque): (
            &mut CudaSlice<f32>,
            &mut CudaSlice<f32>,
            &mut CudaSlice<f32>,
        ),
        (external, laws): (&CudaSlice<f32>, &LawTable),
        c: ClumpStep<'_>,
        law: &LawParams,
        step: u32,
    ) -> Result<()> {
        const LAUNCH: &str = "advance_clumps";
        let (n, count) = (law.n, c.count);
        if count == 0 {
            return Ok(());
        }
        let rows = 4 * n as usize;
        check_len(LAUNCH, "pos", &state.pos, rows)?;
        check_len(LAUNCH, "lo", &state.lo, rows)?;
        check_len(LAUNCH, "vel", &state.vel, rows)?;
        check_len(LAUNCH, "ang", ang, rows)?;
        check_len(LAUNCH, "force", force, 3 * n as usize)?;
        check_len(LAUNCH, "torque", torque, 3 * n as usize)?;
        if law.loaded != 0 {
            check_len(LAUNCH, "external", external, 8 * n as usize)?;
        }
        let words = size_of::<ClumpBodyRow>() / 4;
        check_len(LAUNCH, "bodies", c.bodies, words * count as usize)?;
        let g = DeviceLaw::reading(LAUNCH, &self.stream, law, laws)?;
        let mut launch = self.stream.launch_builder(&self.advance_clumps);
        launch
            .arg(c.bodies)
            .arg(c.shapes)
            .arg(c.parts)
            .arg(c.rows)
            .arg(&mut state.pos)
            .arg(&mut state.lo)
            .arg(&mut state.vel)
            .arg(ang)
            .arg(force)
            .arg(torque)
            .arg(external)
            .arg(&g)
            .arg(&step)
            .arg(&count);
        // SAFETY: the arguments match advance_clumps' signature; bodies hold `count` rows
        // (checked above), each naming a shape of `shapes` and its first component's stable
        // id, the shapes parts within `parts`, and the components' stable ids below the rows'
        // length (ClumpRows::of made them all of one ClumpSet, which Particles::validate
        // checked); the rows, written by this step's integration, are state rows below n, and
        // the state, ang, force and torque hold n rows, external two per sphere where read
        // (checked above).
        unsafe { launch.launch(per_sphere(count)) }.map_err(cuda("launching advance_clumps"))?;
        Ok(())
    }

    /// Reorders `n` rows of 4 floats of `from` into `to`: sorted position p takes row
    /// `order[p]`.
    pub fn permute_rows(
        &self,
        from: &CudaSlice<f32>,
        order: &Order,
        to: &mut CudaSlice<f32>,
        n: u32,
    ) -> Result<()> {
        const LAUNCH: &str = "permute_rows";
        if n == 0 {
            return Ok(());
        }
        check_len(LAUNCH, "rows_in", from, 4 * n as usize)?;
        order.check(LAUNCH, n)?;
        check_len(LAUNCH, "rows", to, 4 * n as usize)?;
        let mut launch = self.stream.launch_builder(&self.permute_rows);
        launch.arg(from).arg(&order.entries).arg(to).arg(&n);
        // SAFETY: the arguments match permute_rows' signature; both buffers hold n rows and the
        // order n entries below n (checked above and in Order::upload).
        unsafe { launch.launch(per_sphere(n)) }.map_err(cuda("launching permute_rows"))?;
        Ok(())
    }
}

/// `static_assert`s of one CUDA struct's size and field offsets against its Rust twin's.
macro_rules! cuda_layout {
    ($cuda:literal, $ty:ty { $($field:ident),* $(,)? }) => {{
        let mut checks = format!(
            "static_assert(sizeof({}) == {}, \"{} has the size of its Rust twin\");\n",
            $cuda,
            size_of::<$ty>(),
            $cuda
        );
        $(
            checks += &format!(
                "static_assert(MOCHI_OFFSET_OF({}, {}) == {}, \"{}.{} lies where Rust has it\");\n",
                $cuda,
                stringify!($field),
                std::mem::offset_of!($ty, $field),
                $cuda,
                stringify!($field)
            );
        )*
        checks
    }};
}

/// CUDA `static_assert`s that every struct of `unit` shared with the host has the size and
/// field offsets of its Rust twin: compiled after the unit (`programs::compile_with_checks`),
/// they need NVRTC but no GPU.
pub fn layout_checks(unit: Unit) -> String {
    let pair_law = || crate::dem::model::materials::pair_law_fields!(cuda_layout, "MochiPairLaw");
    let cohesion = || {
        use crate::dem::model::law::CohesionParams;
        crate::dem::model::law::cohesion_params_fields!(cuda_layout, "MochiCohesion")
    };
    let law_params = || pair_law() + &crate::dem::model::law::law_params_fields!(cuda_layout);
    let table_law = || {
        crate::dem::model::materials::pair_bridge_fields!(cuda_layout, "MochiPairBridge")
            + &crate::dem::model::materials::table_law_fields!(cuda_layout, "MochiTableLaw")
    };
    let device_law = || {
        law_params()
            + &table_law()
            + &cohesion()
            + &cuda_layout!(
                "MochiLaw",
                DeviceLaw {
                    dem,
                    laws,
                    cohesion
                }
            )
    };
    let entry = || {
        cuda_layout!(
            "MochiHistoryEntry",
            HistoryEntry {
                partner,
                tangential,
                rolling
            }
        ) + &cuda_layout!("MochiLoadEntry", LoadEntry { reversal, normal })
    };
    // NVRTC has no offsetof; its front end's __INTADDR__ folds the address to a constant.
    let offset_of =
        "#define MOCHI_OFFSET_OF(T, m) ((unsigned long long)__INTADDR__(&(((T*)0)->m)))\n";
    let checks = match unit {
        Unit::Detect => cuda_layout!(
            "DetectParams",
            DetectParams {
                spheres,
                ids,
                pairs,
                pair_count,
                candidates,
                handle,
                n,
                capacity,
                mode,
                _pad
            }
        ),
        Unit::Kernels => law_params(),
        Unit::Dem => {
            law_params()
                + &cuda_layout!(
                    "DemLaunch",
                    DemLaunch {
                        pos,
                        vel,
                        force,
                        contacts,
                        candidates,
                        handle,
                        n,
                        mode,
                        _pad,
                        dem
                    }
                )
        }
        Unit::Granular(_) => {
            device_law()
                + &entry()
                + &cuda_layout!(
                    "GranularLaunch",
                    GranularLaunch {
                        pos,
                        vel,
                        ang,
                        ids,
                        force,
                        torque,
                        contacts,
                        candidates,
                        old_count,
                        old_entries,
                        new_count,
                        new_entries,
                        old_loads,
                        new_loads,
                        handle,
                        clump_of,
                        n,
                        mode,
                        components,
                        _pad,
                        g
                    }
                )
        }
        Unit::GranularKernels(_) => {
            // The mesh walls' rows go up as the wgpu engines lay them out (encase).
            let row = <MeshWallRow as encase::ShaderSize>::SHADER_SIZE.get();
            device_law()
                + &entry()
                + &format!(
                    "static_assert(sizeof(MochiMeshWall) == {row}, \"MochiMeshWall has the size \
                     of MeshWallRow\");\n"
                )
                + &clump_rows_fields!(cuda_layout, "MochiClumpBody", "MochiClumpShape").concat()
        }
    };
    format!("{offset_of}{checks}")
}

/// The CUDA kernels of `optix/kernels.cu`, each behind a typed, length-checked launch.
pub struct Kernels {
    stream: Arc<CudaStream>,
    proxy_boxes: CudaFunction,
    dem_boxes: CudaFunction,
    dem_integrate: CudaFunction,
    dem_permute: CudaFunction,
}

impl Kernels {
    /// Compiles (NVRTC, once per process) and loads the kernels on `device`.
    pub fn load(device: &Device) -> Result<Self> {
        let ptx = programs::ptx(Unit::Kernels)?;
        let module = device
            .cuda
            .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
            .map_err(cuda("loading optix/kernels.cu"))?;
        let function = |name| {
            module
                .load_function(name)
                .map_err(cuda("loading a kernel of optix/kernels.cu"))
        };
        Ok(Self {
            stream: device.stream.clone(),
            proxy_boxes: function("proxy_boxes")?,
            dem_boxes: function("dem_boxes")?,
            dem_integrate: function("dem_integrate")?,
            dem_permute: function("dem_permute")?,
        })
    }

    /// Gathers `n` spheres into sorted order (`order[p]`: input index of sorted position p)
    /// and writes each one's proxy box in `mode`, padded by `pad_rel`.
    #[allow(clippy::too_many_arguments)]
    pub fn proxy_boxes(
        &self,
        spheres_in: &CudaSlice<f32>,
        order: &Order,
        spheres: &mut CudaSlice<f32>,
        boxes: &mut CudaSlice<f32>,
        n: u32,
        mode: ProxyMode,
        r_max: f32,
        pad_rel: f32,
    ) -> Result<()> {
        const LAUNCH: &str = "proxy_boxes";
        if n == 0 {
            return Ok(());
        }
        check_len(LAUNCH, "spheres_in", spheres_in, 4 * n as usize)?;
        order.check(LAUNCH, n)?;
        check_len(LAUNCH, "spheres", spheres, 4 * n as usize)?;
        check_len(LAUNCH, "boxes", boxes, 6 * n as usize)?;
        let mode = mode.code();
        let mut launch = self.stream.launch_builder(&self.proxy_boxes);
        launch
            .arg(spheres_in)
            .arg(&order.entries)
            .arg(spheres)
            .arg(boxes)
            .arg(&n)
            .arg(&mode)
            .arg(&r_max)
            .arg(&pad_rel);
        // SAFETY: the arguments match proxy_boxes' signature; the buffers hold n spheres and
        // boxes, the order n entries below n (checked above and in Order::upload).
        unsafe { launch.launch(per_sphere(n)) }.map_err(cuda("launching proxy_boxes"))?;
        Ok(())
    }

    /// Writes the proxy box of each of the `n` spheres of `pos` in `mode`, padded by `pad_rel`.
    #[allow(clippy::too_many_arguments)]
    pub fn dem_boxes(
        &self,
        pos: &CudaSlice<f32>,
        boxes: &mut CudaSlice<f32>,
        n: u32,
        mode: ProxyMode,
        r_max: f32,
        pad_rel: f32,
        grow: f32,
    ) -> Result<()> {
        const LAUNCH: &str = "dem_boxes";
        if n == 0 {
            return Ok(());
        }
        check_len(LAUNCH, "pos", pos, 4 * n as usize)?;
        check_len(LAUNCH, "boxes", boxes, 6 * n as usize)?;
        let mode = mode.code();
        let mut launch = self.stream.launch_builder(&self.dem_boxes);
        launch
            .arg(pos)
            .arg(boxes)
            .arg(&n)
            .arg(&mode)
            .arg(&r_max)
            .arg(&pad_rel)
            .arg(&grow);
        // SAFETY: the arguments match dem_boxes' signature; pos holds n rows, boxes 6n floats.
        unsafe { launch.launch(per_sphere(n)) }.map_err(cuda("launching dem_boxes"))?;
        Ok(())
    }

    /// Walls, gravity at `step`, the external loads (`external`: force, then torque, by input
    /// index, 8 floats per sphere; read where `dem.loaded` is 1) and one integration step of
    /// the `dem.n` spheres of `state`, in place; clears `force` for the next step.
    pub fn dem_integrate(
        &self,
        state: &mut State,
        (force, external): (&mut CudaSlice<f32>, &CudaSlice<f32>),
        dem: &LawParams,
        step: u32,
    ) -> Result<()> {
        const LAUNCH: &str = "dem_integrate";
        let n = dem.n;
        if n == 0 {
            return Ok(());
        }
        check_len(LAUNCH, "pos", &state.pos, 4 * n as usize)?;
        check_len(LAUNCH, "lo", &state.lo, 4 * n as usize)?;
        check_len(LAUNCH, "vel", &state.vel, 4 * n as usize)?;
        check_len(LAUNCH, "force", force, 3 * n as usize)?;
        check_len(LAUNCH, "ids", &state.ids, n as usize)?;
        if dem.loaded != 0 {
            check_len(LAUNCH, "external", external, 8 * n as usize)?;
        }
        let mut launch = self.stream.launch_builder(&self.dem_integrate);
        launch
            .arg(&mut state.pos)
            .arg(&mut state.lo)
            .arg(&mut state.vel)
            .arg(force)
            .arg(&state.ids)
            .arg(external)
            .arg(dem)
            .arg(&step);
        // SAFETY: the arguments match dem_integrate's signature; pos, lo and vel hold dem.n
        // rows, force 3·dem.n floats, ids dem.n input indices below dem.n (a permutation),
        // external 8·dem.n floats where dem.loaded is 1 (checked above; read only then).
        unsafe { launch.launch(per_sphere(n)) }.map_err(cuda("launching dem_integrate"))?;
        Ok(())
    }

    /// Reorders the `n` spheres of `from` into `to`: sorted position p takes the sphere at
    /// position `order[p]` of `from`.
    pub fn dem_permute(&self, from: &State, order: &Order, to: &mut State, n: u32) -> Result<()> {
        const LAUNCH: &str = "dem_permute";
        if n == 0 {
            return Ok(());
        }
        let rows = 4 * n as usize;
        check_len(LAUNCH, "pos_in", &from.pos, rows)?;
        check_len(LAUNCH, "lo_in", &from.lo, rows)?;
        check_len(LAUNCH, "vel_in", &from.vel, rows)?;
        check_len(LAUNCH, "ids_in", &from.ids, n as usize)?;
        order.check(LAUNCH, n)?;
        check_len(LAUNCH, "pos", &to.pos, rows)?;
        check_len(LAUNCH, "lo", &to.lo, rows)?;
        check_len(LAUNCH, "vel", &to.vel, rows)?;
        check_len(LAUNCH, "ids", &to.ids, n as usize)?;
        let mut launch = self.stream.launch_builder(&self.dem_permute);
        launch
            .arg(&from.pos)
            .arg(&from.lo)
            .arg(&from.vel)
            .arg(&from.ids)
            .arg(&order.entries)
            .arg(&mut to.pos)
            .arg(&mut to.lo)
            .arg(&mut to.vel)
            .arg(&mut to.ids)
            .arg(&n);
        // SAFETY: the arguments match dem_permute's signature; every buffer holds n entries and
        // the order n entries below n (checked above and in Order::upload).
        unsafe { launch.launch(per_sphere(n)) }.map_err(cuda("launching dem_permute"))?;
        Ok(())
    }
}
