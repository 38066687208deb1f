//! GPU buffers and acceleration structures of one `wgpu-rq` build.

use super::shaders::rq_build::BuildParams;
use super::shaders::rq_pairs::{self, PairParams};
use crate::gpu::AABB_STRIDE;
use crate::gpu::Gpu;
use crate::gpu::pair_output::{self, PairOutput};

/// The buffers, BLAS and TLAS of a build over `n` spheres.
pub(crate) struct Accel {
    /// Number of spheres.
    pub n: u32,
    /// Primitives per BLAS (the last one may hold fewer).
    pub chunk: u32,
    pub build_params: wgpu::Buffer,
    pub pair_params: wgpu::Buffer,
    /// `vec4(x, y, z, r)` in input order.
    pub spheres_in: wgpu::Buffer,
    /// Morton keys, sorted by the build.
    pub keys: wgpu::Buffer,
    /// Input index of each sorted sphere.
    pub ids: wgpu::Buffer,
    /// `vec4(x, y, z, r)` in sorted order.
    pub spheres: wgpu::Buffer,
    /// Proxy boxes in sorted order, 6 floats each.
    pub boxes: wgpu::Buffer,
    /// One box buffer per BLAS when there are several (copied from `boxes`).
    chunk_boxes: Vec<wgpu::Buffer>,
    sizes: Vec<wgpu::BlasAABBGeometrySizeDescriptor>,
    blas: Vec<wgpu::Blas>,
    tlas: wgpu::Tlas,
}

impl Accel {
    /// Allocates everything for `n` spheres in BLAS of at most `chunk` primitives.
    pub fn new(gpu: &Gpu, n: u32, chunk: u32) -> Accel {
        use wgpu::BufferUsages as U;
        let n64 = n as u64;
        let chunks = n.div_ceil(chunk);
        let boxes = gpu.storage("mochi.rq.boxes", n64 * AABB_STRIDE, U::BLAS_INPUT);
        let chunk_boxes = if chunks > 1 {
            (0..chunks)
                .map(|k| {
                    let len = chunk.min(n - k * chunk) as u64;
                    gpu.storage("mochi.rq.chunk_boxes", len * AABB_STRIDE, U::BLAS_INPUT)
                })
                .collect()
        } else {
            Vec::new()
        };
        let sizes: Vec<_> = (0..chunks)
            .map(|k| wgpu::BlasAABBGeometrySizeDescriptor {
                primitive_count: chunk.min(n - k * chunk),
                flags: wgpu::AccelerationStructureGeometryFlags::empty(),
            })
            .collect();
        let blas = sizes
            .iter()
            .map(|size| {
                gpu.device.create_blas(
                    &wgpu::CreateBlasDescriptor {
                        label: Some("mochi.rq.blas"),
                        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
                    },
                    wgpu::BlasGeometrySizeDescriptors::AABBs {
                        descriptors: vec![size.clone()],
                    },
                )
            })
            .collect::<Vec<_>>();
        let mut tlas = gpu.device.create_tlas(&wgpu::CreateTlasDescriptor {
            label: Some("mochi.rq.tlas"),
            max_instances: chunks,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        });
        const IDENTITY: [f32; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        for (k, b) in blas.iter().enumerate() {
            tlas[k] = Some(wgpu::TlasInstance::new(b, IDENTITY, k as u32, 0xff));
        }
        Accel {
            n,
            chunk,
            build_params: gpu.uniform("mochi.rq.build_params", &BuildParams::default()),
            pair_params: gpu.uniform("mochi.rq.pair_params", &PairParams::default()),
            spheres_in: gpu.storage("mochi.rq.spheres_in", n64 * 16, U::empty()),
            keys: gpu.storage("mochi.rq.keys", n64 * 4, U::empty()),
            ids: gpu.storage("mochi.rq.ids", n64 * 4, U::empty()),
            spheres: gpu.storage("mochi.rq.spheres", n64 * 16, U::empty()),
            boxes,
            chunk_boxes,
            sizes,
            blas,
            tlas,
        }
    }

    /// Records the copies into the per-BLAS box buffers and the BLAS and TLAS builds.
    pub fn encode_build(&self, encoder: &mut wgpu::CommandEncoder) {
        for (k, dst) in self.chunk_boxes.iter().enumerate() {
            let offset = k as u64 * self.chunk as u64 * AABB_STRIDE;
            encoder.copy_buffer_to_buffer(
                &self.boxes,
                offset,
                dst,
                0,
                dst.size().min(self.boxes.size() - offset),
            );
        }
        let inputs: Vec<&wgpu::Buffer> = if self.chunk_boxes.is_empty() {
            vec![&self.boxes]
        } else {
            self.chunk_boxes.iter().collect()
        };
        let entries: Vec<_> = self
            .blas
            .iter()
            .zip(&self.sizes)
            .zip(inputs)
            .map(|((blas, size), aabb_buffer)| wgpu::BlasBuildEntry {
                blas,
                geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
                    size,
                    stride: AABB_STRIDE,
                    aabb_buffer,
                    primitive_offset: 0,
                }]),
            })
            .collect();
        encoder.build_acceleration_structures(&entries, [&self.tlas]);
    }

    /// The top-level acceleration structure (one instance per BLAS).
    pub fn tlas(&self) -> &wgpu::Tlas {
        &self.tlas
    }

    /// The bind group of the detection shader over this build and `output`.
    pub fn pairs_bind(
        &self,
        gpu: &Gpu,
        pipeline: &wgpu::ComputePipeline,
        output: &PairOutput,
    ) -> wgpu::BindGroup {
        gpu.bind_with_tlas(
            "mochi.rq.find_pairs",
            pipeline,
            &[
                (rq_pairs::PARAMS, &self.pair_params),
                (rq_pairs::SPHERES, &self.spheres),
                (rq_pairs::IDS, &self.ids),
                (pair_output::COUNTERS, &output.counters),
                (pair_output::PAIRS, &output.pairs),
            ],
            (rq_pairs::TLAS, &self.tlas),
        )
    }
}
