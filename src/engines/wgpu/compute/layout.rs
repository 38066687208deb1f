//! The wgpu-compute engine's layout policy, pure (no GPU): which grid (single or multi-level,
//! dense or hashed) and which cells a sphere set gets within a budget of table cells per sphere
//! (docs/method.md, "Grids"). [`GridParams`] is its result and the shaders' uniform.

use crate::gpu::shader::{Vec3f, Vec4u};
use crate::proxy::ProxyMode;
use crate::spheres::Spheres;

/// Relative padding of the cell side: far above the `f32` rounding of the cell coordinates of
/// up to [`MAX_AXIS_CELLS`] cells (about 2^-22 per cell of coordinate), so a pair the narrow phase
/// accepts is never two cells apart.
const CELL_PADDING: f64 = 1.0 / 256.0;

/// Most cells along one axis of a dense table, margin included (bounds the rounding above).
const MAX_AXIS_CELLS: u64 = 4096;

/// A dense table's cells may grow up to this factor over the mode's size to fit the budget.
const MAX_DENSE_GROWTH: f64 = 16.0;

/// Most other spheres expected in a sphere's own cell for a grown dense table; above it, hash.
pub(crate) const MAX_CROWDING: f64 = 4.0;

/// Spheres sampled to estimate [`crowding`].
const CROWDING_SAMPLE: usize = 4096;

/// Most cells along one axis of a hashed grid (coordinates stay exact in `u32` arithmetic).
const MAX_HASHED_AXIS_CELLS: u64 = 1 << 21;

/// Cells of the dense tables per sphere, at most, for detection (a table of at least 2^20 cells is
/// always fine). Fewer cells per sphere mean fewer levels and a cheaper build, paid for with a
/// few more candidates; for detection alone the build weighs more (the cell budget experiment in
/// docs/performance-log/2026-11-22-h200.md).
pub const DETECT_CELLS_PER_SPHERE: u64 = 4;

/// Cells of the dense tables per sphere, at most, for the DEM step on a multi-level grid, whose
/// detection pass also resolves contacts, so fewer candidates pay for a larger table (its
/// coarser levels need the cells; the budget the DEM step takes follows its levels, see
/// docs/performance-log/).
pub const DEM_CELLS_PER_SPHERE: u64 = 8;

/// As [`DEM_CELLS_PER_SPHERE`] on a single grid, where the larger cells' shorter walk and
/// cheaper build pay for their candidates (docs/performance-log/, 2026-11-27).
pub const DEM_CELLS_PER_SPHERE_ONE_LEVEL: u64 = 4;

/// What a layout may spend on its tables: for the dense build `spheres` × `cells_per_sphere`
/// cells; the sorted build has no table, only keys (see [`cell_budget`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Budget {
    pub spheres: u64,
    pub cells_per_sphere: u64,
    pub build: BuildKind,
}

/// The grids' uniform; WGSL twin: `GridParams` in `wgsl/grid/grid_params.wgsl` (`tests/bindings.rs`
/// checks that both lay it out alike).
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct GridParams {
    pub lo: Vec3f,
    pub n: u32,
    pub inv_cell: f32,
    pub nx: u32,
    pub ny: u32,
    pub nz: u32,
    pub cells: u32,
    pub row: u32,
    pub capacity: u32,
    pub hashed: u32,
    pub levels: u32,
    pub top_cell: f32,
    pub level_pad: f32,
    /// Log2 of the table entries per block of the scan ([`block_shift`]).
    pub block_shift: u32,
    /// Largest radius, padded by [`CELL_PADDING`] (the search windows' reach).
    pub max_radius: f32,
    /// Multi-level grids: 4 bits a level (level `k` at bits `4k..4k + 4`), how many times its
    /// cells are halved below its class's size ([`refine_levels`]).
    pub refine: u32,
    /// The DEM step's skin (set by `skin_of` of the step's skin module): how far a sphere may move
    /// before its grid is re-binned; 0 (detection, and the steps that re-bin every step).
    pub skin: f32,
    /// Dense tables: index of each level's first cell (level `k` at `[k / 4].0[k % 4]`).
    pub level_first: [Vec4u; 2],
}

