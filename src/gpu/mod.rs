//! Shared wgpu plumbing of the GPU backends: finding an adapter, opening a device, buffers,
//! pipelines, dispatch sizes and read-back, with every GPU failure turned into an [`Error`].

pub(crate) mod pair_output;
pub(crate) mod pair_sort;
pub mod radix_sort;
pub mod scan;
pub mod shader;
pub(crate) mod timer;

use crate::error::{Error, Result};
use rayon::prelude::*;
use shader::Binding;
use shader::WgslModule;
use std::collections::HashMap;
use std::ops::Range;
use std::sync::{Arc, Mutex, OnceLock};
use wgpu::WriteOnly;

/// The WGSL modules of the shared plumbing (scan, radix sort and the pair sort's kernels),
/// exactly as the device gets them.
pub fn shaders() -> Vec<WgslModule> {
    vec![scan::module(), radix_sort::module(), pair_sort::module()]
}

/// Bytes of one box in a BLAS's AABB input: two `vec3<f32>`, min then max (as
/// `wgsl/rq/rq_build.wgsl` and `wgsl/rq/dem_rq.wgsl` write them: 6 floats per box).
pub(crate) const AABB_STRIDE: u64 = 24;

/// What a backend needs from an adapter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Need {
    /// Compute shaders only.
    Compute,
    /// Compute shaders with ray queries over acceleration structures.
    RayQuery,
}

impl Need {
    fn features(self) -> wgpu::Features {
        match self {
            Need::Compute => wgpu::Features::empty(),
            Need::RayQuery => wgpu::Features::EXPERIMENTAL_RAY_QUERY,
        }
    }
}

/// Optional features a backend uses when the adapter has them.
const WANTED: wgpu::Features = wgpu::Features::SHADER_FLOAT32_ATOMIC
    .union(wgpu::Features::TIMESTAMP_QUERY)
    .union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS)
    .union(wgpu::Features::SUBGROUP);

/// An open device and what it offers (cloning shares the device).
#[derive(Clone)]
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Adapter name, driver and type.
    pub info: wgpu::AdapterInfo,
    /// Limits the device was opened with (all the adapter allows).
    pub limits: wgpu::Limits,
    /// What was compiled on this device, shared by its clones.
    compiled: Arc<Mutex<Compiled>>,
}

/// The modules (by source) and auto-layout pipelines (by module and entry point) compiled on
/// one device, kept for the device's life: an engine opened again on the same device (a run
/// whose spheres come and go reopens its step) compiles nothing.
#[derive(Default)]
struct Compiled {
    /// By source: those whose loops wgpu bounds ([`Gpu::module`]), then the crate's own
    /// ([`Gpu::own_module`]).
    modules: [HashMap<String, Module>; 2],
    pipelines: HashMap<(usize, String), wgpu::ComputePipeline>,
}

/// A compiled WGSL module of a [`Gpu`] (dereferences to wgpu's).
#[derive(Debug, Clone)]
pub struct Module {
    module: wgpu::ShaderModule,
    /// Its index among the device's modules: the key of its pipelines.
    index: usize,
}

impl std::ops::Deref for Module {
    type Target = wgpu::ShaderModule;

    fn deref(&self) -> &wgpu::ShaderModule {
        &self.module
    }
}

fn instance() -> &'static wgpu::Instance {
    static INSTANCE: OnceLock<wgpu::Instance> = OnceLock::new();
    INSTANCE.get_or_init(|| {
        // wgpu validates every indirect dispatch by default (a compute pass of its own before
        // each, which costs the DEM step's skipped binnings more than the binning they skip).
        // The engines' indirect dispatches are written by the host within the device's limits
        // or set to zero by their kernels; WGPU_VALIDATION_INDIRECT_CALL=1 turns it back on.
        let mut flags = wgpu::InstanceFlags::from_build_config();
        flags.remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
        wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::PRIMARY,
            flags: flags.with_env(),
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        })
    })
}

