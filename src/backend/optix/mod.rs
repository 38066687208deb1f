//! The `optix` backend (cargo feature `optix`): the paper's own path on NVIDIA GPUs. Every
//! sphere's proxy box (2·r, or 2·r_max in `nns` mode) is a custom primitive of one OptiX
//! acceleration structure; one point ray per sphere visits every box its centre lies in, and the
//! intersection program applies the proxy-sphere rule and writes the kept pairs without ever
//! reporting a hit (`optix/detect.cu`). Boxes are written by a CUDA kernel (`optix/kernels.cu`);
//! `update` refits the structure instead of rebuilding it.
//!
//! Everything NVIDIA is loaded at run time (CUDA driver and NVRTC through `cudarc`, OptiX
//! through our own FFI of ABI 105 in `ffi.rs`), so the crate builds anywhere and a machine without
//! the driver gets a clear "unavailable" instead of a crash. Spheres are launched in Morton
//! order (coherent rays: faster than random order, docs/PERFORMANCE.md).

// The one place of the crate that calls foreign code: every unsafe block says why it holds.
#![allow(unsafe_code)]

pub(crate) mod device;
mod ffi;
pub mod programs;

use super::{Backend, BackendInfo, DetectStats, GpuTimes};
use crate::error::{Error, Result};
use crate::proxy::BOX_PADDING;
use crate::proxy::ProxyMode;
use crate::spheres::SphereSet;
use crate::types::Pair;
use cudarc::driver::{
    CudaFunction, CudaModule, CudaSlice, LaunchConfig, PushKernelArg, sys::CUevent_flags,
};
use device::{AccelOp, Device, Gas, Pipeline};
use rayon::prelude::*;
use std::sync::Arc;

/// Most spheres one launch takes (OptiX's launch width limit is 2^30; the acceleration
/// structure's own limit, 2^29 on driver 580, is read from the device).
const MAX_LAUNCH: u64 = 1 << 30;

/// Largest |coordinate| + box half-width the backend accepts. Measured on the H100 (driver
/// 580, OptiX 9.0): boxes out at 1e12 are found exactly, boxes at 1e14 are silently dropped by
/// the traversal; beyond this bound the backend refuses the set instead.
pub const MAX_COORDINATE: f32 = 1e12;

/// Threads per block of the CUDA kernels.
pub(crate) const BLOCK: u32 = 256;

/// Counters the device programs spread their candidate (and contact) counts over: a power of
/// two, indexed by `i & (COUNTER_SLOTS - 1)` (the `& 255u` of `optix/detect.cu` and
/// `optix/dem.cu`, checked by `tests/optix.rs`).
pub const COUNTER_SLOTS: usize = 256;

/// Launch parameters of `optix/detect.cu`; keep in sync with `DetectParams` there.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DetectParams {
    spheres: u64,
    ids: u64,
    pairs: u64,
    pair_count: u64,
    candidates: u64,
    handle: u64,
    n: u32,
    capacity: u32,
    mode: u32,
    _pad: u32,
}
const _: () = assert!(size_of::<DetectParams>() == 64);

/// Why the optix backend cannot run here, if it cannot; else the GPU, in words.
pub fn probe() -> std::result::Result<String, String> {
    let device = Device::open()?;
    Ok(describe(&device))
}

/// Why `auto` should prefer another backend on this GPU (no RT cores), if it should.
pub fn auto_skip() -> Option<String> {
    let device = Device::open().ok()?;
    (device.rtcore_version == 0).then(|| {
        format!(
            "{} has no RT cores: OptiX traverses in software there, slower than wgpu-compute's grid",
            device.name
        )
    })
}

fn describe(device: &Device) -> String {
    let cores = if device.rtcore_version == 0 {
        "no RT cores".to_string()
    } else {
        format!("RT cores v{}", device.rtcore_version)
    };
    format!("{}, OptiX ABI {}, {cores}", device.name, ffi::ABI_VERSION)
}

pub(crate) fn gpu_error(e: impl std::fmt::Display) -> Error {
    Error::Gpu(e.to_string())
}

