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
//! from a GPU reduction of the bounds every [`RELAYOUT_EVERY`] steps. Between, spheres that
//! leave the layout's region are clamped into its border cells: exact, only slower.
//! Float atomics add in no fixed order, so GPU runs are not bit-for-bit reproducible.
//!
//! The binning is the dense build's counting sort into a table of every cell, or the sorted
//! build's radix sort of the cell keys (`wgsl/grid/dem_grid_sorted.wgsl`, no table: its cost follows
//! the spheres, not the box); [`GridBuild`] chooses, once, from the spheres at the start.
//! A step on the dense build moves its state into sorted order only every [`SORT_EVERY`]
//! steps (a sorting step); the steps between bin the spheres by index and resolve and
//! integrate the state where it is (binning steps, [`StepKind`]).
//!
//! The paper's step on a dense grid has a skin (`skin.rs`, docs/method.md "Re-binning only when
//! a sphere may have left its cells"): its search windows reach a little further, and a step
//! re-bins only where the GPU finds that a sphere may have moved that far since the last
//! binning ([`Rebin`]). A re-binning sorts the state into the other set and copies it back, so
//! the state stays on one set in the last binning's order ([`StepKind::Skin`]) and the
//! integration only reports how far the spheres moved (it does not count). Where a batch re-bins
//! at more than [`MAX_REBIN_SHARE`] of its steps the skin is off for a while.
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
    NEAR_ROOM, OMEGA_A, PARAMS, POS_A, POS_LO_A, RANKS, SKIN, SKIN_LIMIT, SORT_KEYS, SORT_ORDER,
    VEL_A, WALK_POS, WALK_ROW,
};
use super::skin::{SKIN_CELLS, Skin, skin_of};
use crate::dem::flow::NewSphere;
use crate::dem::model::StepParams;
use crate::dem::stepper::Clock;
use crate::dem::stepper::{Advance, StageTimes, Stepper};
use crate::dem::walls::WallLoad;
use crate::engines::common::flow::DeviceFlow;
use crate::engines::common::flow::{FlowQuery, Room, Scan};
use crate::engines::common::rows::{
    StateRows, advance_in_batches, particles_with, residual_rows, rows,
};
use crate::engines::setup::DemSetup;
use crate::engines::wgpu::flow::FlowScan;
use crate::engines::wgpu::granular::shader::OMEGA;
use crate::engines::wgpu::readback::{BatchReadback, InFlight};
use crate::engines::wgpu::state::{InputOrder, ParamsUniform, move_rows};
use crate::engines::wgpu::step::physics::{CLOCK, DEM, FORCE, POS, POS_LO, VEL};
use crate::engines::wgpu::step::{
    BatchParts, DemModule, GROUP, Granular, KernelSet, MAX_BATCH, RedoableBatch, StepTimer, Turn,
    max_spheres, run_batch,
};
use crate::engines::wgpu::walls;
use crate::error::{Error, Result};
use crate::gpu::radix_sort::{PreparedSort, RadixSort};
use crate::gpu::shader::Binding;
use crate::gpu::{self, Gpu, Need};
use crate::particles::{FIRST_MESH_WALL, Particles};
use crate::proxy::ProxyMode;

/// Steps between two re-derivations of the grid layout.
pub const RELAYOUT_EVERY: u64 = 100;

/// Steps a submission holds where a batch the host waits for (the granular step's, which may
/// be redone) is submitted a few steps at a time: the GPU starts on them while the host records
/// the next.
const STEPS_A_SUBMISSION: u32 = 10;

/// How the next batch the host waits for is submitted, from the last one's GPU time (`times`,
/// where timestamps are taken) and the host's time recording it: [`STEPS_A_SUBMISSION`] steps
/// at a time where the GPU's work took several times the recording, so that the GPU never
/// waits for a submission and its timestamps stay its own work; in one submission otherwise;
/// a few steps at a time where no timestamps are taken.
fn submissions(times: Option<&StageTimes>, recorded_ms: f64) -> Option<u32> {
    match times {
        Some(t) if t.total_ms() <= 4.0 * recorded_ms => None,
        _ => Some(STEPS_A_SUBMISSION),
    }
}

/// Steps from one sorting step to the next where binning steps run between them (the state
/// drifts out of sorted order only as fast as spheres change cells).
pub const SORT_EVERY: u64 = 16;

/// Share of a batch's steps above which re-binning is so frequent that the skin costs more
/// than it saves (its wider windows, and the copy back of each re-binning); the skin is then
/// off for [`SKIN_RETRY_STEPS`] steps (docs/performance-log/2026-11-27-h100-session-6.md has the
/// scenes where the skin loses, docs/performance-log/2026-11-27-h100-session-7.md the share swept
/// with the skin's width).
pub const MAX_REBIN_SHARE: f64 = 0.25;

/// Steps the skin stays off after a batch re-binned too often; then it is tried again.
pub const SKIN_RETRY_STEPS: u64 = 1000;

/// When a step on the dense build moves its state into sorted order (a sorting step); the
/// other steps bin by index. Only speed depends on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sorting {
    /// Every 16 steps (`SORT_EVERY`), as `Every`; where the step has a skin, only after the
    /// state was written out of order (each of its re-binnings sorts).
    Auto,
    /// At the steps whose number is a multiple of `k` (≥ 1), and at the first step after the
    /// state was written out of order (uploaded, spheres appended or removed); where the step
    /// has a skin, those steps re-bin whatever the drift.
    Every(u64),
    /// Never: the state stays in the order given and every step bins by index (where the step
    /// has a skin, it re-bins only where a sphere may have moved the skin).
    Never,
}

/// How a step bins its spheres.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StepKind {
    /// The state moves into sorted order in the other set, and the step runs there.
    Sorting,
    /// The spheres are binned by index (`home`, `walk_pos`) and the step runs on the state where
    /// it is.
    Binning,
    /// The step with a skin: the state stays on its set in the order of the last binning; where
    /// the step re-bins ([`Rebin`]) it sorts the state into the other set and copies it back.
    Skin,
}

/// Whether a step with a skin re-bins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rebin {
    /// Whatever the drift: the first step after the host wrote the state or laid the grid out,
    /// a timed batch's first step (whose phases the batch's times are split by), and the steps
    /// [`Sorting`] sorts at.
    Always,
    /// Where some sphere may have moved more than the skin since the last binning.
    IfMoved,
}

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
    /// multi-level grid's long walks run.
    listing: Option<[wgpu::ComputePipeline; 2]>,
    /// The mesh walls' kernels (granular step with mesh walls only), in the order of
    /// `walls::ENTRY_POINTS`.
    mesh: Option<[wgpu::ComputePipeline; 2]>,
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

/// Bind groups of the steps from one state set (the source of the next binning).
struct Binds {
    bin_first: wgpu::BindGroup,
    bin_last: wgpu::BindGroup,
    /// The sorting step's, on the other set.
    resolving: ResolveBinds,
    integrate: wgpu::BindGroup,
    reduce_bounds: wgpu::BindGroup,
    /// A binning step's own bind groups on set `from` (where the step has binning steps).
    binning: Option<BinningBinds>,
    /// The skin's kernels' (where the step has them).
    skin: Option<SkinBinds>,
}