/// Every adapter of this machine, best first (discrete, integrated, virtual, other, CPU); of
/// several discrete GPUs, a process an MPI launcher started puts the one of its local rank
/// first (local rank L: the (L mod G)-th of G), so the processes of a run over ranks on one
/// machine each open their own. Enumerated once per process: probing a backend, `auto` and
/// opening a device all read this list, so none of them asks the drivers again (an adapter
/// that appears later is not seen).
fn all_adapters() -> &'static [wgpu::Adapter] {
    static ADAPTERS: OnceLock<Vec<wgpu::Adapter>> = OnceLock::new();
    ADAPTERS.get_or_init(|| {
        let mut found = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::PRIMARY));
        found.sort_by_key(|a| match a.get_info().device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        });
        let discrete = found
            .iter()
            .take_while(|a| a.get_info().device_type == wgpu::DeviceType::DiscreteGpu)
            .count();
        if discrete > 1 {
            found[..discrete].rotate_left(crate::launcher::local_rank() % discrete);
        }
        found
    })
}

/// Adapters that can serve `need`, best first.
fn adapters(need: Need) -> impl Iterator<Item = &'static wgpu::Adapter> {
    all_adapters()
        .iter()
        .filter(move |a| a.features().contains(need.features()))
}

/// Describes an adapter in one line: name, backend, driver.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    let driver = if info.driver_info.is_empty() {
        &info.driver
    } else {
        &info.driver_info
    };
    format!("{}, {:?}, {driver}", info.name, info.backend)
}

/// The adapter a backend with `need` would run on, or why there is none.
pub fn probe(need: Need) -> Result<wgpu::AdapterInfo, String> {
    match adapters(need).next() {
        Some(a) => Ok(a.get_info()),
        None => Err(match need {
            Need::Compute => "no GPU adapter found (Vulkan, Metal or DX12)".into(),
            Need::RayQuery => {
                let others: Vec<_> = adapters(Need::Compute).map(|a| a.get_info().name).collect();
                if others.is_empty() {
                    "no GPU adapter found (Vulkan, Metal or DX12)".into()
                } else {
                    format!("no adapter has ray queries (found: {})", others.join(", "))
                }
            }
        }),
    }
}

impl Gpu {
    /// Opens a device on the best adapter for `need`, with all the adapter's limits.
    pub fn open(need: Need) -> Result<Gpu> {
        Self::open_limited(need, |_| {})
    }

