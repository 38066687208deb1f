//! Detection on the wgpu-compute engine: [`WgpuComputeBackend`] implements [`crate::Backend`].

use super::cell_table::{CellScan, CellTable};
use super::layout::{
    Budget, BuildKind, DETECT_CELLS_PER_SPHERE, GridBuild, GridParams, LayoutRequest, MAX_CROWDING,
    Structure, choose_layout, core_bounds, crowding, describe_layout, key_bits,
};

use super::shaders::{CELL_KEYS, grid_build, grid_pairs, grid_sort};
use crate::detect::BackendInfo;
use crate::engines::common::detect::GpuBackend;
use crate::engines::wgpu::detection::{DetectKernel, WgpuDetection};
use crate::error::Result;
use crate::gpu::pair_output;
use crate::gpu::pair_output::{PairOutput, TakePairs};
use crate::gpu::radix_sort::RadixSort;
use crate::gpu::{self, Gpu, Need};
use crate::proxy::ProxyMode;
use crate::spheres::{Bounds, SphereSet, Spheres, Survey};
use crate::types::{DetectStats, GpuTimes};

/// Workgroup sizes, as in the shaders.
const BUILD_GROUP: u32 = 256;
const PAIRS_GROUP: u32 = 256;

/// Label of the detection pipeline, its bind group and pass.
const FIND_PAIRS: &str = "mochi.grid.find_pairs";

/// The wgpu compute (sorted grid) backend.
pub struct WgpuComputeBackend {
    detection: WgpuDetection<Grid>,
    scan: CellScan,
    join_spheres: wgpu::ComputePipeline,
    count_cells: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    find_pairs: wgpu::ComputePipeline,
    /// The sorted-key build: keys, their sort, and the search over them.
    key_spheres: wgpu::ComputePipeline,
    sort: RadixSort,
    find_pairs_sorted: wgpu::ComputePipeline,
    structure: Structure,
    grid_build: GridBuild,
    /// The last layout chosen, which builds of spheres that barely moved reuse.
    last_layout: Option<ChosenLayout>,
}

/// What a layout is chosen for: the spheres' count and radii, the mode, and the backend's
/// structure and build settings.
#[derive(Clone, Copy, PartialEq)]
struct LayoutFor {
    n: usize,
    mode: ProxyMode,
    radii: (f32, f32),
    structure: Structure,
    grid_build: GridBuild,
}

/// A layout, what it was chosen for, and the centres' bounds then ([`WgpuComputeBackend::layout`]).
#[derive(Clone, Copy)]
struct ChosenLayout {
    chosen_for: LayoutFor,
    bounds: Bounds,
    build: BuildKind,
    layout: GridParams,
}

/// A layout is reused while each face of the centres' bounds stays within this fraction of the
/// bounds' extent along its axis of where it was (moving spheres keep their layout; any layout
/// is exact, centres outside it are clamped to its border cells, so this only bounds the cost).
const LAYOUT_SLACK: f32 = 1.0 / 64.0;

impl ChosenLayout {
    /// Whether this layout serves spheres within `bounds` chosen for the same.
    fn serves(&self, chosen_for: &LayoutFor, (lo, hi): Bounds) -> bool {
        let (old_lo, old_hi) = self.bounds;
        let near = |a: usize| {
            let slack = LAYOUT_SLACK * (old_hi[a] - old_lo[a]);
            (lo[a] - old_lo[a]).abs() <= slack && (hi[a] - old_hi[a]).abs() <= slack
        };
        self.chosen_for == *chosen_for && (0..3).all(near)
    }
}

/// What a build copies from its grid's upload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Upload {
    /// Centres and radii: a build of a sphere set.
    Spheres,
    /// Centres alone: spheres moved, radii as built.
    Centres,
}

