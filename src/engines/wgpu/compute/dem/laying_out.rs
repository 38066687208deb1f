//! The grid's layout over the state's bounds: a GPU reduction of the bounds, the layout chosen
//! over them (clipped to the box), and the tables and bind groups it needs.

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

impl GridStepper {
    /// The centres' bounds now (a GPU reduction), or `None` for no spheres.
    pub(super) fn bounds(&self) -> Result<Option<([f32; 3], [f32; 3])>> {
        if self.n == 0 {
            return Ok(None);
        }
        let gpu = &self.gpu;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.record_bounds(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        let keys: Vec<u32> = gpu.read(&self.bounds, 6)?;
        self.decode_bounds(&keys).map(Some)
    }

    /// Records the reduction of the current state's bounds into `self.bounds` (its reset is
    /// queued to run before the submission `encoder` goes into).
    pub(super) fn record_bounds(&self, encoder: &mut wgpu::CommandEncoder) {
        let empty: [u32; 6] = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];
        let gpu = &self.gpu;
        gpu.queue
            .write_buffer(&self.bounds, 0, bytemuck::cast_slice(&empty));
        let binds = self.binds.as_ref().expect("laid out");
        gpu.dispatch(
            encoder,
            "mochi.dem.reduce_bounds",
            &self.pipelines.reduce_bounds,
            &binds[self.current].reduce_bounds,
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
            self.state()?;
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
        if self.binds.is_none() {
            // Bounds need bind groups; a first layout over the box gives them.
            let (lo, hi) = (self.params.box_lo, self.params.box_hi);
            self.apply_layout(lo, hi)?;
        }
        let Some((lo, hi)) = self.bounds()? else {
            self.laid_out_at = Some(self.step);
            return Ok(());
        };
        self.layout_over(lo, hi)
    }

    /// Lays the grid out over the bounds `lo`..`hi` clipped to the box and a margin.
    pub(super) fn layout_over(&mut self, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        let margin = self.mode_cell as f32;
        let lo: [f32; 3] = std::array::from_fn(|a| lo[a].max(self.params.box_lo[a] - margin));
        let hi: [f32; 3] =
            std::array::from_fn(|a| hi[a].min(self.params.box_hi[a] + margin).max(lo[a]));
        self.apply_layout(lo, hi)
    }

    pub(super) fn apply_layout(&mut self, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        let gpu = &self.gpu;
        let layout = GridParams {
            row: self.groups.0 * GROUP,
            ..choose_layout(
                &gpu.limits,
                &LayoutRequest {
                    levels: self.levels,
                    bounds: (lo, hi),
                    budget: Budget {
                        spheres: self.n as u64,
                        cells_per_sphere: self.levels.dem_cells_per_sphere(),
                        build: self.build(),
                    },
                    base_cell: self.mode_cell,
                    radii: self.radii,
                    dense_check: &|_| true,
                },
            )
        };
        let layout = GridParams {
            skin: match self.pipelines.skin {
                Some(_) if self.step >= self.skin_off_until => skin_of(&layout),
                _ => 0.0,
            },
            ..layout
        };
        match &mut self.sorter {
            Sorter::Dense {
                cell_table,
                scan,
                scan_bind,
                ..
            } => {
                if cell_table.capacity < layout.cells || self.binds.is_none() {
                    *cell_table = gpu.checked("allocating the DEM cell table", || {
                        CellTable::new(gpu, layout.cells)
                    })?;
                    *scan_bind = Some(scan.bind(gpu, &self.grid_uniform, cell_table));
                    self.binds = None;
                }
            }
            Sorter::Sorted {
                keys,
                order,
                sort,
                prepared,
            } => {
                // The sort ends in the scratch or in `keys`/`order` by its passes' parity, so
                // the binds follow it.
                let sort = sort.prepare(gpu, keys, order, self.n, key_bits(layout.cells));
                *prepared = Some(Box::new(sort));
                self.binds = None;
            }
        }
        if self.binds.is_none() {
            self.binds = Some([self.make_binds(0), self.make_binds(1)]);
        }
        gpu.write_uniform(&self.grid_uniform, &layout);
        self.layout = layout;
        self.laid_out_at = Some(self.step);
        self.counted = false;
        Ok(())
    }
}
