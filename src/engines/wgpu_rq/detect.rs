//! Detection on the wgpu-rq engine: [`WgpuRqBackend`] implements [`crate::Backend`].

use super::accel::Accel;
use super::shaders::rq_build::{self, BuildParams};
use super::shaders::rq_pairs::{self, PairParams};
use crate::detect::BackendInfo;
use crate::engines::rebuilding::RebuildingBackend;
use crate::error::{Error, Result};
use crate::gpu::AABB_STRIDE;
use crate::gpu::pair_output::PairOutput;
use crate::gpu::radix_sort::RadixSort;
use crate::gpu::timer::{self, GpuTimer, Span};
use crate::gpu::{self, Gpu, Need};
use crate::morton;
use crate::proxy::BOX_PADDING;
use crate::proxy::ProxyMode;
use crate::spheres::SphereSet;
use crate::types::Pair;
use crate::types::{DetectStats, GpuTimes};

/// Timer spans of a build and of a detection pass.
const BUILD_SPAN: Span = Span(0);
const DETECT_SPAN: Span = Span(1);

/// Workgroup sizes, as in the shaders.
const BUILD_GROUP: u32 = 256;
const PAIRS_GROUP: u32 = 64;

/// The wgpu ray-query backend.
pub struct WgpuRqBackend {
    gpu: Gpu,
    sort: RadixSort,
    morton_keys: wgpu::ComputePipeline,
    proxy_boxes: wgpu::ComputePipeline,
    find_pairs: wgpu::ComputePipeline,
    /// Most primitives in one BLAS (the adapter's limit, or lower for tests).
    blas_capacity: u32,
    built: Option<Built>,
    timer: Option<GpuTimer>,
    times: GpuTimes,
}

/// What one build leaves on the GPU.
struct Built {
    n: u32,
    mode: ProxyMode,
    /// `None` for an empty set.
    accel: Option<Accel>,
    output: PairOutput,
}

impl WgpuRqBackend {
    /// Opens the best adapter with ray queries.
    pub fn new() -> Result<Self> {
        let gpu = Gpu::open(Need::RayQuery)?;
        let build = gpu.module("mochi.rq.build", rq_build::SOURCE);
        let pairs = gpu.module("mochi.rq.pairs", rq_pairs::SOURCE);
        Ok(Self {
            sort: RadixSort::new(&gpu),
            morton_keys: gpu.pipeline("mochi.rq.morton_keys", &build, "morton_keys"),
            proxy_boxes: gpu.pipeline("mochi.rq.proxy_boxes", &build, "proxy_boxes"),
            find_pairs: gpu.pipeline("mochi.rq.find_pairs", &pairs, "find_pairs"),
            blas_capacity: gpu.limits.max_blas_primitive_count,
            built: None,
            timer: GpuTimer::new(&gpu, 2),
            times: GpuTimes::default(),
            gpu,
        })
    }

    /// Caps the primitives per BLAS below the adapter's limit, so that splitting a scene over
    /// several BLAS can be exercised on small inputs.
    pub fn with_blas_capacity(mut self, primitives: u32) -> Self {
        self.blas_capacity = primitives.clamp(1, self.gpu.limits.max_blas_primitive_count);
        self
    }

    fn max_spheres(&self) -> u64 {
        let l = &self.gpu.limits;
        let by_binding = l.max_storage_buffer_binding_size / AABB_STRIDE;
        let by_buffer = l.max_buffer_size / AABB_STRIDE;
        let by_accel = self.blas_capacity as u64 * l.max_tlas_instance_count as u64;
        by_binding.min(by_buffer).min(by_accel).min(u32::MAX as u64)
    }
}

impl RebuildingBackend for WgpuRqBackend {
    fn info(&self) -> BackendInfo {
        BackendInfo {
            name: "wgpu-rq",
            device: gpu::describe(&self.gpu.info),
            max_spheres: self.max_spheres(),
        }
    }