/// GPU buffers of a grid over `n` spheres, and the layout and build of its last build.
struct Grid {
    n: u32,
    layout: GridParams,
    build: BuildKind,
    params: wgpu::Buffer,
    pair_params: wgpu::Buffer,
    /// Where the host writes the centres (three floats each), then the radii, for each build
    /// (kept: no staging per build); a move writes the centres alone.
    upload: wgpu::Buffer,
    /// The centres and radii uploaded, in input order.
    centres: wgpu::Buffer,
    radii: wgpu::Buffer,
    /// `vec4(x, y, z, r)` in input order, joined from `centres` and `radii`.
    spheres_in: wgpu::Buffer,
    /// Cell key and rank among the spheres of that cell of each sphere, in input order.
    slots: wgpu::Buffer,
    /// Input index of each sorted sphere.
    ids: wgpu::Buffer,
    /// `vec4(x, y, z, r)` in sorted order.
    spheres: wgpu::Buffer,
    /// The sorted build's cell key of each sphere: in input order, then sorted.
    keys: wgpu::Buffer,
    /// The dense build's table (`None` in the sorted build, which has none).
    table: Option<CellTable>,
}

impl Grid {
    fn new(gpu: &Gpu, n: u32, build: BuildKind, cells: u32) -> Grid {
        let none = wgpu::BufferUsages::empty();
        let n64 = n as u64;
        Grid {
            n,
            layout: GridParams::default(),
            build,
            params: gpu.uniform("mochi.grid.params", &GridParams::default()),
            pair_params: gpu.uniform("mochi.grid.pair_params", &GridParams::default()),
            upload: gpu.upload_buffer("mochi.grid.upload", n64 * 16),
            centres: gpu.storage("mochi.grid.centres", n64 * 12, none),
            radii: gpu.storage("mochi.grid.radii", n64 * 4, none),
            spheres_in: gpu.storage("mochi.grid.spheres_in", n64 * 16, none),
            slots: gpu.storage("mochi.grid.slots", n64 * 8, none),
            ids: gpu.storage("mochi.grid.ids", n64 * 4, none),
            spheres: gpu.storage("mochi.grid.spheres", n64 * 16, none),
            keys: gpu.storage("mochi.grid.keys", n64 * 4, none),
            table: (build == BuildKind::Dense).then(|| CellTable::new(gpu, cells)),
        }
    }

    /// Whether this grid's buffers take a build of `n` spheres by `build` over `cells` cells.
    fn fits(&self, n: u32, build: BuildKind, cells: u32) -> bool {
        self.n == n
            && match (build, &self.table) {
                (BuildKind::Dense, Some(table)) => table.capacity >= cells,
                (BuildKind::Dense, None) => false,
                (BuildKind::Sorted, _) => true,
            }
    }
}

impl WgpuComputeBackend {
    /// Opens the best adapter with compute shaders.
    pub fn new() -> Result<Self> {
        let gpu = Gpu::open(Need::Compute)?;
        let build = gpu.own_module("mochi.grid.build", grid_build::SOURCE);
        let pairs = gpu.own_module("mochi.grid.pairs", grid_pairs::DENSE_SOURCE);
        let sort = gpu.own_module("mochi.grid.sort", grid_sort::SOURCE);
        let pairs_sorted = gpu.own_module("mochi.grid.pairs_sorted", grid_pairs::SORTED_SOURCE);
        Ok(Self {
            scan: CellScan::new(&gpu),
            join_spheres: gpu.pipeline("mochi.grid.join_spheres", &build, "join_spheres"),
            count_cells: gpu.pipeline("mochi.grid.count_cells", &build, "count_cells"),
            scatter: gpu.pipeline("mochi.grid.scatter", &build, "scatter"),
            gather: gpu.pipeline("mochi.grid.gather", &build, "gather"),
            find_pairs: gpu.pipeline(FIND_PAIRS, &pairs, "find_pairs"),
            key_spheres: gpu.pipeline("mochi.grid.key_spheres", &sort, "key_spheres"),
            sort: RadixSort::new(&gpu),
            find_pairs_sorted: gpu.pipeline(FIND_PAIRS, &pairs_sorted, "find_pairs"),
            structure: Structure::Auto,
            grid_build: GridBuild::Auto,
            last_layout: None,
            detection: WgpuDetection::new("wgpu-compute", gpu),
        })
    }

    /// Builds `structure` from now on.
    pub fn with_structure(mut self, structure: Structure) -> Self {
        self.structure = structure;
        self
    }

