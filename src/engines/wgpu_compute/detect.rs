//! Detection on the wgpu-compute engine: [`WgpuComputeBackend`] implements [`crate::Backend`].

use super::cell_table::{CellScan, CellTable};
use super::layout::{
    Budget, DETECT_CELLS_PER_SPHERE, GridParams, LayoutRequest, MAX_CROWDING, Structure,
    choose_layout, core_bounds, crowding, describe_layout,
};

use super::shaders::{grid_build, grid_pairs};
use crate::detect::BackendInfo;
use crate::engines::rebuilding::RebuildingBackend;
use crate::error::{Error, Result};
use crate::gpu::pair_output::{self, PairOutput};
use crate::gpu::timer::{self, GpuTimer, Span};
use crate::gpu::{self, Gpu, Need};
use crate::proxy::ProxyMode;
use crate::spheres::SphereSet;
use crate::types::Pair;
use crate::types::{DetectStats, GpuTimes};

/// Timer spans of a build and of a detection pass.
const BUILD_SPAN: Span = Span(0);
const DETECT_SPAN: Span = Span(1);

/// Workgroup sizes, as in the shaders.
const BUILD_GROUP: u32 = 256;
const PAIRS_GROUP: u32 = 256;

/// The wgpu compute (sorted grid) backend.
pub struct WgpuComputeBackend {
    gpu: Gpu,
    scan: CellScan,
    count_cells: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    find_pairs: wgpu::ComputePipeline,
    built: Option<Built>,
    structure: Structure,
    timer: Option<GpuTimer>,
    times: GpuTimes,
}

/// What one build leaves on the GPU.
struct Built {
    n: u32,
    mode: ProxyMode,
    params: GridParams,
    /// `None` for an empty set.
    grid: Option<Grid>,
    output: PairOutput,
}

/// GPU buffers of a grid over `n` spheres.
struct Grid {
    n: u32,
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
            find_pairs: gpu.pipeline("mochi.grid.find_pairs", &pairs, "find_pairs"),
            built: None,
            structure: Structure::Auto,
            timer: GpuTimer::new(&gpu, 2),
            times: GpuTimes::default(),
            gpu,
        })
    }

    /// Builds `structure` from now on.
    pub fn with_structure(mut self, structure: Structure) -> Self {
        self.structure = structure;
        self
    }

    fn max_spheres(&self) -> u64 {
        let l = &self.gpu.limits;
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
        choose_layout(&self.gpu.limits, &request)
    }
}

impl RebuildingBackend for WgpuComputeBackend {
    fn info(&self) -> BackendInfo {
        BackendInfo {
            name: "wgpu-compute",
            device: gpu::describe(&self.gpu.info),
            max_spheres: self.max_spheres(),
        }
    }

    fn rebuild(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        let n = spheres.len();
        if n as u64 > self.max_spheres() {
            return Err(Error::TooLarge {
                what: format!("spheres for wgpu-compute on {}", self.gpu.info.name),
                got: n as u64,
                limit: self.max_spheres(),
            });
        }
        let n = n as u32;
        if n == 0 {
            let output = PairOutput::new(&self.gpu, 1);
            let params = GridParams::default();
            self.built = Some(Built {
                n,
                mode,
                params,
                grid: None,
                output,
            });
            return Ok(());
        }
        let gpu = &self.gpu;
        let (x, y) = gpu.grid(n, BUILD_GROUP);
        let params = GridParams {
            row: x * BUILD_GROUP,
            ..self.layout(spheres, mode)
        };
        let (grid, output) = match self.built.take() {
            Some(Built {
                grid: Some(g),
                output,
                ..
            }) if g.n == n && g.table.capacity >= params.cells => (g, output),
            _ => gpu.checked("allocating the wgpu-compute buffers", || {
                (
                    Grid::new(gpu, n, params.cells),
                    PairOutput::new(gpu, n.max(1024)),
                )
            })?,
        };
        let rows: Vec<[f32; 4]> = spheres.xyzr().collect();
        gpu.checked("building the wgpu-compute grid", || {
            gpu.write_uniform(&grid.params, &params);
            gpu.queue
                .write_buffer(&grid.spheres_in, 0, bytemuck::cast_slice(&rows));
            let g = &grid;
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
            gpu.submit_timed(self.timer.as_ref(), BUILD_SPAN, |encoder| {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("mochi.grid.build"),
                    timestamp_writes: None,
                });
                gpu::record(&mut pass, &self.count_cells, &count, (x, y));
                self.scan.record(&mut pass, &scan, &params);
                gpu::record(&mut pass, &self.scatter, &scatter, (x, y));
                gpu::record(&mut pass, &self.gather, &gather, (x, y));
            });
        })?;
        gpu.wait()?;
        self.times = GpuTimes {
            build_ms: timer::read_ms(gpu, self.timer.as_ref(), BUILD_SPAN)?,
            detect_ms: None,
        };
        self.built = Some(Built {
            n,
            mode,
            params,
            grid: Some(grid),
            output,
        });
        Ok(())
    }

    fn built(&self) -> Option<(usize, ProxyMode)> {
        self.built.as_ref().map(|b| (b.n as usize, b.mode))
    }

    /// Runs the detection pass; with `collect`, grows the output until every pair fits.
    fn detect(&mut self, collect: bool) -> Result<(Vec<Pair>, DetectStats)> {
        let gpu = &self.gpu;
        let built = self
            .built
            .as_mut()
            .ok_or_else(|| Error::Usage("detection asked for before build".into()))?;
        let Some(grid) = built.grid.as_ref() else {
            return Ok((Vec::new(), DetectStats::default()));
        };
        let (x, y) = gpu.grid(built.n, PAIRS_GROUP);
        let base = built.params;
        let find_pairs = &self.find_pairs;
        let timer = self.timer.as_ref();
        let result = built.output.detect(gpu, collect, |output, capacity| {
            let params = GridParams {
                row: x * PAIRS_GROUP,
                capacity,
                ..base
            };
            gpu.checked("running the wgpu-compute grid search", || {
                gpu.write_uniform(&grid.pair_params, &params);
                let bind = gpu.bind(
                    "mochi.grid.find_pairs",
                    find_pairs,
                    &[
                        (grid_pairs::PARAMS, &grid.pair_params),
                        (grid_pairs::SPHERES, &grid.spheres),
                        (grid_pairs::IDS, &grid.ids),
                        (pair_output::COUNTERS, &output.counters),
                        (pair_output::PAIRS, &output.pairs),
                        (grid_pairs::CELL_START, &grid.table.cell_start),
                    ],
                );
                gpu.submit_timed(timer, DETECT_SPAN, |encoder| {
                    gpu.dispatch(encoder, "mochi.grid.find_pairs", find_pairs, &bind, (x, y));
                });
            })
        })?;
        self.times.detect_ms = timer::read_ms(gpu, timer, DETECT_SPAN)?;
        Ok(result)
    }

    fn gpu_times(&self) -> GpuTimes {
        self.times
    }

    fn structure(&self) -> Option<String> {
        let built = self.built.as_ref()?;
        built.grid.as_ref()?;
        Some(describe_layout(&built.params))
    }
}
