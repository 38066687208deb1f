//! The wgpu-compute engine's WGSL modules: each one's composed source, entry points and
//! bindings, named once for the bind-group code and checked against the WGSL by
//! `tests/bindings.rs`.

use super::layout::{BuildKind, GridParams};
use crate::engines::wgpu::granular::shader as granular;
use crate::engines::wgpu::step::{self, Variant, physics};
use crate::gpu::pair_output;
use crate::gpu::shader::{Binding, SharedStruct, WgslModule, shared_struct, wgsl};

/// [`GridParams`], the uniform of every module here.
fn grid_params() -> SharedStruct {
    shared_struct!(
        "GridParams",
        GridParams {
            lo,
            n,
            inv_cell,
            nx,
            ny,
            nz,
            cells,
            row,
            capacity,
            hashed,
            levels,
            top_cell,
            level_pad,
            block_shift,
            max_radius,
            refine,
            skin,
            level_first,
        }
    )
}

/// The counting sort by cell of a detection build (`wgsl/grid/grid_build.wgsl`).
pub(crate) mod grid_build {
    use super::{Binding, wgsl};

    pub const SOURCE: &str = wgsl!("grid/grid_params.wgsl", "grid/grid_build.wgsl");
    pub const ENTRY_POINTS: &[&str] = &["join_spheres", "count_cells", "scatter", "gather"];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const CENTRES: Binding = Binding::read(9, "centres");
    pub const RADII: Binding = Binding::read(10, "radii");
    pub const JOINED: Binding = Binding::read_write(11, "joined");
    pub const SPHERES_IN: Binding = Binding::read(1, "spheres_in");
    pub const SLOTS: Binding = Binding::read_write(3, "slots");
    pub const COUNTS: Binding = Binding::read_write(4, "counts");
    pub const CELL_START: Binding = Binding::read(5, "cell_start");
    pub const IDS: Binding = Binding::read_write(7, "ids");
    pub const SPHERES: Binding = Binding::read_write(8, "spheres");
    pub const BINDINGS: &[Binding] = &[
        PARAMS, CENTRES, RADII, JOINED, SPHERES_IN, SLOTS, COUNTS, CELL_START, IDS, SPHERES,
    ];
}

/// The sorted-key build's keys (`wgsl/grid/grid_sort.wgsl`); the radix sort and `grid_build`'s
/// `gather` do the rest.
pub(crate) mod grid_sort {
    use super::{Binding, wgsl};

    pub const SOURCE: &str = wgsl!("grid/grid_params.wgsl", "grid/grid_sort.wgsl");
    pub const ENTRY_POINTS: &[&str] = &["key_spheres"];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const SPHERES_IN: Binding = Binding::read(1, "spheres_in");
    pub const KEYS: Binding = Binding::read_write(2, "keys");
    pub const IDS: Binding = Binding::read_write(7, "ids");
    pub const BINDINGS: &[Binding] = &[PARAMS, SPHERES_IN, KEYS, IDS];
}

/// The sorted keys the search of the sorted-key build reads (`wgsl/grid/grid_cells_sorted.wgsl`).
pub(crate) const CELL_KEYS: Binding = Binding::read(41, "cell_keys");

/// Detection over a built grid (`wgsl/grid/grid_pairs.wgsl`), in two variants: runs of cells read
/// from the dense build's table, or searched in the sorted-key build's keys.
pub(crate) mod grid_pairs {
    use super::{Binding, CELL_KEYS, pair_output, wgsl};