/// Which grid the backend builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Structure {
    /// The multi-level grid where the radii span a factor of 4 or more (`AUTO_MLGRID_RATIO`;
    /// docs/performance-log/ has the comparison), else the single grid.
    #[default]
    Auto,
    /// One grid with cells of the largest proxy (2·r_max; 4·r_max in `nns` mode).
    Grid,
    /// Multi-level proxy grid (docs/method.md, "Grids"): cells halve level by level, each level a dense table,
    /// and each sphere searches from its own size upwards (`mochi` mode; `nns` mode, and sets
    /// whose levels would not fit the budget of cells per sphere, keep the single grid).
    Mlgrid,
}

crate::names::named!(Structure { Auto => "auto", Grid => "grid", Mlgrid => "mlgrid" });

/// Smallest r_max / r_min for which `auto` builds the multi-level grid.
pub const AUTO_MLGRID_RATIO: f64 = 4.0;

/// How the backend sorts the spheres by cell and finds a cell's run of sorted spheres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum GridBuild {
    /// `sorted` where the dense table over the spheres' bounds, at the mode's cell size, would
    /// have more than [`AUTO_SORTED_CELLS_PER_SPHERE`] cells per sphere (and more than
    /// [`AUTO_SORTED_MIN_CELLS`]), else `dense`.
    #[default]
    Auto,
    /// A counting sort into a table of every cell (or hashed bucket): cheapest where the spheres
    /// fill their bounds, but its cost follows the table, so cells may grow to fit a budget.
    Dense,
    /// The spheres' cell keys radix-sorted, runs of cells found by binary search in the sorted
    /// keys: no table, so the cost follows the spheres whatever the box, and cells keep the
    /// mode's size.
    Sorted,
}

crate::names::named!(GridBuild { Auto => "auto", Dense => "dense", Sorted => "sorted" });

/// A build [`GridBuild`] resolves to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BuildKind {
    Dense,
    Sorted,
}

impl BuildKind {
    /// The build in words, for reports ("dense" or "sorted").
    pub fn name(self) -> &'static str {
        match self {
            BuildKind::Dense => "dense",
            BuildKind::Sorted => "sorted",
        }
    }
}

/// Cells per sphere of the dense table at the mode's cell size above which `auto` takes the
/// sorted build. Not yet timed against the dense build: set above every scene of
/// docs/performance-log/, so `auto` keeps the dense build on each of them (1M spheres: `polylog`
/// 0.10, `pour` 0.57, `slab` 2.2, 14 filled tori 3.6, the 14-bunny drop 6.8, `freefall` 576
/// cells per sphere), to be lowered where `mochi bench --experiments clustered` shows the
/// sorted build faster. Above the DEM budget ([`DEM_CELLS_PER_SPHERE`], 8) the dense table
/// grows its cells (more candidates), the sorted build never does.
pub const AUTO_SORTED_CELLS_PER_SPHERE: f64 = 1024.0;

/// Cells of a dense table at or below which `auto` keeps it whatever the sphere count (the
/// dense layout's budget never goes below this many cells: small tables cost little).
pub const AUTO_SORTED_MIN_CELLS: f64 = (1 << 20) as f64;

impl GridBuild {
    /// The build for `n` centres within `bounds` and cells of `base_cell` (the mode's size).
    pub fn resolve(self, n: u64, bounds: ([f32; 3], [f32; 3]), base_cell: f64) -> BuildKind {
        match self {
            GridBuild::Dense => BuildKind::Dense,
            GridBuild::Sorted => BuildKind::Sorted,
            GridBuild::Auto => {
                let cells = dense_cells(bounds, base_cell);
                if cells > AUTO_SORTED_MIN_CELLS && cells > AUTO_SORTED_CELLS_PER_SPHERE * n as f64
                {
                    BuildKind::Sorted
                } else {
                    BuildKind::Dense
                }
            }
        }
    }
}

/// Cells of a single dense table over `bounds` at the cell size `base_cell` (padded), margin
/// included; as `f64`, since it may exceed any integer table.
pub fn dense_cells((lo, hi): ([f32; 3], [f32; 3]), base_cell: f64) -> f64 {
    let size = base_cell * (1.0 + CELL_PADDING);
    (0..3)
        .map(|a| ((hi[a] - lo[a]) as f64 / size).floor() + 3.0)
        .product()
}

/// Most cells (all levels together) of a layout for the sorted build: keys and the ends of
/// runs (a key + a row's width) stay below 2^32.
const SORTED_MAX_CELLS: u64 = 1 << 31;

