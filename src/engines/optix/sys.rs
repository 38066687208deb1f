//! The raw layer of the OptiX 9.0 host API (ABI 105): the few structs, constants and functions
//! mochi calls, declared from the documented ABI (no NVIDIA header is used or shipped). The
//! driver's `libnvoptix.so.1` hands out a table of function pointers; [`Api::get`] loads it once
//! per process and [`Api`] holds the entries, typed, by their [`slot`] in the table. Every
//! struct's size is checked at compile time against the ABI. Nothing here is safe to call on its
//! own: `device.rs` and `launches.rs` are the safe layer over it.

#![allow(missing_docs)]

use crate::error::OptixError;
use std::ffi::{c_char, c_int, c_uint, c_void};
use std::sync::OnceLock;

/// The OptiX ABI this FFI speaks (OptiX 9.0); driver 580 accepts up to 105.
pub const ABI_VERSION: c_int = 105;
/// Entries of the function table under [`ABI_VERSION`].
const TABLE_SLOTS: usize = 52;

/// Indices into the function table of [`ABI_VERSION`] (OptiX 9.0's order) of the functions
/// mochi calls.
pub mod slot {
    pub const GET_ERROR_NAME: usize = 0;
    pub const DEVICE_CONTEXT_CREATE: usize = 2;
    pub const DEVICE_CONTEXT_DESTROY: usize = 3;
    pub const DEVICE_CONTEXT_GET_PROPERTY: usize = 4;
    pub const MODULE_CREATE: usize = 12;
    pub const MODULE_DESTROY: usize = 15;
    pub const PROGRAM_GROUP_CREATE: usize = 18;
    pub const PROGRAM_GROUP_DESTROY: usize = 19;
    pub const PIPELINE_CREATE: usize = 21;
    pub const PIPELINE_DESTROY: usize = 22;
    pub const ACCEL_COMPUTE_MEMORY_USAGE: usize = 24;
    pub const ACCEL_BUILD: usize = 25;
    pub const SBT_RECORD_PACK_HEADER: usize = 40;
    pub const LAUNCH: usize = 41;
    /// Slots up to here must be filled (every one above is below it).
    pub const USED: usize = LAUNCH + 1;
}

pub type OptixResult = c_int;
pub type DeviceContext = *mut c_void;
pub type Module = *mut c_void;
pub type ProgramGroup = *mut c_void;
pub type Pipeline = *mut c_void;
pub type TraversableHandle = u64;
pub type DevicePtr = u64;
pub type CuContext = *mut c_void;
pub type CuStream = *mut c_void;

pub const SUCCESS: OptixResult = 0;
pub const DEVICE_PROPERTY_LIMIT_MAX_PRIMITIVES_PER_GAS: c_int = 0x2003;
pub const DEVICE_PROPERTY_RTCORE_VERSION: c_int = 0x2005;
pub const PROGRAM_GROUP_KIND_RAYGEN: c_int = 0x2421;
pub const PROGRAM_GROUP_KIND_MISS: c_int = 0x2422;
pub const PROGRAM_GROUP_KIND_HITGROUP: c_int = 0x2424;
pub const BUILD_INPUT_TYPE_CUSTOM_PRIMITIVES: c_int = 0x2142;
pub const BUILD_OPERATION_BUILD: c_int = 0x2161;
pub const BUILD_OPERATION_UPDATE: c_int = 0x2162;
pub const BUILD_FLAG_ALLOW_UPDATE: c_uint = 1;
pub const BUILD_FLAG_PREFER_FAST_BUILD: c_uint = 8;
pub const GEOMETRY_FLAG_DISABLE_ANYHIT: c_uint = 1;
pub const TRAVERSABLE_GRAPH_FLAG_ALLOW_SINGLE_GAS: c_uint = 1;
pub const PRIMITIVE_TYPE_FLAGS_CUSTOM: c_uint = 1;
/// Bytes of a shader-binding-table record header, and the records' alignment.
pub const SBT_RECORD_HEADER_SIZE: usize = 32;
pub const SBT_RECORD_ALIGNMENT: usize = 16;

pub type LogCallback = Option<
    unsafe extern "C" fn(level: c_uint, tag: *const c_char, msg: *const c_char, data: *mut c_void),
>;

