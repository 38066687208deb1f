//! The safe layer over OptiX (`sys.rs`) and the CUDA kernels, its owners: the OptiX objects mochi
//! uses (the device with its CUDA and OptiX contexts, the pipelines of the device programs, a
//! geometry acceleration structure of custom primitives that can be built and refitted) and the
//! buffers the launches read (the DEM state, an order, the contact history, the material table,
//! the mesh walls), each freeing what it created when dropped. The typed launches over them are
//! `launches.rs`'s; nothing outside these two files holds a raw device pointer.
//!
//! Every launch and build is enqueued on the device's one stream, and `cudarc` frees a buffer on
//! that stream too: a buffer dropped after a launch is freed only after the GPU is done with it,
//! which is what makes the asynchronous launches sound.

use super::sys::{self, Api};
use crate::dem::model::law::CohesionParams;
use crate::dem::model::{MaterialTable, TableLaw};
use crate::engines::common::walls::WallTables;
use crate::error::OptixError;
use crate::gpu::shader::storage_bytes;
use crate::particles::{HistoryEntry, LoadEntry};
use cudarc::driver::{
    CudaContext, CudaSlice, CudaStream, DevicePtr, DevicePtrMut, DeviceRepr, LaunchConfig,
};
use std::ffi::{CString, c_char, c_void};
use std::sync::Arc;

/// Result of this layer.
pub type Result<T> = std::result::Result<T, OptixError>;

/// Counters the device programs spread their candidate (and contact) counts over: a power of
/// two, indexed by `i & (COUNTER_SLOTS - 1)` (the `& 255u` of `optix/detect.cu` and
/// `optix/dem.cu`, checked by `tests/optix.rs`).
pub const COUNTER_SLOTS: usize = 256;

/// Threads per block of the CUDA kernels.
const BLOCK: u32 = 256;

/// Bytes between two proxy boxes (6 floats: min x, y, z, then max), as the kernels write them.
const BOX_STRIDE: u32 = 6 * size_of::<f32>() as u32;

/// Maps a CUDA driver error of `call` into [`OptixError::Cuda`].
pub fn cuda(call: &'static str) -> impl Fn(cudarc::driver::DriverError) -> OptixError {
    move |error| OptixError::Cuda { call, error }
}

/// `Ok` if `buffer` of `launch` holds at least `needed` elements.
pub(super) fn check_len<T>(
    launch: &'static str,
    buffer: &'static str,
    slice: &CudaSlice<T>,
    needed: usize,
) -> Result<()> {
    if slice.len() >= needed {
        return Ok(());
    }
    Err(OptixError::BufferTooShort {
        launch,
        buffer,
        len: slice.len(),
        needed,
    })
}

/// The GPU with its CUDA context, stream and OptiX context.
pub struct Device {
    api: &'static Api,
    pub(super) cuda: Arc<CudaContext>,
    /// The one stream every copy, launch and build of the engine is ordered on.
    pub stream: Arc<CudaStream>,
    context: sys::DeviceContext,
    /// GPU name.
    pub name: String,
    /// RT core generation (0: none, traversal runs in software).
    pub rtcore_version: u32,
    /// Most primitives one acceleration structure takes.
    pub max_primitives: u32,
}

// SAFETY: the OptiX context is a handle OptiX allows to be used from any thread; mochi only
// makes calls on it that OptiX documents as thread-safe (creating objects, building, launching).
unsafe impl Send for Device {}
// SAFETY: as for Send; `&Device` offers no call that mutates the context.
unsafe impl Sync for Device {}

