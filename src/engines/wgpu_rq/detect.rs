//! Detection on the wgpu-rq engine: [`WgpuRqBackend`] implements [`crate::Backend`].

use super::accel::Accel;
use crate::detect::BackendInfo;
use crate::engines::rebuilding::RebuildingBackend;
use crate::error::{Error, Result};
use crate::gpu::pair_output::PairOutput;
use crate::gpu::radix_sort::RadixSort;
use crate::gpu::timer::{self, GpuTimer, Span};
use crate::gpu::{self, Gpu, Need};
use crate::proxy::BOX_PADDING;
use crate::proxy::ProxyMode;
use crate::spheres::SphereSet;
use crate::types::Pair;
use crate::types::{DetectStats, GpuTimes};

const BUILD_WGSL: &str = concat!(
    include_str!("../../../wgsl/proxy.wgsl"),
    include_str!("../../../wgsl/rq_build.wgsl")
);
const PAIRS_WGSL: &str = concat!(
    include_str!("../../../wgsl/rq_pairs.wgsl"),
    include_str!("../../../wgsl/rq_walk.wgsl"),
    include_str!("../../../wgsl/proxy.wgsl"),
    include_str!("../../../wgsl/pair_output.wgsl")
);

/// Every WGSL module of this backend, by label, exactly as the device gets it.
pub(crate) const SHADERS: [(&str, &str); 2] = [("rq_build", BUILD_WGSL), ("rq_pairs", PAIRS_WGSL)];

/// Timer spans of a build and of a detection pass.
const BUILD_SPAN: Span = Span(0);
const DETECT_SPAN: Span = Span(1);

/// Workgroup sizes, as in the shaders.
const BUILD_GROUP: u32 = 256;
const PAIRS_GROUP: u32 = 64;

/// Bits of the Morton keys (10 per axis).
const MORTON_BITS: u32 = 30;

/// Keep in sync with `BuildParams` in `wgsl/rq_build.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct BuildParams {
    lo: [f32; 3],
    n: u32,
    scale: [f32; 3],
    mode: u32,
    r_max: f32,
    pad_rel: f32,
    row: u32,
    _pad0: u32,
}
const _: () = assert!(size_of::<BuildParams>() == 48);

/// Keep in sync with `PairParams` in `wgsl/rq_pairs.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct PairParams {
    n: u32,
    capacity: u32,
    mode: u32,
    chunk: u32,
    row: u32,
    _pad: [u32; 3],
}
const _: () = assert!(size_of::<PairParams>() == 32);

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
        let build = gpu.module("mochi.rq.build", BUILD_WGSL);
        let pairs = gpu.module("mochi.rq.pairs", PAIRS_WGSL);
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
        let by_binding = l.max_storage_buffer_binding_size / 24;
        let by_buffer = l.max_buffer_size / 24;
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
        let params = BuildParams {
            lo,
            n,
            scale: std::array::from_fn(|a| {
                let extent = hi[a] - lo[a];
                if extent > 0.0 { 1023.0 / extent } else { 0.0 }
            }),
            mode: mode.code(),
            r_max: spheres.max_radius(),
            pad_rel: BOX_PADDING,
            row: x * BUILD_GROUP,
            _pad0: 0,
        };
        let rows: Vec<[f32; 4]> = spheres.xyzr().collect();
        gpu.checked("building the wgpu-rq acceleration structure", || {
            gpu.queue
                .write_buffer(&accel.build_params, 0, bytemuck::bytes_of(&params));
            gpu.queue
                .write_buffer(&accel.spheres_in, 0, bytemuck::cast_slice(&rows));
            gpu.submit_timed(self.timer.as_ref(), BUILD_SPAN, |encoder| {
                gpu.pass(
                    encoder,
                    "mochi.rq.morton_keys",
                    &self.morton_keys,
                    &[
                        (0, &accel.build_params),
                        (1, &accel.spheres_in),
                        (2, &accel.keys),
                        (3, &accel.ids),
                    ],
                    (x, y),
                );
                self.sort
                    .encode(gpu, encoder, &accel.keys, &accel.ids, n, MORTON_BITS);
                gpu.pass(
                    encoder,
                    "mochi.rq.proxy_boxes",
                    &self.proxy_boxes,
                    &[
                        (0, &accel.build_params),
                        (1, &accel.spheres_in),
                        (3, &accel.ids),
                        (4, &accel.spheres),
                        (5, &accel.boxes),
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
                _pad: [0; 3],
            };
            gpu.checked("running the wgpu-rq ray queries", || {
                gpu.queue
                    .write_buffer(&accel.pair_params, 0, bytemuck::bytes_of(&params));
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
