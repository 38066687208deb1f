//! Detection on the optix engine: [`OptixBackend`] implements [`crate::Backend`].

use super::device::{AccelOp, COUNTER_SLOTS, Device, Gas, Order, cuda};
use super::engine::{MAX_COORDINATE, MAX_LAUNCH, describe, morton_order_of, open_device};
use super::launches::{DetectBuffers, DetectProgram, Kernels};
use crate::detect::BackendInfo;
use crate::engines::common::detect::GpuBackend;
use crate::error::{Error, OptixError, Result};
use crate::gpu::pair_output::TakePairs;
use crate::proxy::BOX_PADDING;
use crate::proxy::ProxyMode;
use crate::spheres::Spheres;
use crate::types::Pair;
use crate::types::{DetectStats, GpuTimes};
use cudarc::driver::{CudaEvent, CudaSlice, CudaStream, sys::CUevent_flags};
use rayon::slice::ParallelSliceMut;
use std::sync::Arc;

/// The OptiX backend.
pub struct OptixBackend {
    device: Arc<Device>,
    program: DetectProgram,
    kernels: Kernels,
    built: Option<Built>,
    times: GpuTimes,
}

/// What one build leaves on the GPU.
struct Built {
    n: u32,
    mode: ProxyMode,
    r_max: f32,
    /// Input index of each sorted position.
    order: Order,
    /// x, y, z, r per sphere, input order (the upload) and sorted order.
    spheres_in: CudaSlice<f32>,
    spheres: CudaSlice<f32>,
    boxes: CudaSlice<f32>,
    /// `None` for an empty set.
    gas: Option<Gas>,
    pairs: CudaSlice<u32>,
    pair_count: CudaSlice<u32>,
    candidates: CudaSlice<u64>,
}

impl OptixBackend {
    /// Opens GPU 0 and compiles the programs (NVRTC, cached for the process).
    pub fn new() -> Result<Self> {
        let device = open_device()?;
        Ok(Self {
            program: DetectProgram::new(&device)?,
            kernels: Kernels::load(&device)?,
            device,
            built: None,
            times: GpuTimes::default(),
        })
    }

    /// Refuses sets whose boxes reach beyond [`MAX_COORDINATE`].
    fn check_extent(spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        let r_max = spheres.max_radius();
        let reach = spheres
            .xyzr()
            .map(|[x, y, z, r]| x.abs().max(y.abs()).max(z.abs()) + mode.box_half_width(r, r_max))
            .fold(0.0f32, f32::max);
        if reach > MAX_COORDINATE {
            return Err(Error::InvalidConfig {
                what: "optix".into(),
                reason: format!(
                    "a proxy box reaches coordinate {reach:e}, beyond the ±{MAX_COORDINATE:e} \
                     OptiX traverses reliably; use another backend (wgpu-compute or cpu) for \
                     this set"
                ),
            });
        }
        Ok(())
    }

    fn max_spheres(&self) -> u64 {
        (self.device.max_primitives as u64).min(MAX_LAUNCH)
    }

    /// Writes the input spheres and gathers them into sorted order with their boxes.
    fn write_boxes(&self, built: &mut Built, spheres: Spheres<'_>) -> Result<()> {
        let stream = &self.device.stream;
        let rows: Vec<f32> = spheres.xyzr().flatten().collect();
        stream
            .memcpy_htod(&rows, &mut built.spheres_in)
            .map_err(cuda("uploading the spheres"))?;
        self.kernels.proxy_boxes(
            &built.spheres_in,
            &built.order,
            &mut built.spheres,
            &mut built.boxes,
            built.n,
            built.mode,
            built.r_max,
            BOX_PADDING,
        )?;
        Ok(())
    }

    /// Runs the point rays; with `collect`, grows the pair buffer until every pair fits.
    fn run_detection(&mut self, collect: bool) -> Result<(Vec<Pair>, DetectStats)> {
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
                .map_err(cuda("clearing the pair count"))?;
            stream
                .memset_zeros(&mut built.candidates)
                .map_err(cuda("clearing the candidate counters"))?;
            let start = mark(stream)?;
            let buffers = DetectBuffers {
                spheres: &built.spheres,
                ids: built.order.entries(),
                pairs: &mut built.pairs,
                pair_count: &mut built.pair_count,
                candidates: &mut built.candidates,
            };
            self.program.launch(gas, built.mode, capacity, buffers)?;
            let end = mark(stream)?;
            let read = cuda("reading the counters back");
            let found = stream.clone_dtoh(&built.pair_count).map_err(&read)?[0];
            let candidates: u64 = stream
                .clone_dtoh(&built.candidates)
                .map_err(&read)?
                .iter()
                .sum();
            self.times.detect_ms = Some(elapsed_ms(&start, &end)?);
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
                    .map_err(cuda("growing the pair buffer"))?;
                continue;
            }
            let flat = stream
                .clone_dtoh(&built.pairs)
                .map_err(cuda("reading the pairs back"))?;
            let mut pairs: Vec<Pair> = flat[..2 * found as usize]
                .chunks_exact(2)
                .map(|p| Pair { i: p[0], j: p[1] })
                .collect();
            pairs.par_sort_unstable();
            return Ok((pairs, stats));
        }
    }
}