/// Opens GPU 0 with the pipeline of `unit` (entry points `__raygen__{name}` and
/// `__intersection__{name}`, `payloads` payload words) and the module of the CUDA kernels
/// (`optix/kernels.cu`), compiling both with NVRTC on first use.
pub(crate) fn open_programs(
    unit: programs::Unit,
    name: &str,
    payloads: i32,
) -> Result<(Arc<Device>, Pipeline, Arc<CudaModule>)> {
    let unavailable = |reason: String| Error::BackendUnavailable {
        backend: "optix",
        reason,
    };
    let device = Arc::new(Device::open().map_err(unavailable)?);
    let programs_ptx = programs::ptx(unit).map_err(unavailable)?;
    let kernels_ptx = programs::ptx(programs::Unit::Kernels).map_err(unavailable)?;
    let pipeline = Pipeline::new(&device, programs_ptx, name, payloads).map_err(gpu_error)?;
    let module = device
        .cuda
        .load_module(cudarc::nvrtc::Ptx::from_src(kernels_ptx))
        .map_err(gpu_error)?;
    Ok((device, pipeline, module))
}

/// The OptiX backend.
pub struct OptixBackend {
    device: Arc<Device>,
    pipeline: Pipeline,
    proxy_boxes: CudaFunction,
    built: Option<Built>,
    times: GpuTimes,
}

/// What one build leaves on the GPU.
struct Built {
    n: u32,
    mode: ProxyMode,
    r_max: f32,
    /// Input index of each sorted position.
    order: CudaSlice<u32>,
    /// x, y, z, r per sphere, input order (the upload) and sorted order.
    spheres_in: CudaSlice<f32>,
    spheres: CudaSlice<f32>,
    boxes: CudaSlice<f32>,
    /// `None` for an empty set.
    gas: Option<Gas>,
    pairs: CudaSlice<u32>,
    pair_count: CudaSlice<u32>,
    candidates: CudaSlice<u64>,
    params: CudaSlice<u8>,
}

impl OptixBackend {
    /// Opens GPU 0 and compiles the programs (NVRTC, cached for the process).
    pub fn new() -> Result<Self> {
        let (device, pipeline, module) = open_programs(programs::Unit::Detect, "detect", 1)?;
        let proxy_boxes = module.load_function("proxy_boxes").map_err(gpu_error)?;
        Ok(Self {
            device,
            pipeline,
            proxy_boxes,
            built: None,
            times: GpuTimes::default(),
        })
    }

    /// Refuses sets whose boxes reach beyond [`MAX_COORDINATE`].
    fn check_extent(spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        let r_max = spheres.max_radius();
        let reach = spheres
            .xyzr()
            .map(|[x, y, z, r]| x.abs().max(y.abs()).max(z.abs()) + mode.box_half_width(r, r_max))
            .fold(0.0f32, f32::max);
        if reach > MAX_COORDINATE {
            return Err(Error::Usage(format!(
                "optix: a proxy box reaches coordinate {reach:e}, beyond the ±{MAX_COORDINATE:e} \
                 OptiX traverses reliably; use another backend (wgpu-compute or cpu) for this set"
            )));
        }
        Ok(())
    }

    fn max_spheres(&self) -> u64 {
        (self.device.max_primitives as u64).min(MAX_LAUNCH)
    }

    /// Starts a GPU timing span on the stream.
    fn mark(&self) -> Result<cudarc::driver::CudaEvent> {
        self.device
            .stream
            .record_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
            .map_err(gpu_error)
    }

    /// Writes the input spheres and gathers them into sorted order with their boxes.
    fn write_boxes(&self, built: &mut Built, spheres: &SphereSet) -> Result<()> {
        let stream = &self.device.stream;
        let rows: Vec<f32> = spheres.xyzr().flatten().collect();
        stream
            .memcpy_htod(&rows, &mut built.spheres_in)
            .map_err(gpu_error)?;
        let mode = built.mode.code();
        let config = LaunchConfig {
            grid_dim: (built.n.div_ceil(BLOCK), 1, 1),
            block_dim: (BLOCK, 1, 1),
            shared_mem_bytes: 0,
        };
        let mut launch = stream.launch_builder(&self.proxy_boxes);
        launch
            .arg(&built.spheres_in)
            .arg(&built.order)
            .arg(&mut built.spheres)
            .arg(&mut built.boxes)
            .arg(&built.n)
            .arg(&mode)
            .arg(&built.r_max)
            .arg(&BOX_PADDING);
        // SAFETY: the arguments match proxy_boxes' signature; buffers hold n spheres and boxes.
        unsafe { launch.launch(config) }.map_err(gpu_error)?;
        Ok(())
    }

