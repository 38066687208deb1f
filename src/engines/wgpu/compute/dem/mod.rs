//! The wgpu-compute backend's DEM step, resident on the GPU: per step a counting sort of the
//! spheres by cell (the backend's sorted proxy grid; see the skin below), one pass that finds
//! every touching pair once and adds equal and opposite forces to both spheres (float atomics,
//! or compare-and-swap loops where the adapter has none), and one pass for walls, gravity and
//! integration (`wgsl/grid/dem_grid.wgsl`, `wgsl/dem/dem_physics.wgsl`), which in the dense build also
//! counts each sphere into its new cell: the next step's binning starts from those counts (a
//! batch counts afresh only after the host laid the grid out or wrote the state). The step's own
//! passes zero what the next step accumulates into (the cell counts in the scan, the forces in
//! the scatter, the contact counter in the binning's last pass), so no buffer is cleared but at
//! such a fresh count. Many steps go into one submission
//! and one compute pass (the first one phase by phase when timed, see `StepTimer`); the host
//! reads back only the contact count and timestamps per batch, and the particles when asked.
//!
//! The grid's layout (cell size, dense or hashed table over the centres' bounds) is re-derived
//! from a GPU reduction of the bounds every [`RELAYOUT_EVERY`](schedule::RELAYOUT_EVERY) steps. Between, spheres that
//! leave the layout's region are clamped into its border cells: exact, only slower.
//! Float atomics add in no fixed order, so GPU runs are not bit-for-bit reproducible.
//!
//! The binning is the dense build's counting sort into a table of every cell, or the sorted
//! build's radix sort of the cell keys (`wgsl/grid/dem_grid_sorted.wgsl`, no table: its cost follows
//! the spheres, not the box); [`GridBuild`] chooses, once, from the spheres at the start.
//! A step on the dense build moves its state into sorted order only every [`SORT_EVERY`](schedule::SORT_EVERY)
//! steps (a sorting step); the steps between bin the spheres by index and resolve and
//! integrate the state where it is (binning steps, [`StepKind`](schedule::StepKind)).
//!
//! The paper's step on a dense grid has a skin (`skin.rs`, docs/method.md "Re-binning only when
//! a sphere may have left its cells"): its search windows reach a little further, and a step
//! re-bins only where the GPU finds that a sphere may have moved that far since the last
//! binning ([`Rebin`](schedule::Rebin)). A re-binning sorts the state into the other set and copies it back, so
//! the state stays on one set in the last binning's order ([`StepKind::Skin`](schedule::StepKind::Skin)) and the
//! integration only reports how far the spheres moved (it does not count). Where a batch re-bins
//! at more than [`MAX_REBIN_SHARE`](schedule::MAX_REBIN_SHARE) of its steps the skin is off for a while.
//!
//! A scene with friction, rolling resistance, rotation or another law than the paper's runs the
//! granular variant of the step (`wgsl/grid/dem_grid_granular.wgsl`, [`Granular`]): its own module
//! and pipelines, with angular velocities, torques and the contact history bound besides; the
//! walls are resolved in the contact pass, where their history lives. The paper's scenes run
//! the paper's kernels as before; a frictionless scene with a stiffness per pair runs them too,
//! with `wgsl/dem/dem_physics.wgsl`'s per-pair stiffness (`Variant::PerPair`).