/// Bits of the largest key of a layout of `cells` cells (what the radix sort sorts by).
pub(crate) fn key_bits(cells: u32) -> u32 {
    32 - cells.saturating_sub(1).leading_zeros()
}

/// Levels a grid may have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Levels {
    /// One level.
    One,
    /// As many as the radii call for and the cell budget allows.
    Many,
}

impl Levels {
    /// The DEM step's budget of dense cells per sphere for a grid of these levels.
    pub(crate) fn dem_cells_per_sphere(self) -> u64 {
        match self {
            Levels::One => DEM_CELLS_PER_SPHERE_ONE_LEVEL,
            Levels::Many => DEM_CELLS_PER_SPHERE,
        }
    }
}

impl Structure {
    /// The levels this structure builds in `mode` for radii spanning `radius_ratio`.
    pub(crate) fn levels_for(self, mode: ProxyMode, radius_ratio: f64) -> Levels {
        match (self, mode) {
            (Structure::Mlgrid, ProxyMode::Mochi) => Levels::Many,
            (Structure::Auto, ProxyMode::Mochi) if radius_ratio >= AUTO_MLGRID_RATIO => {
                Levels::Many
            }
            _ => Levels::One,
        }
    }
}

/// Most levels of a multi-level grid (the shaders keep 8 table offsets).
const MAX_LEVELS: u32 = 8;

/// Fraction of the centres that may lie outside [`core_bounds`] on each side of each axis.
const OUTLIER_FRACTION: f64 = 1e-3;

/// Centres sampled per axis for [`core_bounds`].
const BOUNDS_SAMPLE: usize = 16384;

/// Bounds of the bulk of the centres: per axis, from the [`OUTLIER_FRACTION`] quantile to the
/// 1 − [`OUTLIER_FRACTION`] one of an even sample, widened by 1% of their span and kept within
/// the true bounds. The shaders clamp the centres outside into the border cells (still exact),
/// so a few spheres thrown far away (a bounce, a stray outlier) cannot stretch the table over
/// empty space and coarsen the cells of all the others.
pub(crate) fn core_bounds(spheres: Spheres<'_>) -> Option<([f32; 3], [f32; 3])> {
    let (lo, hi) = spheres.bounds()?;
    let centers = spheres.centers();
    let step = centers.len().div_ceil(BOUNDS_SAMPLE).max(1);
    // One pass over the sample (each sampled centre is a cache miss), then the two quantiles of
    // each axis by selection.
    let sample: Vec<[f32; 3]> = centers.iter().step_by(step).copied().collect();
    let mut core_lo = lo;
    let mut core_hi = hi;
    for a in 0..3 {
        let mut axis: Vec<f32> = sample.iter().map(|c| c[a]).collect();
        let k = (axis.len() as f64 * OUTLIER_FRACTION) as usize;
        let last = axis.len() - 1 - k;
        let q_hi = *axis.select_nth_unstable_by(last, f32::total_cmp).1;
        let q_lo = *axis[..=last].select_nth_unstable_by(k, f32::total_cmp).1;
        let widen = 0.01 * (q_hi - q_lo);
        core_lo[a] = (q_lo - widen).max(lo[a]);
        core_hi[a] = (q_hi + widen).min(hi[a]);
    }
    Some((core_lo, core_hi))
}

/// Estimated number of other spheres in a sphere's own cell, for cells of side `size` anchored at
/// `lo`, from an evenly spread sample of the centres (n·P/m² with P the ordered same-cell pairs
/// among m sampled spheres).
pub(crate) fn crowding(centers: &[[f32; 3]], lo: [f32; 3], size: f64) -> f64 {
    let step = centers.len().div_ceil(CROWDING_SAMPLE).max(1);
    let mut cells: Vec<[u64; 3]> = centers
        .iter()
        .step_by(step)
        .map(|c| std::array::from_fn(|a| ((c[a] as f64 - lo[a] as f64) / size) as u64))
        .collect();
    cells.sort_unstable();
    let m = cells.len() as f64;
    let same_cell_pairs: f64 = cells
        .chunk_by(|a, b| a == b)
        .map(|run| (run.len() * (run.len() - 1)) as f64)
        .sum();
    centers.len() as f64 * same_cell_pairs / (m * m)
}

