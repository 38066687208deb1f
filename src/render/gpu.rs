//! The GPU render paths: `wgpu-rq` (ray queries over a BLAS of the spheres' boxes) and
//! `wgpu-compute` (our own BVH, traversed in WGSL); both share `wgsl/render/render_common.wgsl` and
//! differ only in `trace`.

use super::Picture;
use super::bvh::Node;
use super::scene::Scene;
use super::shaders::{
    BVH_SOURCE, COLOURS, ENTRY_POINT, NODES, PIXELS, RQ_SOURCE, SPHERES, TLAS, VIEW, View,
    WALL_NODES, WALLS,
};
use crate::error::{Error, Result};
use crate::gpu::AABB_STRIDE;
use crate::gpu::shader::storage_bytes;
use crate::gpu::{self, Gpu, Need};
use encase::ShaderSize;

/// Workgroup side, as in `wgsl/render/render_common.wgsl` (8×8 pixels).
const GROUP: u32 = 8;

/// A GPU render path on an open device.
pub(crate) struct GpuRenderer {
    gpu: Gpu,
    pipeline: wgpu::ComputePipeline,
    ray_query: bool,
}

impl GpuRenderer {
    /// Opens the best adapter for the path: with ray queries (`ray_query`), or any.
    pub fn open(ray_query: bool) -> Result<Self> {
        let (need, source, label) = if ray_query {
            (Need::RayQuery, RQ_SOURCE, "mochi.render.rq")
        } else {
            (Need::Compute, BVH_SOURCE, "mochi.render.bvh")
        };
        let gpu = Gpu::open(need)?;
        let pipeline = gpu.checked("compiling the render shader", || {
            let module = gpu.own_module(label, source);
            gpu.pipeline(label, &module, ENTRY_POINT)
        })?;
        Ok(Self {
            gpu,
            pipeline,
            ray_query,
        })
    }

    /// The adapter, in one line.
    pub fn device(&self) -> String {
        gpu::describe(&self.gpu.info)
    }

    /// The pixels of `picture` of `scene` (not empty), row by row.
    pub fn render(&self, scene: &Scene, picture: &Picture) -> Result<Vec<u32>> {
        let n = scene.len() as u32;
        let pixels_len = picture.width as u64 * picture.height as u64;
        let limit = self.gpu.limits.max_storage_buffer_binding_size;
        for (what, bytes) in [
            ("pixels", pixels_len * 4),
            ("spheres", n as u64 * 16),
            (
                "tree nodes",
                scene.nodes.len() as u64 * Node::SHADER_SIZE.get(),
            ),
            ("wall triangles", scene.walls.len() as u64 * 16),
            (
                "wall tree nodes",
                scene.wall_nodes.len() as u64 * Node::SHADER_SIZE.get(),
            ),
        ] {
            if bytes > limit {
                return Err(Error::TooLarge {
                    what: format!("bytes of {what} in one GPU buffer"),
                    got: bytes,
                    limit,
                });
            }
        }
        if self.ray_query && n > self.gpu.limits.max_blas_primitive_count {
            return Err(Error::TooLarge {
                what: "spheres in one BLAS".into(),
                got: n as u64,
                limit: self.gpu.limits.max_blas_primitive_count as u64,
            });
        }
        let grid = picture.camera.grid(picture.width, picture.height);
        let floor = picture.floor();
        let view = View {
            eye: grid.eye.into(),
            width: picture.width,
            corner: grid.corner.into(),
            height: picture.height,
            right: grid.right.into(),
            samples: picture.samples,
            down: grid.down.into(),
            shadows: picture.shadows as u32,
            light: grid.light.into(),
            n,
            floor_lo: floor.map_or([0.0; 3], |f| f.lo.to_array()).into(),
            floor_on: floor.is_some() as u32,
            floor_hi: floor.map_or([0.0; 3], |f| f.hi.to_array()).into(),
            walls: scene.wall_triangles() as u32,
        };
        let gpu = &self.gpu;
        let pixels = gpu.checked("rendering", || {
            let upload = |label: &str, bytes: &[u8], extra| {
                let buffer = gpu.storage(label, bytes.len() as u64, extra);
                gpu.queue.write_buffer(&buffer, 0, bytes);
                buffer
            };
            let none = wgpu::BufferUsages::empty();
            let view = gpu.uniform("mochi.render.view", &view);
            let spheres = upload(
                "mochi.render.spheres",
                bytemuck::cast_slice(&scene.spheres),
                none,
            );
            let colours = upload(
                "mochi.render.colours",
                bytemuck::cast_slice(&scene.colours),
                none,
            );
            let pixels = gpu.storage("mochi.render.pixels", pixels_len * 4, none);
            let nodes = upload("mochi.render.nodes", &storage_bytes(&scene.nodes), none);
            let wall_nodes = upload(
                "mochi.render.wall_nodes",
                &storage_bytes(&scene.wall_nodes),
                none,
            );
            let walls = upload(
                "mochi.render.walls",
                bytemuck::cast_slice(&scene.walls),
                none,
            );
            let buffers = [
                (VIEW, &view),
                (SPHERES, &spheres),
                (COLOURS, &colours),
                (PIXELS, &pixels),
                (NODES, &nodes),
                (WALL_NODES, &wall_nodes),
                (WALLS, &walls),
            ];
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let bind = if self.ray_query {
                let tlas = self.build_accel(scene, &mut encoder);
                gpu.bind_with_tlas("mochi.render.rq", &self.pipeline, &buffers, (TLAS, &tlas))
            } else {
                gpu.bind("mochi.render.bvh", &self.pipeline, &buffers)
            };
            let groups = (
                picture.width.div_ceil(GROUP),
                picture.height.div_ceil(GROUP),
            );
            gpu.dispatch(&mut encoder, "mochi.render", &self.pipeline, &bind, groups);
            gpu.queue.submit([encoder.finish()]);
            pixels
        })?;
        gpu.read(&pixels, pixels_len as usize)
    }

