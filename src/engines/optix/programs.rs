//! The device code in `optix/`, compiled to PTX by NVRTC at run time, once per process.

pub use super::sys::nvrtc_present;
use crate::error::OptixError;
use std::sync::OnceLock;

const DEVICE_CUH: &str = include_str!("../../../optix/device.cuh");
const DETECT_CU: &str = include_str!("../../../optix/detect.cu");
const KERNELS_CU: &str = include_str!("../../../optix/kernels.cu");
const PHYSICS_CUH: &str = include_str!("../../../optix/physics.cuh");
const DEM_CU: &str = include_str!("../../../optix/dem.cu");
const CONTACT_CUH: &str = include_str!("../../../optix/contact.cuh");
const HISTORY_CUH: &str = include_str!("../../../optix/history.cuh");
const GRANULAR_CU: &str = include_str!("../../../optix/granular.cu");
const GRANULAR_KERNELS_CU: &str = include_str!("../../../optix/granular_kernels.cu");
const MESH_WALLS_CUH: &str = include_str!("../../../optix/mesh_walls.cuh");
const CLUMPS_CUH: &str = include_str!("../../../optix/clumps.cuh");

/// What the Mindlin–Deresiewicz units prepend (`optix/contact.cuh`, `optix/history.cuh`).
const LOAD_HISTORY: &str = "#define MOCHI_LOAD_HISTORY 1\n";

/// What the cohesive units prepend (`optix/contact.cuh`: the cohesion laws compiled in).
const COHESIVE: &str = "#define MOCHI_COHESIVE true\n";

/// Virtual architecture of the PTX: Turing, the first GPUs with RT cores (the driver compiles
/// it for the GPU at hand).
const ARCH: &str = "compute_75";

/// Which contact law a granular unit compiles: the tangential model and whether contacts
/// adhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GranularLaw {
    /// The Mindlin–Deresiewicz tangential model (`MOCHI_LOAD_HISTORY`: its law, and the load
    /// history beside the contact history); else Mindlin's spring.
    pub loaded: bool,
    /// The cohesion laws (`MOCHI_COHESIVE`: JKR, liquid bridges, the simplified JKR, contacts
    /// held past touching).
    pub cohesive: bool,
}

impl GranularLaw {
    /// Every combination.
    pub const ALL: [GranularLaw; 4] = [
        GranularLaw {
            loaded: false,
            cohesive: false,
        },
        GranularLaw {
            loaded: true,
            cohesive: false,
        },
        GranularLaw {
            loaded: false,
            cohesive: true,
        },
        GranularLaw {
            loaded: true,
            cohesive: true,
        },
    ];

    /// What its units prepend.
    fn defines(self) -> String {
        [(self.loaded, LOAD_HISTORY), (self.cohesive, COHESIVE)]
            .into_iter()
            .filter_map(|(on, define)| on.then_some(define))
            .collect()
    }
}

/// A compilation unit of the device code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// OptiX programs of detection (raygen + intersection).
    Detect,
    /// Plain CUDA kernels (proxy boxes; the DEM step's boxes, integration and reordering).
    Kernels,
    /// OptiX programs of the frictionless DEM step (raygen + intersection resolving contacts).
    Dem,
    /// OptiX programs of the granular DEM step (contacts with friction, history and rolling
    /// resistance) of a law.
    Granular(GranularLaw),
    /// Plain CUDA kernels of the granular DEM step (box and mesh walls, integration with
    /// rotation) of a law.
    GranularKernels(GranularLaw),
}

impl Unit {
    /// Every unit.
    pub const ALL: [Unit; 11] = {
        let laws = GranularLaw::ALL;
        [
            Unit::Detect,
            Unit::Kernels,
            Unit::Dem,
            Unit::Granular(laws[0]),
            Unit::Granular(laws[1]),
            Unit::Granular(laws[2]),
            Unit::Granular(laws[3]),
            Unit::GranularKernels(laws[0]),
            Unit::GranularKernels(laws[1]),
            Unit::GranularKernels(laws[2]),
            Unit::GranularKernels(laws[3]),
        ]
    };

