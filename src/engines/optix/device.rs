//! Safe owners of the OptiX objects mochi uses: the device (CUDA context, stream, OptiX
//! context), a pipeline of one raygen and one intersection program with its shader binding
//! table, and a geometry acceleration structure (GAS) of custom primitives (AABBs) that can be
//! built and updated (refit). Each frees what it created when dropped.

use super::ffi::{self, Api};
use cudarc::driver::{CudaContext, CudaSlice, CudaStream, DevicePtr, DevicePtrMut};
use std::ffi::{CString, c_char, c_void};
use std::sync::Arc;

/// Result of this layer: errors are messages.
pub type Result<T> = std::result::Result<T, String>;

fn cuda_error(what: &str) -> impl Fn(cudarc::driver::DriverError) -> String + '_ {
    move |e| format!("CUDA {what}: {e}")
}

/// Whether the CUDA driver library can be loaded here.
pub fn cuda_present() -> bool {
    // SAFETY: only tries to open the library.
    unsafe { cudarc::driver::sys::is_culib_present() }
}

/// The GPU with its CUDA context, stream and OptiX context.
pub struct Device {
    pub api: Api,
    pub cuda: Arc<CudaContext>,
    pub stream: Arc<CudaStream>,
    context: ffi::DeviceContext,
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
unsafe impl Sync for Device {}

impl Device {
    /// Opens GPU 0, or says why it cannot.
    pub fn open() -> Result<Device> {
        if !cuda_present() {
            return Err("no NVIDIA driver (libcuda.so) found".into());
        }
        let api = Api::load()?;
        let cuda = CudaContext::new(0).map_err(cuda_error("opening GPU 0"))?;
        let name = cuda.name().map_err(cuda_error("reading the GPU name"))?;
        let stream = cuda.default_stream();
        let options = ffi::DeviceContextOptions {
            log_callback: None,
            log_callback_data: std::ptr::null_mut(),
            log_callback_level: 0,
            validation_mode: 0,
        };
        let mut context = std::ptr::null_mut();
        // SAFETY: a live CUDA context, options and out-pointer valid for the call.
        api.check(
            unsafe { (api.device_context_create)(cuda.cu_ctx().cast(), &options, &mut context) },
            "creating the device context",
        )?;
        let mut device = Device {
            api,
            cuda,
            stream,
            context,
            name,
            rtcore_version: 0,
            max_primitives: 0,
        };
        device.rtcore_version =
            device.property(ffi::DEVICE_PROPERTY_RTCORE_VERSION, "the RT core version")?;
        device.max_primitives = device.property(
            ffi::DEVICE_PROPERTY_LIMIT_MAX_PRIMITIVES_PER_GAS,
            "the primitive limit",
        )?;
        Ok(device)
    }

    /// A u32 property of the device context.
    fn property(&self, property: std::ffi::c_int, what: &str) -> Result<u32> {
        let mut value = 0u32;
        // SAFETY: the property is a u32 written into value.
        let status = unsafe {
            (self.api.device_context_get_property)(
                self.context,
                property,
                (&mut value as *mut u32).cast(),
                size_of::<u32>(),
            )
        };
        self.api.check(status, &format!("reading {what}"))?;
        Ok(value)
    }

    /// The raw device pointer of `slice`, for OptiX calls and launch parameters.
    pub fn ptr<T>(&self, slice: &CudaSlice<T>) -> ffi::DevicePtr {
        slice.device_ptr(&self.stream).0
    }

    /// The raw device pointer of `slice`, which the GPU will write.
    pub fn ptr_mut<T>(&self, slice: &mut CudaSlice<T>) -> ffi::DevicePtr {
        slice.device_ptr_mut(&self.stream).0
    }