impl Device {
    /// Opens GPU 0 (under an MPI launcher, the GPU of the process's local rank L: the
    /// (L mod G)-th of G), or says why it cannot ([`OptixError::Unavailable`] without a
    /// driver).
    pub fn open() -> Result<Device> {
        if !sys::cuda_present() {
            return Err(OptixError::Unavailable(
                "no NVIDIA driver (libcuda.so) found".into(),
            ));
        }
        let api = Api::get()?;
        let gpus = CudaContext::device_count().map_err(cuda("counting the GPUs"))?;
        let ordinal = crate::launcher::local_rank() % gpus.max(1) as usize;
        let context_cuda =
            CudaContext::new(ordinal).map_err(cuda("opening the GPU of this process"))?;
        let name = context_cuda.name().map_err(cuda("reading the GPU name"))?;
        let stream = context_cuda.default_stream();
        let options = sys::DeviceContextOptions {
            log_callback: None,
            log_callback_data: std::ptr::null_mut(),
            log_callback_level: 0,
            validation_mode: 0,
        };
        let mut context = std::ptr::null_mut();
        // SAFETY: a live CUDA context, options and out-pointer valid for the call.
        let status = unsafe {
            (api.device_context_create)(context_cuda.cu_ctx().cast(), &options, &mut context)
        };
        api.check(status, "creating the device context", "")?;
        let mut device = Device {
            api,
            cuda: context_cuda,
            stream,
            context,
            name,
            rtcore_version: 0,
            max_primitives: 0,
        };
        device.rtcore_version = device.property(
            sys::DEVICE_PROPERTY_RTCORE_VERSION,
            "reading the RT core version",
        )?;
        device.max_primitives = device.property(
            sys::DEVICE_PROPERTY_LIMIT_MAX_PRIMITIVES_PER_GAS,
            "reading the primitive limit",
        )?;
        Ok(device)
    }

    /// Free memory of the GPU \[bytes\].
    pub fn free_memory(&self) -> Result<u64> {
        let (free, _total) = self
            .cuda
            .mem_get_info()
            .map_err(cuda("reading the free memory"))?;
        Ok(free as u64)
    }

    /// A u32 property of the device context.
    fn property(&self, property: std::ffi::c_int, call: &'static str) -> Result<u32> {
        let mut value = 0u32;
        // SAFETY: the property is a u32 written into value, which has room for it.
        let status = unsafe {
            (self.api.device_context_get_property)(
                self.context,
                property,
                (&mut value as *mut u32).cast(),
                size_of::<u32>(),
            )
        };
        self.api.check(status, call, "")?;
        Ok(value)
    }

    /// A zeroed device buffer of `len` bytes (OptiX's alignment holds: CUDA allocations are
    /// 256-byte aligned).
    fn bytes(&self, len: usize) -> Result<CudaSlice<u8>> {
        self.stream
            .alloc_zeros::<u8>(len.max(1))
            .map_err(cuda("allocating device memory"))
    }

    /// The raw device pointer of `slice`, for OptiX calls and launch parameters.
    pub(super) fn ptr<T>(&self, slice: &CudaSlice<T>) -> sys::DevicePtr {
        slice.device_ptr(&self.stream).0
    }

    /// The raw device pointer of `slice`, which the GPU will write.
    pub(super) fn ptr_mut<T>(&self, slice: &mut CudaSlice<T>) -> sys::DevicePtr {
        slice.device_ptr_mut(&self.stream).0
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: created in open, destroyed once; pipelines hold an Arc of the device, so they
        // are gone by now.
        unsafe { (self.api.device_context_destroy)(self.context) };
    }
}

/// Runs an OptiX call that writes a log, and puts the log in its error.
fn with_log(
    api: &Api,
    call: &'static str,
    run: impl FnOnce(*mut c_char, *mut usize) -> sys::OptixResult,
) -> Result<()> {
    let mut log = vec![0u8; 4096];
    let mut len = log.len();
    let status = run(log.as_mut_ptr().cast(), &mut len);
    let text = String::from_utf8_lossy(&log[..len.min(log.len())]);
    api.check(status, call, &text)
}

/// A pipeline of one raygen and one intersection-only hit group (no miss program), with its
/// shader binding table: records of headers only.
pub(super) struct Pipeline {
    pub(super) device: Arc<Device>,
    module: sys::Module,
    groups: [sys::ProgramGroup; 3],
    pipeline: sys::Pipeline,
    sbt: sys::ShaderBindingTable,
    _records: CudaSlice<u8>,
}