    /// File name and the law it is compiled for, for messages.
    pub fn name(self) -> String {
        let (file, law) = match self {
            Unit::Detect => return "optix/detect.cu".into(),
            Unit::Kernels => return "optix/kernels.cu".into(),
            Unit::Dem => return "optix/dem.cu".into(),
            Unit::Granular(law) => ("optix/granular.cu", law),
            Unit::GranularKernels(law) => ("optix/granular_kernels.cu", law),
        };
        let defines = [
            (law.loaded, "MOCHI_LOAD_HISTORY"),
            (law.cohesive, "MOCHI_COHESIVE"),
        ];
        let defined: Vec<&str> = defines
            .into_iter()
            .filter_map(|(on, name)| on.then_some(name))
            .collect();
        match defined.is_empty() {
            true => file.into(),
            false => format!("{file} ({})", defined.join(", ")),
        }
    }

    /// Whether the unit is an OptiX module (relocatable device code) rather than plain kernels.
    fn is_optix_module(self) -> bool {
        !matches!(self, Unit::Kernels | Unit::GranularKernels(_))
    }

    /// The full source NVRTC gets.
    fn source(self) -> String {
        match self {
            Unit::Detect => format!("{DEVICE_CUH}\n{DETECT_CU}"),
            Unit::Kernels => format!("{DEVICE_CUH}\n{PHYSICS_CUH}\n{KERNELS_CU}"),
            Unit::Dem => format!("{DEVICE_CUH}\n{PHYSICS_CUH}\n{DEM_CU}"),
            Unit::Granular(law) => format!(
                "{}{DEVICE_CUH}\n{PHYSICS_CUH}\n{CONTACT_CUH}\n{HISTORY_CUH}\n{GRANULAR_CU}",
                law.defines()
            ),
            Unit::GranularKernels(law) => format!(
                "{}{DEVICE_CUH}\n{PHYSICS_CUH}\n{CONTACT_CUH}\n{HISTORY_CUH}\n{MESH_WALLS_CUH}\n\
                 {CLUMPS_CUH}\n{GRANULAR_KERNELS_CU}",
                law.defines()
            ),
        }
    }
}

/// PTX of `unit`, compiled on first use (NVRTC is slow; OptiX caches its own compilation too).
pub fn ptx(unit: Unit) -> Result<&'static str, OptixError> {
    static CACHE: [OnceLock<Result<String, OptixError>>; Unit::ALL.len()] =
        [const { OnceLock::new() }; Unit::ALL.len()];
    let slot = &CACHE[Unit::ALL.iter().position(|&u| u == unit).unwrap_or(0)];
    slot.get_or_init(|| compile(unit))
        .as_deref()
        .map_err(Clone::clone)
}

/// Compiles `unit` with NVRTC (no fused multiply-adds: the proxy rule rounds as the cpu does).
pub fn compile(unit: Unit) -> Result<String, OptixError> {
    compile_source(&unit.name(), unit.source(), unit.is_optix_module())
}

/// Compiles `unit` followed by `checks` (CUDA `static_assert`s over its types, which emit no
/// code): the layout test compiles each launch-parameter struct against its Rust twin this way.
pub fn compile_with_checks(unit: Unit, checks: &str) -> Result<String, OptixError> {
    compile_source(
        &unit.name(),
        format!("{}\n{checks}", unit.source()),
        unit.is_optix_module(),
    )
}

/// Compiles plain CUDA kernels `body` (named `name` in messages) with `optix/device.cuh`
/// prepended, as [`compile`] compiles the device programs: the parity test runs the proxy rule
/// through this.
pub fn compile_with_rule(name: &str, body: &str) -> Result<String, OptixError> {
    compile_source(name, format!("{DEVICE_CUH}\n{body}"), false)
}

/// Compiles `source` with NVRTC, as relocatable device code (OptiX modules) where `rdc`.
fn compile_source(name: &str, source: String, rdc: bool) -> Result<String, OptixError> {
    if !nvrtc_present() {
        return Err(OptixError::Unavailable(
            "NVRTC (libnvrtc.so.13, from CUDA 13 or PyPI's nvidia-cuda-nvrtc) is not on the library path".into(),
        ));
    }
    let mut options = vec!["--std=c++17".to_string()];
    if rdc {
        options.push("-rdc=true".into());
    }
    let opts = cudarc::nvrtc::CompileOptions {
        arch: Some(ARCH),
        fmad: Some(false),
        options,
        name: Some(name.into()),
        ..Default::default()
    };
    cudarc::nvrtc::compile_ptx_with_opts(source, opts)
        .map(|ptx| ptx.to_src())
        .map_err(|e| OptixError::Compile {
            unit: name.into(),
            log: match e {
                cudarc::nvrtc::CompileError::CompileError { log, .. } => {
                    log.to_string_lossy().trim().to_owned()
                }
                e => e.to_string(),
            },
        })
}
