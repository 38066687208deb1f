//! The DEM step's bind groups: each phase's buffers on either state set, made at each layout.

use super::schedule::StepKind;
use super::*;

/// Bind groups of the steps from one state set (the source of the next binning).
pub(super) struct Binds {
    pub(super) bin_first: wgpu::BindGroup,
    pub(super) bin_last: wgpu::BindGroup,
    /// The sorting step's, on the other set.
    pub(super) resolving: ResolveBinds,
    pub(super) integrate: wgpu::BindGroup,
    /// The clumps' step's, on the set `integrate` integrates (with clumps only).
    pub(super) clumps: Option<wgpu::BindGroup>,
    pub(super) reduce_bounds: wgpu::BindGroup,
    /// A binning step's own bind groups on set `from` (where the step has binning steps).
    pub(super) binning: Option<BinningBinds>,
    /// The skin's kernels' (where the step has them).
    pub(super) skin: Option<SkinBinds>,
}

/// The skin's bind groups of a step whose state is on one set (binning into the other).
pub(super) struct SkinBinds {
    pub(super) begin_step: wgpu::BindGroup,
    pub(super) begin_binning: wgpu::BindGroup,
    pub(super) integrate: wgpu::BindGroup,
    pub(super) bin_return: wgpu::BindGroup,
}

/// Bind groups of a binning step's own passes on one set (its count and integration are the
/// sorting steps').
pub(super) struct BinningBinds {
    pub(super) bin_index: wgpu::BindGroup,
    pub(super) resolving: ResolveBinds,
}

/// The bind groups of the contact pass of a step on one state set, by the parity of the history
/// it reads (one, 0, in the paper's step).
pub(super) struct ResolveBinds {
    /// The walk's where the granular contact pass runs in two kernels (`Pipelines::listing`);
    /// `resolve` then binds the second.
    pub(super) list_near: Option<wgpu::BindGroup>,
    /// `name_places`', where contacts apart come from the history (`Pipelines::name_places`).
    pub(super) name_places: Option<wgpu::BindGroup>,
    pub(super) resolve: Vec<wgpu::BindGroup>,
    /// The mesh walls' kernels', as `Pipelines::mesh` (granular step with mesh walls).
    pub(super) mesh: Option<Vec<[wgpu::BindGroup; 2]>>,
}