impl Pipeline {
    /// Builds the pipeline from `ptx` with entry points `__raygen__{name}` and
    /// `__intersection__{name}`, launch parameters in `params`, `payloads` payload words.
    pub(super) fn new(
        device: &Arc<Device>,
        ptx: &str,
        name: &str,
        payloads: i32,
    ) -> Result<Pipeline> {
        let api = device.api;
        let params_name = CString::new("params").expect("no NUL");
        let compile = sys::PipelineCompileOptions {
            uses_motion_blur: 0,
            traversable_graph_flags: sys::TRAVERSABLE_GRAPH_FLAG_ALLOW_SINGLE_GAS,
            num_payload_values: payloads,
            num_attribute_values: 0,
            exception_flags: 0,
            pipeline_launch_params_variable_name: params_name.as_ptr(),
            uses_primitive_type_flags: sys::PRIMITIVE_TYPE_FLAGS_CUSTOM,
            allow_opacity_micromaps: 0,
            allow_clustered_geometry: 0,
        };
        let module_options = sys::ModuleCompileOptions {
            max_register_count: 0,
            opt_level: 0,
            debug_level: 0,
            bound_values: std::ptr::null(),
            num_bound_values: 0,
            num_payload_types: 0,
            payload_types: std::ptr::null(),
        };
        let mut module = std::ptr::null_mut();
        with_log(api, "compiling the module", |log, len| {
            // SAFETY: options, PTX and log buffers valid for the call.
            unsafe {
                (api.module_create)(
                    device.context,
                    &module_options,
                    &compile,
                    ptx.as_ptr().cast(),
                    ptx.len(),
                    log,
                    len,
                    &mut module,
                )
            }
        })?;
        let mut pipeline = Pipeline {
            device: device.clone(),
            module,
            groups: [std::ptr::null_mut(); 3],
            pipeline: std::ptr::null_mut(),
            sbt: sys::ShaderBindingTable::default(),
            _records: device.bytes(1)?,
        };
        let raygen = CString::new(format!("__raygen__{name}")).expect("no NUL");
        let intersection = CString::new(format!("__intersection__{name}")).expect("no NUL");
        let none = sys::ProgramEntry {
            module: std::ptr::null_mut(),
            entry_function_name: std::ptr::null(),
        };
        let entry = |name: &CString| sys::ProgramEntry {
            module,
            entry_function_name: name.as_ptr(),
        };
        let descs = [
            sys::ProgramGroupDesc {
                kind: sys::PROGRAM_GROUP_KIND_RAYGEN,
                flags: 0,
                entries: [entry(&raygen), none, none],
            },
            sys::ProgramGroupDesc {
                kind: sys::PROGRAM_GROUP_KIND_MISS,
                flags: 0,
                entries: [none, none, none],
            },
            sys::ProgramGroupDesc {
                kind: sys::PROGRAM_GROUP_KIND_HITGROUP,
                flags: 0,
                entries: [none, none, entry(&intersection)],
            },
        ];
        let group_options = sys::ProgramGroupOptions {
            payload_type: std::ptr::null(),
        };
        for (k, desc) in descs.iter().enumerate() {
            let mut group = std::ptr::null_mut();
            with_log(api, "creating a program group", |log, len| {
                // SAFETY: one valid description, options and log buffers.
                unsafe {
                    (api.program_group_create)(
                        device.context,
                        desc,
                        1,
                        &group_options,
                        log,
                        len,
                        &mut group,
                    )
                }
            })?;
            pipeline.groups[k] = group;
        }
        let link = sys::PipelineLinkOptions { max_trace_depth: 1 };
        let mut raw = std::ptr::null_mut();
        with_log(api, "linking the pipeline", |log, len| {
            // SAFETY: the groups were created above and are valid.
            unsafe {
                (api.pipeline_create)(
                    device.context,
                    &compile,
                    &link,
                    pipeline.groups.as_ptr(),
                    pipeline.groups.len() as u32,
                    log,
                    len,
                    &mut raw,
                )
            }
        })?;
        pipeline.pipeline = raw;

        // One header-only record per group, each padded to the record alignment.
        let stride = sys::SBT_RECORD_HEADER_SIZE.next_multiple_of(sys::SBT_RECORD_ALIGNMENT);
        let mut records = vec![0u8; stride * 3];
        for (k, &group) in pipeline.groups.iter().enumerate() {
            // SAFETY: the header pointer has SBT_RECORD_HEADER_SIZE bytes of room.
            let status = unsafe {
                (api.sbt_record_pack_header)(
                    group,
                    records[k * stride..].as_mut_ptr().cast::<c_void>(),
                )
            };
            api.check(status, "packing a shader-binding-table record", "")?;
        }
        let records = device
            .stream
            .clone_htod(&records)
            .map_err(cuda("uploading the shader binding table"))?;
        let base = device.ptr(&records);
        pipeline.sbt = sys::ShaderBindingTable {
            raygen_record: base,
            miss_record_base: base + stride as u64,
            miss_record_stride_in_bytes: stride as u32,
            miss_record_count: 1,
            hitgroup_record_base: base + 2 * stride as u64,
            hitgroup_record_stride_in_bytes: stride as u32,
            hitgroup_record_count: 1,
            ..Default::default()
        };
        pipeline._records = records;
        Ok(pipeline)
    }