    /// A zeroed device buffer of `len` bytes (OptiX's alignment holds: CUDA allocations are
    /// 256-byte aligned).
    pub fn bytes(&self, len: usize) -> Result<CudaSlice<u8>> {
        self.stream
            .alloc_zeros::<u8>(len.max(1))
            .map_err(cuda_error("allocating device memory"))
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: created in open, destroyed once; pipelines hold an Arc of the device, so they
        // are gone by now.
        unsafe { (self.api.device_context_destroy)(self.context) };
    }
}

/// Runs an OptiX call that writes a log, and appends the log to its error.
fn with_log(
    api: &Api,
    what: &str,
    call: impl FnOnce(*mut c_char, *mut usize) -> ffi::OptixResult,
) -> Result<()> {
    let mut log = vec![0u8; 4096];
    let mut len = log.len();
    let status = call(log.as_mut_ptr().cast(), &mut len);
    api.check(status, what).map_err(|e| {
        let text = String::from_utf8_lossy(&log[..len.min(log.len())]);
        format!("{e}: {}", text.trim_end_matches('\0').trim())
    })
}

/// A pipeline of one raygen and one intersection-only hit group (no miss program), with its
/// shader binding table: records of headers only.
pub struct Pipeline {
    device: Arc<Device>,
    module: ffi::Module,
    groups: [ffi::ProgramGroup; 3],
    pipeline: ffi::Pipeline,
    sbt: ffi::ShaderBindingTable,
    _records: CudaSlice<u8>,
}

impl Pipeline {
    /// Builds the pipeline from `ptx` with entry points `__raygen__{name}` and
    /// `__intersection__{name}`, launch parameters in `params`, `payloads` payload words.
    pub fn new(device: &Arc<Device>, ptx: &str, name: &str, payloads: i32) -> Result<Pipeline> {
        let api = &device.api;
        let params_name = CString::new("params").expect("no NUL");
        let compile = ffi::PipelineCompileOptions {
            uses_motion_blur: 0,
            traversable_graph_flags: ffi::TRAVERSABLE_GRAPH_FLAG_ALLOW_SINGLE_GAS,
            num_payload_values: payloads,
            num_attribute_values: 0,
            exception_flags: 0,
            pipeline_launch_params_variable_name: params_name.as_ptr(),
            uses_primitive_type_flags: ffi::PRIMITIVE_TYPE_FLAGS_CUSTOM,
            allow_opacity_micromaps: 0,
            allow_clustered_geometry: 0,
        };
        let module_options = ffi::ModuleCompileOptions {
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
            sbt: ffi::ShaderBindingTable::default(),
            _records: device.bytes(1)?,
        };
        let raygen = CString::new(format!("__raygen__{name}")).expect("no NUL");
        let intersection = CString::new(format!("__intersection__{name}")).expect("no NUL");
        let none = ffi::ProgramEntry {
            module: std::ptr::null_mut(),
            entry_function_name: std::ptr::null(),
        };
        let entry = |name: &CString| ffi::ProgramEntry {
            module,
            entry_function_name: name.as_ptr(),
        };
        let descs = [
            ffi::ProgramGroupDesc {
                kind: ffi::PROGRAM_GROUP_KIND_RAYGEN,
                flags: 0,
                entries: [entry(&raygen), none, none],
            },
            ffi::ProgramGroupDesc {
                kind: ffi::PROGRAM_GROUP_KIND_MISS,
                flags: 0,
                entries: [none, none, none],
            },
            ffi::ProgramGroupDesc {
                kind: ffi::PROGRAM_GROUP_KIND_HITGROUP,
                flags: 0,
                entries: [none, none, entry(&intersection)],
            },
        ];
        let group_options = ffi::ProgramGroupOptions {
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
        let link = ffi::PipelineLinkOptions { max_trace_depth: 1 };
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
        let stride = ffi::SBT_RECORD_HEADER_SIZE.next_multiple_of(ffi::SBT_RECORD_ALIGNMENT);
        let mut records = vec![0u8; stride * 3];
        for (k, &group) in pipeline.groups.iter().enumerate() {
            // SAFETY: the header pointer has SBT_RECORD_HEADER_SIZE bytes of room.
            let status = unsafe {
                (api.sbt_record_pack_header)(
                    group,
                    records[k * stride..].as_mut_ptr().cast::<c_void>(),
                )
            };
            api.check(status, "packing a shader-binding-table record")?;
        }
        let records = device
            .stream
            .clone_htod(&records)
            .map_err(cuda_error("uploading the shader binding table"))?;
        let base = device.ptr(&records);
        pipeline.sbt = ffi::ShaderBindingTable {
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

    /// Launches `width` raygen invocations with launch parameters `params` (on the device).
    pub fn launch(&self, params: &CudaSlice<u8>, width: u32) -> Result<()> {
        if width == 0 {
            return Ok(());
        }
        let device = &self.device;
        let api = &device.api;
        // SAFETY: pipeline, SBT and parameter buffer are alive until the stream is done (their
        // owners outlive the launch, and readers synchronise the stream).
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
        api.check(status, "launching the point rays")
    }
}

// SAFETY: the OptiX handles are owned by this value and only used through it.
unsafe impl Send for Pipeline {}

impl Drop for Pipeline {
    fn drop(&mut self) {
        let api = &self.device.api;
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
    pub handle: ffi::TraversableHandle,
    primitives: u32,
    output: CudaSlice<u8>,
    temp: CudaSlice<u8>,
}

impl Gas {
    fn input(boxes: &ffi::DevicePtr, primitives: u32, flags: &u32) -> ffi::BuildInput {
        ffi::BuildInput {
            kind: ffi::BUILD_INPUT_TYPE_CUSTOM_PRIMITIVES,
            custom: ffi::BuildInputCustomPrimitiveArray {
                aabb_buffers: boxes,
                num_primitives: primitives,
                stride_in_bytes: 24,
                flags,
                num_sbt_records: 1,
                sbt_index_offset_buffer: 0,
                sbt_index_offset_size_in_bytes: 0,
                sbt_index_offset_stride_in_bytes: 0,
                primitive_index_offset: 0,
            },
            _rest_of_union: [0; 1024 - size_of::<ffi::BuildInputCustomPrimitiveArray>()],
        }
    }

    fn options(op: AccelOp) -> ffi::AccelBuildOptions {
        ffi::AccelBuildOptions {
            build_flags: ffi::BUILD_FLAG_ALLOW_UPDATE | ffi::BUILD_FLAG_PREFER_FAST_BUILD,
            operation: match op {
                AccelOp::Build => ffi::BUILD_OPERATION_BUILD,
                AccelOp::Update => ffi::BUILD_OPERATION_UPDATE,
            },
            motion_options: ffi::MotionOptions {
                num_keys: 0,
                flags: 0,
                time_begin: 0.0,
                time_end: 0.0,
            },
        }
    }

    /// Builds a GAS over `primitives` boxes (6 floats each) in `boxes`.
    pub fn build(device: &Device, boxes: &CudaSlice<f32>, primitives: u32) -> Result<Gas> {
        let api = &device.api;
        let pointer = device.ptr(boxes);
        let flags = ffi::GEOMETRY_FLAG_DISABLE_ANYHIT;
        let input = Gas::input(&pointer, primitives, &flags);
        let mut sizes = ffi::AccelBufferSizes::default();
        // SAFETY: options, input and out-struct valid for the call.
        api.check(
            unsafe {
                (api.accel_compute_memory_usage)(
                    device.context,
                    &Gas::options(AccelOp::Build),
                    &input,
                    1,
                    &mut sizes,
                )
            },
            "sizing the acceleration structure",
        )?;
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
        let api = &device.api;
        let pointer = device.ptr(boxes);
        let flags = ffi::GEOMETRY_FLAG_DISABLE_ANYHIT;
        let input = Gas::input(&pointer, self.primitives, &flags);
        let temp = device.ptr_mut(&mut self.temp);
        let output = device.ptr_mut(&mut self.output);
        // SAFETY: buffers sized by accel_compute_memory_usage for this input; the stream orders
        // the build after the boxes were written and before any launch that reads it.
        api.check(
            unsafe {
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
            },
            "building the acceleration structure",
        )
    }
}