/// Cells a layout (all its levels together) may have: for the dense build the budget's, at
/// least 2^20, within the adapter's binding size; for the sorted build, as many as its keys
/// hold ([`SORTED_MAX_CELLS`]).
fn cell_budget(limits: &wgpu::Limits, budget: Budget) -> u64 {
    if budget.build == BuildKind::Sorted {
        return SORTED_MAX_CELLS;
    }
    let table_limit = limits.max_storage_buffer_binding_size / 4 - 1;
    (budget.spheres * budget.cells_per_sphere)
        .max(1 << 20)
        .min(table_limit)
}

/// Cells along each axis, margin included, for cells of `size` over `extent`; an axis of more
/// than 2^32 cells counts as 2^32 + 3, far beyond what any table takes, so the count never
/// overflows (callers compare it with [`MAX_AXIS_CELLS`] or [`MAX_HASHED_AXIS_CELLS`]).
fn axis_cells(extent: [f64; 3], size: f64) -> [u64; 3] {
    extent.map(|e| (e / size).min(u32::MAX as f64) as u64 + 1 + 2)
}

/// What a layout is chosen for: `budget.spheres` centres within `bounds`, cells of at least
/// `base_cell` (the mode's cell size), radii from `radii.0` to `radii.1`.
pub(crate) struct LayoutRequest<'a> {
    /// One level, or as many as the radii call for.
    pub levels: Levels,
    /// Lower and upper corner of the centres the tables cover (others clamp to the border cells).
    pub bounds: ([f32; 3], [f32; 3]),
    pub budget: Budget,
    pub base_cell: f64,
    /// Smallest and largest radius.
    pub radii: (f64, f64),
    /// Whether grown dense cells of this side stay uncrowded ([`crowding`]).
    pub dense_check: &'a dyn Fn(f64) -> bool,
}

/// The layout for `request`: with `Levels::Many`, a multi-level grid of dense tables when one of
/// at least two levels fits the budget ([`multi_level_layout`]); otherwise a single level
/// ([`grid_layout`]).
pub(crate) fn choose_layout(limits: &wgpu::Limits, request: &LayoutRequest) -> GridParams {
    let (lo, hi) = request.bounds;
    let (r_min, r_max) = request.radii;
    let (budget, base) = (request.budget, request.base_cell);
    let multi = match request.levels {
        Levels::One => None,
        Levels::Many => multi_level_layout(limits, lo, hi, budget, base, r_max / r_min),
    };
    let params =
        multi.unwrap_or_else(|| grid_layout(limits, lo, hi, budget, base, request.dense_check));
    GridParams {
        block_shift: block_shift(params.cells),
        max_radius: (r_max * (1.0 + CELL_PADDING)) as f32,
        ..params
    }
}

/// Multi-level layout: the top level's cells are `base` (padded), each level below halves them,
/// down to the smallest proxy (`radius_ratio` = r_max / r_min) or to where the dense tables of
/// all levels would outgrow the budget's cells per sphere. `None` where fewer than two levels
/// result.
fn multi_level_layout(
    limits: &wgpu::Limits,
    lo: [f32; 3],
    hi: [f32; 3],
    budget: Budget,
    base: f64,
    radius_ratio: f64,
) -> Option<GridParams> {
    let n = budget.spheres;
    // Dense: finer levels only within the cells per sphere (no floor: a small set gets a small
    // table). Sorted: as many as the keys hold.
    let build = budget.build;
    let budget = match build {
        BuildKind::Dense => cell_budget(limits, budget).min(n * budget.cells_per_sphere),
        BuildKind::Sorted => cell_budget(limits, budget),
    };
    let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]) as f64);
    let size = base * (1.0 + CELL_PADDING);
    let top = axis_cells(extent, size);
    let by_radii = radius_ratio
        .log2()
        .floor()
        .clamp(0.0, (MAX_LEVELS - 1) as f64) as u32;
    // Level sizes from the top down, while they fit: cells per axis.
    let mut dims: Vec<[u64; 3]> = Vec::new();
    let mut total = 0u64;
    for shift in 0..=by_radii {
        let level = top.map(|c| ((c - 2) << shift) + 2);
        if level.iter().any(|&d| d > MAX_AXIS_CELLS) {
            break;
        }
        let cells = level.iter().product::<u64>();
        if total + cells > budget {
            break;
        }
        total += cells;
        dims.push(level);
    }
    let levels = dims.len() as u32;
    if levels < 2 {
        return None;
    }
    let refine = match build {
        BuildKind::Dense => refine_levels(&mut dims, budget),
        BuildKind::Sorted => 0,
    };
    // Level `levels - 1` is the top; its table comes first.
    let mut level_first = [Vec4u::default(); 2];
    let mut first = 0u64;
    for (shift, level_dims) in dims.iter().enumerate() {
        let level = levels as usize - 1 - shift;
        level_first[level / 4].0[level % 4] = first as u32;
        first += level_dims.iter().product::<u64>();
    }
    Some(GridParams {
        lo: lo.into(),
        n: n as u32,
        inv_cell: (1.0 / size) as f32,
        nx: top[0] as u32,
        ny: top[1] as u32,
        nz: top[2] as u32,
        cells: first as u32,
        levels,
        top_cell: size as f32,
        level_pad: (1.0 + CELL_PADDING) as f32,
        refine,
        level_first,
        ..GridParams::default()
    })
}