    /// Launches `width` raygen invocations reading launch parameters `params` (on the device).
    ///
    /// # Safety
    /// `params` must hold the launch parameters of this pipeline's programs, every pointer in
    /// them to a live buffer on the device's stream as large as the programs index for `width`
    /// invocations.
    pub(super) unsafe fn launch(&self, params: &CudaSlice<u8>, width: u32) -> Result<()> {
        if width == 0 {
            return Ok(());
        }
        let device = &self.device;
        let api = device.api;
        // SAFETY: pipeline and SBT live as long as self (freed after the stream's work, see the
        // module doc); the caller vouches for the parameters.
        let status = unsafe {
            (api.launch)(
                self.pipeline,
                device.stream.cu_stream().cast(),
                device.ptr(params),
                params.len(),
                &self.sbt,
                width,
                1,
                1,
            )
        };
        api.check(status, "launching the point rays", "")
    }
}

// SAFETY: the OptiX handles are owned by this value and only used through it.
unsafe impl Send for Pipeline {}

impl Drop for Pipeline {
    fn drop(&mut self) {
        let api = self.device.api;
        // SAFETY: each object was created by this pipeline (or is null) and is destroyed once.
        unsafe {
            if !self.pipeline.is_null() {
                (api.pipeline_destroy)(self.pipeline);
            }
            for g in self.groups.iter().filter(|g| !g.is_null()) {
                (api.program_group_destroy)(*g);
            }
            if !self.module.is_null() {
                (api.module_destroy)(self.module);
            }
        }
    }
}

/// A pipeline's launch parameters on the device, uploaded again only when they change (a DEM
/// step's stay the same between rebuilds).
pub(super) struct LaunchParams<P: bytemuck::Pod> {
    on_device: CudaSlice<u8>,
    last: Option<P>,
}

impl<P: bytemuck::Pod> LaunchParams<P> {
    pub(super) fn new(device: &Device) -> Result<Self> {
        Ok(Self {
            on_device: device.bytes(size_of::<P>())?,
            last: None,
        })
    }

    /// Makes the buffer hold `params` (a copy ordered on the stream, only if they differ from
    /// the last ones).
    pub(super) fn set(&mut self, stream: &Arc<CudaStream>, params: P) -> Result<&CudaSlice<u8>> {
        let bytes = bytemuck::bytes_of(&params);
        if self.last.as_ref().map(bytemuck::bytes_of) != Some(bytes) {
            stream
                .memcpy_htod(bytes, &mut self.on_device)
                .map_err(cuda("uploading launch parameters"))?;
            self.last = Some(params);
        }
        Ok(&self.on_device)
    }
}

/// Launch parameters of a pipeline that alternates between a few sets (the granular step's
/// history buffers take turns): each set stays on the device in a buffer of its own, so that
/// a launch uploads parameters only when they are new.
pub(super) struct LaunchParamSets<P: bytemuck::Pod> {
    sets: Vec<LaunchParams<P>>,
    /// The set replaced next once all are in use.
    next: usize,
}

impl<P: bytemuck::Pod> Default for LaunchParamSets<P> {
    fn default() -> Self {
        Self {
            sets: Vec::new(),
            next: 0,
        }
    }
}

impl<P: bytemuck::Pod> LaunchParamSets<P> {
    /// Sets kept on the device (the granular step's three history buffers make six pairs).
    const SETS: usize = 8;

    /// A buffer holding `params`.
    pub(super) fn set(&mut self, device: &Device, params: P) -> Result<&CudaSlice<u8>> {
        let bytes = bytemuck::bytes_of(&params);
        let held = |p: &LaunchParams<P>| p.last.as_ref().map(bytemuck::bytes_of) == Some(bytes);
        let k = match self.sets.iter().position(held) {
            Some(k) => k,
            None if self.sets.len() < Self::SETS => {
                self.sets.push(LaunchParams::new(device)?);
                self.sets.len() - 1
            }
            None => {
                self.next = (self.next + 1) % Self::SETS;
                self.next
            }
        };
        self.sets[k].set(&device.stream, params)
    }
}

/// Words of one entry of the table on the device ([`TableLaw`], `MochiTableLaw` in
/// `optix/physics.cuh`).
pub(super) const LAW_WORDS: usize = size_of::<TableLaw>() / size_of::<u32>();
const _: () = assert!(LAW_WORDS == 12);