    pub const DENSE_SOURCE: &str = wgsl!(
        "grid/grid_params.wgsl",
        "grid/grid_stencil.wgsl",
        "grid/grid_cells_dense.wgsl",
        "grid/grid_pairs.wgsl",
        "grid/grid_walk.wgsl",
        "core/proxy.wgsl",
        "core/pair_output.wgsl"
    );
    pub const SORTED_SOURCE: &str = wgsl!(
        "grid/grid_params.wgsl",
        "grid/grid_stencil.wgsl",
        "grid/grid_cells_sorted.wgsl",
        "grid/grid_pairs.wgsl",
        "grid/grid_walk.wgsl",
        "core/proxy.wgsl",
        "core/pair_output.wgsl"
    );
    pub const ENTRY_POINTS: &[&str] = &["find_pairs"];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const SPHERES: Binding = Binding::read(1, "spheres");
    pub const IDS: Binding = Binding::read(2, "ids");
    pub const CELL_START: Binding = Binding::read(6, "cell_start");
    pub const DENSE_BINDINGS: &[Binding] = &[
        PARAMS,
        SPHERES,
        IDS,
        CELL_START,
        pair_output::COUNTERS,
        pair_output::PAIRS,
    ];
    /// `cell_start` is declared (by `grid_pairs.wgsl`) but not read.
    pub const SORTED_BINDINGS: &[Binding] = &[
        PARAMS,
        SPHERES,
        IDS,
        CELL_START,
        CELL_KEYS,
        pair_output::COUNTERS,
        pair_output::PAIRS,
    ];
}

/// The scan of the cell counts into the cell table (`wgsl/grid/cell_scan.wgsl`), in two variants:
/// on subgroup operations where the adapter has them, else in workgroup memory.
pub(crate) mod cell_scan {
    use super::{Binding, wgsl};

    pub const PLAIN_SOURCE: &str = wgsl!(
        "grid/grid_params.wgsl",
        "grid/cell_scan.wgsl",
        "core/workgroup_scan_plain.wgsl",
        "core/workgroup_scan.wgsl"
    );
    pub const SUBGROUP_SOURCE: &str = wgsl!(
        "grid/grid_params.wgsl",
        "grid/cell_scan.wgsl",
        "core/workgroup_scan_subgroups.wgsl",
        "core/workgroup_scan.wgsl"
    );
    pub const ENTRY_POINTS: &[&str] = &["reduce_blocks", "scan_cells"];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const COUNTS: Binding = Binding::read_write(1, "counts");
    pub const BLOCK_SUMS: Binding = Binding::read_write(2, "block_sums");
    pub const CELL_START: Binding = Binding::read_write(3, "cell_start");
    pub const BINDINGS: &[Binding] = &[PARAMS, COUNTS, BLOCK_SUMS, CELL_START];
}

/// The DEM step's binning and contact resolution (`wgsl/grid/dem_grid.wgsl`), followed by the
/// shared physics ([`physics`]), in three variants: the paper's law and its per-pair stiffness
/// (`wgsl/grid/dem_grid_frictionless.wgsl`) and the granular step (`wgsl/grid/dem_grid_granular.wgsl`,
/// [`granular`]).
pub(crate) mod dem_grid {
    use super::{Binding, CELL_KEYS, granular, physics, wgsl};
    use crate::engines::wgpu::compute::layout::BuildKind;
    use crate::engines::wgpu::step::{Accumulators, Lanes, Variant};

    /// The grid and the binning of the dense build (a counting sort into the cell table).
    const DENSE_GRID: &str = wgsl!(
        "grid/grid_params.wgsl",
        "grid/grid_stencil.wgsl",
        "grid/grid_cells_dense.wgsl",
        "grid/dem_grid.wgsl"
    );
    /// The grid and the binning of the sorted-key build (`wgsl/grid/dem_grid_sorted.wgsl`).
    const SORTED_GRID: &str = wgsl!(
        "grid/grid_params.wgsl",
        "grid/grid_stencil.wgsl",
        "grid/grid_cells_sorted.wgsl",
        "grid/dem_grid.wgsl",
        "grid/dem_grid_sorted.wgsl"
    );
    const FRICTIONLESS: &str = wgsl!("grid/dem_grid_frictionless.wgsl", "grid/grid_walk.wgsl");
    const GRANULAR: &str = wgsl!(
        "grid/dem_grid_granular.wgsl",
        "grid/dem_grid_bonds.wgsl",
        "grid/grid_walk.wgsl"
    );

