//! The `wgpu-compute` backend: a sorted proxy grid built and searched in WGSL compute shaders,
//! for adapters without ray queries or RT cores (where it beats software BVH traversal).
//!
//! Two builds sort the spheres by cell ([`GridBuild`]; `auto` picks by the size of the dense
//! table against the sphere count). The dense build, in one submission and one compute pass, is a
//! counting sort by cell
//! (`wgsl/grid/grid_build.wgsl`): every sphere's cell key and rank within its cell (one atomic add),
//! the cell counts scanned into a table of where each cell's run starts (`cell_table.rs`: two
//! dispatches, which leave the counts zeroed for the next build), each sphere's index scattered
//! to its sorted place, and the spheres gathered in that order. No comparison or radix sort is
//! needed: the table is the sort. Its cost follows the table, so a few spheres in a large
//! box pay for the box. The sorted build (`wgsl/grid/grid_sort.wgsl`) radix-sorts the spheres' cell
//! keys instead (`src/gpu/radix_sort.rs`), and the search finds a cell's run by binary search
//! in the sorted keys (`wgsl/grid/grid_cells_sorted.wgsl`; a hash table of the occupied cells would
//! need a lookup per cell of a window row, its own buffer and a clear each build, where the
//! search needs one binary search per row and nothing else): no table, so its cost follows the
//! spheres, and its cells keep the mode's size however large the box.
//!
//! The single grid has cells of 2·r_max in `mochi` mode and 4·r_max in `nns` mode (the proxy of
//! the largest sphere, or the fixed-radius box), padded a little. Its table is dense over the
//! bulk of the centres (their 0.1% to 99.9% quantiles: a few far outliers are clamped into the
//! border cells) while it fits a budget of [`DETECT_CELLS_PER_SPHERE`] cells per sphere
//! ([`DEM_CELLS_PER_SPHERE`] and [`DEM_CELLS_PER_SPHERE_ONE_LEVEL`] in the DEM step); cells may grow for that (still exact, a few more
//! candidates) as long as a sample shows them uncrowded. Otherwise (a cluster with far-away
//! outliers, say) cells keep their size and are hashed into 2n buckets, so
//! the work never degenerates. The multi-level grid (docs/method.md, "Grids") stacks dense tables whose cells
//! halve level by level, as many levels as the radii need and the same budget holds; each sphere
//! is binned at its own size. Detection (`wgsl/grid/grid_pairs.wgsl`, windows from
//! `wgsl/grid/grid_stencil.wgsl`) searches the cells within r_i + r_max of each centre and visits each
//! pair once, like the cpu backend.

pub(crate) mod cell_table;
mod dem;
mod detect;
pub(crate) mod layout;
mod shaders;
mod skin;

pub use dem::{GridStepOptions, GridStepper, Sorting};
pub use detect::WgpuComputeBackend;
pub use layout::{
    AUTO_MLGRID_RATIO, AUTO_SORTED_CELLS_PER_SPHERE, AUTO_SORTED_MIN_CELLS, BuildKind,
    DEM_CELLS_PER_SPHERE, DEM_CELLS_PER_SPHERE_ONE_LEVEL, DETECT_CELLS_PER_SPHERE, GridBuild,
    Structure, dense_cells,
};
pub use shaders::modules as shaders;