/// The material table on the device (`MaterialTable::device_laws`, row by row: the laws and
/// bridges of a sphere of each material against each material and a rigid wall). Every material index
/// the step reads (the spheres', the walls' columns) is checked on the host against it.
pub struct LawTable {
    pub(super) words: CudaSlice<u32>,
    /// Laws in a row: the materials and a rigid wall.
    pub(super) columns: u32,
    /// The cohesion laws that are the step's (passed beside the table's address).
    pub(super) cohesion: CohesionParams,
}

impl LawTable {
    /// Uploads `table`, to be read with the cohesion laws `cohesion`.
    pub fn upload(
        stream: &Arc<CudaStream>,
        table: &MaterialTable,
        cohesion: CohesionParams,
    ) -> Result<Self> {
        Ok(Self {
            words: stream
                .clone_htod(bytemuck::cast_slice::<TableLaw, u32>(&table.device_laws()))
                .map_err(cuda("uploading the material laws"))?,
            columns: table.count as u32 + 1,
            cohesion,
        })
    }
}

/// Words of one history entry on the device ([`HistoryEntry`], `MochiHistoryEntry` in
/// `optix/history.cuh`).
const ENTRY_WORDS: usize = size_of::<HistoryEntry>() / size_of::<u32>();
const _: () = assert!(ENTRY_WORDS == 7);

/// Words of one load history on the device ([`LoadEntry`], `MochiLoadEntry` in
/// `optix/history.cuh`).
const LOAD_WORDS: usize = size_of::<LoadEntry>() / size_of::<u32>();
const _: () = assert!(LOAD_WORDS == 4);

/// The mesh walls' parameters as `granular_integrate` takes them (`MochiMeshParams` in
/// `optix/mesh_walls.cuh`, [`MeshParams`] of the wgpu engines).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MeshLaunch {
    pub walls: u32,
    pub box_walls: u32,
    pub loads_step: u32,
    pub load_lanes: u32,
    pub own_lo: [f32; 3],
    pub own_hi: [f32; 3],
}

// SAFETY: `#[repr(C)]` plain data laid out as `MochiMeshParams` in optix/mesh_walls.cuh.
unsafe impl DeviceRepr for MeshLaunch {}

/// The mesh walls on the device (`optix/mesh_walls.cuh`): each wall's row (`MochiMeshWall`,
/// the words of [`WallTables::rows`]), the grids, the triangles and the loads summed in the
/// step `params.loads_step`, 8 floats per lane and wall, then the most candidates a sphere had.
pub struct MeshBuffers {
    pub params: MeshLaunch,
    pub(super) walls: CudaSlice<u32>,
    pub(super) grid: CudaSlice<u32>,
    pub(super) tris: CudaSlice<f32>,
    pub(super) loads: CudaSlice<f32>,
}

impl MeshBuffers {
    /// Uploads `tables`.
    pub fn upload(stream: &Arc<CudaStream>, tables: &WallTables) -> Result<Self> {
        let alloc = cuda("uploading the mesh walls");
        let upload_u32 = |words: &[u32]| {
            if words.is_empty() {
                stream.alloc_zeros::<u32>(1)
            } else {
                stream.clone_htod(words)
            }
            .map_err(&alloc)
        };
        let rows = storage_bytes(&tables.rows);
        let tris: &[f32] = bytemuck::cast_slice(&tables.tris);
        let p = tables.params;
        Ok(Self {
            params: MeshLaunch {
                walls: p.walls,
                box_walls: p.box_walls,
                loads_step: p.loads_step,
                load_lanes: p.load_lanes,
                own_lo: p.own_lo.0,
                own_hi: p.own_hi.0,
            },
            walls: upload_u32(bytemuck::cast_slice(&rows))?,
            grid: upload_u32(&tables.grid)?,
            tris: if tris.is_empty() {
                stream.alloc_zeros::<f32>(4)
            } else {
                stream.clone_htod(tris)
            }
            .map_err(&alloc)?,
            loads: stream
                .alloc_zeros::<f32>(tables.load_words())
                .map_err(&alloc)?,
        })
    }