use super::cell_table::{CellScan, CellScanBinds, CellTable};
use super::layout::{
    Budget, BuildKind, GridBuild, GridParams, LayoutRequest, Levels, Structure, choose_layout,
    describe_layout, key_bits,
};
use super::shaders::CELL_KEYS;
use super::shaders::dem_grid::{
    self, BOUNDS, CAME_FROM, CELL_START, COUNTERS, COUNTS, HOME, IDS, IDS_A, LISTED, NEAR,
    NEAR_ROOM, OMEGA_A, PARAMS, PLACE_OF_ID, POS_A, POS_LO_A, RANKS, SKIN, SKIN_LIMIT, SORT_KEYS,
    SORT_ORDER, VEL_A, WALK_POS, WALK_ROW,
};
use super::skin::{SKIN_CELLS, Skin, skin_of};
use crate::dem::flow::NewSphere;
use crate::dem::model::StepParams;
use crate::dem::stepper::Clock;
use crate::dem::stepper::{Advance, ExternalLoads, Motion, Snapshot, StageTimes, Stepper};
use crate::dem::walls::WallLoad;
use crate::engines::common::flow::DeviceFlow;
use crate::engines::common::flow::{FlowQuery, Room, Scan};
use crate::engines::common::rows::{
    StateRows, advance_in_batches, particles_with, residual_rows, rows,
};
use crate::engines::setup::DemSetup;
use crate::engines::wgpu::clumps::shader::ENTRY as CLUMPS_ENTRY;
use crate::engines::wgpu::flow::FlowScan;
use crate::engines::wgpu::granular::shader::OMEGA;
use crate::engines::wgpu::halo::HaloExchange;
use crate::engines::wgpu::readback::{BatchReadback, InFlight};
use crate::engines::wgpu::state::{
    ExternalRows, InputOrder, ParamsUniform, RowMover, write_motion,
};
use crate::engines::wgpu::step::physics::{CLOCK, DEM, EXTERNAL, FORCE, POS, POS_LO, VEL};
use crate::engines::wgpu::step::{
    DemModule, GROUP, Granular, KernelSet, MAX_BATCH, StepTimer, Turn, max_spheres,
};
use crate::engines::wgpu::walls;
use crate::error::{Error, Result};
use crate::gpu::radix_sort::{PreparedSort, RadixSort};
use crate::gpu::shader::Binding;
use crate::gpu::{self, Gpu, Need};
use crate::particles::{FIRST_MESH_WALL, Particles};
use crate::proxy::ProxyMode;

mod binds;
mod device_flow;
mod laying_out;
mod recording;
mod schedule;

use binds::Binds;
use laying_out::{LaidOut, Sizing, start_bounds};
pub use schedule::Sorting;

/// One set of the ping-ponged state, in sorted order.
struct StateSet {
    pos: wgpu::Buffer,
    /// The residuals of the centres in `pos` (`vec4`: x, y, z, 0).
    lo: wgpu::Buffer,
    vel: wgpu::Buffer,
    ids: wgpu::Buffer,
}

/// The binning's first pass (`bin_count` of the dense build, `bin_keys` of the sorted one) and
/// its last (`bin_scatter`, `bin_gather`); between them the scan of the cell table or the sort.
struct Pipelines {
    bin_first: wgpu::ComputePipeline,
    bin_last: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    /// The granular step's contact pass in two kernels (the walk listing each sphere's
    /// candidates within reach, `list_near`, then their contacts, `resolve_near`), which a
    /// multi-level grid's long walks run: each kernel then holds its own registers.
    listing: Option<[wgpu::ComputePipeline; 2]>,
    /// Each stable id's sorted place written before the contact pass, where contacts apart
    /// come from the history (`NearLists::place_of_id`).
    name_places: Option<wgpu::ComputePipeline>,
    /// The mesh walls' kernels (granular step with mesh walls only), in the order of
    /// `walls::ENTRY_POINTS`.
    mesh: Option<[wgpu::ComputePipeline; 2]>,
    /// The clumps' step (`advance_clumps`, before the integration; runs with clumps only) and
    /// its workgroups, one thread a clump.
    clumps: Option<(wgpu::ComputePipeline, (u32, u32))>,
    integrate: wgpu::ComputePipeline,
    reduce_bounds: wgpu::ComputePipeline,
    /// The binning step's last pass, where the step has binning steps.
    bin_index: Option<wgpu::ComputePipeline>,
    /// The skin's kernels (the paper's step on the dense build).
    skin: Option<SkinPipelines>,
}

/// The kernels of a step that may skip its binning (`wgsl/grid/dem_grid_frictionless.wgsl`).
struct SkinPipelines {
    /// A step's first pass where the drift decides whether it re-bins.
    begin_step: wgpu::ComputePipeline,
    /// A step's first pass where it re-bins whatever the drift.
    begin_binning: wgpu::ComputePipeline,
    /// The integration, which notes the displacements.
    integrate: wgpu::ComputePipeline,
    /// A binning's last pass: the sorted state copied back to its own set.
    bin_return: wgpu::ComputePipeline,
}

/// What the resolve kernel reads through: the state row and sphere of each sorted place.
struct SortedPlaces {
    home: wgpu::Buffer,
    walk_pos: wgpu::Buffer,
    /// Row k holds k: `home` of a sorting step, whose state is in sorted order.
    identity: wgpu::Buffer,
    /// The skin's: by sorted place, the row (y, z) of the cell its sphere was binned in (the
    /// paper's step).
    walk_row: wgpu::Buffer,
}