/// Most halvings of a level's cells below its class's size (on the poured pile of
/// docs/performance-log/ a second did not fit the budget; one was measured).
const MAX_REFINE: u64 = 1;

/// Refines the coarser levels of a multi-level grid (`dims`: cells per axis of each level, the
/// top first) within `budget` cells in all; returns [`GridParams::refine`]. A sphere searches
/// each coarser level for the partners within its radius plus that level's largest, about half
/// the level's class size C: at cells of size C its window there is 2 cells (2C) per axis around
/// a small sphere, where the partners' centres lie within a cube of side C; halving the cells
/// makes it 3 cells (1.5C). The small spheres are most of a polydisperse set and search every
/// coarser level, so the level refined first is the one whose table grows least (the top), then
/// the next, while all fit; the finest level, which only its own spheres search, keeps its
/// class's cells.
fn refine_levels(dims: &mut [[u64; 3]], budget: u64) -> u32 {
    let levels = dims.len();
    let mut refined = vec![0u64; levels];
    let mut total: u64 = dims.iter().map(|d| d.iter().product::<u64>()).sum();
    loop {
        let cheapest = (0..levels - 1)
            .filter(|&k| refined[k] < MAX_REFINE)
            .min_by_key(|&k| dims[k].iter().product::<u64>());
        let Some(k) = cheapest else { break };
        let finer = dims[k].map(|c| ((c - 2) << 1) + 2);
        let (now, then) = (
            dims[k].iter().product::<u64>(),
            finer.iter().product::<u64>(),
        );
        if finer.iter().any(|&d| d > MAX_AXIS_CELLS) || total - now + then > budget {
            break;
        }
        total = total - now + then;
        dims[k] = finer;
        refined[k] += 1;
    }
    // dims[shift] is level `levels - 1 - shift`.
    (0..levels)
        .map(|shift| (refined[shift] as u32) << (4 * (levels - 1 - shift)))
        .sum()
}

/// Single-level cell layout for `n` centres within `lo..=hi` and cells of at least `base`: a
/// dense table when one fits the budget (cells grown up to
/// [`MAX_DENSE_GROWTH`]× for that while `dense_check` accepts the grown size), else a hashed
/// table. Centres outside `lo..=hi` are clamped to the border cells by the shaders: still exact,
/// only slower.
pub(crate) fn grid_layout(
    limits: &wgpu::Limits,
    lo: [f32; 3],
    hi: [f32; 3],
    budget: Budget,
    base: f64,
    dense_check: &dyn Fn(f64) -> bool,
) -> GridParams {
    let n = budget.spheres;
    let table_limit = limits.max_storage_buffer_binding_size / 4 - 1;
    let budget = cell_budget(limits, budget);
    let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]) as f64);
    let widest = extent.iter().copied().fold(0.0, f64::max);
    let counts = |size: f64| axis_cells(extent, size);
    let params = |size: f64, [nx, ny, nz]: [u64; 3], cells: u64, hashed: u32| GridParams {
        lo: lo.into(),
        n: n as u32,
        inv_cell: (1.0 / size) as f32,
        nx: nx as u32,
        ny: ny as u32,
        nz: nz as u32,
        cells: cells as u32,
        hashed,
        levels: 1,
        top_cell: size as f32,
        level_pad: 1.0,
        ..GridParams::default()
    };

    // Dense: the smallest cells (from the mode's size, growing) whose table fits the budget,
    // unless growing them crowds the cells (a cluster far from the rest, say). Cells of the
    // mode's own size are never grown, so however crowded they are, hashing would not thin them.
    let smallest = base * (1.0 + CELL_PADDING);
    let mut size = smallest;
    while size <= MAX_DENSE_GROWTH * base {
        let c = counts(size);
        if c.iter().all(|&k| k <= MAX_AXIS_CELLS) {
            let cells = c.iter().product::<u64>(); // ≤ 2^36: no overflow
            if cells <= budget {
                if size == smallest || dense_check(size) {
                    return params(size, c, cells, 0);
                }
                break;
            }
        }
        size *= 1.25;
    }

    // Cell coordinates of up to 2^21 per axis: pad the cells for their f32 rounding too.
    let size = base.max(widest / (MAX_HASHED_AXIS_CELLS - 3) as f64);
    let size = size * (1.0 + CELL_PADDING.max(widest / size / (1u64 << 20) as f64));
    let buckets = (2 * n)
        .next_power_of_two()
        .clamp(1024, 1 << table_limit.ilog2());
    params(size, counts(size), buckets, 1)
}