    /// Zeroes the loads (and, with `counts`, the most candidates a sphere had).
    pub fn clear_loads(&mut self, stream: &Arc<CudaStream>, counts: bool) -> Result<()> {
        let clear = cuda("clearing the mesh walls' loads");
        let words = self.loads.len() - usize::from(!counts);
        let mut loads = self.loads.slice_mut(..words);
        stream.memset_zeros(&mut loads).map_err(clear)
    }

    /// The loads' words (f32 bits; the last the most candidates a sphere had).
    pub fn read_loads(&self, stream: &Arc<CudaStream>) -> Result<Vec<u32>> {
        let floats = stream
            .clone_dtoh(&self.loads)
            .map_err(cuda("reading the mesh walls' loads back"))?;
        Ok(floats.iter().map(|x| x.to_bits()).collect())
    }
}

/// One contact history buffer on the device (`MochiSlots` in `optix/history.cuh`): for each of
/// `n` spheres by stable id, a count and `slots` entries of [`HistoryEntry`]'s words, and under
/// the Mindlin–Deresiewicz model as many [`LoadEntry`]s beside them.
pub struct HistorySlots {
    pub(super) counts: CudaSlice<u32>,
    pub(super) entries: CudaSlice<u32>,
    /// The load histories beside `entries` (`None`: the model keeps none).
    pub(super) loads: Option<CudaSlice<u32>>,
    n: u32,
    slots: u32,
}

impl HistorySlots {
    /// Bytes of a buffer of `n` spheres with `slots` slots each (with load histories where
    /// `loaded`).
    pub fn bytes(n: u32, slots: u32, loaded: bool) -> u64 {
        let slot = size_of::<HistoryEntry>() + if loaded { size_of::<LoadEntry>() } else { 0 };
        n as u64 * (4 + slots as u64 * slot as u64)
    }

    /// A buffer holding, for each of the `counts.len()` spheres, `counts[i]` entries of
    /// `entries[i·slots..]`, and their load histories of `loads` (`None`: none kept).
    pub fn upload(
        stream: &Arc<CudaStream>,
        slots: u32,
        counts: &[u32],
        entries: &[HistoryEntry],
        loads: Option<&[LoadEntry]>,
    ) -> Result<Self> {
        let n = counts.len();
        for (buffer, len) in [
            ("entries", Some(entries.len())),
            ("loads", loads.map(<[_]>::len)),
        ] {
            match len {
                Some(len) if len != n * slots as usize => {
                    return Err(OptixError::BufferTooShort {
                        launch: "uploading the contact history",
                        buffer,
                        len,
                        needed: n * slots as usize,
                    });
                }
                _ => {}
            }
        }
        if let Some(&count) = counts.iter().find(|&&c| c > slots) {
            return Err(OptixError::IndexOutOfRange {
                buffer: "history counts",
                index: count as u64,
                len: slots as usize,
            });
        }
        let upload = |words: &[u32]| {
            if words.is_empty() {
                stream.alloc_zeros::<u32>(1)
            } else {
                stream.clone_htod(words)
            }
            .map_err(cuda("uploading the contact history"))
        };
        Ok(Self {
            counts: upload(counts)?,
            entries: upload(bytemuck::cast_slice(entries))?,
            loads: loads.map(|l| upload(bytemuck::cast_slice(l))).transpose()?,
            n: n as u32,
            slots,
        })
    }

    /// An empty buffer for `n` spheres with `slots` slots each (with load histories where
    /// `loaded`).
    pub fn empty(stream: &Arc<CudaStream>, n: u32, slots: u32, loaded: bool) -> Result<Self> {
        let entries = n as usize * slots as usize * ENTRY_WORDS;
        let zeros = |len: usize| {
            stream
                .alloc_zeros::<u32>(len.max(1))
                .map_err(cuda("allocating the contact history"))
        };
        Ok(Self {
            counts: zeros(n as usize)?,
            entries: zeros(entries)?,
            loads: loaded
                .then(|| zeros(n as usize * slots as usize * LOAD_WORDS))
                .transpose()?,
            n,
            slots,
        })
    }

    /// The device address of the load histories (0 where none are kept: the programs compiled
    /// without `MOCHI_LOAD_HISTORY` never use it).
    pub(super) fn loads_ptr(&self, device: &Device) -> u64 {
        self.loads.as_ref().map_or(0, |l| device.ptr(l))
    }

    /// [`loads_ptr`](Self::loads_ptr), for writing.
    pub(super) fn loads_ptr_mut(&mut self, device: &Device) -> u64 {
        self.loads.as_mut().map_or(0, |l| device.ptr_mut(l))
    }