#[repr(C)]
pub struct DeviceContextOptions {
    pub log_callback: LogCallback,
    pub log_callback_data: *mut c_void,
    pub log_callback_level: c_int,
    pub validation_mode: c_int,
}

#[repr(C)]
pub struct ModuleCompileOptions {
    pub max_register_count: c_int,
    pub opt_level: c_int,
    pub debug_level: c_int,
    pub bound_values: *const c_void,
    pub num_bound_values: c_uint,
    pub num_payload_types: c_uint,
    pub payload_types: *const c_void,
}

#[repr(C)]
pub struct PipelineCompileOptions {
    pub uses_motion_blur: c_int,
    pub traversable_graph_flags: c_uint,
    pub num_payload_values: c_int,
    pub num_attribute_values: c_int,
    pub exception_flags: c_uint,
    pub pipeline_launch_params_variable_name: *const c_char,
    pub uses_primitive_type_flags: c_uint,
    pub allow_opacity_micromaps: c_int,
    pub allow_clustered_geometry: c_int,
}

#[repr(C)]
pub struct PipelineLinkOptions {
    pub max_trace_depth: c_uint,
}

/// A program of a group: its module and entry function (both null: no program).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ProgramEntry {
    pub module: Module,
    pub entry_function_name: *const c_char,
}

/// A program group: one entry for raygen and miss groups; closest-hit, any-hit and
/// intersection for hit groups.
#[repr(C)]
pub struct ProgramGroupDesc {
    pub kind: c_int,
    pub flags: c_uint,
    pub entries: [ProgramEntry; 3],
}

#[repr(C)]
pub struct ProgramGroupOptions {
    pub payload_type: *const c_void,
}

#[repr(C)]
#[derive(Clone, Copy)]
pub struct BuildInputCustomPrimitiveArray {
    pub aabb_buffers: *const DevicePtr,
    pub num_primitives: c_uint,
    pub stride_in_bytes: c_uint,
    pub flags: *const c_uint,
    pub num_sbt_records: c_uint,
    pub sbt_index_offset_buffer: DevicePtr,
    pub sbt_index_offset_size_in_bytes: c_uint,
    pub sbt_index_offset_stride_in_bytes: c_uint,
    pub primitive_index_offset: c_uint,
}

/// A build input; only the custom-primitive member of the ABI's union is used.
#[repr(C)]
pub struct BuildInput {
    pub kind: c_int,
    pub custom: BuildInputCustomPrimitiveArray,
    pub _rest_of_union: [u8; 1024 - size_of::<BuildInputCustomPrimitiveArray>()],
}

#[repr(C)]
pub struct MotionOptions {
    pub num_keys: u16,
    pub flags: u16,
    pub time_begin: f32,
    pub time_end: f32,
}

#[repr(C)]
pub struct AccelBuildOptions {
    pub build_flags: c_uint,
    pub operation: c_int,
    pub motion_options: MotionOptions,
}

#[repr(C)]
#[derive(Default)]
pub struct AccelBufferSizes {
    pub output_size_in_bytes: usize,
    pub temp_size_in_bytes: usize,
    pub temp_update_size_in_bytes: usize,
}

#[repr(C)]
#[derive(Default)]
pub struct ShaderBindingTable {
    pub raygen_record: DevicePtr,
    pub exception_record: DevicePtr,
    pub miss_record_base: DevicePtr,
    pub miss_record_stride_in_bytes: c_uint,
    pub miss_record_count: c_uint,
    pub hitgroup_record_base: DevicePtr,
    pub hitgroup_record_stride_in_bytes: c_uint,
    pub hitgroup_record_count: c_uint,
    pub callables_record_base: DevicePtr,
    pub callables_record_stride_in_bytes: c_uint,
    pub callables_record_count: c_uint,
}

