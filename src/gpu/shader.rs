//! The interface between the Rust side and the WGSL modules, named once: each module's composed
//! source, entry points and bind-group table ([`WgslModule`], [`Binding`]), the structs both
//! sides share ([`SharedStruct`], laid out by `encase`), and the WGSL vector types those structs
//! use ([`Vec3f`], [`Vec4u`]). `tests/bindings.rs` reads every module with naga and fails where
//! the WGSL and these tables disagree.

use encase::internal::WriteInto;
use encase::{ShaderSize, ShaderType, StorageBuffer, UniformBuffer};
use std::num::NonZeroU64;

/// How a shader global is bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindingKind {
    /// `var<uniform>`.
    Uniform,
    /// `var<storage, read>` (`read_only`) or `var<storage, read_write>`.
    Storage {
        /// Whether the shader only reads it.
        read_only: bool,
    },
    /// `var name: acceleration_structure`.
    AccelerationStructure,
}

/// One global of a WGSL module's bind group: what the bind-group code binds, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Binding {
    /// `@group`.
    pub group: u32,
    /// `@binding`.
    pub binding: u32,
    /// The global's name in the WGSL.
    pub name: &'static str,
    /// Its address space and access.
    pub kind: BindingKind,
}

impl Binding {
    /// `@group(0) @binding(binding) var<uniform> name`.
    pub const fn uniform(binding: u32, name: &'static str) -> Binding {
        Self::at(binding, name, BindingKind::Uniform)
    }

    /// `@group(0) @binding(binding) var<storage, read> name`.
    pub const fn read(binding: u32, name: &'static str) -> Binding {
        Self::at(binding, name, BindingKind::Storage { read_only: true })
    }

    /// `@group(0) @binding(binding) var<storage, read_write> name`.
    pub const fn read_write(binding: u32, name: &'static str) -> Binding {
        Self::at(binding, name, BindingKind::Storage { read_only: false })
    }

    /// `@group(0) @binding(binding) var name: acceleration_structure`.
    pub const fn acceleration_structure(binding: u32, name: &'static str) -> Binding {
        Self::at(binding, name, BindingKind::AccelerationStructure)
    }

    /// Its entry in an explicit bind-group layout for compute shaders; `dynamic_offset` and
    /// `min_size` apply to buffers.
    pub fn layout_entry(
        self,
        dynamic_offset: bool,
        min_size: Option<NonZeroU64>,
    ) -> wgpu::BindGroupLayoutEntry {
        let buffer = |ty| wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: dynamic_offset,
            min_binding_size: min_size,
        };
        wgpu::BindGroupLayoutEntry {
            binding: self.binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: match self.kind {
                BindingKind::Uniform => buffer(wgpu::BufferBindingType::Uniform),
                BindingKind::Storage { read_only } => {
                    buffer(wgpu::BufferBindingType::Storage { read_only })
                }
                BindingKind::AccelerationStructure => wgpu::BindingType::AccelerationStructure {
                    vertex_return: false,
                },
            },
            count: None,
        }
    }

    const fn at(binding: u32, name: &'static str, kind: BindingKind) -> Binding {
        Binding {
            group: 0,
            binding,
            name,
            kind,
        }
    }
}

/// A struct declared in WGSL with a Rust twin (`#[derive(ShaderType)]`): its WGSL name and the
/// twin's layout as `encase` computes it (made by the crate's `shared_struct!` macro).
#[derive(Debug, Clone, Copy)]
pub struct SharedStruct {
    /// The struct's name in the WGSL.
    pub name: &'static str,
    /// The Rust twin's size and member offsets .
    pub layout: fn() -> StructLayout,
}

/// Size and member offsets of a struct in bytes, members by name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StructLayout {
    /// Size \[bytes\].
    pub size: u64,
    /// Each member's name and offset \[bytes\], in declaration order.
    pub members: Vec<(&'static str, u64)>,
}

/// One WGSL module as the device gets it, with what the Rust side relies on.
#[derive(Debug, Clone)]
pub struct WgslModule {
    /// Label (also the wgpu label's suffix).
    pub label: String,
    /// The composed source.
    pub source: String,
    /// Its entry points, all of them.
    pub entry_points: &'static [&'static str],
    /// Every global it binds, all in group 0.
    pub bindings: Vec<Binding>,
    /// The structs it shares with Rust.
    pub structs: Vec<SharedStruct>,
}

impl WgslModule {
    /// The module `label` of `source` with the given interface.
    pub fn new(
        label: impl Into<String>,
        source: impl Into<String>,
        entry_points: &'static [&'static str],
        bindings: &[Binding],
        structs: Vec<SharedStruct>,
    ) -> WgslModule {
        WgslModule {
            label: label.into(),
            source: source.into(),
            entry_points,
            bindings: bindings.to_vec(),
            structs,
        }
    }
}