    /// Records the build of one BLAS over the spheres' boxes (Morton order, as lavapipe's
    /// builder needs for speed) and a TLAS with one instance of it.
    fn build_accel(&self, scene: &Scene, encoder: &mut wgpu::CommandEncoder) -> wgpu::Tlas {
        let gpu = &self.gpu;
        let boxes: Vec<[f32; 6]> = scene
            .spheres
            .iter()
            .map(|s| {
                [
                    s[0] - s[3],
                    s[1] - s[3],
                    s[2] - s[3],
                    s[0] + s[3],
                    s[1] + s[3],
                    s[2] + s[3],
                ]
            })
            .collect();
        let buffer = gpu.storage(
            "mochi.render.boxes",
            boxes.len() as u64 * AABB_STRIDE,
            wgpu::BufferUsages::BLAS_INPUT,
        );
        gpu.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(&boxes));
        let size = wgpu::BlasAABBGeometrySizeDescriptor {
            primitive_count: scene.len() as u32,
            flags: wgpu::AccelerationStructureGeometryFlags::empty(),
        };
        let blas = gpu.device.create_blas(
            &wgpu::CreateBlasDescriptor {
                label: Some("mochi.render.blas"),
                flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                update_mode: wgpu::AccelerationStructureUpdateMode::Build,
            },
            wgpu::BlasGeometrySizeDescriptors::AABBs {
                descriptors: vec![size.clone()],
            },
        );
        let mut tlas = gpu.device.create_tlas(&wgpu::CreateTlasDescriptor {
            label: Some("mochi.render.tlas"),
            max_instances: 1,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        });
        const IDENTITY: [f32; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        tlas[0] = Some(wgpu::TlasInstance::new(&blas, IDENTITY, 0, 0xff));
        let entry = wgpu::BlasBuildEntry {
            blas: &blas,
            geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
                size: &size,
                stride: AABB_STRIDE,
                aabb_buffer: &buffer,
                primitive_offset: 0,
            }]),
        };
        encoder.build_acceleration_structures(&[entry], [&tlas]);
        tlas
    }
}
