//! The cell table of the sorted grids and the scan that fills it (`wgsl/grid/cell_scan.wgsl`),
//! shared by the detection build and the DEM step.
//!
//! A counting sort by cell runs: count (every sphere's rank in its cell), scan, scatter. The scan
//! takes two dispatches whatever the table's size: one sums each block of the table, the next
//! has each workgroup add up the blocks before its own and scan its block. It also zeroes the
//! counts, so they are zero between builds and no clear is recorded.

use super::layout::{GridParams, MAX_BLOCKS};
use super::shaders::cell_scan::{self, BLOCK_SUMS, CELL_START, COUNTS, PARAMS};
use crate::gpu::Gpu;

/// The buffers of a cell table with room for `capacity` cells.
pub(crate) struct CellTable {
    /// Spheres per cell while counting; zero between builds.
    pub counts: wgpu::Buffer,
    /// Spheres per block of the table (scratch of the scan).
    block_sums: wgpu::Buffer,
    /// First sorted position of each cell, `cells + 1` entries (the last is n).
    pub cell_start: wgpu::Buffer,
    /// Cells there is room for.
    pub capacity: u32,
}

impl CellTable {
    /// Zeroed buffers for up to `capacity` cells.
    pub fn new(gpu: &Gpu, capacity: u32) -> CellTable {
        let none = wgpu::BufferUsages::empty();
        // cells + 1 entries, rounded up to whole vec4 (the scan moves vec4).
        let bytes = (capacity as u64 + 4) / 4 * 16;
        CellTable {
            counts: gpu.storage("mochi.cells.counts", bytes, none),
            block_sums: gpu.storage("mochi.cells.block_sums", MAX_BLOCKS as u64 * 4, none),
            cell_start: gpu.storage("mochi.cells.start", bytes, none),
            capacity,
        }
    }
}

/// The scan's two pipelines.
pub(crate) struct CellScan {
    reduce_blocks: wgpu::ComputePipeline,
    scan_cells: wgpu::ComputePipeline,
}

impl CellScan {
    /// The scan on subgroup operations where the device has them, else in workgroup memory.
    pub fn new(gpu: &Gpu) -> CellScan {
        let subgroups = gpu.device.features().contains(wgpu::Features::SUBGROUP);
        Self::with_subgroups(gpu, subgroups)
    }

    /// The scan on subgroup operations (the device must have them) or in workgroup memory.
    pub fn with_subgroups(gpu: &Gpu, subgroups: bool) -> CellScan {
        let source = if subgroups {
            cell_scan::SUBGROUP_SOURCE
        } else {
            cell_scan::PLAIN_SOURCE
        };
        let module = gpu.own_module("mochi.cells.scan", source);
        CellScan {
            reduce_blocks: gpu.pipeline("mochi.cells.reduce_blocks", &module, "reduce_blocks"),
            scan_cells: gpu.pipeline("mochi.cells.scan_cells", &module, "scan_cells"),
        }
    }

    /// Bind groups scanning `table` laid out by the `GridParams` in `params`.
    pub fn bind(&self, gpu: &Gpu, params: &wgpu::Buffer, table: &CellTable) -> CellScanBinds {
        let sums = [
            (PARAMS, params),
            (COUNTS, &table.counts),
            (BLOCK_SUMS, &table.block_sums),
        ];
        let scan = [
            (PARAMS, params),
            (COUNTS, &table.counts),
            (BLOCK_SUMS, &table.block_sums),
            (CELL_START, &table.cell_start),
        ];
        CellScanBinds {
            reduce_blocks: gpu.bind("mochi.cells.reduce_blocks", &self.reduce_blocks, &sums),
            scan_cells: gpu.bind("mochi.cells.scan_cells", &self.scan_cells, &scan),
        }
    }

    /// Records the scan of the table laid out by `params` into `pass`.
    pub fn record(&self, pass: &mut wgpu::ComputePass, binds: &CellScanBinds, params: &GridParams) {
        let blocks = params.scan_blocks();
        pass.set_pipeline(&self.reduce_blocks);
        pass.set_bind_group(0, &binds.reduce_blocks, &[]);
        pass.dispatch_workgroups(blocks, 1, 1);
        pass.set_pipeline(&self.scan_cells);
        pass.set_bind_group(0, &binds.scan_cells, &[]);
        pass.dispatch_workgroups(blocks, 1, 1);
    }
}