/// The granular contact pass's lists of candidates within reach (`wgsl/grid/dem_grid_granular.wgsl`).
struct NearLists {
    /// By sorted place, the candidates within reach its walk met (the two-kernel pass).
    listed: wgpu::Buffer,
    /// [`NEAR_ROOM`] places a sphere.
    near: wgpu::Buffer,
    /// Where contacts apart come from the history (`APART_FROM_HISTORY`,
    /// `wgsl/grid/dem_grid_bonds.wgsl`): by stable id, the sorted place of its sphere in the
    /// step ([`PLACE_OF_ID`]), a word for every id below [`GridStepper::next_id`] (one word,
    /// never read, otherwise).
    place_of_id: wgpu::Buffer,
    /// Whether the walk lists only the candidates that touch, and the contacts apart come
    /// from the history.
    apart_from_history: bool,
}

/// Contacts apart come from the history where contacts hold at least this fraction of the
/// smallest radius past touching (`wgsl/grid/dem_grid_bonds.wgsl`); closer, few candidates
/// within reach are apart, and the walk that lists them costs less than the lookups.
const APART_REACH: f32 = 0.005;

/// What sorts the spheres by cell between the binning's passes, bound to the layout.
enum Sorter {
    /// The dense build: ranks in each cell, the table of cells scanned.
    Dense {
        ranks: wgpu::Buffer,
        cell_table: CellTable,
        scan: CellScan,
        /// The scan bound to the cell table.
        scan_bind: CellScanBinds,
    },
    /// The sorted build: each sphere's key and index, radix-sorted.
    Sorted {
        keys: wgpu::Buffer,
        order: wgpu::Buffer,
        sort: RadixSort,
        /// The sort by the layout's keys (boxed: it is large).
        prepared: Box<PreparedSort>,
    },
}

/// What the step's bind groups name: the device, the pipelines, the state sets and every other
/// buffer the kernels bind, and the grid's levels (which choose the contact pass's kernels).
struct Resident {
    gpu: Gpu,
    pipelines: Pipelines,
    levels: Levels,
    grid_uniform: wgpu::Buffer,
    /// The step's parameters (binding `DEM`).
    dem_uniform: ParamsUniform,
    sets: [StateSet; 2],
    places: SortedPlaces,
    force: wgpu::Buffer,
    counters: wgpu::Buffer,
    bounds: wgpu::Buffer,
    clock: wgpu::Buffer,
    /// The external loads by stable id.
    external: ExternalRows,
    /// The granular step's state (`None`: a variant of the paper's step).
    granular: Option<Granular>,
    /// Its contact pass's lists.
    near: Option<NearLists>,
    /// The skin's buffers (the paper's step, whose walk reads the drift in any build; only the
    /// dense build's steps may skip their binning, where the layout's `skin` says).
    skin: Option<Skin>,
}

/// The wgpu-compute DEM step.
pub struct GridStepper {
    res: Resident,
    /// The grid as last laid out, with what is bound to it.
    laid_out: LaidOut,
    /// Whether the next advance lays the grid out afresh (the count or the structure changed).
    stale: bool,
    /// Spheres in the state.
    n: u32,
    /// Spheres the buffers have rows for (spheres appended up to it need no new buffers).
    capacity: u32,
    /// The stable id the next sphere appended gets (ids have gaps where spheres left).
    next_id: u32,
    /// The flow events' scan of the state (made at the first).
    flow_scan: Option<FlowScan>,
    /// A rank's exchange of ghosts on the device (made at the first).
    halo: Option<HaloExchange>,
    /// Moves rows where spheres leave (made at the first removal).
    row_mover: Option<RowMover>,
    mode: ProxyMode,
    mode_cell: f64,
    /// Smallest and largest radius.
    radii: (f64, f64),
    params: StepParams,
    step: u64,
    groups: (u32, u32),
    /// Which set the next step bins from.
    current: usize,
    /// The parity of the next step's history (granular step; 0 in the paper's).
    parity: usize,
    /// `current`, `parity` and `sort_next` when the last batch was recorded (where a redone
    /// batch starts again).
    batch_start: (usize, usize, bool),
    /// Whether the next step must sort (the state was written out of order).
    sort_next: bool,
    /// Whether the cell counts and ranks are those of the current state in the current layout
    /// (the dense build's last step counted them as it integrated; the host laying the grid out
    /// or writing the state undoes it).
    counted: bool,
    /// Steps a submission of the next batch the host waits for holds (`None`: the whole
    /// batch in one), from the last such batch (see [`submissions`](schedule::submissions)).
    submit_every: Option<u32>,
    sorting: Sorting,
    timer: Option<StepTimer>,
    /// Where the paper's step's batches leave their results (see `advance_paper`).
    readback: BatchReadback,
    /// The bounds' keys at the end of the last batch that finished (paper's step).
    last_bounds: Option<[u32; 6]>,
    atomics: &'static str,
    /// Steps run with a skin, and those that re-binned, since the stepper opened.
    rebinned: (u64, u64),
    /// The step before which the skin stays off (a batch re-binned too often: see
    /// [`MAX_REBIN_SHARE`](schedule::MAX_REBIN_SHARE)).
    skin_off_until: u64,
}