    /// Builds with `grid_build` (dense table or sorted keys) from now on.
    pub fn with_grid_build(mut self, grid_build: GridBuild) -> Self {
        self.grid_build = grid_build;
        self
    }

    fn max_spheres(&self) -> u64 {
        let l = &self.detection.gpu.limits;
        (l.max_storage_buffer_binding_size.min(l.max_buffer_size) / 16).min(u32::MAX as u64)
    }

    /// Build and cell layout for `spheres` (see [`GridBuild::resolve`], [`choose_layout`])
    /// over their [`core_bounds`]; the last one again where it serves them (spheres that barely
    /// moved: [`LAYOUT_SLACK`]).
    fn layout(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> (BuildKind, GridParams) {
        let chosen_for = LayoutFor {
            n: spheres.len(),
            mode,
            radii: (spheres.min_radius(), spheres.max_radius()),
            structure: self.structure,
            grid_build: self.grid_build,
        };
        let bounds = spheres.bounds().expect("the set is not empty");
        if let Some(last) = self.last_layout
            && last.serves(&chosen_for, bounds)
        {
            return (last.build, last.layout);
        }
        let (build, layout) = self.choose(spheres, mode);
        self.last_layout = Some(ChosenLayout {
            chosen_for,
            bounds,
            build,
            layout,
        });
        (build, layout)
    }

    /// [`Self::layout`] chosen afresh.
    fn choose(&self, spheres: Spheres<'_>, mode: ProxyMode) -> (BuildKind, GridParams) {
        let (lo, hi) = core_bounds(spheres).expect("the set is not empty");
        let base = mode.cell_size(spheres.max_radius()) as f64;
        let build = self
            .grid_build
            .resolve(spheres.len() as u64, (lo, hi), base);
        let uncrowded = |size: f64| crowding(spheres.centers(), lo, size) <= MAX_CROWDING;
        let radii = (spheres.min_radius() as f64, spheres.max_radius() as f64);
        let budget = Budget {
            spheres: spheres.len() as u64,
            cells_per_sphere: DETECT_CELLS_PER_SPHERE,
            build,
        };
        let request = LayoutRequest {
            levels: self.structure.levels_for(mode, radii.1 / radii.0),
            bounds: (lo, hi),
            budget,
            base_cell: base,
            radii,
            dense_check: &uncrowded,
        };
        (build, choose_layout(&self.detection.gpu.limits, &request))
    }
}

impl WgpuComputeBackend {
    /// Records and submits the build of `grid` over `n` spheres by `build` in `layout` from
    /// what its upload holds, and keeps it as the current build (not waited for).
    fn submit(
        &mut self,
        (n, mode): (u32, ProxyMode),
        (mut grid, output): (Grid, PairOutput),
        (build, layout): (BuildKind, GridParams),
        upload: Upload,
    ) -> Result<()> {
        let (x, y) = self.detection.gpu.grid(n, BUILD_GROUP);
        grid.layout = GridParams {
            row: x * BUILD_GROUP,
            ..layout
        };
        grid.build = build;
        let what = "building the wgpu-compute grid";
        let join = &self.join_spheres;
        let gather = &self.gather;
        let sort = &mut self.sort;
        let key_spheres = &self.key_spheres;
        let record_sorted = |gpu: &Gpu, g: &Grid, encoder: &mut wgpu::CommandEncoder| {
            let joined = record_upload(gpu, join, g, upload, encoder);
            let keys = gpu.bind(
                "mochi.grid.key_spheres",
                key_spheres,
                &[
                    (grid_sort::PARAMS, &g.params),
                    (grid_sort::SPHERES_IN, &g.spheres_in),
                    (grid_sort::KEYS, &g.keys),
                    (grid_sort::IDS, &g.ids),
                ],
            );
            let gathered = gather_bind(gpu, gather, g);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.grid.build.keys"),
                timestamp_writes: None,
            });
            gpu::record(&mut pass, join, &joined, (x, y));
            gpu::record(&mut pass, key_spheres, &keys, (x, y));
            drop(pass);
            sort.encode(gpu, encoder, &g.keys, &g.ids, n, key_bits(g.layout.cells));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.grid.build.gather"),
                timestamp_writes: None,
            });
            gpu::record(&mut pass, gather, &gathered, (x, y));
        };
        if build == BuildKind::Sorted {
            return self
                .detection
                .submit_build(what, (n, mode), (grid, output), record_sorted);
        }
        let record = |gpu: &Gpu, g: &Grid, encoder: &mut wgpu::CommandEncoder| {
            let table = g.table.as_ref().expect("a dense build has a table");
            let joined = record_upload(gpu, join, g, upload, encoder);
            let scan = self.scan.bind(gpu, &g.params, table);
            let count = gpu.bind(
                "mochi.grid.count_cells",
                &self.count_cells,
                &[
                    (grid_build::PARAMS, &g.params),
                    (grid_build::SPHERES_IN, &g.spheres_in),
                    (grid_build::SLOTS, &g.slots),
                    (grid_build::COUNTS, &table.counts),
                ],
            );
            let scatter = gpu.bind(
                "mochi.grid.scatter",
                &self.scatter,
                &[
                    (grid_build::PARAMS, &g.params),
                    (grid_build::SLOTS, &g.slots),
                    (grid_build::CELL_START, &table.cell_start),
                    (grid_build::IDS, &g.ids),
                ],
            );
            let gathered = gather_bind(gpu, gather, g);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.grid.build"),
                timestamp_writes: None,
            });
            gpu::record(&mut pass, join, &joined, (x, y));
            gpu::record(&mut pass, &self.count_cells, &count, (x, y));
            self.scan.record(&mut pass, &scan, &g.layout);
            gpu::record(&mut pass, &self.scatter, &scatter, (x, y));
            gpu::record(&mut pass, gather, &gathered, (x, y));
        };
        self.detection
            .submit_build(what, (n, mode), (grid, output), record)
    }
}