    fn grid(build: BuildKind) -> &'static str {
        match build {
            BuildKind::Dense => DENSE_GRID,
            BuildKind::Sorted => SORTED_GRID,
        }
    }

    /// The paper's step binned by `build` with the accumulators `atomics` (one of
    /// [`physics::FORCE_VARIANTS`]).
    pub fn source(build: BuildKind, atomics: Accumulators) -> String {
        let grid = grid(build);
        format!("{grid}{FRICTIONLESS}{}", physics::frictionless(atomics))
    }

    /// The granular step (`variant`: Mindlin's spring or Mindlin–Deresiewicz) binned by
    /// `build` with the accumulators `atomics`, its contacts shared among `lanes`.
    pub fn granular_source(
        build: BuildKind,
        atomics: Accumulators,
        lanes: Lanes,
        variant: Variant,
    ) -> String {
        let grid = grid(build);
        let lanes = lanes.source();
        let physics = physics::granular(atomics, variant);
        format!("{grid}{lanes}{GRANULAR}{physics}")
    }

    /// The source of `variant` binned by `build` with the accumulators `atomics` (and `lanes`,
    /// which only the granular step uses).
    pub fn variant_source(
        build: BuildKind,
        variant: Variant,
        atomics: Accumulators,
        lanes: Lanes,
    ) -> String {
        match variant {
            Variant::Paper | Variant::PerPair => source(build, atomics),
            Variant::Granular | Variant::Loaded => granular_source(build, atomics, lanes, variant),
        }
    }

    /// The entry points of the dense build's variants.
    pub const ENTRY_POINTS: &[&str] = &[
        "bin_count",
        "bin_scatter",
        "bin_index",
        "resolve",
        "reduce_bounds",
        "integrate",
        "integrate_and_count",
        "begin_step",
        "begin_binning",
        "bin_return",
        "integrate_and_report",
    ];

    /// The entry points of the sorted-key build's variants (the dense binning is in the module
    /// but unused).
    pub const SORTED_ENTRY_POINTS: &[&str] = &[
        "bin_count",
        "bin_scatter",
        "bin_index",
        "bin_keys",
        "bin_gather",
        "resolve",
        "reduce_bounds",
        "integrate",
        "integrate_and_count",
        "begin_step",
        "begin_binning",
        "bin_return",
        "integrate_and_report",
    ];

    /// The entry points of the dense build's granular variant: the mesh walls' kernels too.
    pub const GRANULAR_ENTRY_POINTS: &[&str] = &[
        "bin_count",
        "bin_scatter",
        "bin_index",
        "name_places",
        "list_near",
        "resolve",
        "resolve_near",
        "mesh_walls_near",
        "mesh_wall_contacts",
        "advance_clumps",
        "integrate_clumped",
        "integrate_and_count_clumped",
        "reduce_bounds",
        "integrate",
        "integrate_and_count",
    ];

    /// The entry points of the sorted-key build's granular variant.
    pub const SORTED_GRANULAR_ENTRY_POINTS: &[&str] = &[
        "bin_count",
        "bin_scatter",
        "bin_index",
        "bin_keys",
        "bin_gather",
        "name_places",
        "list_near",
        "resolve",
        "resolve_near",
        "mesh_walls_near",
        "mesh_wall_contacts",
        "advance_clumps",
        "integrate_clumped",
        "integrate_and_count_clumped",
        "reduce_bounds",
        "integrate",
        "integrate_and_count",
    ];

    /// What the sorted-key binning binds besides [`bindings`].
    pub const SORT_KEYS: Binding = Binding::read_write(40, "sort_keys");
    pub const SORT_ORDER: Binding = Binding::read_write(42, "sort_order");
    pub const SORTED: [Binding; 3] = [SORT_KEYS, CELL_KEYS, SORT_ORDER];

    pub const PARAMS: Binding = Binding::uniform(0, "params");
    pub const POS_A: Binding = Binding::read(2, "pos_a");
    pub const VEL_A: Binding = Binding::read(3, "vel_a");
    pub const IDS_A: Binding = Binding::read(4, "ids_a");
    /// The residuals of set a's centres, which the passes that move the state carry along.
    pub const POS_LO_A: Binding = Binding::read(35, "pos_lo_a");
    pub const RANKS: Binding = Binding::read_write(6, "ranks");
    pub const COUNTS: Binding = Binding::read_write(7, "counts");
    pub const CELL_START: Binding = Binding::read(8, "cell_start");
    pub const IDS: Binding = Binding::read_write(12, "ids");
    pub const COUNTERS: Binding = Binding::read_write(14, "counters");
    pub const BOUNDS: Binding = Binding::read_write(15, "bounds");
    /// The granular step's angular velocities of set a (`wgsl/grid/dem_grid_granular.wgsl`).
    pub const OMEGA_A: Binding = Binding::read(25, "omega_a");
    /// The granular step's rows of the old history, by state index (`wgsl/grid/dem_grid_granular.wgsl`).
    pub const CAME_FROM: Binding = Binding::read_write(38, "came_from");
    /// By sorted place: the state row of the sphere there, and its centre and radius.
    pub const HOME: Binding = Binding::read_write(26, "home");
    pub const WALK_POS: Binding = Binding::read_write(27, "walk_pos");
    /// Read-only views of [`HOME`] and [`WALK_POS`] for the kernels that walk (the same
    /// bindings; naga refuses a kernel that uses a buffer through both).
    pub const HOME_RO: Binding = Binding::read(26, "home_ro");
    pub const WALK_POS_RO: Binding = Binding::read(27, "walk_pos_ro");
    /// The granular step's candidates within reach (`wgsl/grid/dem_grid_granular.wgsl`): by sorted
    /// place their count, and [`NEAR_ROOM`] places a sphere.
    pub const LISTED: Binding = Binding::read_write(30, "listed");
    pub const NEAR: Binding = Binding::read_write(31, "near");
    /// Twin of `NEAR_ROOM` in `wgsl/grid/dem_grid_granular.wgsl`.
    pub const NEAR_ROOM: u64 = 16;
    /// Where the granular step's contacts apart come from the history: by stable id, the
    /// sorted place of its sphere (`wgsl/grid/dem_grid_bonds.wgsl`).
    pub const PLACE_OF_ID: Binding = Binding::read_write(39, "place_of_id");

    /// The paper's step's skin (`wgsl/grid/dem_grid_frictionless.wgsl`): by sorted place the row of
    /// the cell its sphere was binned in, and the words the GPU decides in whether a step
    /// re-bins (`skin.rs`).
    pub const WALK_ROW: Binding = Binding::read_write(28, "walk_row");
    /// Read-only views of [`WALK_ROW`] and of the velocities for the paper's resolve kernel.
    pub const WALK_ROW_RO: Binding = Binding::read(28, "walk_row_ro");
    pub const VEL_RO: Binding = Binding::read(11, "vel_ro");
    pub const SKIN: Binding = Binding::read_write(32, "skin_state");
    pub const SKIN_LIMIT: Binding = Binding::read_write(33, "skin_limit");

    const OWN: [Binding; 13] = [
        PARAMS, POS_A, VEL_A, IDS_A, POS_LO_A, RANKS, COUNTS, CELL_START, IDS, COUNTERS, BOUNDS,
        HOME, WALK_POS,
    ];

    /// Every binding of every variant, the physics' included.
    fn shared_bindings() -> Vec<Binding> {
        OWN.into_iter()
            .chain(physics::BINDINGS.iter().copied())
            .collect()
    }

    /// Every binding of the paper's step.
    pub fn bindings() -> Vec<Binding> {
        shared_bindings()
            .into_iter()
            .chain([WALK_ROW, SKIN, SKIN_LIMIT])
            .chain([HOME_RO, WALK_POS_RO, WALK_ROW_RO, VEL_RO])
            .collect()
    }

    /// Every binding of the granular step.
    pub fn granular_bindings() -> Vec<Binding> {
        shared_bindings()
            .into_iter()
            .chain(granular::bindings())
            .chain([OMEGA_A, CAME_FROM, LISTED, NEAR, PLACE_OF_ID])
            .chain([HOME_RO, WALK_POS_RO])
            .collect()
    }

    #[cfg(test)]
    mod tests {
        #[test]
        fn the_lists_room_is_the_shaders() {
            // The host sizes `near` by NEAR_ROOM; the kernels index it by their own.
            let declared = format!("const NEAR_ROOM: u32 = {}u;", super::NEAR_ROOM);
            assert!(super::GRANULAR.contains(&declared), "{declared}");
        }
    }
}

