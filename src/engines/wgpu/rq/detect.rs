//! Detection on the wgpu-rq engine: [`WgpuRqBackend`] implements [`crate::Backend`].

use super::accel::Accel;
use super::shaders::rq_build::{self, BuildParams};
use super::shaders::rq_pairs::{self, PairParams};
use crate::detect::BackendInfo;
use crate::engines::common::detect::GpuBackend;
use crate::engines::wgpu::detection::{DetectKernel, WgpuDetection};
use crate::error::Result;
use crate::gpu::AABB_STRIDE;
use crate::gpu::pair_output::TakePairs;
use crate::gpu::radix_sort::RadixSort;
use crate::gpu::{Gpu, Need};
use crate::morton;
use crate::proxy::BOX_PADDING;
use crate::proxy::ProxyMode;
use crate::spheres::Spheres;
use crate::types::{DetectStats, GpuTimes};

/// Workgroup sizes, as in the shaders.
const BUILD_GROUP: u32 = 256;
const PAIRS_GROUP: u32 = 64;

/// The wgpu ray-query backend.
pub struct WgpuRqBackend {
    detection: WgpuDetection<Accel>,
    sort: RadixSort,
    morton_keys: wgpu::ComputePipeline,
    proxy_boxes: wgpu::ComputePipeline,
    find_pairs: wgpu::ComputePipeline,
    /// Most primitives in one BLAS (the adapter's limit, or lower for tests).
    blas_capacity: u32,
}

impl WgpuRqBackend {
    /// Opens the best adapter with ray queries.
    pub fn new() -> Result<Self> {
        let gpu = Gpu::open(Need::RayQuery)?;
        let build = gpu.own_module("mochi.rq.build", rq_build::SOURCE);
        let pairs = gpu.own_module("mochi.rq.pairs", rq_pairs::SOURCE);
        Ok(Self {
            sort: RadixSort::new(&gpu),
            morton_keys: gpu.pipeline("mochi.rq.morton_keys", &build, "morton_keys"),
            proxy_boxes: gpu.pipeline("mochi.rq.proxy_boxes", &build, "proxy_boxes"),
            find_pairs: gpu.pipeline("mochi.rq.find_pairs", &pairs, "find_pairs"),
            blas_capacity: gpu.limits.max_blas_primitive_count,
            detection: WgpuDetection::new("wgpu-rq", gpu),
        })
    }

    /// Caps the primitives per BLAS below the adapter's limit, so that splitting a scene over
    /// several BLAS can be exercised on small inputs.
    pub fn with_blas_capacity(mut self, primitives: u32) -> Self {
        let limit = self.detection.gpu.limits.max_blas_primitive_count;
        self.blas_capacity = primitives.clamp(1, limit);
        self
    }

    fn max_spheres(&self) -> u64 {
        let l = &self.detection.gpu.limits;
        let by_binding = l.max_storage_buffer_binding_size / AABB_STRIDE;
        let by_buffer = l.max_buffer_size / AABB_STRIDE;
        let by_accel = self.blas_capacity as u64 * l.max_tlas_instance_count as u64;
        by_binding.min(by_buffer).min(by_accel).min(u32::MAX as u64)
    }
}

impl GpuBackend for WgpuRqBackend {
    fn info(&self) -> BackendInfo {
        self.detection.info(self.max_spheres())
    }

    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        let max_spheres = self.max_spheres();
        let Some(n) = self.detection.begin_build(spheres, mode, max_spheres)? else {
            return Ok(());
        };
        let chunk = self.blas_capacity.min(n);
        let structure = self.detection.reuse_or_allocate(
            n,
            |a: &Accel| a.n == n && a.chunk == chunk,
            |gpu| Accel::new(gpu, n, chunk),
        )?;
        let (lo, hi) = spheres.bounds().expect("the set is not empty");
        let (x, y) = self.detection.gpu.grid(n, BUILD_GROUP);
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
        let what = "building the wgpu-rq acceleration structure";
        let record = |gpu: &Gpu, accel: &Accel, encoder: &mut wgpu::CommandEncoder| {
            gpu.write_uniform(&accel.build_params, &params);
            gpu.queue
                .write_buffer(&accel.spheres_in, 0, bytemuck::cast_slice(&rows));
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
        };
        self.detection
            .submit_build(what, (n, mode), structure, record)
    }

    fn finish(&mut self) -> Result<()> {
        self.detection.gpu.wait()
    }

    fn built(&self) -> Option<(usize, ProxyMode)> {
        self.detection.built()
    }

    fn detect(&mut self, take: Option<TakePairs<'_>>) -> Result<DetectStats> {
        let kernel = DetectKernel {
            label: "mochi.rq.find_pairs",
            pipeline: &self.find_pairs,
            group: PAIRS_GROUP,
            what: "running the wgpu-rq ray queries",
        };
        self.detection
            .detect(take, kernel, |gpu, accel, output, run| {
                let params = PairParams {
                    n: run.n,
                    capacity: run.capacity,
                    mode: run.mode.code(),
                    chunk: accel.chunk,
                    row: run.row,
                };
                gpu.write_uniform(&accel.pair_params, &params);
                accel.pairs_bind(gpu, &self.find_pairs, output)
            })
    }

    fn gpu_times(&self) -> GpuTimes {
        self.detection.gpu_times()
    }
}