    /// Slots per sphere.
    pub fn slots(&self) -> u32 {
        self.slots
    }

    /// The counts, the entries (`slots` per sphere) and their load histories (empty where
    /// none are kept), read back.
    pub fn read(&self, stream: &Arc<CudaStream>) -> Result<SlotsRead> {
        let read = cuda("reading the contact history back");
        let mut counts = stream.clone_dtoh(&self.counts).map_err(&read)?;
        counts.truncate(self.n as usize);
        let slots = self.n as usize * self.slots as usize;
        let mut words = stream.clone_dtoh(&self.entries).map_err(&read)?;
        words.truncate(slots * ENTRY_WORDS);
        let loads = match &self.loads {
            Some(l) => {
                let mut words = stream.clone_dtoh(l).map_err(&read)?;
                words.truncate(slots * LOAD_WORDS);
                bytemuck::cast_slice(&words).to_vec()
            }
            None => Vec::new(),
        };
        Ok(SlotsRead {
            counts,
            entries: bytemuck::cast_slice(&words).to_vec(),
            loads,
        })
    }

    /// `Ok` if the buffer covers `n` spheres with `slots` slots each, with load histories
    /// where `loaded` (the programs of the Mindlin–Deresiewicz model read and write them).
    pub(super) fn check(
        &self,
        launch: &'static str,
        n: u32,
        slots: u32,
        loaded: bool,
    ) -> Result<()> {
        let needed = n as usize * slots as usize;
        let len = self.n as usize * self.slots as usize;
        if !(self.n >= n && self.slots == slots) {
            return Err(OptixError::BufferTooShort {
                launch,
                buffer: "history",
                len,
                needed,
            });
        }
        if loaded && n > 0 && self.loads.is_none() {
            return Err(OptixError::BufferTooShort {
                launch,
                buffer: "load history",
                len: 0,
                needed,
            });
        }
        Ok(())
    }
}

/// A history buffer read back ([`HistorySlots::read`]).
pub struct SlotsRead {
    /// Contacts held per sphere.
    pub counts: Vec<u32>,
    /// `slots` entries per sphere.
    pub entries: Vec<HistoryEntry>,
    /// Their load histories, beside them (empty where none are kept).
    pub loads: Vec<LoadEntry>,
}

/// How a GAS is brought up to date.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccelOp {
    /// From scratch.
    Build,
    /// Refit the boxes of the last build (same primitive count).
    Update,
}

/// A geometry acceleration structure over custom primitives (one AABB per sphere).
pub struct Gas {
    pub(super) handle: sys::TraversableHandle,
    pub(super) primitives: u32,
    output: CudaSlice<u8>,
    temp: CudaSlice<u8>,
}

impl Gas {
    fn input(boxes: &sys::DevicePtr, primitives: u32, flags: &u32) -> sys::BuildInput {
        sys::BuildInput {
            kind: sys::BUILD_INPUT_TYPE_CUSTOM_PRIMITIVES,
            custom: sys::BuildInputCustomPrimitiveArray {
                aabb_buffers: boxes,
                num_primitives: primitives,
                stride_in_bytes: BOX_STRIDE,
                flags,
                num_sbt_records: 1,
                sbt_index_offset_buffer: 0,
                sbt_index_offset_size_in_bytes: 0,
                sbt_index_offset_stride_in_bytes: 0,
                primitive_index_offset: 0,
            },
            _rest_of_union: [0; 1024 - size_of::<sys::BuildInputCustomPrimitiveArray>()],
        }
    }

    fn options(op: AccelOp) -> sys::AccelBuildOptions {
        sys::AccelBuildOptions {
            build_flags: sys::BUILD_FLAG_ALLOW_UPDATE | sys::BUILD_FLAG_PREFER_FAST_BUILD,
            operation: match op {
                AccelOp::Build => sys::BUILD_OPERATION_BUILD,
                AccelOp::Update => sys::BUILD_OPERATION_UPDATE,
            },
            motion_options: sys::MotionOptions {
                num_keys: 0,
                flags: 0,
                time_begin: 0.0,
                time_end: 0.0,
            },
        }
    }