impl CellScan {
    /// As [`record`](Self::record), both dispatches of the size at `args` (a buffer and byte
    /// offset of indirect dispatch arguments: the table's blocks, or none).
    pub fn record_indirect(
        &self,
        pass: &mut wgpu::ComputePass,
        binds: &CellScanBinds,
        (buffer, offset): (&wgpu::Buffer, u64),
    ) {
        pass.set_pipeline(&self.reduce_blocks);
        pass.set_bind_group(0, &binds.reduce_blocks, &[]);
        pass.dispatch_workgroups_indirect(buffer, offset);
        pass.set_pipeline(&self.scan_cells);
        pass.set_bind_group(0, &binds.scan_cells, &[]);
        pass.dispatch_workgroups_indirect(buffer, offset);
    }
}

/// [`CellScan`]'s bind groups for one table.
pub(crate) struct CellScanBinds {
    reduce_blocks: wgpu::BindGroup,
    scan_cells: wgpu::BindGroup,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engines::wgpu::compute::layout::{MIN_BLOCK_SHIFT, block_shift};
    use crate::gpu;
    use rand::{RngExt, SeedableRng};

    /// Scans `counts` as a table of `counts.len() - 1` cells on `gpu` with `scan`; checks the
    /// starts against the host's scan and that the counts were zeroed.
    fn check_scan(gpu: &Gpu, (name, scan): &(&str, CellScan), counts: &[u32]) {
        let cells = counts.len() as u32 - 1;
        let table = CellTable::new(gpu, cells);
        let params = GridParams {
            cells,
            block_shift: block_shift(cells),
            ..GridParams::default()
        };
        let uniform = gpu.uniform("test.params", &params);
        gpu.queue
            .write_buffer(&table.counts, 0, bytemuck::cast_slice(counts));
        let binds = scan.bind(gpu, &uniform, &table);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            scan.record(&mut pass, &binds, &params);
        }
        gpu.queue.submit([encoder.finish()]);
        let starts: Vec<u32> = gpu.read(&table.cell_start, counts.len()).unwrap();
        let mut want = 0u32;
        for (k, (&got, &count)) in starts.iter().zip(counts).enumerate() {
            assert_eq!(got, want, "{name}, {cells} cells: start of cell {k}");
            want += count;
        }
        let left: Vec<u32> = gpu.read(&table.counts, counts.len()).unwrap();
        assert!(
            left.iter().all(|&c| c == 0),
            "{name}, {cells} cells: counts not zeroed"
        );
    }

    #[test]
    fn scans_tables_of_one_and_of_many_tiles_per_block() {
        let Some(gpu) = gpu::test_gpu("the cell scan") else {
            return;
        };
        let subgroups = gpu.device.features().contains(wgpu::Features::SUBGROUP);
        // CI's lavapipe has subgroup operations: both scans are tested there.
        assert!(
            !gpu::under_ci() || subgroups,
            "CI expects subgroup operations (lavapipe has them)"
        );
        let mut scans = vec![("plain", CellScan::with_subgroups(&gpu, false))];
        if subgroups {
            scans.push(("subgroups", CellScan::with_subgroups(&gpu, true)));
        } else {
            eprintln!("note: no subgroup operations here: only the plain scan is tested");
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        // One tile per block (and a partial last tile), then 4, 8 and 16 tiles per block.
        for len in [1, 2, 1025, 3_000_001, 5_000_001, 9_000_003] {
            let counts: Vec<u32> = (0..len)
                .map(|k| {
                    if k + 1 == len {
                        0
                    } else {
                        rng.random_range(0..4)
                    }
                })
                .collect();
            for scan in &scans {
                check_scan(&gpu, scan, &counts);
            }
        }
    }

    #[test]
    fn blocks_cover_the_table_within_the_limit() {
        for cells in [
            0,
            1,
            1023,
            1024,
            4_194_302,
            4_194_303,
            4_194_304,
            40_000_000,
            u32::MAX - 1,
        ] {
            let shift = block_shift(cells);
            let blocks = (cells >> shift) + 1;
            assert!(blocks <= MAX_BLOCKS, "{cells} cells: {blocks} blocks");
            // The blocks reach the last entry (index `cells`).
            assert!(u64::from(blocks) << shift > u64::from(cells));
            // And no smaller block (of at least a tile) would do.
            assert!(shift == MIN_BLOCK_SHIFT || (cells >> (shift - 1)) + 1 > MAX_BLOCKS);
        }
    }
}