/// The skin's bind groups of a step whose state is on one set (binning into the other).
struct SkinBinds {
    begin_step: wgpu::BindGroup,
    begin_binning: wgpu::BindGroup,
    integrate: wgpu::BindGroup,
    bin_return: wgpu::BindGroup,
}

/// Bind groups of a binning step's own passes on one set (its count and integration are the
/// sorting steps').
struct BinningBinds {
    bin_index: wgpu::BindGroup,
    resolving: ResolveBinds,
}

/// The bind groups of the contact pass of a step on one state set, by the parity of the history
/// it reads (one, 0, in the paper's step).
struct ResolveBinds {
    /// The walk's where the granular contact pass runs in two kernels (`Pipelines::listing`);
    /// `resolve` then binds the second.
    list_near: Option<wgpu::BindGroup>,
    resolve: Vec<wgpu::BindGroup>,
    /// The mesh walls' kernels', as `Pipelines::mesh` (granular step with mesh walls).
    mesh: Option<Vec<[wgpu::BindGroup; 2]>>,
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
}

/// What sorts the spheres by cell between the binning's passes.
enum Sorter {
    /// The dense build: ranks in each cell, the table of cells scanned.
    Dense {
        ranks: wgpu::Buffer,
        cell_table: CellTable,
        scan: CellScan,
        /// The scan bound to the current cell table.
        scan_bind: Option<CellScanBinds>,
    },
    /// The sorted build: each sphere's key and index, radix-sorted.
    Sorted {
        keys: wgpu::Buffer,
        order: wgpu::Buffer,
        sort: RadixSort,
        /// The sort by the current layout's keys (boxed: it is large).
        prepared: Option<Box<PreparedSort>>,
    },
}