    fn rebuild(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        let n = spheres.len();
        if n as u64 > self.max_spheres() {
            return Err(Error::TooLarge {
                what: format!("spheres for wgpu-rq on {}", self.gpu.info.name),
                got: n as u64,
                limit: self.max_spheres(),
            });
        }
        let n = n as u32;
        if n == 0 {
            let output = PairOutput::new(&self.gpu, 1);
            self.built = Some(Built {
                n,
                mode,
                accel: None,
                output,
            });
            return Ok(());
        }
        let gpu = &self.gpu;
        let (accel, output) = match self.built.take() {
            Some(Built {
                accel: Some(a),
                output,
                ..
            }) if a.n == n && a.chunk == self.blas_capacity.min(n) => (a, output),
            _ => gpu.checked("allocating the wgpu-rq buffers", || {
                let accel = Accel::new(gpu, n, self.blas_capacity.min(n));
                (accel, PairOutput::new(gpu, n.max(1024)))
            })?,
        };
        let (lo, hi) = spheres.bounds().expect("the set is not empty");
        let (x, y) = gpu.grid(n, BUILD_GROUP);
        let morton = morton::Grid::over(lo, hi);
        let params = BuildParams {
            lo: morton.lo.into(),
            n,
            scale: morton.scale.into(),
            mode: mode.code(),
            r_max: spheres.max_radius(),
            pad_rel: BOX_PADDING,
            row: x * BUILD_GROUP,
        };
        let rows: Vec<[f32; 4]> = spheres.xyzr().collect();
        gpu.checked("building the wgpu-rq acceleration structure", || {
            gpu.write_uniform(&accel.build_params, &params);
            gpu.queue
                .write_buffer(&accel.spheres_in, 0, bytemuck::cast_slice(&rows));
            gpu.submit_timed(self.timer.as_ref(), BUILD_SPAN, |encoder| {
                gpu.pass(
                    encoder,
                    "mochi.rq.morton_keys",
                    &self.morton_keys,
                    &[
                        (rq_build::PARAMS, &accel.build_params),
                        (rq_build::SPHERES_IN, &accel.spheres_in),
                        (rq_build::KEYS, &accel.keys),
                        (rq_build::ORDER, &accel.ids),
                    ],
                    (x, y),
                );
                self.sort
                    .encode(gpu, encoder, &accel.keys, &accel.ids, n, morton::KEY_BITS);
                gpu.pass(
                    encoder,
                    "mochi.rq.proxy_boxes",
                    &self.proxy_boxes,
                    &[
                        (rq_build::PARAMS, &accel.build_params),
                        (rq_build::SPHERES_IN, &accel.spheres_in),
                        (rq_build::ORDER, &accel.ids),
                        (rq_build::SPHERES_SORTED, &accel.spheres),
                        (rq_build::BOXES, &accel.boxes),
                    ],
                    (x, y),
                );
                accel.encode_build(encoder);
            });
        })?;
        // Finish here, so that a build's time is its own and its errors are reported by it.
        gpu.wait()?;
        self.times = GpuTimes {
            build_ms: timer::read_ms(gpu, self.timer.as_ref(), BUILD_SPAN)?,
            detect_ms: None,
        };
        self.built = Some(Built {
            n,
            mode,
            accel: Some(accel),
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
        let Some(accel) = built.accel.as_ref() else {
            return Ok((Vec::new(), DetectStats::default()));
        };
        let (x, y) = gpu.grid(built.n, PAIRS_GROUP);
        let find_pairs = &self.find_pairs;
        let (n, mode) = (built.n, built.mode);
        let timer = self.timer.as_ref();
        let result = built.output.detect(gpu, collect, |output, capacity| {
            let params = PairParams {
                n,
                capacity,
                mode: mode.code(),
                chunk: accel.chunk,
                row: x * PAIRS_GROUP,
            };
            gpu.checked("running the wgpu-rq ray queries", || {
                gpu.write_uniform(&accel.pair_params, &params);
                let bind = accel.pairs_bind(gpu, find_pairs, output);
                gpu.submit_timed(timer, DETECT_SPAN, |encoder| {
                    gpu.dispatch(encoder, "mochi.rq.find_pairs", find_pairs, &bind, (x, y));
                });
            })
        })?;
        self.times.detect_ms = timer::read_ms(gpu, timer, DETECT_SPAN)?;
        Ok(result)
    }

    fn gpu_times(&self) -> GpuTimes {
        self.times
    }
}