    /// Builds a GAS over `primitives` boxes (6 floats each) in `boxes`.
    pub fn build(device: &Device, boxes: &CudaSlice<f32>, primitives: u32) -> Result<Gas> {
        check_len("building the GAS", "boxes", boxes, 6 * primitives as usize)?;
        let api = device.api;
        let pointer = device.ptr(boxes);
        let flags = sys::GEOMETRY_FLAG_DISABLE_ANYHIT;
        let input = Gas::input(&pointer, primitives, &flags);
        let mut sizes = sys::AccelBufferSizes::default();
        // SAFETY: options, input and out-struct valid for the call.
        let status = unsafe {
            (api.accel_compute_memory_usage)(
                device.context,
                &Gas::options(AccelOp::Build),
                &input,
                1,
                &mut sizes,
            )
        };
        api.check(status, "sizing the acceleration structure", "")?;
        let mut gas = Gas {
            handle: 0,
            primitives,
            output: device.bytes(sizes.output_size_in_bytes)?,
            temp: device.bytes(
                sizes
                    .temp_size_in_bytes
                    .max(sizes.temp_update_size_in_bytes),
            )?,
        };
        gas.run(device, boxes, AccelOp::Build)?;
        Ok(gas)
    }

    /// Rebuilds or refits from `boxes` (same primitive count as the build).
    pub fn run(&mut self, device: &Device, boxes: &CudaSlice<f32>, op: AccelOp) -> Result<()> {
        check_len(
            "building the GAS",
            "boxes",
            boxes,
            6 * self.primitives as usize,
        )?;
        let api = device.api;
        let pointer = device.ptr(boxes);
        let flags = sys::GEOMETRY_FLAG_DISABLE_ANYHIT;
        let input = Gas::input(&pointer, self.primitives, &flags);
        let temp = device.ptr_mut(&mut self.temp);
        let output = device.ptr_mut(&mut self.output);
        // SAFETY: buffers sized by accel_compute_memory_usage for this input (same primitive
        // count), boxes as long as the input says (checked above); the stream orders the build
        // after the boxes were written and before any launch that reads it.
        let status = unsafe {
            (api.accel_build)(
                device.context,
                device.stream.cu_stream().cast(),
                &Gas::options(op),
                &input,
                1,
                temp,
                self.temp.len(),
                output,
                self.output.len(),
                &mut self.handle,
                std::ptr::null(),
                0,
            )
        };
        api.check(status, "building the acceleration structure", "")
    }
}

/// The DEM state of `n` spheres on the device.
pub struct State {
    /// x, y, z, r per sphere.
    pub pos: CudaSlice<f32>,
    /// The residuals of the centres in `pos`: x, y, z, 0 per sphere.
    pub lo: CudaSlice<f32>,
    /// vx, vy, vz, mass per sphere.
    pub vel: CudaSlice<f32>,
    /// Input index of each sphere.
    pub ids: CudaSlice<u32>,
}

/// An order of `n` spheres on the device: entry p is the position (below n) of the sphere that
/// goes to sorted position p. The kernels read rows through it, so every entry is checked.
pub struct Order {
    pub(super) entries: CudaSlice<u32>,
    len: usize,
}

impl Order {
    /// Uploads `order`, refusing an entry that is not below its length.
    pub fn upload(stream: &Arc<CudaStream>, order: &[u32]) -> Result<Self> {
        if let Some(&index) = order.iter().find(|&&p| p as usize >= order.len()) {
            return Err(OptixError::IndexOutOfRange {
                buffer: "order",
                index: index as u64,
                len: order.len(),
            });
        }
        let entries = if order.is_empty() {
            stream.alloc_zeros::<u32>(1)
        } else {
            stream.clone_htod(order)
        }
        .map_err(cuda("uploading an order"))?;
        Ok(Self {
            entries,
            len: order.len(),
        })
    }

    /// The entries, for a launch that reads them as plain data.
    pub fn entries(&self) -> &CudaSlice<u32> {
        &self.entries
    }

    /// `Ok` if the order covers `n` spheres.
    pub(super) fn check(&self, launch: &'static str, n: u32) -> Result<()> {
        if self.len == n as usize {
            return Ok(());
        }
        Err(OptixError::BufferTooShort {
            launch,
            buffer: "order",
            len: self.len,
            needed: n as usize,
        })
    }
}

/// The grid of one thread per sphere.
pub(super) fn per_sphere(n: u32) -> LaunchConfig {
    LaunchConfig {
        grid_dim: (n.div_ceil(BLOCK), 1, 1),
        block_dim: (BLOCK, 1, 1),
        shared_mem_bytes: 0,
    }
}