impl GpuBackend for WgpuComputeBackend {
    fn info(&self) -> BackendInfo {
        self.detection.info(self.max_spheres())
    }

    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        let max_spheres = self.max_spheres();
        let Some(n) = self.detection.begin_build(spheres, mode, max_spheres)? else {
            return Ok(());
        };
        let (build, layout) = self.layout(spheres, mode);
        let (grid, output) = self.detection.reuse_or_allocate(
            n,
            |g: &Grid| g.fits(n, build, layout.cells),
            |gpu| Grid::new(gpu, n, build, layout.cells),
        )?;
        let centre_bytes = n as usize * 12;
        self.detection
            .gpu
            .fill_upload(&grid.upload, 0..n as u64 * 16, |view| {
                let (centres, radii) = view.split_at(centre_bytes);
                gpu::copy_into(centres, spheres.centers());
                gpu::copy_into(radii, spheres.radii());
                Ok(())
            })?;
        self.submit((n, mode), (grid, output), (build, layout), Upload::Spheres)
    }

    fn finish(&mut self) -> Result<()> {
        self.detection.gpu.wait()
    }

    fn takes_centers(&self) -> bool {
        true
    }

    /// Uploads the centres straight into the grid's upload, checked as they are copied (a
    /// refused centre leaves the build as it was), and rebuilds in the last layout, not waiting
    /// for the GPU (the pairs' read-back does); spheres that moved out of that layout are built
    /// afresh, their radii read back.
    fn move_centers(&mut self, centers: &[[f32; 3]]) -> Result<bool> {
        let (n, mode) = self
            .detection
            .built()
            .expect("the caller checked the build");
        let Some(grid) = self.detection.structure() else {
            return Ok(true); // No spheres, none moved.
        };
        let gpu = &self.detection.gpu;
        let survey = gpu.fill_upload(&grid.upload, 0..n as u64 * 12, |view| {
            let survey = Survey::of_centers;
            Ok(gpu::copy_surveyed(
                view,
                centers,
                survey,
                Survey::merge,
                Survey::empty,
            ))
        })?;
        let bounds = survey.into_bounds(n)?.expect("a built grid has spheres");
        let last = self.last_layout.filter(|last| {
            let chosen_for = LayoutFor {
                n,
                mode,
                structure: self.structure,
                grid_build: self.grid_build,
                ..last.chosen_for
            };
            last.serves(&chosen_for, bounds)
        });
        let Some(last) = last else {
            let radii = gpu.read(&grid.radii, n)?;
            let spheres = SphereSet::new(centers.to_vec(), radii)?;
            GpuBackend::build(self, spheres.view(), mode)?;
            return Ok(true);
        };
        let n = n as u32;
        // The grid just written (same spheres and layout): reused, never allocated.
        let (grid, output) = self.detection.reuse_or_allocate(
            n,
            |_| true,
            |gpu| Grid::new(gpu, n, last.build, last.layout.cells),
        )?;
        self.submit(
            (n, mode),
            (grid, output),
            (last.build, last.layout),
            Upload::Centres,
        )?;
        Ok(true)
    }

    fn built(&self) -> Option<(usize, ProxyMode)> {
        self.detection.built()
    }

    fn detect(&mut self, take: Option<TakePairs<'_>>) -> Result<DetectStats> {
        let sorted = self
            .detection
            .structure()
            .is_some_and(|g| g.build == BuildKind::Sorted);
        let pipeline = match sorted {
            true => &self.find_pairs_sorted,
            false => &self.find_pairs,
        };
        let kernel = DetectKernel {
            label: FIND_PAIRS,
            pipeline,
            group: PAIRS_GROUP,
            what: "running the wgpu-compute grid search",
        };
        self.detection
            .detect(take, kernel, |gpu, grid, output, run| {
                let params = GridParams {
                    row: run.row,
                    capacity: run.capacity,
                    ..grid.layout
                };
                gpu.write_uniform(&grid.pair_params, &params);
                let cells = match grid.build {
                    BuildKind::Dense => {
                        let table = grid.table.as_ref().expect("a dense build has a table");
                        (grid_pairs::CELL_START, &table.cell_start)
                    }
                    BuildKind::Sorted => (CELL_KEYS, &grid.keys),
                };
                gpu.bind(
                    FIND_PAIRS,
                    pipeline,
                    &[
                        (grid_pairs::PARAMS, &grid.pair_params),
                        (grid_pairs::SPHERES, &grid.spheres),
                        (grid_pairs::IDS, &grid.ids),
                        (pair_output::COUNTERS, &output.counters),
                        (pair_output::PAIRS, &output.pairs),
                        cells,
                    ],
                )
            })
    }

    fn gpu_times(&self) -> GpuTimes {
        self.detection.gpu_times()
    }

    fn structure(&self) -> Option<String> {
        let grid = self.detection.structure()?;
        Some(describe_layout(&grid.layout, grid.build))
    }
}