/// A grid layout in words: build, table, levels, cells per axis and cell side.
pub(crate) fn describe_layout(p: &GridParams, build: BuildKind) -> String {
    let table = match (p.hashed != 0, build) {
        (true, _) => format!("{} build, hashed into {} buckets", build.name(), p.cells),
        (false, BuildKind::Dense) => format!("dense build, {} cells", p.cells),
        (false, BuildKind::Sorted) => format!("sorted build, keys of {} cells", p.cells),
    };
    let refined: Vec<String> = (0..p.levels)
        .rev()
        .filter_map(|k| match (p.refine >> (4 * k)) & 15 {
            0 => None,
            halvings => Some(format!(
                "level {k}'s cells 1/{} of its class",
                1 << halvings
            )),
        })
        .collect();
    let levels = match p.levels {
        1 => "1 level".to_string(),
        k if refined.is_empty() => format!("{k} levels"),
        k => format!("{k} levels ({})", refined.join(", ")),
    };
    // The top level's own cells (refined or not).
    let halvings = (p.refine >> (4 * (p.levels.max(1) - 1))) & 15;
    let [nx, ny, nz] = [p.nx, p.ny, p.nz].map(|c| (c.saturating_sub(2) << halvings) + 2);
    format!(
        "grid {table}, {levels}, top level {nx}×{ny}×{nz} cells of {:.4e} m",
        p.top_cell / (1u32 << halvings) as f32
    )
}

/// Most blocks the cell table is cut into for its scan (`wgsl/grid/cell_scan.wgsl`; each scan
/// workgroup sums the blocks before it).
/// More blocks mean more block sums to add up, fewer mean too few workgroups, each scanning more
/// tiles in a row; 1024 measured best (docs/performance-log/2026-11-22-h200.md, the sweep of the
/// most blocks).
pub(crate) const MAX_BLOCKS: u32 = 1024;

/// Smallest block: one tile of a scan workgroup (`TILE` in the shader).
pub(crate) const MIN_BLOCK_SHIFT: u32 = 10;

/// Log2 of the entries per block for a table of `cells` cells (`cells + 1` entries): the
/// smallest block of at least one tile that cuts the table into at most [`MAX_BLOCKS`].
pub(crate) fn block_shift(cells: u32) -> u32 {
    let mut shift = MIN_BLOCK_SHIFT;
    while (cells >> shift) + 1 > MAX_BLOCKS {
        shift += 1;
    }
    shift
}