/// `own` bindings and `more` (the granular step's or the per-pair variant's).
pub(super) fn joined<'a>(
    own: &[(Binding, &'a wgpu::Buffer)],
    more: &[(Binding, &'a wgpu::Buffer)],
) -> Vec<(Binding, &'a wgpu::Buffer)> {
    [own, more].concat()
}

impl Resident {
    /// Bind groups for binning from set `from` into the other with `sorter` (and, in the
    /// granular step, moving the angular velocities with the state).
    pub(super) fn make_binds(&self, sorter: &Sorter, from: usize) -> Binds {
        let a = &self.sets[from];
        let p = &self.pipelines;
        let gpu = &self.gpu;
        let (scatter_more, integrate_more) = match (&self.granular, &self.near) {
            (Some(g), Some(_)) => {
                let [omega_a, omega] = g.sorted_omega(from);
                let integrate = g.integrate_bindings(1 - from);
                (
                    vec![
                        (OMEGA_A, omega_a),
                        (OMEGA, omega),
                        (CAME_FROM, g.came_from()),
                    ],
                    integrate,
                )
            }
            // The paper's scatter notes the binned rows for the steps that may skip their binning.
            _ => (self.skin_rows(), Vec::new()),
        };
        // What the binning's passes and the integration bind of the sorter.
        let (first, last, counting) = match sorter {
            Sorter::Dense {
                ranks, cell_table, ..
            } => (
                vec![(RANKS, ranks), (COUNTS, &cell_table.counts)],
                vec![
                    (RANKS, ranks),
                    (CELL_START, &cell_table.cell_start),
                    (COUNTERS, &self.counters),
                    (CLOCK, &self.clock),
                ],
                vec![
                    (PARAMS, &self.grid_uniform),
                    (RANKS, ranks),
                    (COUNTS, &cell_table.counts),
                ],
            ),
            Sorter::Sorted {
                keys,
                order,
                prepared,
                ..
            } => {
                let (_, sorted_order) = prepared.sorted();
                (
                    vec![
                        (SORT_KEYS, keys),
                        (SORT_ORDER, order),
                        (COUNTERS, &self.counters),
                        (CLOCK, &self.clock),
                    ],
                    vec![(SORT_ORDER, sorted_order)],
                    Vec::new(),
                )
            }
        };
        Binds {
            bin_first: gpu.bind(
                "mochi.dem.bin_first",
                &p.bin_first,
                &joined(&[(PARAMS, &self.grid_uniform), (POS_A, &a.pos)], &first),
            ),
            bin_last: gpu.bind(
                "mochi.dem.bin_last",
                &p.bin_last,
                &joined(
                    &self.moving(from, 1 - from),
                    &[&last[..], &scatter_more[..]].concat(),
                ),
            ),
            resolving: self.resolving(sorter, 1 - from, StepKind::Sorting),
            integrate: gpu.bind(
                "mochi.dem.integrate",
                &p.integrate,
                &[&self.integrated(1 - from)[..], &integrate_more, &counting].concat(),
            ),
            clumps: self.clumps_binds(1 - from),
            reduce_bounds: gpu.bind(
                "mochi.dem.reduce_bounds",
                &p.reduce_bounds,
                &[
                    (PARAMS, &self.grid_uniform),
                    (POS_A, &a.pos),
                    (BOUNDS, &self.bounds),
                ],
            ),
            binning: self.binning_binds(sorter, from),
            skin: self.skin_binds(from, &integrate_more),
        }
    }

    /// What a pass moving the state from set `from` (as set a) into set `to` binds.
    pub(super) fn moving(&self, from: usize, to: usize) -> [(Binding, &wgpu::Buffer); 9] {
        let (a, b) = (&self.sets[from], &self.sets[to]);
        [
            (PARAMS, &self.grid_uniform),
            (POS_A, &a.pos),
            (POS_LO_A, &a.lo),
            (VEL_A, &a.vel),
            (IDS_A, &a.ids),
            (POS, &b.pos),
            (POS_LO, &b.lo),
            (VEL, &b.vel),
            (IDS, &b.ids),
        ]
    }

    /// What every integration kernel binds to step state set `on`.
    pub(super) fn integrated(&self, on: usize) -> [(Binding, &wgpu::Buffer); 8] {
        let set = &self.sets[on];
        [
            (DEM, self.dem_uniform.buffer()),
            (POS, &set.pos),
            (POS_LO, &set.lo),
            (VEL, &set.vel),
            (IDS, &set.ids),
            (FORCE, &self.force),
            (CLOCK, &self.clock),
            (EXTERNAL, self.external.buffer()),
        ]
    }

    /// The bind group of the clumps' step on state set `on` (`None` without clumps).
    pub(super) fn clumps_binds(&self, on: usize) -> Option<wgpu::BindGroup> {
        let (pipeline, _) = self.pipelines.clumps.as_ref()?;
        let own = self.granular.as_ref()?.advance_bindings(on)?;
        let set = &self.sets[on];
        let state = [
            (DEM, self.dem_uniform.buffer()),
            (POS, &set.pos),
            (POS_LO, &set.lo),
            (VEL, &set.vel),
            (FORCE, &self.force),
            (CLOCK, &self.clock),
            (EXTERNAL, self.external.buffer()),
        ];
        let bindings = joined(&state, &own);
        Some(
            self.gpu
                .bind("mochi.dem.advance_clumps", pipeline, &bindings),
        )
    }

    /// What the paper's scatter writes for its skin (the binned rows), none in the granular
    /// step.
    pub(super) fn skin_rows(&self) -> Vec<(Binding, &wgpu::Buffer)> {
        match self.granular {
            Some(_) => Vec::new(),
            None => vec![(WALK_ROW, &self.places.walk_row)],
        }
    }

    /// The skin's bind groups of a step whose state is on set `on` (`law`: the law's bindings),
    /// where the step has a skin.
    pub(super) fn skin_binds(
        &self,
        on: usize,
        law: &[(Binding, &wgpu::Buffer)],
    ) -> Option<SkinBinds> {
        let (pipelines, skin) = (self.pipelines.skin.as_ref()?, self.skin.as_ref()?);
        let gpu = &self.gpu;
        let started = [
            (CLOCK, &self.clock),
            (COUNTERS, &self.counters),
            (SKIN, &skin.state),
        ];
        Some(SkinBinds {
            begin_step: gpu.bind(
                "mochi.dem.begin_step",
                &pipelines.begin_step,
                &joined(
                    &[(PARAMS, &self.grid_uniform), (SKIN_LIMIT, &skin.limit)],
                    &started,
                ),
            ),
            begin_binning: gpu.bind(
                "mochi.dem.begin_binning",
                &pipelines.begin_binning,
                &joined(&started, &[(SKIN_LIMIT, &skin.limit)]),
            ),
            integrate: gpu.bind(
                "mochi.dem.integrate_and_report",
                &pipelines.integrate,
                &[
                    &self.integrated(on)[..],
                    &[(SKIN, &skin.state), (SKIN_LIMIT, &skin.limit)],
                    law,
                ]
                .concat(),
            ),
            bin_return: gpu.bind(
                "mochi.dem.bin_return",
                &pipelines.bin_return,
                &self.moving(1 - on, on),
            ),
        })
    }

    /// Bind groups of a binning step on set `on` (`None` where the step has none).
    pub(super) fn binning_binds(&self, sorter: &Sorter, on: usize) -> Option<BinningBinds> {
        let bin_index = self.pipelines.bin_index.as_ref()?;
        let Sorter::Dense {
            ranks, cell_table, ..
        } = sorter
        else {
            return None;
        };
        let (set, gpu, places) = (&self.sets[on], &self.gpu, &self.places);
        Some(BinningBinds {
            bin_index: gpu.bind(
                "mochi.dem.bin_index",
                bin_index,
                &[
                    (PARAMS, &self.grid_uniform),
                    (POS_A, &set.pos),
                    (RANKS, ranks),
                    (CELL_START, &cell_table.cell_start),
                    (COUNTERS, &self.counters),
                    (CLOCK, &self.clock),
                    (HOME, &places.home),
                    (WALK_POS, &places.walk_pos),
                ],
            ),
            resolving: self.resolving(sorter, on, StepKind::Binning),
        })
    }

    /// The contact pass's bind groups of a step of kind `kind` that resolves state set `on`:
    /// the search's cells, the state, the sorted places (the state itself in a sorting step,
    /// `bin_index`'s in a binning step) and the variant's bindings, by the history's parity.
    pub(super) fn resolving(&self, sorter: &Sorter, on: usize, kind: StepKind) -> ResolveBinds {
        let (set, places, gpu) = (&self.sets[on], &self.places, &self.gpu);
        let cells = match sorter {
            Sorter::Dense { cell_table, .. } => (CELL_START, &cell_table.cell_start),
            Sorter::Sorted { prepared, .. } => (CELL_KEYS, prepared.sorted().0),
        };
        let placed = match kind {
            StepKind::Sorting | StepKind::Skin => [(HOME, &places.identity), (WALK_POS, &set.pos)],
            StepKind::Binning => [(HOME, &places.home), (WALK_POS, &places.walk_pos)],
        };
        let own = [
            (PARAMS, &self.grid_uniform),
            (DEM, self.dem_uniform.buffer()),
            cells,
            (VEL, &set.vel),
            (FORCE, &self.force),
            (COUNTERS, &self.counters),
            placed[0],
            placed[1],
        ];
        let Some(g) = &self.granular else {
            // The walk starts from the row of its sphere's binned cell and widens its windows by
            // the drift since (the skin's).
            let skin = self.skin.as_ref().expect("the paper's step's skin buffers");
            let drift = [(WALK_ROW, &places.walk_row), (SKIN_LIMIT, &skin.limit)];
            let resolve = gpu.bind(
                "mochi.dem.resolve",
                &self.pipelines.resolve,
                &joined(&own, &drift),
            );
            return ResolveBinds {
                list_near: None,
                name_places: None,
                resolve: vec![resolve],
                mesh: None,
            };
        };
        let lists = self.near.as_ref().expect("the granular step's lists");
        // A multi-level grid's walk is long: it runs in a kernel of its own, without the
        // contact law's registers.
        let listed = [(NEAR, &lists.near), (LISTED, &lists.listed)];
        let place_of_id = (PLACE_OF_ID, &lists.place_of_id);
        let name_places = self.pipelines.name_places.as_ref().map(|pipeline| {
            let names = [
                (PARAMS, &self.grid_uniform),
                placed[0],
                (IDS, &set.ids),
                place_of_id,
            ];
            gpu.bind("mochi.dem.name_places", pipeline, &names)
        });
        let (list_near, resolve) = match &self.pipelines.listing {
            Some([list_near, resolve_near]) if matches!(self.levels, Levels::Many) => {
                // The law's parameters for the reach past touching of cohesive contacts.
                // And the stable ids by sorted place: no two components of one clump are a pair.
                let walk = [
                    (PARAMS, &self.grid_uniform),
                    (DEM, self.dem_uniform.buffer()),
                    cells,
                    placed[1],
                    placed[0],
                    (IDS, &set.ids),
                    g.listing_binding(),
                ];
                let walk = [&walk[..], &listed].concat();
                let list_near = gpu.bind("mochi.dem.list_near", list_near, &walk);
                (Some(list_near), resolve_near)
            }
            _ => (None, &self.pipelines.resolve),
        };
        let own = joined(&own, &listed);
        // A binning step leaves the state where it is: each sphere's old history row is the
        // row it is in.
        let came_from = match kind {
            StepKind::Sorting | StepKind::Skin => g.came_from(),
            StepKind::Binning => &places.identity,
        };
        let state = [
            (DEM, self.dem_uniform.buffer()),
            (POS, &set.pos),
            (CLOCK, &self.clock),
            (VEL, &set.vel),
            (FORCE, &self.force),
            (IDS, &set.ids),
            (CAME_FROM, came_from),
        ];
        let turns = [0, 1].map(|parity| Turn { set: on, parity });
        let mesh = self.pipelines.mesh.as_ref().and_then(|[near, contacts]| {
            turns
                .iter()
                .map(|&turn| {
                    let [near_walls, walls] = g.mesh_bindings(turn)?;
                    Some([
                        gpu.bind(
                            "mochi.dem.mesh_near",
                            near,
                            &joined(&state[..3], &near_walls),
                        ),
                        gpu.bind("mochi.dem.mesh_walls", contacts, &joined(&state, &walls)),
                    ])
                })
                .collect()
        });
        ResolveBinds {
            list_near,
            name_places,
            resolve: turns
                .iter()
                .map(|&turn| {
                    let more = [(IDS, &set.ids), (CAME_FROM, came_from), place_of_id];
                    let clumps = g.contact_bindings();
                    let all = [&own[..], &g.resolve_bindings(turn), &more, &clumps].concat();
                    gpu.bind("mochi.dem.resolve", resolve, &all)
                })
                .collect(),
            mesh,
        }
    }
}