/// How a `wgpu-compute` DEM step is opened besides its [`DemSetup`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridStepOptions {
    /// Which kernels the step runs (`KernelSet::Portable`: those any adapter runs).
    pub kernels: KernelSet,
    /// How the grid is built (`GridBuild::Auto` decides from the spheres' bounds at the start,
    /// for the whole run).
    pub grid_build: GridBuild,
    /// The grid's structure.
    pub structure: Structure,
}

impl Default for GridStepOptions {
    /// The kernels that make the most of the adapter, the build and the structure `auto`.
    fn default() -> Self {
        GridStepOptions {
            kernels: KernelSet::Auto,
            grid_build: GridBuild::Auto,
            structure: Structure::Auto,
        }
    }
}

impl GridStepper {
    /// The step of `setup` with `options` on the best adapter with compute shaders.
    pub fn open(setup: DemSetup, options: GridStepOptions) -> Result<Self> {
        let room = Room::of(&setup.particles);
        Self::opening(setup, options, room, || Gpu::open(Need::Compute))
    }

    /// The step of `setup` with `options` on `gpu` (a test's device with lowered limits, say
    /// the largest storage binding, to run the paths of large runs at small sizes).
    pub fn open_on(gpu: Gpu, setup: DemSetup, options: GridStepOptions) -> Result<Self> {
        let room = Room::of(&setup.particles);
        Self::opening(setup, options, room, || Ok(gpu))
    }

    /// As [`open_on`](Self::open_on), with `room` for spheres flowing in, which are appended on
    /// the device ([`DeviceFlow::append`]): a flowing run's step, opened again on the device of
    /// the last (whose compiled pipelines it reuses).
    pub(crate) fn flowing_on(
        gpu: Gpu,
        setup: DemSetup,
        room: Room,
        options: GridStepOptions,
    ) -> Result<Self> {
        let mut step = Self::opening(setup, options, room, || Ok(gpu))?;
        // Compiled now, not in the first flow event.
        step.flow_scan = Some(FlowScan::new(&step.res.gpu));
        Ok(step)
    }

