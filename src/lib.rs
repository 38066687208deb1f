//! # mochi — every pair of touching spheres, fast
//!
//! mochi finds all colliding pairs in a set of spheres (discrete collision detection) with the
//! proxy-sphere method of Mandarapu et al., "Rethinking Collision Detection on GPU Ray Tracing
//! Architecture" (ICS '26): each sphere j gets a *proxy* of radius 2·r_j, the point ray of sphere
//! i finds the proxies that contain c_i, and a symmetric rule ([`proxy::keep`]) keeps each
//! colliding pair exactly once. Only the smaller sphere of a pair has to find it, so boxes follow
//! each sphere's own size instead of the largest radius.
//!
//! - [`SphereSet`]: validated centres and radii (`f32`); [`Spheres`]: the same checked where
//!   they lie (what a backend builds over); [`Pair`]: `(i, j)` with `i < j`.
//! - [`proxy`]: the rule, the one definition every backend mirrors; [`ProxyMode`] selects the
//!   paper's proxies (`mochi`) or the older fixed-radius boxes (`nns`).
//! - [`Backend`]: the detection trait; [`engines`]: one engine per backend (detection and DEM
//!   step over the same device state), the registry and `auto`; [`engines::cpu`] runs anywhere.
//! - [`oracle`]: brute force, for tests.
//! - [`io`]: sphere files (CSV `x,y,z,r[,vx,vy,vz[,wx,wy,wz]]`, NumPy `.npy` N×4, N×7 or
//!   N×10), pair files (CSV `i,j`), simulation frames (VTK `.vtu` + `.pvd`) and checkpoints.
//! - [`numbers`]: numbers as people read them (significant digits; `f32` widened without noise).
//! - [`scenes`]: the paper's datasets, seeded and reproducible.
//! - [`dem`]: the discrete-element simulation: the contact model, scene files and the
//!   [`dem::Stepper`] trait each engine implements (GPU-resident on the GPU engines).
//! - [`mesh`]: triangle meshes (OBJ, PLY, STL) filled with spheres, for the `mesh` scene.
//! - [`names`]: the names of the values a user types (backends, scenes, modes…), read alike on
//!   the command line and in scene files.
//! - [`render`]: pictures of spheres, ray traced on the GPU (ray queries or our own BVH) or the
//!   CPU, with a colour legend, as PNG frames or an animated GIF.
//! - [`prelude`]: what most programs use, in one import.
//!
//! The `mochi` command-line tool (its commands and `mochi bench`) is the crate `mochi-cli` in
//! `cli/`; this library depends on none of its crates (clap only behind the `clap` feature, which
//! the tool turns on).
//!
//! ```
//! use mochi::prelude::*;
//! let spheres = SphereSet::new(vec![[0.0; 3], [1.5, 0.0, 0.0], [9.0, 0.0, 0.0]], vec![1.0, 0.5, 1.0])?;
//! let mut cpu = BackendKind::Cpu.open()?;
//! cpu.build(spheres.view(), ProxyMode::Mochi)?;
//! let (pairs, _stats) = cpu.find_pairs()?;
//! assert_eq!(pairs, vec![mochi::Pair::new(0, 1)]);
//! # Ok::<(), mochi::Error>(())
//! ```
#![deny(unsafe_code)]

pub mod clump;
pub mod dem;
mod detect;
pub mod distributed;
pub mod engines;
mod error;
pub mod gpu;
pub mod io;
mod launcher;
pub mod mesh;
mod morton;
pub mod names;
pub mod numbers;
pub mod oracle;
mod particles;
pub mod proxy;
pub mod render;
pub mod run;
pub mod scenes;
mod spheres;
mod types;

pub use detect::{Backend, BackendInfo};
#[cfg(feature = "optix")]
pub use error::OptixError;
pub use error::{Error, Result};
pub use proxy::ProxyMode;
pub use spheres::{
    MAX_MAGNITUDE, MAX_SPACING_PER_RADIUS, MAX_SPHERES, MIN_RADIUS, SphereSet, Spheres,
    check_count, coarse_coordinates,
};
pub use types::{DetectStats, Pair};

/// What most programs use, in one import (`use mochi::prelude::*;`): spheres and detection,
/// opening a backend's detection or DEM step, scenes, and stepping them.
pub mod prelude {
    pub use crate::dem::scene::{SceneConfig, Start};
    pub use crate::dem::{Advance, Material, Particles, StepParams, Stepper};
    pub use crate::engines::{
        BackendChoice, BackendKind, DemSetup, Opened, Options, open, open_scene, open_setup,
    };
    pub use crate::{Backend, Error, Pair, ProxyMode, Result, SphereSet, Spheres};
}