    /// Runs the point rays; with `collect`, grows the pair buffer until every pair fits.
    fn detect(&mut self, collect: bool) -> Result<(Vec<Pair>, DetectStats)> {
        let built = self
            .built
            .as_mut()
            .ok_or_else(|| Error::Usage("detection asked for before build".into()))?;
        let Some(gas) = built.gas.as_ref() else {
            return Ok((Vec::new(), DetectStats::default()));
        };
        let device = &self.device;
        let stream = &device.stream;
        loop {
            let capacity = if collect {
                (built.pairs.len() / 2) as u32
            } else {
                0
            };
            stream
                .memset_zeros(&mut built.pair_count)
                .map_err(gpu_error)?;
            stream
                .memset_zeros(&mut built.candidates)
                .map_err(gpu_error)?;
            let params = DetectParams {
                spheres: device.ptr(&built.spheres),
                ids: device.ptr(&built.order),
                pairs: device.ptr_mut(&mut built.pairs),
                pair_count: device.ptr_mut(&mut built.pair_count),
                candidates: device.ptr_mut(&mut built.candidates),
                handle: gas.handle,
                n: built.n,
                capacity,
                mode: built.mode.code(),
                _pad: 0,
            };
            stream
                .memcpy_htod(bytemuck::bytes_of(&params), &mut built.params)
                .map_err(gpu_error)?;
            let start = stream
                .record_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
                .map_err(gpu_error)?;
            self.pipeline
                .launch(&built.params, built.n)
                .map_err(gpu_error)?;
            let end = stream
                .record_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
                .map_err(gpu_error)?;
            let found = stream.clone_dtoh(&built.pair_count).map_err(gpu_error)?[0];
            let candidates: u64 = stream
                .clone_dtoh(&built.candidates)
                .map_err(gpu_error)?
                .iter()
                .sum();
            self.times.detect_ms = Some(start.elapsed_ms(&end).map_err(gpu_error)? as f64);
            let stats = DetectStats {
                candidates,
                pairs: found as u64,
            };
            if !collect {
                return Ok((Vec::new(), stats));
            }
            if found > capacity {
                built.pairs = stream
                    .alloc_zeros::<u32>(2 * (found as usize).next_power_of_two())
                    .map_err(gpu_error)?;
                continue;
            }
            let flat = stream.clone_dtoh(&built.pairs).map_err(gpu_error)?;
            let mut pairs: Vec<Pair> = flat[..2 * found as usize]
                .chunks_exact(2)
                .map(|p| Pair { i: p[0], j: p[1] })
                .collect();
            pairs.par_sort_unstable();
            return Ok((pairs, stats));
        }
    }
}

/// Input indices in Morton order of the centres (ties by index), for coherent rays.
fn morton_order(spheres: &SphereSet) -> Vec<u32> {
    morton_order_of(spheres.centers())
}