/// Records an event on `stream` (the start or end of a timed span).
fn mark(stream: &CudaStream) -> std::result::Result<CudaEvent, OptixError> {
    stream
        .record_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
        .map_err(cuda("recording an event"))
}

/// Milliseconds between two recorded events.
fn elapsed_ms(start: &CudaEvent, end: &CudaEvent) -> std::result::Result<f64, OptixError> {
    Ok(start
        .elapsed_ms(end)
        .map_err(cuda("reading the GPU timers"))? as f64)
}

/// Input indices in Morton order of the centres (ties by index), for coherent rays.
fn morton_order(spheres: Spheres<'_>) -> Vec<u32> {
    morton_order_of(spheres.centers())
}

impl GpuBackend for OptixBackend {
    fn info(&self) -> BackendInfo {
        BackendInfo {
            name: "optix",
            device: describe(&self.device),
            max_spheres: self.max_spheres(),
        }
    }

    fn build(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
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
        let alloc = cuda("allocating the structure's buffers");
        let alloc_f32 = |len: usize| stream.alloc_zeros::<f32>(len.max(1)).map_err(&alloc);
        let mut built = Built {
            n,
            mode,
            r_max: spheres.max_radius(),
            order: Order::upload(&stream, &morton_order(spheres))?,
            spheres_in: alloc_f32(4 * n as usize)?,
            spheres: alloc_f32(4 * n as usize)?,
            boxes: alloc_f32(6 * n as usize)?,
            gas: None,
            pairs: stream
                .alloc_zeros::<u32>(2 * (n as usize).max(1024))
                .map_err(&alloc)?,
            pair_count: stream.alloc_zeros::<u32>(1).map_err(&alloc)?,
            candidates: stream.alloc_zeros::<u64>(COUNTER_SLOTS).map_err(&alloc)?,
        };
        self.times = GpuTimes::default();
        if n > 0 {
            let start = mark(&self.device.stream)?;
            self.write_boxes(&mut built, spheres)?;
            built.gas = Some(Gas::build(&self.device, &built.boxes, n)?);
            let end = mark(&self.device.stream)?;
            self.times.build_ms = Some(elapsed_ms(&start, &end)?);
        }
        self.built = Some(built);
        Ok(())
    }

    /// Nothing to wait for: a build returns once its time between the stream's events is
    /// known.
    fn finish(&mut self) -> Result<()> {
        Ok(())
    }

    fn built(&self) -> Option<(usize, ProxyMode)> {
        self.built.as_ref().map(|b| (b.n as usize, b.mode))
    }

    /// Refits: the boxes are rewritten and the structure updated in place.
    fn refresh(&mut self, spheres: Spheres<'_>, mode: ProxyMode) -> Result<()> {
        let mut built = self
            .built
            .take()
            .ok_or_else(|| Error::Usage("update asked for before build".into()))?;
        let result = (|| {
            if built.n == 0 {
                return Ok(());
            }
            Self::check_extent(spheres, mode)?;
            let start = mark(&self.device.stream)?;
            self.write_boxes(&mut built, spheres)?;
            if let Some(gas) = built.gas.as_mut() {
                gas.run(&self.device, &built.boxes, AccelOp::Update)?;
            }
            let end = mark(&self.device.stream)?;
            self.times.build_ms = Some(elapsed_ms(&start, &end)?);
            Ok(())
        })();
        self.built = Some(built);
        result
    }

    fn detect(&mut self, take: Option<TakePairs<'_>>) -> Result<DetectStats> {
        let (pairs, stats) = self.run_detection(take.is_some())?;
        if let Some(take) = take {
            take(&pairs);
        }
        Ok(stats)
    }

    fn gpu_times(&self) -> GpuTimes {
        self.times
    }
}