const _: () = {
    assert!(size_of::<DeviceContextOptions>() == 24);
    assert!(size_of::<ModuleCompileOptions>() == 40);
    assert!(size_of::<PipelineCompileOptions>() == 48);
    assert!(
        std::mem::offset_of!(PipelineCompileOptions, pipeline_launch_params_variable_name) == 24
    );
    assert!(size_of::<PipelineLinkOptions>() == 4);
    assert!(size_of::<ProgramGroupDesc>() == 56);
    assert!(size_of::<ProgramGroupOptions>() == 8);
    assert!(size_of::<BuildInputCustomPrimitiveArray>() == 56);
    assert!(size_of::<BuildInput>() == 1032);
    assert!(std::mem::offset_of!(BuildInput, custom) == 8);
    assert!(size_of::<AccelBuildOptions>() == 20);
    assert!(size_of::<AccelBufferSizes>() == 24);
    assert!(size_of::<ShaderBindingTable>() == 64);
    assert!(size_of::<[*const c_void; TABLE_SLOTS]>() == 416);
};

/// Whether the CUDA driver library (`libcuda.so`) can be loaded here.
pub fn cuda_present() -> bool {
    // SAFETY: only tries to open the library.
    unsafe { cudarc::driver::sys::is_culib_present() }
}

/// Whether NVRTC (`libnvrtc.so.13`) can be loaded here.
pub fn nvrtc_present() -> bool {
    // SAFETY: only tries to open the library.
    unsafe { cudarc::nvrtc::sys::is_culib_present() }
}

type QueryFunctionTable = unsafe extern "C" fn(
    abi: c_int,
    num_options: c_uint,
    option_keys: *mut c_void,
    option_values: *mut *const c_void,
    table: *mut c_void,
    table_size: usize,
) -> OptixResult;

/// The function table of the driver's OptiX, typed where mochi calls it.
#[allow(clippy::type_complexity)]
pub struct Api {
    _library: libloading::Library,
    pub error_name: unsafe extern "C" fn(OptixResult) -> *const c_char,
    pub device_context_create: unsafe extern "C" fn(
        CuContext,
        *const DeviceContextOptions,
        *mut DeviceContext,
    ) -> OptixResult,
    pub device_context_destroy: unsafe extern "C" fn(DeviceContext) -> OptixResult,
    pub device_context_get_property:
        unsafe extern "C" fn(DeviceContext, c_int, *mut c_void, usize) -> OptixResult,
    pub module_create: unsafe extern "C" fn(
        DeviceContext,
        *const ModuleCompileOptions,
        *const PipelineCompileOptions,
        *const c_char,
        usize,
        *mut c_char,
        *mut usize,
        *mut Module,
    ) -> OptixResult,
    pub module_destroy: unsafe extern "C" fn(Module) -> OptixResult,
    pub program_group_create: unsafe extern "C" fn(
        DeviceContext,
        *const ProgramGroupDesc,
        c_uint,
        *const ProgramGroupOptions,
        *mut c_char,
        *mut usize,
        *mut ProgramGroup,
    ) -> OptixResult,
    pub program_group_destroy: unsafe extern "C" fn(ProgramGroup) -> OptixResult,
    pub pipeline_create: unsafe extern "C" fn(
        DeviceContext,
        *const PipelineCompileOptions,
        *const PipelineLinkOptions,
        *const ProgramGroup,
        c_uint,
        *mut c_char,
        *mut usize,
        *mut Pipeline,
    ) -> OptixResult,
    pub pipeline_destroy: unsafe extern "C" fn(Pipeline) -> OptixResult,
    pub accel_compute_memory_usage: unsafe extern "C" fn(
        DeviceContext,
        *const AccelBuildOptions,
        *const BuildInput,
        c_uint,
        *mut AccelBufferSizes,
    ) -> OptixResult,
    pub accel_build: unsafe extern "C" fn(
        DeviceContext,
        CuStream,
        *const AccelBuildOptions,
        *const BuildInput,
        c_uint,
        DevicePtr,
        usize,
        DevicePtr,
        usize,
        *mut TraversableHandle,
        *const c_void,
        c_uint,
    ) -> OptixResult,
    pub sbt_record_pack_header: unsafe extern "C" fn(ProgramGroup, *mut c_void) -> OptixResult,
    pub launch: unsafe extern "C" fn(
        Pipeline,
        CuStream,
        DevicePtr,
        usize,
        *const ShaderBindingTable,
        c_uint,
        c_uint,
        c_uint,
    ) -> OptixResult,
}

/// A table slot as the function-pointer type `F` it holds.
///
/// # Safety
/// `F` must be the slot's function-pointer type under [`ABI_VERSION`].
unsafe fn typed<F: Copy>(slot: *const c_void) -> F {
    const { assert!(size_of::<F>() == size_of::<*const c_void>()) };
    // SAFETY: same size (checked above); the caller vouches for the type.
    unsafe { std::mem::transmute_copy(&slot) }
}