/// Indices of `centers` in Morton order (ties by index).
pub(crate) fn morton_order_of(centers: &[[f32; 3]]) -> Vec<u32> {
    if centers.is_empty() {
        return Vec::new();
    }
    let (lo, hi) = centers.iter().fold(
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(lo, hi), c| {
            (
                std::array::from_fn(|a| lo[a].min(c[a])),
                std::array::from_fn(|a| hi[a].max(c[a])),
            )
        },
    );
    let scale: [f32; 3] = std::array::from_fn(|a| {
        let extent = hi[a] - lo[a];
        if extent > 0.0 { 1023.0 / extent } else { 0.0 }
    });
    let spread = |v: u32| -> u64 {
        (0..10).fold(0u64, |acc, bit| {
            acc | ((((v >> bit) & 1) as u64) << (3 * bit))
        })
    };
    let mut keyed: Vec<(u64, u32)> = centers
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let q: [u32; 3] =
                std::array::from_fn(|a| ((c[a] - lo[a]) * scale[a]).clamp(0.0, 1023.0) as u32);
            (
                spread(q[0]) | spread(q[1]) << 1 | spread(q[2]) << 2,
                i as u32,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

impl Backend for OptixBackend {
    fn info(&self) -> BackendInfo {
        BackendInfo {
            name: "optix",
            device: describe(&self.device),
            max_spheres: self.max_spheres(),
        }
    }

    fn build(&mut self, spheres: &SphereSet, mode: ProxyMode) -> Result<()> {
        let n64 = spheres.len() as u64;
        if n64 > self.max_spheres() {
            return Err(Error::TooLarge {
                what: format!(
                    "spheres for one OptiX acceleration structure on {}",
                    self.device.name
                ),
                got: n64,
                limit: self.max_spheres(),
            });
        }
        Self::check_extent(spheres, mode)?;
        let n = n64 as u32;
        let stream = self.device.stream.clone();
        let alloc_f32 = |len: usize| stream.alloc_zeros::<f32>(len.max(1)).map_err(gpu_error);
        let order = morton_order(spheres);
        let order = if order.is_empty() {
            stream.alloc_zeros::<u32>(1)
        } else {
            stream.clone_htod(&order)
        }
        .map_err(gpu_error)?;
        let mut built = Built {
            n,
            mode,
            r_max: spheres.max_radius(),
            order,
            spheres_in: alloc_f32(4 * n as usize)?,
            spheres: alloc_f32(4 * n as usize)?,
            boxes: alloc_f32(6 * n as usize)?,
            gas: None,
            pairs: stream
                .alloc_zeros::<u32>(2 * (n as usize).max(1024))
                .map_err(gpu_error)?,
            pair_count: stream.alloc_zeros::<u32>(1).map_err(gpu_error)?,
            candidates: stream
                .alloc_zeros::<u64>(COUNTER_SLOTS)
                .map_err(gpu_error)?,
            params: stream
                .alloc_zeros::<u8>(size_of::<DetectParams>())
                .map_err(gpu_error)?,
        };
        self.times = GpuTimes::default();
        if n > 0 {
            let start = self.mark()?;
            self.write_boxes(&mut built, spheres)?;
            built.gas = Some(Gas::build(&self.device, &built.boxes, n).map_err(gpu_error)?);
            let end = self.mark()?;
            self.times.build_ms = Some(start.elapsed_ms(&end).map_err(gpu_error)? as f64);
        }
        self.built = Some(built);
        Ok(())
    }

    fn update(&mut self, spheres: &SphereSet) -> Result<()> {
        let mut built = self
            .built
            .take()
            .ok_or_else(|| Error::Usage("update asked for before build".into()))?;
        if spheres.len() != built.n as usize {
            let n = built.n;
            self.built = Some(built);
            return Err(Error::Usage(format!(
                "update with {} spheres, built with {n}",
                spheres.len()
            )));
        }
        let result = (|| {
            if built.n == 0 {
                return Ok(());
            }
            Self::check_extent(spheres, built.mode)?;
            let start = self.mark()?;
            self.write_boxes(&mut built, spheres)?;
            if let Some(gas) = built.gas.as_mut() {
                gas.run(&self.device, &built.boxes, AccelOp::Update)
                    .map_err(gpu_error)?;
            }
            let end = self.mark()?;
            self.times.build_ms = Some(start.elapsed_ms(&end).map_err(gpu_error)? as f64);
            Ok(())
        })();
        self.built = Some(built);
        result
    }

    fn find_pairs(&mut self) -> Result<(Vec<Pair>, DetectStats)> {
        self.detect(true)
    }

    fn count_pairs(&mut self) -> Result<DetectStats> {
        Ok(self.detect(false)?.1)
    }

    fn for_each_contact(&mut self, visit: &(dyn Fn(Pair) + Sync)) -> Result<DetectStats> {
        let (pairs, stats) = self.detect(true)?;
        pairs.into_par_iter().for_each(visit);
        Ok(stats)
    }

    fn gpu_times(&self) -> GpuTimes {
        self.times
    }
}
