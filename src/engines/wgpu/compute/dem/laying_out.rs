//! The grid's layout over the state's bounds: a GPU reduction of the bounds, the layout chosen
//! over them (clipped to the box), and the tables and bind groups it needs, made together into
//! one [`LaidOut`].

use super::*;

/// The centres' bounds of `particles` within the box of `params` widened by `margin` (as the
/// step's layouts take them), or `None` for no spheres.
pub(super) fn start_bounds(
    particles: &Particles,
    params: &StepParams,
    margin: f32,
) -> Option<([f32; 3], [f32; 3])> {
    let first = *particles.positions.first()?;
    let (mut lo, mut hi) = (first, first);
    for c in &particles.positions {
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    let lo: [f32; 3] = std::array::from_fn(|a| lo[a].max(params.box_lo[a] - margin));
    let hi: [f32; 3] = std::array::from_fn(|a| hi[a].min(params.box_hi[a] + margin).max(lo[a]));
    Some((lo, hi))
}

/// The grid as laid out: its layout, the step it was made at, the sorter bound to it and the
/// bind groups of both state sets. A layout makes it whole; a later one changes what it must.
pub(super) struct LaidOut {
    pub(super) layout: GridParams,
    /// The step it was laid out at.
    pub(super) at: u64,
    pub(super) sorter: Sorter,
    pub(super) binds: [Binds; 2],
}

/// What a layout is sized for besides the bounds: the spheres, the dispatch's row, the build,
/// the proxy mode's cell and the radii.
pub(super) struct Sizing {
    pub(super) n: u32,
    pub(super) row: u32,
    pub(super) build: BuildKind,
    pub(super) mode_cell: f64,
    pub(super) radii: (f64, f64),
}

impl Sizing {
    /// The layout over `bounds` for the buffers of `res` (with a skin where `skin` and the step
    /// has one).
    pub(super) fn layout(
        &self,
        res: &Resident,
        bounds: ([f32; 3], [f32; 3]),
        skin: bool,
    ) -> GridParams {
        let layout = GridParams {
            row: self.row,
            ..choose_layout(
                &res.gpu.limits,
                &LayoutRequest {
                    levels: res.levels,
                    bounds,
                    budget: Budget {
                        spheres: self.n as u64,
                        cells_per_sphere: res.levels.dem_cells_per_sphere(),
                        build: self.build,
                    },
                    base_cell: self.mode_cell,
                    radii: self.radii,
                    dense_check: &|_| true,
                },
            )
        };
        GridParams {
            skin: match res.pipelines.skin {
                Some(_) if skin => skin_of(&layout),
                _ => 0.0,
            },
            ..layout
        }
    }
}

impl LaidOut {
    /// The grid laid out as `layout` at step `at`: its sorter's buffers made for it and bound,
    /// with both sets' bind groups.
    pub(super) fn new(
        res: &Resident,
        sizing: &Sizing,
        layout: GridParams,
        at: u64,
    ) -> Result<Self> {
        let gpu = &res.gpu;
        let rows = res.sets[0].ids.size() / 4;
        let none = wgpu::BufferUsages::empty();
        let make = |label: &str, bytes: u64| gpu.storage(label, bytes, none);
        let sorter = gpu.checked("allocating the DEM sorter", || match sizing.build {
            BuildKind::Dense => {
                let cell_table = CellTable::new(gpu, layout.cells);
                let scan = CellScan::new(gpu);
                Sorter::Dense {
                    ranks: make("mochi.dem.ranks", rows * 4),
                    scan_bind: scan.bind(gpu, &res.grid_uniform, &cell_table),
                    cell_table,
                    scan,
                }
            }
            BuildKind::Sorted => {
                let (keys, order) = (
                    make("mochi.dem.sort_keys", rows * 4),
                    make("mochi.dem.sort_order", rows * 4),
                );
                let mut sort = RadixSort::new(gpu);
                let prepared = sort.prepare(gpu, &keys, &order, sizing.n, key_bits(layout.cells));
                Sorter::Sorted {
                    keys,
                    order,
                    sort,
                    prepared: Box::new(prepared),
                }
            }
        })?;
        gpu.write_uniform(&res.grid_uniform, &layout);
        let binds = [0, 1].map(|from| res.make_binds(&sorter, from));
        Ok(LaidOut {
            layout,
            at,
            sorter,
            binds,
        })
    }

    /// Lays the grid out again as `layout` at step `at` for `n` spheres: a larger cell table
    /// where the dense build's is too small, the sorted build's sort prepared for the new keys,
    /// and the bind groups made again where what they bind changed.
    pub(super) fn relay(
        &mut self,
        res: &Resident,
        layout: GridParams,
        (at, n): (u64, u32),
    ) -> Result<()> {
        let gpu = &res.gpu;
        let rebound = match &mut self.sorter {
            Sorter::Dense {
                cell_table,
                scan,
                scan_bind,
                ..
            } => {
                let grown = cell_table.capacity < layout.cells;
                if grown {
                    *cell_table = gpu.checked("allocating the DEM cell table", || {
                        CellTable::new(gpu, layout.cells)
                    })?;
                    *scan_bind = scan.bind(gpu, &res.grid_uniform, cell_table);
                }
                grown
            }
            Sorter::Sorted {
                keys,
                order,
                sort,
                prepared,
            } => {
                // The sort ends in the scratch or in `keys`/`order` by its passes' parity, so
                // the binds follow it.
                **prepared = sort.prepare(gpu, keys, order, n, key_bits(layout.cells));
                true
            }
        };
        if rebound {
            self.binds = [0, 1].map(|from| res.make_binds(&self.sorter, from));
        }
        gpu.write_uniform(&res.grid_uniform, &layout);
        (self.layout, self.at) = (layout, at);
        Ok(())
    }

    /// Records the sorter's pass between the binning's first and last: the scan of the cell
    /// table (its dispatch read from `indirect` where given), or the sort of the keys.
    pub(super) fn record_scan(
        &self,
        pass: &mut wgpu::ComputePass,
        indirect: Option<(&wgpu::Buffer, u64)>,
    ) {
        match &self.sorter {
            Sorter::Dense {
                scan, scan_bind, ..
            } => match indirect {
                Some(args) => scan.record_indirect(pass, scan_bind, args),
                None => scan.record(pass, scan_bind, &self.layout),
            },
            Sorter::Sorted { prepared, .. } => prepared.record(pass),
        }
    }
}

impl GridStepper {
    /// The centres' bounds now (a GPU reduction), or `None` for no spheres.
    pub(super) fn bounds(&self) -> Result<Option<([f32; 3], [f32; 3])>> {
        if self.n == 0 {
            return Ok(None);
        }
        let gpu = &self.res.gpu;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.record_bounds(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        let keys: Vec<u32> = gpu.read(&self.res.bounds, 6)?;
        self.decode_bounds(&keys).map(Some)
    }

    /// Records the reduction of the current state's bounds into the bounds buffer (its reset
    /// is queued to run before the submission `encoder` goes into).
    pub(super) fn record_bounds(&self, encoder: &mut wgpu::CommandEncoder) {
        let empty: [u32; 6] = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];
        let gpu = &self.res.gpu;
        gpu.queue
            .write_buffer(&self.res.bounds, 0, bytemuck::cast_slice(&empty));
        gpu.dispatch(
            encoder,
            "mochi.dem.reduce_bounds",
            &self.res.pipelines.reduce_bounds,
            &self.laid_out.binds[self.current].reduce_bounds,
            self.groups,
        );
    }

    /// The bounds from the reduction's keys ([`Error::Unstable`] naming a sphere if they are
    /// not finite).
    pub(super) fn decode_bounds(&self, keys: &[u32]) -> Result<([f32; 3], [f32; 3])> {
        let value = |k: u32| {
            f32::from_bits(if k & 0x8000_0000 != 0 {
                k & 0x7fff_ffff
            } else {
                !k
            })
        };
        let lo = [value(keys[0]), value(keys[1]), value(keys[2])];
        let hi = [value(keys[3]), value(keys[4]), value(keys[5])];
        if lo.iter().chain(&hi).any(|x| !x.is_finite()) {
            // A position is not finite: the state read back names the sphere (Error::Unstable).
            self.state(false)?;
            return Err(Error::Gpu(format!(
                "the bounds at step {} are not finite, yet every sphere is",
                self.step
            )));
        }
        Ok((lo, hi))
    }

    /// Re-derives the grid layout from the current bounds (clipped to the box and a margin:
    /// walls keep the spheres in, so far-away outliers cannot stretch the grid).
    pub(super) fn relayout(&mut self) -> Result<()> {
        match self.bounds()? {
            Some((lo, hi)) => self.layout_over(lo, hi),
            None => {
                (self.laid_out.at, self.stale) = (self.step, false);
                Ok(())
            }
        }
    }

    /// Lays the grid out over the bounds `lo`..`hi` clipped to the box and a margin.
    pub(super) fn layout_over(&mut self, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        let margin = self.mode_cell as f32;
        let lo: [f32; 3] = std::array::from_fn(|a| lo[a].max(self.params.box_lo[a] - margin));
        let hi: [f32; 3] =
            std::array::from_fn(|a| hi[a].min(self.params.box_hi[a] + margin).max(lo[a]));
        let sizing = Sizing {
            n: self.n,
            row: self.groups.0 * GROUP,
            build: self.build(),
            mode_cell: self.mode_cell,
            radii: self.radii,
        };
        let skin = self.step >= self.skin_off_until;
        let layout = sizing.layout(&self.res, (lo, hi), skin);
        self.laid_out
            .relay(&self.res, layout, (self.step, self.n))?;
        self.stale = false;
        self.counted = false;
        Ok(())
    }

    /// Makes both sets' bind groups again (the granular state's buffers or the levels changed).
    pub(super) fn rebind(&mut self) {
        self.laid_out.binds = [0, 1].map(|from| self.res.make_binds(&self.laid_out.sorter, from));
    }
}
