//! The `cpu` backend: a sorted proxy grid searched in parallel with rayon.
//!
//! Build = bin the spheres into cells of the mode's size ([`crate::ProxyMode::cell_size`]) and sort
//! them by cell; detection = the half-stencil search of `query`. `update` re-bins: sorting is
//! cheap enough that a grid has nothing to refit.

mod dem;
mod detect;
pub(crate) mod grid;
pub(crate) mod query;
mod walls;

pub use dem::CpuStepper;
pub use detect::CpuBackend;