/// The files of the repository's `wgsl/` folder, concatenated in the order given and embedded
/// at compile time (a `&'static str`): `wgsl!("grid/grid_params.wgsl", "grid/grid_build.wgsl")`. A
/// module's later files use what its earlier ones declare.
macro_rules! wgsl {
    ($($file:literal),+ $(,)?) => {
        concat!($(include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/wgsl/", $file))),+)
    };
}
pub(crate) use wgsl;

/// A WGSL `vec3<f32>` (16-byte aligned; a `u32` or `f32` may follow in its last 4 bytes). As
/// plain `#[repr(C)]` data (a CUDA twin) it is three floats.
#[repr(transparent)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vec3f(pub [f32; 3]);

/// A WGSL `vec4<f32>`; as plain `#[repr(C)]` data, four floats.
#[repr(transparent)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vec4f(pub [f32; 4]);

/// A WGSL `vec3<u32>` (16-byte aligned; a scalar may follow in its last 4 bytes).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Vec3u(pub [u32; 3]);

/// A WGSL `vec4<u32>`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Vec4u(pub [u32; 4]);

macro_rules! vector_parts {
    ($vec:ident, $scalar:ty, $n:literal) => {
        impl AsRef<[$scalar; $n]> for $vec {
            fn as_ref(&self) -> &[$scalar; $n] {
                &self.0
            }
        }
        impl AsMut<[$scalar; $n]> for $vec {
            fn as_mut(&mut self) -> &mut [$scalar; $n] {
                &mut self.0
            }
        }
        impl From<[$scalar; $n]> for $vec {
            fn from(parts: [$scalar; $n]) -> Self {
                $vec(parts)
            }
        }
        impl From<$vec> for [$scalar; $n] {
            fn from(v: $vec) -> Self {
                v.0
            }
        }
        encase::impl_vector!($n, $vec, $scalar; using AsRef AsMut From);
    };
}
vector_parts!(Vec3f, f32, 3);

/// A `vec3<f32>` reads as its components.
impl std::ops::Deref for Vec3f {
    type Target = [f32; 3];
    fn deref(&self) -> &[f32; 3] {
        &self.0
    }
}
vector_parts!(Vec4f, f32, 4);
vector_parts!(Vec3u, u32, 3);
vector_parts!(Vec4u, u32, 4);

impl From<glam::Vec3> for Vec3f {
    fn from(v: glam::Vec3) -> Self {
        Vec3f(v.to_array())
    }
}

impl From<Vec3f> for glam::Vec3 {
    fn from(v: Vec3f) -> Self {
        glam::Vec3::from_array(v.0)
    }
}

/// The bytes of `value` as a `var<uniform>` holds them.
pub fn uniform_bytes<T: ShaderType + ShaderSize + WriteInto>(value: &T) -> Vec<u8> {
    let mut buffer = UniformBuffer::new(Vec::new());
    buffer
        .write(value)
        .expect("a Vec grows to any fixed-size value");
    buffer.into_inner()
}

/// The bytes of `values` as a `var<storage>` runtime-sized array of them holds them.
pub fn storage_bytes<T: ShaderType + ShaderSize + WriteInto>(values: &[T]) -> Vec<u8> {
    let mut buffer = StorageBuffer::new(Vec::new());
    buffer
        .write(values)
        .expect("a Vec grows to any array of fixed-size values");
    buffer.into_inner()
}

/// Bytes whose 4-byte word `k` holds `k` (little endian): read into a struct, each member's
/// first word tells its offset (see [`FirstWord`]).
pub(crate) fn ramp(size: u64) -> Vec<u8> {
    (0..size.div_ceil(4) as u32)
        .flat_map(u32::to_le_bytes)
        .collect()
}

/// The bit pattern of a member's first 4 bytes (its first scalar).
pub(crate) trait FirstWord {
    /// The first scalar's bits.
    fn first_word(&self) -> u32;
}

impl FirstWord for u32 {
    fn first_word(&self) -> u32 {
        *self
    }
}

impl FirstWord for f32 {
    fn first_word(&self) -> u32 {
        self.to_bits()
    }
}

impl FirstWord for Vec3f {
    fn first_word(&self) -> u32 {
        self.0[0].to_bits()
    }
}

impl FirstWord for Vec4f {
    fn first_word(&self) -> u32 {
        self.0[0].to_bits()
    }
}

impl FirstWord for Vec3u {
    fn first_word(&self) -> u32 {
        self.0[0]
    }
}

impl FirstWord for Vec4u {
    fn first_word(&self) -> u32 {
        self.0[0]
    }
}

impl<T: FirstWord, const N: usize> FirstWord for [T; N] {
    fn first_word(&self) -> u32 {
        self[0].first_word()
    }
}

/// The [`SharedStruct`] of a `#[derive(ShaderType)]` struct: `shared_struct!("Wgsl", Rust {
/// every, field })`, the WGSL struct's name first. The field list must name every field (it is a destructuring pattern), so
/// a field added on the Rust side fails to compile until it is listed here too. Offsets come
/// from `encase`: the struct is read from [`ramp`] bytes and each field's first word is its
/// offset in words.
macro_rules! shared_struct {
    ($wgsl:literal, $ty:ident { $($field:ident),* $(,)? }) => {
        $crate::gpu::shader::SharedStruct {
            name: $wgsl,
            layout: || {
                use $crate::gpu::shader::FirstWord;
                let size = <$ty as encase::ShaderType>::min_size().get();
                let bytes = $crate::gpu::shader::ramp(size);
                let value: $ty = encase::StorageBuffer::new(&bytes[..])
                    .create()
                    .expect("the ramp is as long as the struct");
                let $ty { $($field),* } = value;
                $crate::gpu::shader::StructLayout {
                    size,
                    members: vec![$((stringify!($field), u64::from($field.first_word()) * 4)),*],
                }
            },
        }
    };
}
pub(crate) use shared_struct;