/// Writes `g`'s parameters, records the copies of what its upload holds (`upload`) into its
/// centres and radii, and returns the bind group of `grid_build`'s `join_spheres` over `g`.
fn record_upload(
    gpu: &Gpu,
    join: &wgpu::ComputePipeline,
    g: &Grid,
    upload: Upload,
    encoder: &mut wgpu::CommandEncoder,
) -> wgpu::BindGroup {
    gpu.write_uniform(&g.params, &g.layout);
    let centre_bytes = g.n as u64 * 12;
    encoder.copy_buffer_to_buffer(&g.upload, 0, &g.centres, 0, centre_bytes);
    if upload == Upload::Spheres {
        encoder.copy_buffer_to_buffer(&g.upload, centre_bytes, &g.radii, 0, g.n as u64 * 4);
    }
    gpu.bind(
        "mochi.grid.join_spheres",
        join,
        &[
            (grid_build::PARAMS, &g.params),
            (grid_build::CENTRES, &g.centres),
            (grid_build::RADII, &g.radii),
            (grid_build::JOINED, &g.spheres_in),
        ],
    )
}

/// The bind group of `grid_build`'s `gather` over `g`: the spheres fetched in the order of
/// `g.ids`.
fn gather_bind(gpu: &Gpu, gather: &wgpu::ComputePipeline, g: &Grid) -> wgpu::BindGroup {
    gpu.bind(
        "mochi.grid.gather",
        gather,
        &[
            (grid_build::PARAMS, &g.params),
            (grid_build::SPHERES_IN, &g.spheres_in),
            (grid_build::IDS, &g.ids),
            (grid_build::SPHERES, &g.spheres),
        ],
    )
}