    /// Opens a device on the best adapter for `need`, with the adapter's limits as `lower`
    /// changes them (it may only lower them). Everything sized by the device reads its limits
    /// from [`Gpu::limits`], so a test can, say, lower `max_compute_workgroups_per_dimension` to
    /// run the 2-D dispatch paths at small sizes.
    #[allow(unsafe_code)] // wgpu's opt-in to experimental features (ray queries)
    pub fn open_limited(need: Need, lower: impl FnOnce(&mut wgpu::Limits)) -> Result<Gpu> {
        let unavailable = |reason: String| Error::Gpu(reason);
        let adapter = adapters(need)
            .next()
            .ok_or_else(|| unavailable(probe(need).err().unwrap_or_default()))?;
        let features = need.features() | (adapter.features() & WANTED);
        let mut limits = adapter.limits();
        lower(&mut limits);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("mochi"),
            required_features: features,
            required_limits: limits.clone(),
            // SAFETY: the experimental feature requested is ray queries, used only through
            // wgpu's validated API; wgpu documents these features as possibly buggy, not unsound
            // for validated use.
            experimental_features: unsafe { wgpu::ExperimentalFeatures::enabled() },
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::Gpu(format!("cannot open {}: {e}", adapter.get_info().name)))?;
        device.on_uncaptured_error(std::sync::Arc::new(|e| {
            eprintln!("mochi: uncaptured GPU error: {e}");
        }));
        Ok(Gpu {
            device,
            queue,
            info: adapter.get_info(),
            limits,
            compiled: Arc::default(),
        })
    }

    /// Runs `work` and turns any out-of-memory or validation error it caused into an [`Error`].
    pub fn checked<T>(&self, what: &str, work: impl FnOnce() -> T) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = work();
        let validation = pollster::block_on(validation.pop());
        let oom = pollster::block_on(oom.pop());
        match oom.or(validation) {
            Some(wgpu::Error::Validation { description, .. }) => {
                Err(Error::Gpu(format!("{what}: {description}")))
            }
            Some(e) => Err(Error::Gpu(format!("{what}: {e}"))),
            None => Ok(out),
        }
    }

    /// Blocks until the GPU has finished all submitted work.
    pub fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))
    }

    /// A storage buffer of `size` bytes (at least 16) with `extra` usages besides STORAGE.
    pub fn storage(&self, label: &str, size: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16).next_multiple_of(4),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC
                | extra,
            mapped_at_creation: false,
        })
    }

    /// A compute pipeline for `entry` of `module` (bind groups laid out by wgpu), compiled once
    /// per device.
    pub fn pipeline(&self, label: &str, module: &Module, entry: &str) -> wgpu::ComputePipeline {
        self.pipeline_with(label, module, entry, &[])
    }

    /// [`pipeline`](Self::pipeline) with the module's `override` constants set to `constants`
    /// (each name's value), compiled once per device and set of values.
    pub fn pipeline_with(
        &self,
        label: &str,
        module: &Module,
        entry: &str,
        constants: &[(&str, f64)],
    ) -> wgpu::ComputePipeline {
        let key = (module.index, format!("{entry} {constants:?}"));
        if let Some(pipeline) = self.compiled().pipelines.get(&key) {
            return pipeline.clone();
        }
        let pipeline = self
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            });
        self.compiled().pipelines.insert(key, pipeline.clone());
        pipeline
    }

    /// Compiles a WGSL module with every check wgpu makes of a shader, once per device and
    /// source.
    pub fn module(&self, label: &str, source: &str) -> Module {
        self.compile(label, source, true)
    }

    /// Compiles one of the crate's own WGSL modules, once per device and source: every check
    /// wgpu makes of a shader but the bound it puts on each loop (a counter a loop, there so
    /// that a driver cannot compile a loop that never ends as unreachable), which costs the
    /// walks of the DEM steps a few percent. The crate's shaders end every loop on the counts
    /// and sizes the host gives them; a loop that did not would hang the step with the bound
    /// too (it allows 2^64 passes).
    pub(crate) fn own_module(&self, label: &str, source: &str) -> Module {
        self.compile(label, source, false)
    }

    /// Compiles `source`, its loops bounded by wgpu where `bounded`, once per device, source
    /// and bounding.
    fn compile(&self, label: &str, source: &str, bounded: bool) -> Module {
        let kind = usize::from(!bounded);
        if let Some(module) = self.compiled().modules[kind].get(source) {
            return module.clone();
        }
        let desc = wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        };
        let module = match bounded {
            true => self.device.create_shader_module(desc),
            false => {
                let checks = wgpu::ShaderRuntimeChecks {
                    force_loop_bounding: false,
                    ..wgpu::ShaderRuntimeChecks::checked()
                };
                // SAFETY: only `own_module` asks for no bound, for the crate's shaders, whose
                // every loop ends.
                #[allow(unsafe_code)]
                unsafe {
                    self.device.create_shader_module_trusted(desc, checks)
                }
            }
        };
        let mut compiled = self.compiled();
        // Another thread may have compiled the same source meanwhile: its module is the one
        // (so that the indices, the pipelines' keys, stay one per source and bounding).
        if let Some(module) = compiled.modules[kind].get(source) {
            return module.clone();
        }
        let module = Module {
            module,
            index: compiled.modules.iter().map(HashMap::len).sum(),
        };
        compiled.modules[kind].insert(source.to_owned(), module.clone());
        module
    }

    /// The cache of compiled modules and pipelines (a panic while it was held left nothing
    /// half-written: each insertion is one call).
    fn compiled(&self) -> std::sync::MutexGuard<'_, Compiled> {
        self.compiled.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A bind group for `pipeline`'s group 0 with each buffer at its binding.
    pub fn bind(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[(Binding, &wgpu::Buffer)],
    ) -> wgpu::BindGroup {
        self.bind_entries(label, pipeline, buffers, None)
    }

    /// As [`bind`](Self::bind), with the acceleration structure `tlas` at its binding too.
    pub fn bind_with_tlas(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[(Binding, &wgpu::Buffer)],
        tlas: (Binding, &wgpu::Tlas),
    ) -> wgpu::BindGroup {
        self.bind_entries(label, pipeline, buffers, Some(tlas))
    }

    fn bind_entries(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[(Binding, &wgpu::Buffer)],
        tlas: Option<(Binding, &wgpu::Tlas)>,
    ) -> wgpu::BindGroup {
        let mut entries: Vec<_> = buffers
            .iter()
            .map(|&(at, b)| {
                debug_assert_eq!(at.group, 0, "{label}: {} is not in group 0", at.name);
                wgpu::BindGroupEntry {
                    binding: at.binding,
                    resource: b.as_entire_binding(),
                }
            })
            .collect();
        if let Some((at, tlas)) = tlas {
            entries.push(wgpu::BindGroupEntry {
                binding: at.binding,
                resource: wgpu::BindingResource::AccelerationStructure(tlas),
            });
        }
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    /// A uniform buffer holding `value` (laid out by `encase`), its size rounded up to 16 bytes.
    pub fn uniform<T>(&self, label: &str, value: &T) -> wgpu::Buffer
    where
        T: encase::ShaderType + encase::ShaderSize + encase::internal::WriteInto,
    {
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: T::SHADER_SIZE.get().next_multiple_of(16),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.write_uniform(&buffer, value);
        buffer
    }

    /// Writes `value` into the uniform buffer `buffer` (made by [`uniform`](Self::uniform) for
    /// its type), ahead of the commands submitted next.
    pub fn write_uniform<T>(&self, buffer: &wgpu::Buffer, value: &T)
    where
        T: encase::ShaderType + encase::ShaderSize + encase::internal::WriteInto,
    {
        self.queue
            .write_buffer(buffer, 0, &shader::uniform_bytes(value));
    }

    /// Records one compute pass of `pipeline` with `bind` at group 0 over the workgroups `(x, y)`.
    pub fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        bind: &wgpu::BindGroup,
        (x, y): (u32, u32),
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: None,
        });
        record(&mut pass, pipeline, bind, (x, y));
    }

    /// Records one compute pass of `pipeline` over the workgroups `groups`, with each buffer bound
    /// at its binding number of group 0.
    pub fn pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[(Binding, &wgpu::Buffer)],
        groups: (u32, u32),
    ) {
        let bind = self.bind(label, pipeline, buffers);
        self.dispatch(encoder, label, pipeline, &bind, groups);
    }

    /// Records `record` into a new encoder, between the marks of `span` when there is a timer,
    /// and submits it.
    pub fn submit_timed(
        &self,
        timer: Option<&timer::GpuTimer>,
        span: timer::Span,
        record: impl FnOnce(&mut wgpu::CommandEncoder),
    ) {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        if let Some(t) = timer {
            t.start(&mut encoder, span);
        }
        record(&mut encoder);
        if let Some(t) = timer {
            t.end(&mut encoder, span);
        }
        self.queue.submit([encoder.finish()]);
    }

    /// Workgroups `(x, y)` for `n` invocations of `size` threads on this device (see [`workgroups`]).
    pub fn grid(&self, n: u32, size: u32) -> (u32, u32) {
        workgroups(n, size, self.limits.max_compute_workgroups_per_dimension)
    }

    /// Copies the first `count` values of `buffer` back to the host (waits for the GPU).
    pub fn read<T: bytemuck::Pod + Send + Sync>(
        &self,
        buffer: &wgpu::Buffer,
        count: usize,
    ) -> Result<Vec<T>> {
        self.read_through(&mut Staging::default(), buffer, count)
    }

    /// [`Gpu::read`] through `staging`, which is reused where it is large enough (else
    /// replaced by one that is): repeated read-backs allocate no buffer once warm.
    pub fn read_through<T: bytemuck::Pod + Send + Sync>(
        &self,
        staging: &mut Staging,
        buffer: &wgpu::Buffer,
        count: usize,
    ) -> Result<Vec<T>> {
        self.read_through_with(staging, buffer, count, |values: &[T]| {
            // Large read-backs (the pairs) are copied out on every core.
            if size_of_val(values) < PARALLEL_COPY_BYTES {
                values.to_vec()
            } else {
                values.par_iter().copied().collect()
            }
        })
    }

    /// [`Gpu::read_through`] handing the values to `take` where they lie, in the mapped
    /// staging buffer: a caller that converts them copies them once.
    pub fn read_through_with<T: bytemuck::Pod, R>(
        &self,
        staging: &mut Staging,
        buffer: &wgpu::Buffer,
        count: usize,
        take: impl FnOnce(&[T]) -> R,
    ) -> Result<R> {
        let bytes = (count * size_of::<T>()) as u64;
        if bytes == 0 {
            return Ok(take(&[]));
        }
        let size = bytes.next_multiple_of(4);
        // Taken out while in use: a read-back that fails leaves no buffer behind in a mapping.
        let kept = staging.0.take();
        let buffer_back = match kept {
            Some(b) if b.size() >= size => b,
            _ => self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("mochi.readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        let taken = self.read_via(&buffer_back, buffer, size, bytes, take)?;
        staging.0 = Some(buffer_back);
        Ok(taken)
    }

    /// The bytes of each of `ranges` of `buffer` (each a whole number of 4-byte words), copied
    /// back in one read through `staging` into `into`, one vector a range (as
    /// [`read_through`](Self::read_through); waits for the GPU). The vectors are reused: a
    /// caller that keeps them from read to read allocates nothing once they are large enough.
    pub fn read_ranges(
        &self,
        staging: &mut Staging,
        buffer: &wgpu::Buffer,
        ranges: &[Range<u64>],
        into: &mut Vec<Vec<u8>>,
    ) -> Result<()> {
        into.resize_with(ranges.len(), Vec::new);
        // Each vector as long as its range (only what it grows by is zeroed first).
        for (part, r) in into.iter_mut().zip(ranges) {
            part.resize((r.end - r.start) as usize, 0);
        }
        let total: u64 = ranges.iter().map(|r| r.end - r.start).sum();
        if total == 0 {
            return Ok(());
        }
        let kept = staging.0.take();
        let buffer_back = match kept {
            Some(b) if b.size() >= total => b,
            _ => self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("mochi.readback"),
                size: total,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let mut at = 0;
        for r in ranges {
            encoder.copy_buffer_to_buffer(buffer, r.start, &buffer_back, at, r.end - r.start);
            at += r.end - r.start;
        }
        self.queue.submit([encoder.finish()]);
        self.map(&buffer_back, 0..total, wgpu::MapMode::Read, "read-back")?;
        let taken = match buffer_back.get_mapped_range(..total) {
            Ok(view) => {
                let mut rest = &view[..];
                for part in into.iter_mut() {
                    let (from, after) = rest.split_at(part.len());
                    // On every core, a piece at a time.
                    (part.par_chunks_mut(PIECE_BYTES))
                        .zip(from.par_chunks(PIECE_BYTES))
                        .for_each(|(to, from)| to.copy_from_slice(from));
                    rest = after;
                }
                Ok(())
            }
            Err(e) => Err(Error::Gpu(format!("read-back failed: {e}"))),
        };
        buffer_back.unmap();
        staging.0 = Some(buffer_back);
        taken
    }

    /// A buffer the host writes (mapped) and the GPU copies from, of `bytes` bytes, kept by its
    /// owner between uploads ([`fill_upload`](Self::fill_upload)).
    pub fn upload_buffer(&self, label: &str, bytes: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.max(16),
            usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    }

    /// Maps `range` of `upload` (from [`upload_buffer`](Self::upload_buffer)), hands it to
    /// `fill` (which may write it on the rayon pool, as `copy_surveyed` does) and unmaps it,
    /// ready for a copy: an upload that allocates no staging memory. After an error of `fill` the
    /// range holds anything.
    pub fn fill_upload<R>(
        &self,
        upload: &wgpu::Buffer,
        range: Range<u64>,
        fill: impl FnOnce(WriteOnly<'_, [u8]>) -> Result<R>,
    ) -> Result<R> {
        if range.is_empty() {
            return fill(WriteOnly::default());
        }
        self.map(upload, range.clone(), wgpu::MapMode::Write, "upload")?;
        let filled = match upload.get_mapped_range_mut(range) {
            Ok(mut view) => fill(view.slice(..)),
            Err(e) => Err(Error::Gpu(format!("upload failed: {e}"))),
        };
        upload.unmap();
        filled
    }

    /// Maps `range` of `buffer` in `mode` and waits for it; errors name `what`.
    fn map(
        &self,
        buffer: &wgpu::Buffer,
        range: Range<u64>,
        mode: wgpu::MapMode,
        what: &str,
    ) -> Result<()> {
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.slice(range).map_async(mode, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .map_err(|_| Error::Gpu(format!("{what} was cancelled")))?
            .map_err(|e| Error::Gpu(format!("{what} failed: {e}")))
    }

    /// Copies `size` bytes of `buffer` into `staging`, maps it, hands the first `bytes` as
    /// values to `take` and unmaps it again.
    fn read_via<T: bytemuck::Pod, R>(
        &self,
        staging: &wgpu::Buffer,
        buffer: &wgpu::Buffer,
        size: u64,
        bytes: u64,
        take: impl FnOnce(&[T]) -> R,
    ) -> Result<R> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, staging, 0, size);
        self.queue.submit([encoder.finish()]);
        self.map(staging, 0..size, wgpu::MapMode::Read, "read-back")?;
        let taken = match staging.get_mapped_range(..size) {
            Ok(view) => Ok(take(bytemuck::cast_slice::<u8, T>(&view[..bytes as usize]))),
            Err(e) => Err(Error::Gpu(format!("read-back failed: {e}"))),
        };
        staging.unmap();
        taken
    }
}

/// Bytes of one piece of a [`copy_surveyed`] (whole `f32`, `[f32; 3]` and `[f32; 4]` values).
const PIECE_BYTES: usize = 3 << 16;

/// Copies `values` into `view` (exactly their bytes) on the rayon pool, a piece of
/// `PIECE_BYTES` at a time, calling `survey(first, values)` on each piece's values as they are
/// copied (`first` the index of the first); the pieces' surveys folded in order by `merge`,
/// from `empty`: a caller that checks values while uploading them reads them once.
pub(crate) fn copy_surveyed<T, S>(
    view: WriteOnly<'_, [u8]>,
    values: &[T],
    survey: impl Fn(usize, &[T]) -> S + Sync,
    merge: impl Fn(S, S) -> S + Sync + Send,
    empty: impl Fn() -> S + Sync + Send,
) -> S
where
    T: bytemuck::Pod + Sync,
    S: Send,
{
    let per_piece = PIECE_BYTES / size_of::<T>();
    assert_eq!(view.len(), size_of_val(values), "the view holds the values");
    let (pieces, mut tail) = view.into_chunks::<PIECE_BYTES>();
    let whole = pieces.len() * per_piece;
    let (head, rest) = values.split_at(whole);
    // Whole pieces (sized, so each can go to another thread), then the rest here.
    let pieces: Vec<_> = pieces.into_iter().collect();
    let surveyed = head
        .par_chunks(per_piece)
        .zip(pieces)
        .enumerate()
        .map(|(k, (from, to))| {
            let found = survey(k * per_piece, from);
            WriteOnly::<[u8]>::from(to).copy_from_slice(bytemuck::cast_slice(from));
            found
        })
        .reduce(&empty, &merge);
    tail.copy_from_slice(bytemuck::cast_slice(rest));
    merge(surveyed, survey(whole, rest))
}

/// [`copy_surveyed`] without a survey: `values` copied into `view` on the rayon pool.
pub(crate) fn copy_into<T: bytemuck::Pod + Sync>(view: WriteOnly<'_, [u8]>, values: &[T]) {
    copy_surveyed(view, values, |_, _| (), |(), ()| (), || ());
}

/// Read-backs of at least this many bytes are copied out of the mapping on the rayon pool.
const PARALLEL_COPY_BYTES: usize = 1 << 20;

/// A host-readable buffer kept between read-backs ([`Gpu::read_through`]); empty at first.
#[derive(Debug, Default)]
pub struct Staging(Option<wgpu::Buffer>);

/// Records a dispatch of `pipeline` with `bind` at group 0 over the workgroups `(x, y)` into an
/// open pass. Dependent dispatches recorded in one pass cost less than one pass each (every pass
/// boundary costs the GPU time: docs/performance-log/).
pub fn record(
    pass: &mut wgpu::ComputePass,
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    (x, y): (u32, u32),
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind, &[]);
    pass.dispatch_workgroups(x, y, 1);
}

/// Workgroup counts `(x, y)` covering `n` invocations of `size` threads, within the per-dimension
/// limit; shaders rebuild the flat index as `id.x + id.y * x * size`.
pub fn workgroups(n: u32, size: u32, max_per_dim: u32) -> (u32, u32) {
    let groups = n.div_ceil(size).max(1);
    if groups <= max_per_dim {
        (groups, 1)
    } else {
        (max_per_dim, groups.div_ceil(max_per_dim))
    }
}

/// Whether this is a CI run (`CI=true`), where every GPU test must find an adapter.
#[cfg(test)]
pub(crate) fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// For unit tests: an open compute device; without an adapter a panic under CI, else a printed
/// note that `what` is not tested on this machine, and `None`.
#[cfg(test)]
pub(crate) fn test_gpu(what: &str) -> Option<Gpu> {
    match Gpu::open(Need::Compute) {
        Ok(gpu) => Some(gpu),
        Err(why) => {
            assert!(!under_ci(), "CI expects a GPU adapter for {what}: {why}");
            eprintln!("note: {what} is not tested on this machine: {why}");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spheres::{SphereSet, Survey};

    #[test]
    fn modules_compiled_on_many_threads_at_once_keep_one_index_per_source() {
        // The index keys a module's pipelines: two sources sharing one would hand out each
        // other's pipelines (a step would run another variant's kernels).
        let Some(gpu) = test_gpu("compiling modules on several threads") else {
            return;
        };
        let sources: Vec<String> = (0..6)
            .map(|k| format!("@compute @workgroup_size(1) fn main() {{ let x = {k}u; }}"))
            .collect();
        std::thread::scope(|scope| {
            for _ in 0..8 {
                scope.spawn(|| {
                    for source in &sources {
                        gpu.own_module("mochi.test", source);
                    }
                });
            }
        });
        let mut indices: Vec<usize> = sources
            .iter()
            .map(|s| gpu.own_module("mochi.test", s).index)
            .collect();
        indices.sort_unstable();
        indices.dedup();
        assert_eq!(indices.len(), sources.len(), "{indices:?}");
    }

    /// Centres spread over several whole pieces and a tail, surveyed while copied into bytes.
    fn surveyed(centers: &[[f32; 3]]) -> (Vec<u8>, Result<Option<crate::spheres::Bounds>>) {
        let mut bytes = vec![0u8; size_of_val(centers)];
        let found = copy_surveyed(
            WriteOnly::from(bytes.as_mut_slice()),
            centers,
            Survey::of_centers,
            Survey::merge,
            Survey::empty,
        );
        (bytes, found.into_bounds(centers.len()))
    }

    #[test]
    fn ranges_read_into_kept_vectors_hold_each_range_alone_as_the_ranges_shrink_and_grow() {
        // A rank reads its lists back into the vectors of the last round: each must end up
        // exactly its range, whether it was longer or shorter before (more than a copy's
        // piece, so that the copy runs on several threads).
        let Some(gpu) = test_gpu("reading ranges into kept vectors") else {
            return;
        };
        let words: Vec<u32> = (0..300_000u32)
            .map(|k| k.wrapping_mul(2_654_435_761))
            .collect();
        let buffer = gpu.storage(
            "mochi.test.ranges",
            4 * words.len() as u64,
            wgpu::BufferUsages::empty(),
        );
        gpu.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(&words));
        let bytes: &[u8] = bytemuck::cast_slice(&words);
        let mut staging = Staging::default();
        let mut kept = Vec::new();
        let rounds: [&[Range<u64>]; 4] = [
            &[0..400_000, 400_000..400_000, 800_000..1_200_000],
            &[4..8, 1_000_000..1_199_996],
            &[12..1_000_012, 0..0, 0..0],
            &[],
        ];
        for ranges in rounds {
            gpu.read_ranges(&mut staging, &buffer, ranges, &mut kept)
                .unwrap();
            assert_eq!(kept.len(), ranges.len());
            for (got, r) in kept.iter().zip(ranges) {
                assert!(got[..] == bytes[r.start as usize..r.end as usize], "{r:?}");
            }
        }
    }

    #[test]
    fn a_surveyed_copy_copies_every_centre_and_finds_the_bounds_and_the_first_bad_one() {
        let per_piece = PIECE_BYTES / 12;
        let n = 3 * per_piece + 1234;
        let centers: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                let t = i as f32;
                [
                    t.sin() * 5.0,
                    (t * 0.37).cos() * 3.0 - 1.0,
                    (i % 977) as f32 * 0.01,
                ]
            })
            .collect();
        let (bytes, bounds) = surveyed(&centers);
        assert_eq!(bytes, bytemuck::cast_slice::<_, u8>(&centers));
        let set = SphereSet::new(centers.clone(), vec![0.1; n]).unwrap();
        assert_eq!(bounds.unwrap(), set.bounds());
        // A bad centre in the first, a middle and the last whole piece, and in the tail; the
        // first of two is named.
        for bad in [0, per_piece + 17, 3 * per_piece - 1, 3 * per_piece, n - 1] {
            let mut broken = centers.clone();
            broken[bad][2] = f32::INFINITY;
            broken[n - 1][0] = f32::NAN;
            if bad < 2 * per_piece {
                broken[2 * per_piece + 5][1] = -f32::INFINITY;
            }
            let found = surveyed(&broken).1;
            assert!(
                matches!(found, Err(Error::InvalidSphere { index, .. }) if index == bad),
                "{bad}: {found:?}"
            );
        }
    }
}