    /// The stepper of `setup` with `options` and `room` (at least the particles') on the
    /// device `open` gives once the particles are checked.
    fn opening(
        setup: DemSetup,
        options: GridStepOptions,
        room: Room,
        open: impl FnOnce() -> Result<Gpu>,
    ) -> Result<Self> {
        let DemSetup {
            mut particles,
            params,
            mode,
            walls,
        } = setup;
        let GridStepOptions {
            kernels,
            grid_build,
            structure,
        } = options;
        let walls = &walls;
        particles.separate_coincident()?;
        let room = room.holding(&particles);
        let (r_min, r_max) = room.radii;
        // Where contacts hold far past touching, the walk lists only the candidates that touch
        // and the contacts apart come from the history, which every cohesive step keeps.
        let apart_from_history = params.adheres()
            && params.friction.has_history()
            && params.search_margin(r_max) >= APART_REACH * r_min;
        // Cells hold every pair the walk lists: those within the search's reach (the spheres
        // grown by half of it), or those that touch.
        let searched = match apart_from_history {
            true => 0.0,
            false => params.search_margin(r_max),
        };
        let mode_cell = mode.cell_size(r_max + 0.5 * searched) as f64;
        // The build for where the spheres are and where more will come.
        let bounds = match (
            start_bounds(&particles, &params, mode_cell as f32),
            room.region,
        ) {
            (Some((lo, hi)), Some((a, b))) => Some((
                std::array::from_fn(|k| lo[k].min(a[k])),
                std::array::from_fn(|k| hi[k].max(b[k])),
            )),
            (bounds, region) => bounds.or(region),
        };
        let build = match bounds {
            Some(bounds) => grid_build.resolve(room.spheres as u64, bounds, mode_cell),
            None => BuildKind::Dense,
        };
        let gpu = open()?;
        let DemModule {
            atomics,
            granular,
            params: dem_uniform,
            module,
            mut constants,
        } = DemModule::open(
            &gpu,
            "wgpu-compute",
            &particles,
            &params,
            walls,
            max_spheres(&gpu),
            // The two sets of the ping-ponged state.
            (2, room),
            kernels,
            |accumulators, lanes, variant| {
                dem_grid::variant_source(build, variant, accumulators, lanes)
            },
        )?;
        let n = particles.len() as u32;
        let rows = room.spheres as u64;
        let clumped = !particles.clumps.clumps.is_empty();
        if apart_from_history {
            constants.push(("APART_FROM_HISTORY", 1.0));
        }
        // The paper's step on the dense build may skip its binning (the skin).
        let paper = granular.is_none();
        let skinned = paper && build == BuildKind::Dense;
        let pipeline = |entry: &str| {
            gpu.pipeline_with(&format!("mochi.dem.{entry}"), &module, entry, &constants)
        };
        let (first, last) = match build {
            BuildKind::Dense => ("bin_count", "bin_scatter"),
            BuildKind::Sorted => ("bin_keys", "bin_gather"),
        };
        let pipelines = Pipelines {
            bin_first: pipeline(first),
            bin_last: pipeline(last),
            resolve: pipeline("resolve"),
            listing: granular
                .is_some()
                .then(|| ["list_near", "resolve_near"].map(pipeline)),
            name_places: apart_from_history.then(|| pipeline("name_places")),
            mesh: granular
                .as_ref()
                .is_some_and(|g| g.mesh().any())
                .then(|| walls::ENTRY_POINTS.map(pipeline)),
            clumps: granular
                .as_ref()
                .and_then(|g| g.clumps())
                .map(|c| (pipeline(CLUMPS_ENTRY), gpu.grid(c.count(), GROUP))),
            // The dense build counts the spheres for the next step as it integrates them; a
            // run with clumps leaves their components to them.
            integrate: pipeline(match (build, clumped) {
                (BuildKind::Dense, false) => "integrate_and_count",
                (BuildKind::Dense, true) => "integrate_and_count_clumped",
                (BuildKind::Sorted, false) => "integrate",
                (BuildKind::Sorted, true) => "integrate_clumped",
            }),
            reduce_bounds: pipeline("reduce_bounds"),
            bin_index: (build == BuildKind::Dense).then(|| pipeline("bin_index")),
            skin: skinned.then(|| SkinPipelines {
                begin_step: pipeline("begin_step"),
                begin_binning: pipeline("begin_binning"),
                integrate: pipeline("integrate_and_report"),
                bin_return: pipeline("bin_return"),
            }),
        };
        let none = wgpu::BufferUsages::empty();
        let make = |label: &str, bytes: u64| gpu.storage(label, bytes, none);
        let res = gpu.checked("allocating the DEM buffers", || {
            let set = |k: usize| StateSet {
                pos: make(&format!("mochi.dem.pos{k}"), rows * 16),
                lo: make(&format!("mochi.dem.pos_lo{k}"), rows * 16),
                vel: make(&format!("mochi.dem.vel{k}"), rows * 16),
                ids: make(&format!("mochi.dem.ids{k}"), rows * 4),
            };
            Resident {
                pipelines,
                levels: structure.levels_for(mode, r_max as f64 / r_min as f64),
                grid_uniform: gpu.uniform("mochi.dem.grid", &GridParams::default()),
                dem_uniform,
                sets: [set(0), set(1)],
                places: {
                    let identity = make("mochi.dem.identity", rows * 4);
                    let places: Vec<u32> = (0..rows as u32).collect();
                    gpu.queue
                        .write_buffer(&identity, 0, bytemuck::cast_slice(&places));
                    // Only a step with binning steps writes places of its own (the paper's
                    // kernels bind them in either build).
                    let binning = (build == BuildKind::Dense || granular.is_none()) as u64;
                    let paper = granular.is_none() as u64;
                    SortedPlaces {
                        home: make("mochi.dem.home", binning * rows * 4),
                        walk_pos: make("mochi.dem.walk_pos", binning * rows * 16),
                        identity,
                        walk_row: make("mochi.dem.walk_row", paper * rows * 4),
                    }
                },
                force: make("mochi.dem.force", rows * 12),
                counters: make("mochi.dem.counters", 16),
                bounds: make("mochi.dem.bounds", 24),
                clock: make("mochi.dem.clock", 4),
                external: ExternalRows::new(&gpu),
                near: granular.is_some().then(|| NearLists {
                    listed: make("mochi.dem.listed", rows * 4),
                    near: make("mochi.dem.near", rows * NEAR_ROOM * 4),
                    // Bound but never read where contacts apart come from the walk.
                    place_of_id: make(
                        "mochi.dem.place_of_id",
                        4 * if apart_from_history { rows } else { 1 },
                    ),
                    apart_from_history,
                }),
                granular,
                // The paper's walk reads the drift in any build (none without a skin).
                skin: paper.then(|| Skin::new(&gpu)),
                gpu: gpu.clone(),
            }
        })?;
        let sizing = Sizing {
            n,
            row: gpu.grid(n, GROUP).0 * GROUP,
            build,
            mode_cell,
            radii: (r_min as f64, r_max as f64),
        };
        // Laid out over the box until the first advance lays it out over the spheres.
        let layout = sizing.layout(&res, (params.box_lo, params.box_hi), true);
        let laid_out = LaidOut::new(&res, &sizing, layout, particles.step)?;
        let mut stepper = GridStepper {
            res,
            laid_out,
            stale: true,
            n,
            capacity: rows as u32,
            next_id: n,
            flow_scan: None,
            halo: None,
            row_mover: None,
            mode,
            mode_cell,
            radii: sizing.radii,
            params,
            step: particles.step,
            groups: gpu.grid(n, GROUP),
            current: 0,
            parity: 0,
            batch_start: (0, 0, true),
            sort_next: true,
            counted: false,
            submit_every: None,
            sorting: Sorting::Auto,
            timer: StepTimer::new(&gpu),
            readback: BatchReadback::new(&gpu),
            last_bounds: None,
            atomics,
            rebinned: (0, 0),
            skin_off_until: 0,
        };
        stepper.upload(&particles)?;
        Ok(stepper)
    }