// SAFETY: the table holds plain function pointers into the driver, which OptiX documents as
// callable from any thread.
unsafe impl Send for Api {}
// SAFETY: as for Send; the table is never written after loading.
unsafe impl Sync for Api {}

impl Api {
    /// The driver's OptiX, loaded on first use (once per process), or why it cannot be used.
    pub fn get() -> Result<&'static Api, OptixError> {
        static API: OnceLock<Result<Api, String>> = OnceLock::new();
        API.get_or_init(Api::load)
            .as_ref()
            .map_err(|why| OptixError::Unavailable(why.clone()))
    }

    /// Opens the driver's OptiX and fetches its function table, or says why it cannot.
    fn load() -> Result<Api, String> {
        // SAFETY: loading the driver's own library runs its initialisers, as any OptiX program does.
        let library = unsafe { libloading::Library::new("libnvoptix.so.1") }.map_err(|e| {
            format!("the NVIDIA driver's OptiX library (libnvoptix.so.1) did not load: {e}")
        })?;
        let mut table = [std::ptr::null::<c_void>(); TABLE_SLOTS];
        // SAFETY: the symbol has this signature in every OptiX ABI; the table is as large as the
        // ABI's and outlives the call.
        let status = unsafe {
            let query: libloading::Symbol<QueryFunctionTable> = library
                .get(b"optixQueryFunctionTable\0")
                .map_err(|e| format!("libnvoptix.so.1 has no optixQueryFunctionTable: {e}"))?;
            query(
                ABI_VERSION,
                0,
                std::ptr::null_mut(),
                std::ptr::null_mut(),
                table.as_mut_ptr().cast(),
                size_of_val(&table),
            )
        };
        if status != SUCCESS {
            return Err(format!(
                "the driver's OptiX does not offer ABI {ABI_VERSION} (OptiX 9.0; error {status}): update the NVIDIA driver (580 or newer)"
            ));
        }
        if table.iter().take(slot::USED).any(|p| p.is_null()) {
            return Err("the driver's OptiX function table is incomplete".into());
        }
        // SAFETY: under ABI 105 the slots of `slot` hold these functions (OptiX 9.0's table
        // order), none null (checked above).
        unsafe {
            Ok(Api {
                error_name: typed(table[slot::GET_ERROR_NAME]),
                device_context_create: typed(table[slot::DEVICE_CONTEXT_CREATE]),
                device_context_destroy: typed(table[slot::DEVICE_CONTEXT_DESTROY]),
                device_context_get_property: typed(table[slot::DEVICE_CONTEXT_GET_PROPERTY]),
                module_create: typed(table[slot::MODULE_CREATE]),
                module_destroy: typed(table[slot::MODULE_DESTROY]),
                program_group_create: typed(table[slot::PROGRAM_GROUP_CREATE]),
                program_group_destroy: typed(table[slot::PROGRAM_GROUP_DESTROY]),
                pipeline_create: typed(table[slot::PIPELINE_CREATE]),
                pipeline_destroy: typed(table[slot::PIPELINE_DESTROY]),
                accel_compute_memory_usage: typed(table[slot::ACCEL_COMPUTE_MEMORY_USAGE]),
                accel_build: typed(table[slot::ACCEL_BUILD]),
                sbt_record_pack_header: typed(table[slot::SBT_RECORD_PACK_HEADER]),
                launch: typed(table[slot::LAUNCH]),
                _library: library,
            })
        }
    }

    /// `Ok` for success, else [`OptixError::Call`] naming `call` and carrying `log`.
    pub fn check(
        &self,
        status: OptixResult,
        call: &'static str,
        log: &str,
    ) -> Result<(), OptixError> {
        if status == SUCCESS {
            return Ok(());
        }
        // SAFETY: OptiX returns a static NUL-terminated string for any result code.
        let name = unsafe { std::ffi::CStr::from_ptr((self.error_name)(status)) };
        Err(OptixError::Call {
            call,
            code: status,
            name: name.to_string_lossy().into_owned(),
            log: log.to_owned(),
        })
    }
}