/// The wgpu-compute DEM step.
pub struct GridStepper {
    gpu: Gpu,
    pipelines: Pipelines,
    sorter: Sorter,
    /// Spheres in the state.
    n: u32,
    /// Spheres the buffers have rows for (spheres appended up to it need no new buffers).
    capacity: u32,
    /// The stable id the next sphere appended gets (ids have gaps where spheres left).
    next_id: u32,
    /// The flow events' scan of the state (made at the first).
    flow_scan: Option<FlowScan>,
    mode: ProxyMode,
    mode_cell: f64,
    /// Smallest and largest radius.
    radii: (f64, f64),
    levels: Levels,
    params: StepParams,
    layout: GridParams,
    /// Step count at the last layout.
    laid_out_at: Option<u64>,
    step: u64,
    groups: (u32, u32),
    grid_uniform: wgpu::Buffer,
    /// The step's parameters (binding `DEM`).
    dem_uniform: ParamsUniform,
    sets: [StateSet; 2],
    /// Which set the next step bins from.
    current: usize,
    /// The parity of the next step's history (granular step; 0 in the paper's).
    parity: usize,
    /// `current`, `parity` and `sort_next` when the last batch was recorded (where a redone
    /// batch starts again).
    batch_start: (usize, usize, bool),
    places: SortedPlaces,
    /// Whether the next step must sort (the state was written out of order).
    sort_next: bool,
    /// Whether the cell counts and ranks are those of the current state in the current layout
    /// (the dense build's last step counted them as it integrated; the host laying the grid out
    /// or writing the state undoes it).
    counted: bool,
    /// Steps a submission of the next batch the host waits for holds (`None`: the whole
    /// batch in one), from the last such batch (see [`submissions`]).
    submit_every: Option<u32>,
    sorting: Sorting,
    force: wgpu::Buffer,
    counters: wgpu::Buffer,
    bounds: wgpu::Buffer,
    clock: wgpu::Buffer,
    binds: Option<[Binds; 2]>,
    timer: Option<StepTimer>,
    /// Where the paper's step's batches leave their results (see `advance_paper`).
    readback: BatchReadback,
    /// The bounds' keys at the end of the last batch that finished (paper's step).
    last_bounds: Option<[u32; 6]>,
    atomics: &'static str,
    /// The granular step's state (`None`: a variant of the paper's step).
    granular: Option<Granular>,
    /// Its contact pass's lists.
    near: Option<NearLists>,
    /// The skin's buffers (the paper's step, whose walk reads the drift in any build; only the
    /// dense build's steps may skip their binning, where the layout's `skin` says).
    skin: Option<Skin>,
    /// Steps run with a skin, and those that re-binned, since the stepper opened.
    rebinned: (u64, u64),
    /// The step before which the skin stays off (a batch re-binned too often: see
    /// [`MAX_REBIN_SHARE`]).
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
        step.flow_scan = Some(FlowScan::new(&step.gpu));
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
        let mode_cell = mode.cell_size(r_max) as f64;
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
            constants,
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
        // The paper's step on the dense build may skip its binning (the skin).
        let paper = granular.is_none();
        let skinned = paper && build == BuildKind::Dense;
        let pipeline = |entry: &str| {
            gpu.pipeline_with(&format!("mochi.dem.{entry}"), &module, entry, constants)
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
            mesh: granular
                .as_ref()
                .is_some_and(|g| g.mesh().any())
                .then(|| walls::ENTRY_POINTS.map(pipeline)),
            // The dense build counts the spheres for the next step as it integrates them.
            integrate: pipeline(match build {
                BuildKind::Dense => "integrate_and_count",
                BuildKind::Sorted => "integrate",
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
        let stepper = gpu.checked("allocating the DEM buffers", || {
            let set = |k: usize| StateSet {
                pos: make(&format!("mochi.dem.pos{k}"), rows * 16),
                lo: make(&format!("mochi.dem.pos_lo{k}"), rows * 16),
                vel: make(&format!("mochi.dem.vel{k}"), rows * 16),
                ids: make(&format!("mochi.dem.ids{k}"), rows * 4),
            };
            let timer = StepTimer::new(&gpu);
            let sorter = match build {
                BuildKind::Dense => Sorter::Dense {
                    ranks: make("mochi.dem.ranks", rows * 4),
                    cell_table: CellTable::new(&gpu, 1),
                    scan: CellScan::new(&gpu),
                    scan_bind: None,
                },
                BuildKind::Sorted => Sorter::Sorted {
                    keys: make("mochi.dem.sort_keys", rows * 4),
                    order: make("mochi.dem.sort_order", rows * 4),
                    sort: RadixSort::new(&gpu),
                    prepared: None,
                },
            };
            GridStepper {
                sorter,
                pipelines,
                n,
                capacity: rows as u32,
                next_id: n,
                flow_scan: None,
                mode,
                mode_cell,
                radii: (r_min as f64, r_max as f64),
                levels: Structure::Auto.levels_for(mode, r_max as f64 / r_min as f64),
                params,
                layout: GridParams::default(),
                laid_out_at: None,
                step: particles.step,
                groups: gpu.grid(n, GROUP),
                grid_uniform: gpu.uniform("mochi.dem.grid", &GridParams::default()),
                dem_uniform,
                sets: [set(0), set(1)],
                current: 0,
                parity: 0,
                batch_start: (0, 0, true),
                near: granular.is_some().then(|| NearLists {
                    listed: make("mochi.dem.listed", rows * 4),
                    near: make("mochi.dem.near", rows * NEAR_ROOM * 4),
                }),
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
                sort_next: true,
                counted: false,
                submit_every: None,
                sorting: Sorting::Auto,
                force: make("mochi.dem.force", rows * 12),
                counters: make("mochi.dem.counters", 16),
                bounds: make("mochi.dem.bounds", 24),
                clock: make("mochi.dem.clock", 4),
                binds: None,
                timer,
                readback: BatchReadback::new(&gpu),
                last_bounds: None,
                atomics,
                granular,
                // The paper's walk reads the drift in any build (none without a skin).
                skin: paper.then(|| Skin::new(&gpu)),
                rebinned: (0, 0),
                skin_off_until: 0,
                gpu: gpu.clone(),
            }
        })?;
        let mut stepper = stepper.with_structure(structure);
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
        self.levels = structure.levels_for(self.mode, self.radii.1 / self.radii.0);
        self.laid_out_at = None;
        // The granular contact pass's kernels follow the levels.
        self.binds = None;
        self
    }

    /// Writes the particles (in input order) into the current set and the parameters.
    fn upload(&mut self, particles: &Particles) -> Result<()> {
        let (pos, vel) = rows(particles, &self.params.materials);
        let lo = residual_rows(particles);
        let ids: Vec<u32> = (0..self.n).collect();
        let q = &self.gpu.queue;
        let set = &self.sets[self.current];
        q.write_buffer(&set.pos, 0, bytemuck::cast_slice(&pos));
        q.write_buffer(&set.lo, 0, bytemuck::cast_slice(&lo));
        q.write_buffer(&set.vel, 0, bytemuck::cast_slice(&vel));
        q.write_buffer(&set.ids, 0, bytemuck::cast_slice(&ids));
        q.write_buffer(&self.clock, 0, bytemuck::bytes_of(&(self.step as u32)));
        self.write_count();
        self.sort_next = true;
        self.counted = false;
        Ok(())
    }

    /// The state read back in input order ([`Error::Unstable`] if it is not finite).
    fn state(&self) -> Result<Particles> {
        let n = self.n as usize;
        let set = &self.sets[self.current];
        let pos: Vec<[f32; 4]> = self.gpu.read(&set.pos, n)?;
        let lo: Vec<[f32; 4]> = self.gpu.read(&set.lo, n)?;
        let vel: Vec<[f32; 4]> = self.gpu.read(&set.vel, n)?;
        let ids: Vec<u32> = self.gpu.read(&set.ids, n)?;
        let order = InputOrder::of(&ids);
        let rotation = || {
            let g = self.granular.as_ref();
            g.map(|g| g.read(&self.gpu, self.turn(), Some(&order)))
                .transpose()
        };
        let rows = StateRows {
            pos: &pos,
            lo: &lo,
            vel: &vel,
        };
        particles_with(rows, Some(&order.rank), self.step, rotation)
    }

    /// The centres' bounds now (a GPU reduction), or `None` for no spheres.
    fn bounds(&self) -> Result<Option<([f32; 3], [f32; 3])>> {
        if self.n == 0 {
            return Ok(None);
        }
        let gpu = &self.gpu;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.record_bounds(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        let keys: Vec<u32> = gpu.read(&self.bounds, 6)?;
        self.decode_bounds(&keys).map(Some)
    }

    /// Records the reduction of the current state's bounds into `self.bounds` (its reset is
    /// queued to run before the submission `encoder` goes into).
    fn record_bounds(&self, encoder: &mut wgpu::CommandEncoder) {
        let empty: [u32; 6] = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];
        let gpu = &self.gpu;
        gpu.queue
            .write_buffer(&self.bounds, 0, bytemuck::cast_slice(&empty));
        let binds = self.binds.as_ref().expect("laid out");
        gpu.dispatch(
            encoder,
            "mochi.dem.reduce_bounds",
            &self.pipelines.reduce_bounds,
            &binds[self.current].reduce_bounds,
            self.groups,
        );
    }

    /// The bounds from the reduction's keys ([`Error::Unstable`] naming a sphere if they are
    /// not finite).
    fn decode_bounds(&self, keys: &[u32]) -> Result<([f32; 3], [f32; 3])> {
        let value = |k: u32| {
            f32::from_bits(if k & 0x8000_0000 != 0 {
                k & 0x7fff_ffff
            } else {
                !k
            })
        };
        let lo = [value(keys[0]), value(keys[1]), value(keys[2])];
        let hi = [value(keys[3]), value(keys[4]), value(keys[5])];
        if lo.iter().chain(&hi).any(|x| !x.is_finite()) {
            // A position is not finite: the state read back names the sphere (Error::Unstable).
            self.state()?;
            return Err(Error::Gpu(format!(
                "the bounds at step {} are not finite, yet every sphere is",
                self.step
            )));
        }
        Ok((lo, hi))
    }

    /// Re-derives the grid layout from the current bounds (clipped to the box and a margin:
    /// walls keep the spheres in, so far-away outliers cannot stretch the grid).
    fn relayout(&mut self) -> Result<()> {
        if self.binds.is_none() {
            // Bounds need bind groups; a first layout over the box gives them.
            let (lo, hi) = (self.params.box_lo, self.params.box_hi);
            self.apply_layout(lo, hi)?;
        }
        let Some((lo, hi)) = self.bounds()? else {
            self.laid_out_at = Some(self.step);
            return Ok(());
        };
        self.layout_over(lo, hi)
    }

    /// Lays the grid out over the bounds `lo`..`hi` clipped to the box and a margin.
    fn layout_over(&mut self, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        let margin = self.mode_cell as f32;
        let lo: [f32; 3] = std::array::from_fn(|a| lo[a].max(self.params.box_lo[a] - margin));
        let hi: [f32; 3] =
            std::array::from_fn(|a| hi[a].min(self.params.box_hi[a] + margin).max(lo[a]));
        self.apply_layout(lo, hi)
    }

    fn apply_layout(&mut self, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        let gpu = &self.gpu;
        let layout = GridParams {
            row: self.groups.0 * GROUP,
            ..choose_layout(
                &gpu.limits,
                &LayoutRequest {
                    levels: self.levels,
                    bounds: (lo, hi),
                    budget: Budget {
                        spheres: self.n as u64,
                        cells_per_sphere: self.levels.dem_cells_per_sphere(),
                        build: self.build(),
                    },
                    base_cell: self.mode_cell,
                    radii: self.radii,
                    dense_check: &|_| true,
                },
            )
        };
        let layout = GridParams {
            skin: match self.pipelines.skin {
                Some(_) if self.step >= self.skin_off_until => skin_of(&layout),
                _ => 0.0,
            },
            ..layout
        };
        match &mut self.sorter {
            Sorter::Dense {
                cell_table,
                scan,
                scan_bind,
                ..
            } => {
                if cell_table.capacity < layout.cells || self.binds.is_none() {
                    *cell_table = gpu.checked("allocating the DEM cell table", || {
                        CellTable::new(gpu, layout.cells)
                    })?;
                    *scan_bind = Some(scan.bind(gpu, &self.grid_uniform, cell_table));
                    self.binds = None;
                }
            }
            Sorter::Sorted {
                keys,
                order,
                sort,
                prepared,
            } => {
                // The sort ends in the scratch or in `keys`/`order` by its passes' parity, so
                // the binds follow it.
                let sort = sort.prepare(gpu, keys, order, self.n, key_bits(layout.cells));
                *prepared = Some(Box::new(sort));
                self.binds = None;
            }
        }
        if self.binds.is_none() {
            self.binds = Some([self.make_binds(0), self.make_binds(1)]);
        }
        gpu.write_uniform(&self.grid_uniform, &layout);
        self.layout = layout;
        self.laid_out_at = Some(self.step);
        self.counted = false;
        Ok(())
    }

    /// Bind groups for binning from set `from` into the other (and, in the granular step,
    /// moving the angular velocities with the state).
    fn make_binds(&self, from: usize) -> Binds {
        let a = &self.sets[from];
        let p = &self.pipelines;
        let gpu = &self.gpu;
        let (scatter_more, integrate_more) = match &self.granular {
            Some(g) => {
                let [omega_a, omega] = g.sorted_omega(from);
                (
                    vec![
                        (OMEGA_A, omega_a),
                        (OMEGA, omega),
                        (CAME_FROM, g.came_from()),
                    ],
                    g.integrate_bindings(1 - from).to_vec(),
                )
            }
            // The paper's scatter notes the binned rows for the steps that may skip their binning.
            None => (self.skin_rows(), Vec::new()),
        };
        // What the binning's passes and the integration bind of the sorter.
        let (first, last, counting) = match &self.sorter {
            Sorter::Dense {
                ranks, cell_table, ..
            } => (
                vec![(RANKS, ranks), (COUNTS, &cell_table.counts)],
                vec![
                    (RANKS, ranks),
                    (CELL_START, &cell_table.cell_start),
                    (COUNTERS, &self.counters),
                    (CLOCK, &self.clock),
                ],
                vec![
                    (PARAMS, &self.grid_uniform),
                    (RANKS, ranks),
                    (COUNTS, &cell_table.counts),
                ],
            ),
            Sorter::Sorted {
                keys,
                order,
                prepared,
                ..
            } => {
                let (_, sorted_order) = prepared.as_ref().expect("laid out").sorted();
                (
                    vec![
                        (SORT_KEYS, keys),
                        (SORT_ORDER, order),
                        (COUNTERS, &self.counters),
                        (CLOCK, &self.clock),
                    ],
                    vec![(SORT_ORDER, sorted_order)],
                    Vec::new(),
                )
            }
        };
        Binds {
            bin_first: gpu.bind(
                "mochi.dem.bin_first",
                &p.bin_first,
                &joined(&[(PARAMS, &self.grid_uniform), (POS_A, &a.pos)], &first),
            ),
            bin_last: gpu.bind(
                "mochi.dem.bin_last",
                &p.bin_last,
                &joined(
                    &self.moving(from, 1 - from),
                    &[&last[..], &scatter_more[..]].concat(),
                ),
            ),
            resolving: self.resolving(1 - from, StepKind::Sorting),
            integrate: gpu.bind(
                "mochi.dem.integrate",
                &p.integrate,
                &[&self.integrated(1 - from)[..], &integrate_more, &counting].concat(),
            ),
            reduce_bounds: gpu.bind(
                "mochi.dem.reduce_bounds",
                &p.reduce_bounds,
                &[
                    (PARAMS, &self.grid_uniform),
                    (POS_A, &a.pos),
                    (BOUNDS, &self.bounds),
                ],
            ),
            binning: self.binning_binds(from),
            skin: self.skin_binds(from, &integrate_more),
        }
    }

    /// What a pass moving the state from set `from` (as set a) into set `to` binds.
    fn moving(&self, from: usize, to: usize) -> [(Binding, &wgpu::Buffer); 9] {
        let (a, b) = (&self.sets[from], &self.sets[to]);
        [
            (PARAMS, &self.grid_uniform),
            (POS_A, &a.pos),
            (POS_LO_A, &a.lo),
            (VEL_A, &a.vel),
            (IDS_A, &a.ids),
            (POS, &b.pos),
            (POS_LO, &b.lo),
            (VEL, &b.vel),
            (IDS, &b.ids),
        ]
    }

    /// What every integration kernel binds to step state set `on`.
    fn integrated(&self, on: usize) -> [(Binding, &wgpu::Buffer); 6] {
        let set = &self.sets[on];
        [
            (DEM, self.dem_uniform.buffer()),
            (POS, &set.pos),
            (POS_LO, &set.lo),
            (VEL, &set.vel),
            (FORCE, &self.force),
            (CLOCK, &self.clock),
        ]
    }

    /// What the paper's scatter writes for its skin (the binned rows), none in the granular
    /// step.
    fn skin_rows(&self) -> Vec<(Binding, &wgpu::Buffer)> {
        match self.granular {
            Some(_) => Vec::new(),
            None => vec![(WALK_ROW, &self.places.walk_row)],
        }
    }

    /// The skin's bind groups of a step whose state is on set `on` (`law`: the law's bindings),
    /// where the step has a skin.
    fn skin_binds(&self, on: usize, law: &[(Binding, &wgpu::Buffer)]) -> Option<SkinBinds> {
        let (pipelines, skin) = (self.pipelines.skin.as_ref()?, self.skin.as_ref()?);
        let gpu = &self.gpu;
        let started = [
            (CLOCK, &self.clock),
            (COUNTERS, &self.counters),
            (SKIN, &skin.state),
        ];
        Some(SkinBinds {
            begin_step: gpu.bind(
                "mochi.dem.begin_step",
                &pipelines.begin_step,
                &joined(
                    &[(PARAMS, &self.grid_uniform), (SKIN_LIMIT, &skin.limit)],
                    &started,
                ),
            ),
            begin_binning: gpu.bind(
                "mochi.dem.begin_binning",
                &pipelines.begin_binning,
                &joined(&started, &[(SKIN_LIMIT, &skin.limit)]),
            ),
            integrate: gpu.bind(
                "mochi.dem.integrate_and_report",
                &pipelines.integrate,
                &[
                    &self.integrated(on)[..],
                    &[(SKIN, &skin.state), (SKIN_LIMIT, &skin.limit)],
                    law,
                ]
                .concat(),
            ),
            bin_return: gpu.bind(
                "mochi.dem.bin_return",
                &pipelines.bin_return,
                &self.moving(1 - on, on),
            ),
        })
    }

    /// Bind groups of a binning step on set `on` (`None` where the step has none).
    fn binning_binds(&self, on: usize) -> Option<BinningBinds> {
        let bin_index = self.pipelines.bin_index.as_ref()?;
        let Sorter::Dense {
            ranks, cell_table, ..
        } = &self.sorter
        else {
            return None;
        };
        let (set, gpu, places) = (&self.sets[on], &self.gpu, &self.places);
        Some(BinningBinds {
            bin_index: gpu.bind(
                "mochi.dem.bin_index",
                bin_index,
                &[
                    (PARAMS, &self.grid_uniform),
                    (POS_A, &set.pos),
                    (RANKS, ranks),
                    (CELL_START, &cell_table.cell_start),
                    (COUNTERS, &self.counters),
                    (CLOCK, &self.clock),
                    (HOME, &places.home),
                    (WALK_POS, &places.walk_pos),
                ],
            ),
            resolving: self.resolving(on, StepKind::Binning),
        })
    }

    /// The contact pass's bind groups of a step of kind `kind` that resolves state set `on`:
    /// the search's cells, the state, the sorted places (the state itself in a sorting step,
    /// `bin_index`'s in a binning step) and the variant's bindings, by the history's parity.
    fn resolving(&self, on: usize, kind: StepKind) -> ResolveBinds {
        let (set, places, gpu) = (&self.sets[on], &self.places, &self.gpu);
        let cells = match &self.sorter {
            Sorter::Dense { cell_table, .. } => (CELL_START, &cell_table.cell_start),
            Sorter::Sorted { prepared, .. } => {
                (CELL_KEYS, prepared.as_ref().expect("laid out").sorted().0)
            }
        };
        let placed = match kind {
            StepKind::Sorting | StepKind::Skin => [(HOME, &places.identity), (WALK_POS, &set.pos)],
            StepKind::Binning => [(HOME, &places.home), (WALK_POS, &places.walk_pos)],
        };
        let own = [
            (PARAMS, &self.grid_uniform),
            (DEM, self.dem_uniform.buffer()),
            cells,
            (VEL, &set.vel),
            (FORCE, &self.force),
            (COUNTERS, &self.counters),
            placed[0],
            placed[1],
        ];
        let Some(g) = &self.granular else {
            // The walk starts from the row of its sphere's binned cell and widens its windows by
            // the drift since (the skin's).
            let skin = self.skin.as_ref().expect("the paper's step's skin buffers");
            let drift = [(WALK_ROW, &places.walk_row), (SKIN_LIMIT, &skin.limit)];
            let resolve = gpu.bind(
                "mochi.dem.resolve",
                &self.pipelines.resolve,
                &joined(&own, &drift),
            );
            return ResolveBinds {
                list_near: None,
                resolve: vec![resolve],
                mesh: None,
            };
        };
        let lists = self.near.as_ref().expect("the granular step's lists");
        // A multi-level grid's walk is long: it runs in a kernel of its own, without the
        // contact law's registers.
        let listed = [(NEAR, &lists.near), (LISTED, &lists.listed)];
        let (list_near, resolve) = match (&self.pipelines.listing, self.levels) {
            (Some([list_near, resolve_near]), Levels::Many) => {
                let walk = [(PARAMS, &self.grid_uniform), cells, placed[1]];
                let walk = joined(&walk, &listed);
                let list_near = gpu.bind("mochi.dem.list_near", list_near, &walk);
                (Some(list_near), resolve_near)
            }
            _ => (None, &self.pipelines.resolve),
        };
        let own = joined(&own, &listed);
        // A binning step leaves the state where it is: each sphere's old history row is the
        // row it is in.
        let came_from = match kind {
            StepKind::Sorting | StepKind::Skin => g.came_from(),
            StepKind::Binning => &places.identity,
        };
        let state = [
            (DEM, self.dem_uniform.buffer()),
            (POS, &set.pos),
            (CLOCK, &self.clock),
            (VEL, &set.vel),
            (FORCE, &self.force),
            (IDS, &set.ids),
            (CAME_FROM, came_from),
        ];
        let turns = [0, 1].map(|parity| Turn { set: on, parity });
        let mesh = self.pipelines.mesh.as_ref().and_then(|[near, contacts]| {
            turns
                .iter()
                .map(|&turn| {
                    let [near_walls, walls] = g.mesh_bindings(turn)?;
                    Some([
                        gpu.bind(
                            "mochi.dem.mesh_near",
                            near,
                            &joined(&state[..3], &near_walls),
                        ),
                        gpu.bind("mochi.dem.mesh_walls", contacts, &joined(&state, &walls)),
                    ])
                })
                .collect()
        });
        ResolveBinds {
            list_near,
            resolve: turns
                .iter()
                .map(|&turn| {
                    let more = [(IDS, &set.ids), (CAME_FROM, came_from)];
                    let all = [&own[..], &g.resolve_bindings(turn), &more].concat();
                    gpu.bind("mochi.dem.resolve", resolve, &all)
                })
                .collect(),
            mesh,
        }
    }

    /// How the step after the next `ahead` steps bins.
    fn kind_of_step(&self, ahead: u32) -> StepKind {
        if self.skinned() {
            return StepKind::Skin;
        }
        match self.pipelines.bin_index.is_some() && !self.sorts(ahead) {
            true => StepKind::Binning,
            false => StepKind::Sorting,
        }
    }

    /// Whether the step after the next `ahead` steps sorts (as [`Sorting`] says).
    fn sorts(&self, ahead: u32) -> bool {
        let every = match (self.sorting, self.skinned()) {
            (Sorting::Auto, false) => Some(SORT_EVERY),
            (Sorting::Auto, true) | (Sorting::Never, _) => None,
            (Sorting::Every(k), _) => Some(k),
        };
        let due = |k: u64| (self.step + ahead as u64).is_multiple_of(k.max(1));
        (self.sort_next && ahead == 0 && every.is_some()) || every.is_some_and(due)
    }

    /// The buffers the next step starts from.
    fn turn(&self) -> Turn {
        Turn {
            set: self.current,
            parity: self.parity,
        }
    }

    /// The buffers the step after one of kind `kind` from `turn` starts from: a sorting step
    /// moves the state into the other set (a step with a skin moves it back); the granular
    /// step's history changes sides at every step.
    fn turn_after(&self, kind: StepKind, turn: Turn) -> Turn {
        Turn {
            set: match kind {
                StepKind::Sorting => 1 - turn.set,
                StepKind::Binning | StepKind::Skin => turn.set,
            },
            parity: match self.granular {
                Some(_) => 1 - turn.parity,
                None => 0,
            },
        }
    }

    /// Whether the layout has a skin: steps may skip their binning.
    fn skinned(&self) -> bool {
        self.pipelines.skin.is_some() && self.layout.skin > 0.0
    }

    /// Records one phase of a step of kind `kind` from `from` into `pass` (without a skin, the
    /// dense build's spheres counted already: see [`counted`](Self::counted); with one, the
    /// step re-bins where `rebin` is `Always`, else where the GPU finds it must).
    fn record_phase(
        &self,
        pass: &mut wgpu::ComputePass,
        from: Turn,
        kind: StepKind,
        rebin: Rebin,
        phase: Phase,
    ) {
        if kind == StepKind::Skin {
            return self.record_skin_phase(pass, from.set, rebin, phase);
        }
        let binds = self.binds.as_ref().expect("laid out");
        let b = &binds[from.set];
        let p = &self.pipelines;
        let binning = (kind == StepKind::Binning).then(|| {
            let own = b.binning.as_ref().expect("a step with binning steps");
            let bin_index = p.bin_index.as_ref().expect("a step with binning steps");
            (own, bin_index)
        });
        match phase {
            Phase::Build => {
                if self.build() == BuildKind::Sorted {
                    gpu::record(pass, &p.bin_first, &b.bin_first, self.groups);
                }
                self.record_scan(pass, None);
                match binning {
                    Some((own, bin_index)) => {
                        gpu::record(pass, bin_index, &own.bin_index, self.groups)
                    }
                    None => gpu::record(pass, &p.bin_last, &b.bin_last, self.groups),
                }
            }
            Phase::Resolve => {
                let r = binning.map_or(&b.resolving, |(own, _)| &own.resolving);
                let resolve = match (&p.listing, &r.list_near) {
                    (Some([list_near, resolve_near]), Some(bind)) => {
                        gpu::record(pass, list_near, bind, self.groups);
                        resolve_near
                    }
                    _ => &p.resolve,
                };
                gpu::record(pass, resolve, &r.resolve[from.parity], self.groups);
                if let (Some(pipelines), Some(binds)) = (&p.mesh, &r.mesh) {
                    for (pipeline, bind) in pipelines.iter().zip(&binds[from.parity]) {
                        gpu::record(pass, pipeline, bind, self.groups);
                    }
                }
            }
            // A binning step integrates the set it is on, as the sorting step from the other
            // set does.
            Phase::Integrate => {
                let integrate = match kind {
                    StepKind::Binning => &binds[1 - from.set].integrate,
                    _ => &b.integrate,
                };
                gpu::record(pass, &p.integrate, integrate, self.groups)
            }
        }
    }

    /// Records one phase of a step with a skin whose state is on set `on`: where it re-bins
    /// (`rebin`, or the GPU's decision), the count, the scan, the scatter into the other set
    /// and the copy back; then the contact pass and the integration on `on`, as a sorting
    /// step's on a sorted set.
    fn record_skin_phase(
        &self,
        pass: &mut wgpu::ComputePass,
        on: usize,
        rebin: Rebin,
        phase: Phase,
    ) {
        let binds = self.binds.as_ref().expect("laid out");
        let (b, p) = (&binds[on], &self.pipelines);
        let own = b.skin.as_ref().expect("a step with a skin");
        let pipelines = p.skin.as_ref().expect("a step with a skin");
        let skin = self.skin.as_ref().expect("a step with a skin");
        match phase {
            Phase::Build => {
                let passes = [
                    (&p.bin_first, &b.bin_first),
                    (&p.bin_last, &b.bin_last),
                    (&pipelines.bin_return, &own.bin_return),
                ];
                if rebin == Rebin::IfMoved {
                    gpu::record(pass, &pipelines.begin_step, &own.begin_step, (1, 1));
                    skin.dispatch_spheres(pass, passes[0].0, passes[0].1);
                    self.record_scan(pass, Some(skin.blocks_args()));
                    for (pipeline, bind) in &passes[1..] {
                        skin.dispatch_spheres(pass, pipeline, bind);
                    }
                } else {
                    gpu::record(pass, &pipelines.begin_binning, &own.begin_binning, (1, 1));
                    gpu::record(pass, passes[0].0, passes[0].1, self.groups);
                    self.record_scan(pass, None);
                    for (pipeline, bind) in &passes[1..] {
                        gpu::record(pass, pipeline, bind, self.groups);
                    }
                }
            }
            // The sorting step's contact pass from the other set resolves `on`.
            Phase::Resolve => {
                let resolve = &binds[1 - on].resolving.resolve[0];
                gpu::record(pass, &p.resolve, resolve, self.groups)
            }
            Phase::Integrate => {
                gpu::record(pass, &pipelines.integrate, &own.integrate, self.groups)
            }
        }
    }

    /// Records the sorter's pass between the binning's first and last: the scan of the cell
    /// table (its dispatch read from `indirect` where given), or the sort of the keys.
    fn record_scan(&self, pass: &mut wgpu::ComputePass, indirect: Option<(&wgpu::Buffer, u64)>) {
        match &self.sorter {
            Sorter::Dense {
                scan, scan_bind, ..
            } => {
                let binds = scan_bind.as_ref().expect("laid out");
                match indirect {
                    Some(args) => scan.record_indirect(pass, binds, args),
                    None => scan.record(pass, binds, &self.layout),
                }
            }
            Sorter::Sorted { prepared, .. } => prepared.as_ref().expect("laid out").record(pass),
        }
    }
}

impl RedoableBatch for GridStepper {
    fn batch_parts(&mut self) -> BatchParts<'_> {
        let (turn, set) = (self.turn(), &self.sets[self.current]);
        let state = vec![&set.pos, &set.lo, &set.vel, &set.ids, &self.clock];
        let (granular, params) = (self.granular.as_mut(), &mut self.dem_uniform);
        (&self.gpu, granular, turn, state, params)
    }

    fn record_batch(
        &mut self,
        mut encoder: wgpu::CommandEncoder,
        steps: u32,
    ) -> Result<(u64, Option<StageTimes>)> {
        let recording = std::time::Instant::now();
        let profiled = self.encode_steps(&mut encoder, steps, self.submit_every)?;
        let recorded_ms = recording.elapsed().as_secs_f64() * 1e3;
        let gpu = &self.gpu;
        let timer = self.timer.as_ref();
        gpu.checked("running DEM steps", || gpu.queue.submit([encoder.finish()]))?;
        let contacts = gpu.read::<u32>(&self.counters, 1)?[0] as u64;
        let times = timer.map(|t| t.read(gpu, profiled)).transpose()?;
        self.submit_every = submissions(times.as_ref(), recorded_ms);
        Ok((contacts, times))
    }

    fn rewind(&mut self, steps: u32) {
        self.step -= steps as u64;
        (self.current, self.parity, self.sort_next) = self.batch_start;
        self.counted = false;
    }

    fn rebind(&mut self) {
        self.binds = Some([self.make_binds(0), self.make_binds(1)]);
    }
}

impl GridStepper {
    /// Records `steps` steps into `encoder` and moves the clock past them; returns how many
    /// were marked phase by phase. With a timer, the first step is recorded phase by phase
    /// between timestamps (see [`StepTimer`]), the others share a compute pass for every
    /// `submit_every` of them (all in one where `None`), each but the last submitted as soon as
    /// it is recorded (`encoder` then holds the last), and the batch's end is marked and
    /// resolved.
    fn encode_steps(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        steps: u32,
        submit_every: Option<u32>,
    ) -> Result<u32> {
        let timer = self.timer.as_ref();
        let mut turn = self.turn();
        self.batch_start = (self.current, self.parity, self.sort_next);
        let mut profiled = 0;
        let skinned = self.skinned();
        // With a skin the first step re-bins where its places may be stale or its phases are
        // timed; the counts are zero between steps but where the layout or the state changed.
        let first_rebin = match self.counted && timer.is_none() {
            true => Rebin::IfMoved,
            false => Rebin::Always,
        };
        // A step with a skin re-bins where the batch's first step must or [`Sorting`] sorts.
        let rebin_at = |step: u32| match step == 0 && first_rebin == Rebin::Always {
            true => Rebin::Always,
            false if self.sorts(step) => Rebin::Always,
            false => Rebin::IfMoved,
        };
        if let Some(skin) = self.skin.as_ref().filter(|_| skinned) {
            skin.prepare(&self.gpu, self.groups, self.layout.scan_blocks());
        }
        if let Sorter::Dense { cell_table, .. } = &self.sorter
            && !self.counted
        {
            // What a step counted before the layout or the state changed is cleared; without a
            // skin the spheres are counted afresh, ahead of the batch's first step and its
            // timestamps (with one, that step re-bins and counts them itself).
            encoder.clear_buffer(&cell_table.counts, 0, None);
            if !skinned {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("mochi.dem.count"),
                    timestamp_writes: None,
                });
                let b = &self.binds.as_ref().expect("laid out")[turn.set];
                gpu::record(
                    &mut pass,
                    &self.pipelines.bin_first,
                    &b.bin_first,
                    self.groups,
                );
            }
        }
        if timer.is_some() {
            let kind = self.kind_of_step(0);
            StepTimer::mark(timer, encoder, 0, 0);
            for (k, phase) in Phase::ALL.into_iter().enumerate() {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(phase.label()),
                    timestamp_writes: None,
                });
                self.record_phase(&mut pass, turn, kind, rebin_at(0), phase);
                drop(pass);
                StepTimer::mark(timer, encoder, 0, k as u32 + 1);
            }
            turn = self.turn_after(kind, turn);
            profiled = 1;
        }
        let mut k = profiled;
        while k < steps {
            let end = submit_every.map_or(steps, |every| (k + every).min(steps));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.dem.steps"),
                timestamp_writes: None,
            });
            for step in k..end {
                let kind = self.kind_of_step(step);
                for phase in Phase::ALL {
                    self.record_phase(&mut pass, turn, kind, rebin_at(step), phase);
                }
                turn = self.turn_after(kind, turn);
            }
            drop(pass);
            k = end;
            if k < steps {
                let gpu = &self.gpu;
                let next = gpu.device.create_command_encoder(&Default::default());
                let done = std::mem::replace(encoder, next);
                gpu.checked("running DEM steps", || gpu.queue.submit([done.finish()]))?;
            }
        }
        let timer = self.timer.as_ref();
        if let Some(t) = timer {
            t.end(encoder, profiled);
        }
        (self.current, self.parity) = (turn.set, turn.parity);
        self.step += steps as u64;
        self.sort_next = false;
        self.counted = self.build() == BuildKind::Dense;
        Ok(profiled)
    }

    /// Records a batch of `steps` steps of the paper's step that ends by reducing its bounds
    /// and copying its results for the host, and submits it.
    fn submit_batch(&mut self, steps: u32) -> Result<InFlight> {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        let profiled = self.encode_steps(&mut encoder, steps, None)?;
        self.record_bounds(&mut encoder);
        let timer = self.timer.as_ref().map(|t| (t, profiled));
        let skin = self.skin.as_ref().filter(|_| self.skinned());
        let rebins = skin.map(|s| (&s.state, Skin::REBINS_AT));
        self.readback.record(
            &mut encoder,
            &self.counters,
            rebins,
            Some(&self.bounds),
            timer,
        );
        let rebinning = skin.map(|_| steps);
        self.readback
            .submit(&self.gpu, encoder, profiled, rebinning)
    }

    /// The paper's step, `steps` steps in batches kept in flight: batch k + 1 is recorded and
    /// submitted before the host waits for batch k. A layout falls due at a batch's start; it
    /// is made from the bounds of the last batch that finished (one batch old while another
    /// runs: spheres outside a layout are clamped into its border cells, exact, so a layout
    /// need not be fresh).
    fn advance_paper(&mut self, steps: u32) -> Result<Advance> {
        if self.laid_out_at.is_none() {
            self.relayout()?;
        }
        let mut times = StageTimes::default();
        let mut timed = self.timer.is_some();
        let mut contacts = 0;
        let mut left = steps;
        let mut in_flight: Option<InFlight> = None;
        loop {
            let next = if left > 0 {
                let laid_out_at = self.laid_out_at.unwrap_or(self.step);
                if self.step >= laid_out_at + RELAYOUT_EVERY
                    && let Some(keys) = self.last_bounds.take()
                {
                    let (lo, hi) = self.decode_bounds(&keys)?;
                    self.layout_over(lo, hi)?;
                }
                let batch = left.min(MAX_BATCH).min(RELAYOUT_EVERY as u32);
                left -= batch;
                Some(self.submit_batch(batch)?)
            } else {
                None
            };
            if let Some(done) = in_flight.take() {
                let results = self.readback.finish(&self.gpu, done)?;
                contacts = results.contacts;
                if let Some((steps, rebins)) = results.rebins {
                    self.rebinned.0 += steps as u64;
                    self.rebinned.1 += rebins as u64;
                    // Off from the next layout on where it re-binned too often.
                    if rebins as f64 > MAX_REBIN_SHARE * steps as f64 {
                        self.skin_off_until = self.step + SKIN_RETRY_STEPS;
                    }
                }
                self.last_bounds = Some(results.bounds);
                match results.times {
                    Some(t) => times.add(&t),
                    None => timed = false,
                }
            }
            match next {
                Some(batch) => in_flight = Some(batch),
                None => break,
            }
        }
        Ok(Advance {
            steps,
            contacts,
            times,
            clock: if timed { Clock::Gpu } else { Clock::None },
        })
    }
}