    /// Sorts the state as `sorting` says from the next step on.
    pub fn with_sorting(mut self, sorting: Sorting) -> Self {
        self.sorting = sorting;
        self
    }

    /// Bins into `structure` from the next step on.
    pub fn with_structure(mut self, structure: Structure) -> Self {
        self.res.levels = structure.levels_for(self.mode, self.radii.1 / self.radii.0);
        self.stale = true;
        // The granular contact pass's kernels follow the levels.
        self.rebind();
        self
    }

    /// Writes the particles (in input order) into the current set and the parameters.
    fn upload(&mut self, particles: &Particles) -> Result<()> {
        let (pos, vel) = rows(particles, &self.params.materials);
        let lo = residual_rows(particles);
        let ids: Vec<u32> = (0..self.n).collect();
        let q = &self.res.gpu.queue;
        let set = &self.res.sets[self.current];
        q.write_buffer(&set.pos, 0, bytemuck::cast_slice(&pos));
        q.write_buffer(&set.lo, 0, bytemuck::cast_slice(&lo));
        q.write_buffer(&set.vel, 0, bytemuck::cast_slice(&vel));
        q.write_buffer(&set.ids, 0, bytemuck::cast_slice(&ids));
        q.write_buffer(&self.res.clock, 0, bytemuck::bytes_of(&(self.step as u32)));
        self.write_count();
        self.sort_next = true;
        self.counted = false;
        Ok(())
    }