/// Both builds, each with the suffix of its modules' labels.
fn build_variants() -> [(BuildKind, &'static str); 2] {
    [(BuildKind::Dense, ""), (BuildKind::Sorted, "_sorted")]
}

/// Every WGSL module of this engine (detection and DEM step), exactly as the device may get it.
pub fn modules() -> Vec<WgslModule> {
    let module = |label: String, source: String, entry_points, bindings: &[Binding]| {
        WgslModule::new(label, source, entry_points, bindings, vec![grid_params()])
    };
    let mut all = vec![
        module(
            "grid_build".into(),
            grid_build::SOURCE.into(),
            grid_build::ENTRY_POINTS,
            grid_build::BINDINGS,
        ),
        module(
            "grid_sort".into(),
            grid_sort::SOURCE.into(),
            grid_sort::ENTRY_POINTS,
            grid_sort::BINDINGS,
        ),
        module(
            "grid_pairs".into(),
            grid_pairs::DENSE_SOURCE.into(),
            grid_pairs::ENTRY_POINTS,
            grid_pairs::DENSE_BINDINGS,
        ),
        module(
            "grid_pairs_sorted".into(),
            grid_pairs::SORTED_SOURCE.into(),
            grid_pairs::ENTRY_POINTS,
            grid_pairs::SORTED_BINDINGS,
        ),
        module(
            "cell_scan_plain".into(),
            cell_scan::PLAIN_SOURCE.into(),
            cell_scan::ENTRY_POINTS,
            cell_scan::BINDINGS,
        ),
        module(
            "cell_scan_subgroups".into(),
            cell_scan::SUBGROUP_SOURCE.into(),
            cell_scan::ENTRY_POINTS,
            cell_scan::BINDINGS,
        ),
    ];
    for (build, suffix) in build_variants() {
        let (entry_points, granular_entry_points, extra): (_, _, &[Binding]) = match build {
            BuildKind::Dense => (dem_grid::ENTRY_POINTS, dem_grid::GRANULAR_ENTRY_POINTS, &[]),
            BuildKind::Sorted => (
                dem_grid::SORTED_ENTRY_POINTS,
                dem_grid::SORTED_GRANULAR_ENTRY_POINTS,
                &dem_grid::SORTED,
            ),
        };
        for (name, atomics) in physics::FORCE_VARIANTS {
            let bindings = [&dem_grid::bindings()[..], extra].concat();
            let mut dem = module(
                format!("dem_grid_{name}{suffix}"),
                dem_grid::source(build, atomics),
                entry_points,
                &bindings,
            );
            dem.structs.extend(step::law_structs());
            all.push(dem);
            for ((lane_suffix, lanes), (model, variant)) in step::Lanes::ALL
                .into_iter()
                .flat_map(|l| [("", Variant::Granular), ("_md", Variant::Loaded)].map(|v| (l, v)))
            {
                let bindings = [&dem_grid::granular_bindings()[..], extra].concat();
                let mut dem = module(
                    format!("dem_grid_granular_{name}{suffix}{lane_suffix}{model}"),
                    dem_grid::granular_source(build, atomics, lanes, variant),
                    granular_entry_points,
                    &bindings,
                );
                dem.structs.extend(step::law_structs());
                dem.structs.extend(step::material_table());
                dem.structs
                    .extend(crate::engines::common::clumps::clump_structs());
                dem.structs.extend([
                    step::cohesion_params(),
                    crate::engines::common::walls::mesh_params(),
                    crate::engines::common::walls::mesh_wall_row(),
                ]);
                all.push(dem);
            }
        }
    }
    // The flow events' scan of the state (`engines/wgpu/flow.rs`).
    all.push(crate::engines::wgpu::flow::module());
    // A rank's exchange of ghosts (`engines/wgpu/halo.rs`).
    all.push(crate::engines::wgpu::halo::module());
    // Rows moved where spheres leave (`engines/wgpu/state.rs`).
    all.push(crate::engines::wgpu::state::move_module());
    // The history's held slots saved, packed, their partners picked (`engines/wgpu/held_slots.rs`).
    all.push(crate::engines::wgpu::held_slots::module());
    all
}