impl GridStepper {
    /// The build this step bins with.
    pub fn build(&self) -> BuildKind {
        match self.sorter {
            Sorter::Dense { .. } => BuildKind::Dense,
            Sorter::Sorted { .. } => BuildKind::Sorted,
        }
    }
}

/// The centres' bounds of `particles` within the box of `params` widened by `margin` (as the
/// step's layouts take them), or `None` for no spheres.
fn start_bounds(
    particles: &Particles,
    params: &StepParams,
    margin: f32,
) -> Option<([f32; 3], [f32; 3])> {
    let first = *particles.positions.first()?;
    let (mut lo, mut hi) = (first, first);
    for c in &particles.positions {
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    let lo: [f32; 3] = std::array::from_fn(|a| lo[a].max(params.box_lo[a] - margin));
    let hi: [f32; 3] = std::array::from_fn(|a| hi[a].min(params.box_hi[a] + margin).max(lo[a]));
    Some((lo, hi))
}

/// `own` bindings and `more` (the granular step's or the per-pair variant's).
fn joined<'a>(
    own: &[(Binding, &'a wgpu::Buffer)],
    more: &[(Binding, &'a wgpu::Buffer)],
) -> Vec<(Binding, &'a wgpu::Buffer)> {
    [own, more].concat()
}

/// The phases of a step, in order.
#[derive(Debug, Clone, Copy)]
enum Phase {
    /// Sort of the spheres by cell (the dense build's counts come from the last step).
    Build,
    /// Detection with the contact forces.
    Resolve,
    /// Walls, gravity and integration (the dense build's also counts the spheres into their
    /// cells for the next step).
    Integrate,
}

impl Phase {
    const ALL: [Phase; 3] = [Phase::Build, Phase::Resolve, Phase::Integrate];

    fn label(self) -> &'static str {
        match self {
            Phase::Build => "mochi.dem.build",
            Phase::Resolve => "mochi.dem.resolve",
            Phase::Integrate => "mochi.dem.integrate",
        }
    }
}

/// Flow events scan the state on the device and append inserted spheres to it, in rows kept
/// for them at opening ([`GridStepper::flowing_on`]).
impl DeviceFlow for GridStepper {
    fn scan(&mut self, query: &FlowQuery) -> Result<Option<Scan>> {
        let set = self.turn().set;
        let gpu = &self.gpu;
        let scan = self.flow_scan.get_or_insert_with(|| FlowScan::new(gpu));
        let pos = &self.sets[set].pos;
        let spin = self.granular.as_ref().map(|g| g.omega_of(set));
        scan.scan(gpu, pos, spin, self.n, query).map(Some)
    }

    fn append(&mut self, new: &[NewSphere]) -> Result<bool> {
        let k = new.len() as u32;
        let (r_min, r_max) = new.iter().fold((f32::MAX, 0.0f32), |(a, b), s| {
            (a.min(s.radius), b.max(s.radius))
        });
        // The grid's cells and levels were chosen for the radii present.
        let radii_fit = k == 0 || (r_min as f64 >= self.radii.0 && r_max as f64 <= self.radii.1);
        // Stable ids stay below the walls' (a reopening numbers the spheres afresh).
        let ids_fit = self
            .next_id
            .checked_add(k)
            .is_some_and(|end| end <= FIRST_MESH_WALL);
        if self.n.checked_add(k).is_none_or(|n| n > self.capacity) || !radii_fit || !ids_fit {
            return Ok(false);
        }
        if k == 0 {
            return Ok(true);
        }
        let table = &self.params.materials;
        let pos: Vec<[f32; 4]> = new
            .iter()
            .map(|s| [s.centre[0], s.centre[1], s.centre[2], s.radius])
            .collect();
        let vel: Vec<[f32; 4]> = new
            .iter()
            .map(|s| {
                [
                    s.velocity[0],
                    s.velocity[1],
                    s.velocity[2],
                    table.mass(s.material as u32, s.radius),
                ]
            })
            .collect();
        let ids: Vec<u32> = (self.next_id..self.next_id + k).collect();
        self.next_id += k;
        let (q, set) = (&self.gpu.queue, &self.sets[self.current]);
        let at = self.n as u64;
        q.write_buffer(&set.pos, at * 16, bytemuck::cast_slice(&pos));
        // Inserted at their f32 centres: no residual (the rows may hold a removed sphere's).
        let lo = vec![[0.0f32; 4]; new.len()];
        q.write_buffer(&set.lo, at * 16, bytemuck::cast_slice(&lo));
        q.write_buffer(&set.vel, at * 16, bytemuck::cast_slice(&vel));
        q.write_buffer(&set.ids, at * 4, bytemuck::cast_slice(&ids));
        let next = self.turn();
        if let Some(g) = &mut self.granular {
            let materials: Vec<u8> = new.iter().map(|s| s.material).collect();
            g.append(&self.gpu, next, &materials)?;
        }
        self.resize(self.n + k);
        Ok(true)
    }

    fn remove(&mut self, rows: &[u32]) -> Result<bool> {
        let k = rows.len() as u32;
        let Some(kept) = self.n.checked_sub(k) else {
            return Ok(false);
        };
        // The last rows that stay fill the places of those that leave before them.
        let mut leaving = rows.to_vec();
        leaving.sort_unstable();
        let holes = leaving.iter().copied().take_while(|&r| r < kept);
        let fillers = (kept..self.n).filter(|r| leaving.binary_search(r).is_err());
        let moves: Vec<(u32, u32)> = fillers.zip(holes).collect();
        if !moves.is_empty() {
            let gpu = &self.gpu;
            let row_bytes = self.granular.as_ref().map_or(16, |g| g.row_bytes());
            let bytes = moves.len() as u64 * row_bytes;
            let none = wgpu::BufferUsages::empty();
            gpu.checked("removing spheres", || {
                let scratch = gpu.storage("mochi.dem.flow_scratch", bytes, none);
                let mut encoder = gpu.device.create_command_encoder(&Default::default());
                let set = &self.sets[self.current];
                move_rows(&mut encoder, &scratch, &moves, 16, |r| {
                    (&set.pos, r as u64 * 16)
                });
                move_rows(&mut encoder, &scratch, &moves, 16, |r| {
                    (&set.lo, r as u64 * 16)
                });
                move_rows(&mut encoder, &scratch, &moves, 16, |r| {
                    (&set.vel, r as u64 * 16)
                });
                move_rows(&mut encoder, &scratch, &moves, 4, |r| {
                    (&set.ids, r as u64 * 4)
                });
                if let Some(g) = &self.granular {
                    g.move_rows(&mut encoder, self.turn(), &scratch, &moves);
                }
                gpu.queue.submit([encoder.finish()]);
            })?;
        }
        if let Some(g) = &mut self.granular {
            g.shrink(k);
        }
        self.resize(kept);
        Ok(true)
    }
}

impl GridStepper {
    /// The state now holds `n` spheres: the dispatch and the uniform follow, and the next
    /// advance lays the grid out again, over the new bounds and count.
    fn resize(&mut self, n: u32) {
        self.n = n;
        self.sort_next = true;
        self.counted = false;
        self.groups = self.gpu.grid(n, GROUP);
        self.write_count();
        self.laid_out_at = None;
    }

    /// Writes the sphere count and the dispatch rows into the step's parameters.
    fn write_count(&mut self) {
        let (n, row) = (self.n, self.groups.0 * GROUP);
        self.dem_uniform
            .update(&self.gpu, |p| (p.n, p.row) = (n, row));
    }
}

impl Stepper for GridStepper {
    fn describe(&self) -> String {
        let history = self.granular.as_ref().and_then(Granular::describe_history);
        // The grid as last laid out (it follows the spheres' bounds through the run).
        let grid = match self.laid_out_at {
            Some(_) => describe_layout(&self.layout, self.build()),
            None => format!("{} build", self.build().name()),
        };
        let skin = match self.rebinned {
            (steps, rebins) if steps > 0 => {
                format!("; skin of {SKIN_CELLS} cell on {steps} steps, re-binned at {rebins}")
            }
            _ => String::new(),
        };
        format!(
            "wgpu-compute ({}; {}; {grid}{skin}{})",
            gpu::describe(&self.gpu.info),
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
        let Some(granular) = &mut self.granular else {
            return self.advance_paper(steps);
        };
        let last = self.step + steps as u64 - 1;
        granular.mesh_mut().sum_loads_in(&self.gpu, last);
        let advance = advance_in_batches(steps, self.timer.is_some(), |left| {
            let due = match self.laid_out_at {
                None => true,
                Some(at) => self.step >= at + RELAYOUT_EVERY,
            };
            if due {
                self.relayout()?;
            }
            let until_relayout = self.laid_out_at.unwrap_or(self.step) + RELAYOUT_EVERY - self.step;
            let batch = left.min(MAX_BATCH).min(until_relayout.max(1) as u32);
            let (contacts, times) = run_batch(self, batch)?;
            Ok((batch, contacts, times))
        })?;
        if let Some(g) = &mut self.granular {
            g.mesh_mut().read_loads(&self.gpu)?;
        }
        Ok(advance)
    }

    fn particles(&mut self) -> Result<Particles> {
        self.state()
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.granular
            .as_ref()
            .map_or_else(Vec::new, |g| g.mesh().loads().to_vec())
    }

    fn grid_build(&self) -> Option<&'static str> {
        Some(self.build().name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_is_split_where_the_gpu_outlasts_its_recording() {
        let gpu_ms = |total: f64| StageTimes {
            build_ms: total / 2.0,
            dcd_ms: total / 4.0,
            update_ms: total / 4.0,
        };
        assert_eq!(
            submissions(Some(&gpu_ms(32.0)), 3.0),
            Some(STEPS_A_SUBMISSION)
        );
        assert_eq!(submissions(Some(&gpu_ms(2.0)), 3.0), None);
        assert_eq!(submissions(Some(&gpu_ms(12.0)), 3.0), None);
        assert_eq!(submissions(None, 3.0), Some(STEPS_A_SUBMISSION));
    }
}