impl GridParams {
    /// Blocks the scan cuts this layout's table into: the workgroups of each of its dispatches.
    pub(crate) fn scan_blocks(&self) -> u32 {
        (self.cells >> self.block_shift) + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn core_bounds_leave_out_a_few_far_centres_and_keep_the_bulk() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let mut centers: Vec<[f32; 3]> = (0..200_000)
            .map(|_| std::array::from_fn(|_| rng.random_range(0.0..1.0)))
            .collect();
        // Outliers on both sides of every axis, fewer than the share left out.
        for k in 0..20 {
            let far = if k % 2 == 0 { 1e6 } else { -1e6 };
            centers[k * 9973] = [far, -far, far];
        }
        let n = centers.len();
        let spheres = crate::spheres::SphereSet::new(centers, vec![1e-3; n]).unwrap();
        let (lo, hi) = core_bounds(spheres.view()).unwrap();
        for a in 0..3 {
            assert!(
                (-0.02..0.01).contains(&lo[a]),
                "axis {a}: core from {}",
                lo[a]
            );
            assert!((0.99..1.02).contains(&hi[a]), "axis {a}: core to {}", hi[a]);
        }
    }

    fn budget(spheres: u64) -> Budget {
        Budget {
            spheres,
            cells_per_sphere: DETECT_CELLS_PER_SPHERE,
            build: BuildKind::Dense,
        }
    }

    #[test]
    fn crowded_cells_of_the_modes_size_stay_dense() {
        // A dense pile of small spheres around a few big ones: every cell of 2·r_max holds many
        // spheres, but the table fits at that size, so it stays dense (hashing cannot help).
        let limits = wgpu::Limits::default();
        let crowded = |_: f64| false;
        let p = grid_layout(&limits, [0.0; 3], [1.0; 3], budget(100_000), 0.1, &crowded);
        assert_eq!(p.hashed, 0);
        assert!((p.top_cell as f64 - 0.1 * (1.0 + CELL_PADDING)).abs() < 1e-7);
        // Grown cells are checked: too big a box for the budget at the mode's size hashes when
        // the grown cells would be crowded, and grows them when not.
        let p = grid_layout(&limits, [0.0; 3], [100.0; 3], budget(1000), 0.1, &crowded);
        assert_eq!(p.hashed, 1);
        let p = grid_layout(&limits, [0.0; 3], [20.0; 3], budget(1000), 0.1, &|_| true);
        assert_eq!(p.hashed, 0);
        assert!(p.top_cell as f64 > 0.1);
    }

    #[test]
    fn auto_takes_the_sorted_build_where_the_dense_table_outgrows_the_spheres() {
        // 10^6 spheres in a box of 100 cells per side at the mode's size (10^6 cells, one per
        // sphere): dense. The same box at 2000 cells per side (8·10^9 cells): sorted.
        let bounds = ([0.0; 3], [1.0; 3]);
        assert_eq!(
            GridBuild::Auto.resolve(1_000_000, bounds, 0.01),
            BuildKind::Dense
        );
        assert_eq!(
            GridBuild::Auto.resolve(1_000_000, bounds, 0.0005),
            BuildKind::Sorted
        );
        // A small table stays dense however few spheres it holds.
        assert_eq!(GridBuild::Auto.resolve(2, bounds, 0.1), BuildKind::Dense);
        // Forced builds are taken as they are.
        assert_eq!(GridBuild::Dense.resolve(2, bounds, 0.001), BuildKind::Dense);
        assert_eq!(GridBuild::Sorted.resolve(2, bounds, 1.0), BuildKind::Sorted);
    }

    #[test]
    fn the_sorted_build_keeps_the_modes_cells_where_the_dense_one_grows_them() {
        // 10^4 spheres over 300 cells per side: the dense table grows its cells to fit the
        // budget, the sorted build keeps the mode's and sorts by keys of 27M cells.
        let limits = wgpu::Limits::default();
        let request = |build| LayoutRequest {
            levels: Levels::One,
            bounds: ([0.0; 3], [3.0; 3]),
            budget: Budget {
                build,
                ..budget(10_000)
            },
            base_cell: 0.01,
            radii: (0.005, 0.005),
            dense_check: &|_| true,
        };
        let dense = choose_layout(&limits, &request(BuildKind::Dense));
        let sorted = choose_layout(&limits, &request(BuildKind::Sorted));
        assert_eq!((dense.hashed, sorted.hashed), (0, 0));
        assert!(dense.top_cell > 0.012, "{}", dense.top_cell);
        assert!((sorted.top_cell as f64 - 0.01 * (1.0 + CELL_PADDING)).abs() < 1e-7);
        assert!(sorted.cells > 27_000_000);
        assert_eq!(key_bits(sorted.cells), 25);
        assert_eq!(
            (key_bits(1), key_bits(2), key_bits(3), key_bits(4)),
            (0, 1, 2, 2)
        );
        assert_eq!(key_bits(u32::MAX), 32);
    }