    /// The state read back in input order ([`Error::Unstable`] if it is not finite), with
    /// the history where `springs` (else each sphere's contacts counted).
    fn state(&self, springs: bool) -> Result<Snapshot> {
        let n = self.n as usize;
        let set = &self.res.sets[self.current];
        let pos: Vec<[f32; 4]> = self.res.gpu.read(&set.pos, n)?;
        let lo: Vec<[f32; 4]> = self.res.gpu.read(&set.lo, n)?;
        let vel: Vec<[f32; 4]> = self.res.gpu.read(&set.vel, n)?;
        let ids: Vec<u32> = self.res.gpu.read(&set.ids, n)?;
        let order = InputOrder::of(&ids);
        let rotation = || {
            let g = self.res.granular.as_ref();
            g.map(|g| g.read(&self.res.gpu, self.turn(), Some(&order), springs))
                .transpose()
        };
        let rows = StateRows {
            pos: &pos,
            lo: &lo,
            vel: &vel,
        };
        let mut particles = particles_with(rows, Some(&order.rank), self.step, rotation)?;
        let granular = self.res.granular.as_ref();
        if let Some(c) = granular.and_then(|g| g.clumps()) {
            particles.clumps = c.read(&self.res.gpu)?;
        }
        let contacts = match (springs, granular) {
            (false, Some(g)) => g.contact_counts(&self.res.gpu, self.turn(), Some(&order), true)?,
            _ => particles.history.counts(n),
        };
        Ok(Snapshot {
            particles,
            contacts,
        })
    }
}

impl GridStepper {
    /// The build this step bins with.
    pub fn build(&self) -> BuildKind {
        match self.laid_out.sorter {
            Sorter::Dense { .. } => BuildKind::Dense,
            Sorter::Sorted { .. } => BuildKind::Sorted,
        }
    }
}

impl Stepper for GridStepper {
    fn describe(&self) -> String {
        let history = self
            .res
            .granular
            .as_ref()
            .and_then(Granular::describe_history);
        // The grid as last laid out (it follows the spheres' bounds through the run).
        let grid = describe_layout(&self.laid_out.layout, self.build());
        let skin = match self.rebinned {
            (steps, rebins) if steps > 0 => {
                format!("; skin of {SKIN_CELLS} cell on {steps} steps, re-binned at {rebins}")
            }
            _ => String::new(),
        };
        format!(
            "wgpu-compute ({}; {}; {grid}{skin}{})",
            gpu::describe(&self.res.gpu.info),
            self.atomics,
            history.map(|h| format!("; {h}")).unwrap_or_default()
        )
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        if self.n == 0 {
            // No spheres: only the clock moves.
            return advance_in_batches(steps, false, |left| {
                self.step += left as u64;
                Ok((left, 0, None))
            });
        }
        if let Some(g) = &mut self.res.granular {
            let last = (self.step + steps as u64).saturating_sub(1);
            g.mesh_mut().sum_loads_in(&self.res.gpu, last);
        }
        let advance = self.advance_batches(steps)?;
        if let Some(g) = &mut self.res.granular {
            g.mesh_mut().read_loads(&self.res.gpu)?;
        }
        Ok(advance)
    }

    fn particles(&mut self) -> Result<Particles> {
        Ok(self.state(true)?.particles)
    }

    fn snapshot(&mut self) -> Result<Snapshot> {
        self.state(false)
    }

    fn step(&self) -> u64 {
        self.step
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        self.params.gravity = gravity;
        let res = &mut self.res;
        res.dem_uniform
            .update(&res.gpu, |p| p.gravity = gravity.into());
        Ok(())
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        if self
            .res
            .granular
            .as_ref()
            .is_some_and(|g| g.clumps().is_some())
        {
            motion.check_clumps(&self.state(true)?.particles)?;
        }
        let (res, n) = (&self.res, self.n as usize);
        let set = &res.sets[self.current];
        // Each row's sphere in input order (stable ids have gaps where spheres left).
        let order = InputOrder::of(&res.gpu.read::<u32>(&set.ids, n)?).rank;
        let omega = res.granular.as_ref().map(|g| g.omega_of(self.current));
        let buffers = (&set.pos, &set.lo, &set.vel, omega);
        if write_motion(&res.gpu, buffers, n, Some(&order), motion)? {
            // Moved spheres are binned afresh, in a grid laid out over where they are now.
            (self.sort_next, self.counted, self.stale) = (true, false, true);
        }
        Ok(())
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        let turns = self.params.friction.turns();
        // A flowing step's stable ids are not input indices (they have gaps).
        let fixed = self.flow_scan.is_none();
        let res = &mut self.res;
        let grown = res.external.set(&res.gpu, loads, (self.n, turns, fixed))?;
        let on = !loads.is_empty() as u32;
        res.dem_uniform.update(&res.gpu, |p| p.loaded = on);
        if grown {
            self.rebind();
        }
        Ok(())
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.res
            .granular
            .as_ref()
            .map_or_else(Vec::new, |g| g.mesh().loads().to_vec())
    }

    fn grid_build(&self) -> Option<&'static str> {
        Some(self.build().name())
    }
}
