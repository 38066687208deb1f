//! Detection on the wgpu-compute engine: [`WgpuComputeBackend`] implements [`crate::Backend`].

use super::cell_table::{CellScan, CellTable};
use super::layout::{
    Budget, DETECT_CELLS_PER_SPHERE, GridParams, LayoutRequest, MAX_CROWDING, Structure,
    choose_layout, core_bounds, crowding, describe_layout,
};

use super::shaders::{grid_build, grid_pairs};
use crate::detect::BackendInfo;
use crate::engines::gpu_detect::{DetectKernel, GpuBackend, WgpuDetection};
use crate::error::Result;
use crate::gpu::pair_output;
use crate::gpu::{self, Gpu, Need};
use crate::proxy::ProxyMode;
use crate::spheres::SphereSet;
use crate::types::Pair;
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
    count_cells: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    find_pairs: wgpu::ComputePipeline,
    structure: Structure,
}

/// GPU buffers of a grid over `n` spheres, and the layout of its last build.
struct Grid {
    n: u32,
    layout: GridParams,
    params: wgpu::Buffer,
    pair_params: wgpu::Buffer,
    /// `vec4(x, y, z, r)` in input order.
    spheres_in: wgpu::Buffer,
    /// Cell key and rank among the spheres of that cell of each sphere, in input order.
    slots: wgpu::Buffer,
    /// Input index of each sorted sphere.
    ids: wgpu::Buffer,
    /// `vec4(x, y, z, r)` in sorted order.
    spheres: wgpu::Buffer,
    table: CellTable,
}

impl Grid {
    fn new(gpu: &Gpu, n: u32, cells: u32) -> Grid {
        let none = wgpu::BufferUsages::empty();
        let n64 = n as u64;
        Grid {
            n,
            layout: GridParams::default(),
            params: gpu.uniform("mochi.grid.params", &GridParams::default()),
            pair_params: gpu.uniform("mochi.grid.pair_params", &GridParams::default()),
            spheres_in: gpu.storage("mochi.grid.spheres_in", n64 * 16, none),
            slots: gpu.storage("mochi.grid.slots", n64 * 8, none),
            ids: gpu.storage("mochi.grid.ids", n64 * 4, none),
            spheres: gpu.storage("mochi.grid.spheres", n64 * 16, none),
            table: CellTable::new(gpu, cells),
        }
    }
}

impl WgpuComputeBackend {
    /// Opens the best adapter with compute shaders.
    pub fn new() -> Result<Self> {
        let gpu = Gpu::open(Need::Compute)?;
        let build = gpu.module("mochi.grid.build", grid_build::SOURCE);
        let pairs = gpu.module("mochi.grid.pairs", grid_pairs::SOURCE);
        Ok(Self {
            scan: CellScan::new(&gpu),
            count_cells: gpu.pipeline("mochi.grid.count_cells", &build, "count_cells"),
            scatter: gpu.pipeline("mochi.grid.scatter", &build, "scatter"),
            gather: gpu.pipeline("mochi.grid.gather", &build, "gather"),
            find_pairs: gpu.pipeline(FIND_PAIRS, &pairs, "find_pairs"),
            structure: Structure::Auto,
            detection: WgpuDetection::new("wgpu-compute", gpu),
        })
    }

    /// Builds `structure` from now on.
    pub fn with_structure(mut self, structure: Structure) -> Self {
        self.structure = structure;
        self
    }

    fn max_spheres(&self) -> u64 {
        let l = &self.detection.gpu.limits;
        (l.max_storage_buffer_binding_size.min(l.max_buffer_size) / 16).min(u32::MAX as u64)
    }

    /// Cell layout for `spheres` (see [`choose_layout`]) over their [`core_bounds`].
    fn layout(&self, spheres: &SphereSet, mode: ProxyMode) -> GridParams {
        let (lo, hi) = core_bounds(spheres).expect("the set is not empty");
        let base = mode.cell_size(spheres.max_radius()) as f64;
        let uncrowded = |size: f64| crowding(spheres.centers(), lo, size) <= MAX_CROWDING;
        let radii = (spheres.min_radius() as f64, spheres.max_radius() as f64);
        let budget = Budget {
            spheres: spheres.len() as u64,
            cells_per_sphere: DETECT_CELLS_PER_SPHERE,
        };
        let request = LayoutRequest {
            levels: self.structure.levels_for(mode, radii.1 / radii.0),
            bounds: (lo, hi),
            budget,
            base_cell: base,
            radii,
            dense_check: &uncrowded,
        };
        choose_layout(&self.detection.gpu.limits, &request)
    }
}