    #[test]
    fn the_coarser_levels_are_refined_while_the_tables_fit_and_the_finest_never() {
        // 1M spheres of `polylog`'s radii (0.5–60 mm) over a pile's bounds: both budgets hold 3
        // levels (12, 6 and 3 cm classes), then refine the coarser ones as far as they fit.
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 1 << 30,
            ..wgpu::Limits::default()
        };
        let request = |cells_per_sphere| LayoutRequest {
            levels: Levels::Many,
            bounds: ([0.0; 3], [4.7, 2.0, 4.7]),
            budget: Budget {
                spheres: 1_000_000,
                cells_per_sphere,
                build: BuildKind::Dense,
            },
            base_cell: 0.12,
            radii: (0.0005, 0.06),
            dense_check: &|_| true,
        };
        let level_cells = |p: &GridParams, level: u32| {
            let shift = p.levels - 1 - level + ((p.refine >> (4 * level)) & 15);
            [p.nx, p.ny, p.nz]
                .map(|c| (((c - 2) as u64) << shift) + 2)
                .iter()
                .product::<u64>()
        };
        for (cells_per_sphere, levels) in [(DEM_CELLS_PER_SPHERE, 3), (DETECT_CELLS_PER_SPHERE, 3)]
        {
            let p = choose_layout(&limits, &request(cells_per_sphere));
            let described = describe_layout(&p, BuildKind::Dense);
            assert_eq!(p.levels, levels, "{described}");
            let top = levels - 1;
            let halvings = |k: u32| (p.refine >> (4 * k)) & 15;
            assert!(halvings(top) >= 1, "{described}");
            assert!(described.contains(&format!("level {top}'s cells 1/")));
            assert_eq!(halvings(0), 0, "the finest level keeps its class's cells");
            let cells: u64 = (0..levels).map(|k| level_cells(&p, k)).sum();
            assert_eq!(cells, p.cells as u64);
            let budget = 1_000_000 * cells_per_sphere;
            assert!(cells <= budget);
            // Greedy to the end: the coarser level with the fewest cells, refined once more,
            // would not fit.
            let cheapest = (1..levels)
                .filter(|&k| (halvings(k) as u64) < MAX_REFINE)
                .map(|k| level_cells(&p, k))
                .min();
            if let Some(c) = cheapest {
                assert!(cells + 7 * c > budget, "{described}");
            }
            // Tables follow each other, the top's first.
            for k in 0..top {
                let next = p.level_first[(k + 1) as usize / 4].0[(k + 1) as usize % 4];
                assert_eq!(
                    p.level_first[k as usize / 4].0[k as usize % 4] as u64,
                    next as u64 + level_cells(&p, k + 1)
                );
            }
        }
        // The sorted build has no table to fit: its levels keep their classes' cells.
        let sorted = choose_layout(
            &limits,
            &LayoutRequest {
                budget: Budget {
                    build: BuildKind::Sorted,
                    ..request(DEM_CELLS_PER_SPHERE).budget
                },
                ..request(DEM_CELLS_PER_SPHERE)
            },
        );
        assert_eq!(sorted.refine, 0);
    }

    #[test]
    fn spans_of_far_more_cells_than_u64_counts_hash() {
        // 2e17 m in cells of 2e-3 m is 10^20 cells, more than a u64 counts: the layout still
        // hashes cells that cover the span (no count wraps into a tiny dense table).
        let limits = wgpu::Limits::default();
        for levels in [Levels::One, Levels::Many] {
            let request = LayoutRequest {
                levels,
                bounds: ([-1e17, 0.0, 0.0], [1e17, 0.0, 0.0]),
                budget: budget(4),
                base_cell: 2e-3,
                radii: (1e-5, 1e-3),
                dense_check: &|_| true,
            };
            let p = choose_layout(&limits, &request);
            assert_eq!((p.hashed, p.levels), (1, 1));
            let cells = (2e17 / p.top_cell as f64) as u64 + 3;
            assert!(
                cells <= p.nx as u64 && p.nx as u64 <= MAX_HASHED_AXIS_CELLS,
                "{}",
                p.nx
            );
        }
        assert_eq!(axis_cells([1e30, 0.0, 1.0], 1e-3)[0], u32::MAX as u64 + 3);
    }
}