impl GpuBackend for WgpuComputeBackend {
    fn info(&self) -> BackendInfo {
        self.detection.info(self.max_spheres())
    }

    fn build(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        let max_spheres = self.max_spheres();
        let Some(n) = self.detection.begin_build(spheres, mode, max_spheres)? else {
            return Ok(());
        };
        let (x, y) = self.detection.gpu.grid(n, BUILD_GROUP);
        let layout = GridParams {
            row: x * BUILD_GROUP,
            ..self.layout(spheres, mode)
        };
        let (mut grid, output) = self.detection.reuse_or_allocate(
            n,
            |g: &Grid| g.n == n && g.table.capacity >= layout.cells,
            |gpu| Grid::new(gpu, n, layout.cells),
        )?;
        grid.layout = layout;
        let rows: Vec<[f32; 4]> = spheres.xyzr().collect();
        let what = "building the wgpu-compute grid";
        let record = |gpu: &Gpu, g: &Grid, encoder: &mut wgpu::CommandEncoder| {
            gpu.write_uniform(&g.params, &g.layout);
            gpu.queue
                .write_buffer(&g.spheres_in, 0, bytemuck::cast_slice(&rows));
            let scan = self.scan.bind(gpu, &g.params, &g.table);
            let count = gpu.bind(
                "mochi.grid.count_cells",
                &self.count_cells,
                &[
                    (grid_build::PARAMS, &g.params),
                    (grid_build::SPHERES_IN, &g.spheres_in),
                    (grid_build::SLOTS, &g.slots),
                    (grid_build::COUNTS, &g.table.counts),
                ],
            );
            let scatter = gpu.bind(
                "mochi.grid.scatter",
                &self.scatter,
                &[
                    (grid_build::PARAMS, &g.params),
                    (grid_build::SLOTS, &g.slots),
                    (grid_build::CELL_START, &g.table.cell_start),
                    (grid_build::IDS, &g.ids),
                ],
            );
            let gather = gpu.bind(
                "mochi.grid.gather",
                &self.gather,
                &[
                    (grid_build::PARAMS, &g.params),
                    (grid_build::SPHERES_IN, &g.spheres_in),
                    (grid_build::IDS, &g.ids),
                    (grid_build::SPHERES, &g.spheres),
                ],
            );
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.grid.build"),
                timestamp_writes: None,
            });
            gpu::record(&mut pass, &self.count_cells, &count, (x, y));
            self.scan.record(&mut pass, &scan, &g.layout);
            gpu::record(&mut pass, &self.scatter, &scatter, (x, y));
            gpu::record(&mut pass, &self.gather, &gather, (x, y));
        };
        self.detection
            .finish_build(what, (n, mode), (grid, output), record)
    }

    fn built(&self) -> Option<(usize, ProxyMode)> {
        self.detection.built()
    }

    fn detect(&mut self, collect: bool) -> Result<(Vec<Pair>, DetectStats)> {
        let kernel = DetectKernel {
            label: FIND_PAIRS,
            pipeline: &self.find_pairs,
            group: PAIRS_GROUP,
            what: "running the wgpu-compute grid search",
        };
        self.detection
            .detect(collect, kernel, |gpu, grid, output, run| {
                let params = GridParams {
                    row: run.row,
                    capacity: run.capacity,
                    ..grid.layout
                };
                gpu.write_uniform(&grid.pair_params, &params);
                gpu.bind(
                    FIND_PAIRS,
                    &self.find_pairs,
                    &[
                        (grid_pairs::PARAMS, &grid.pair_params),
                        (grid_pairs::SPHERES, &grid.spheres),
                        (grid_pairs::IDS, &grid.ids),
                        (pair_output::COUNTERS, &output.counters),
                        (pair_output::PAIRS, &output.pairs),
                        (grid_pairs::CELL_START, &grid.table.cell_start),
                    ],
                )
            })
    }

    fn gpu_times(&self) -> GpuTimes {
        self.detection.gpu_times()
    }

    fn structure(&self) -> Option<String> {
        Some(describe_layout(&self.detection.structure()?.layout))
    }
}
