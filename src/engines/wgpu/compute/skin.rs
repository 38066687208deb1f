//! The skin of the paper's DEM step on a dense single- or multi-level grid: a step re-bins its
//! spheres only where one may have moved more than the skin since the last binning, and the
//! steps between walk the last binning's cells with their search windows widened by the drift
//! since, at most the skin (`wgsl/grid/dem_grid_frictionless.wgsl`, docs/method.md "Re-binning only when a sphere may have
//! left its cells"). The GPU decides at each step's start (`begin_step`) and sets the binning's
//! indirect dispatches to every workgroup or none; this is the buffer it decides in.

use super::layout::GridParams;
use crate::gpu::Gpu;

/// The skin, in cells of the finest level: what a sphere may move before the grid is re-binned.
/// A wider skin re-bins less often; the walk's windows widen by the drift since the last
/// binning, which grows up to it (docs/performance-log/2026-11-27-h100-session-7.md has the
/// sweep).
pub(crate) const SKIN_CELLS: f64 = 0.2;

/// Word offsets in [`Skin::state`]; twins of the constants in `wgsl/grid/dem_grid_frictionless.wgsl`.
const ARGS_SPHERES: u64 = 0;
const ARGS_BLOCKS: u64 = 4;
const REBINS: u64 = 17;
/// Words up to the drift's slots (the shader's `MOVED` + `DRIFT_SLOTS`).
const WORDS: u64 = 32 + 64;

/// The skin of `layout` in its units of length: [`SKIN_CELLS`] of its finest cells, or none for
/// a hashed table (its buckets are found by the cells of the spheres' current centres) or where
/// a binned row's y or z would not fit the 16 bits the shader notes each in.
pub(crate) fn skin_of(layout: &GridParams) -> f32 {
    if layout.hashed != 0 || layout.inv_cell <= 0.0 {
        return 0.0;
    }
    // Level 0's cells: the top's halved once a level and by level 0's own refinement.
    let halvings = layout.levels.saturating_sub(1) + (layout.refine & 15);
    let finest_dims = |n: u32| ((n.saturating_sub(2) as u64) << halvings) + 2;
    if finest_dims(layout.ny).max(finest_dims(layout.nz)) > 1 << 16 {
        return 0.0;
    }
    let finest = 1.0 / (layout.inv_cell as f64 * f64::powi(2.0, halvings as i32));
    (SKIN_CELLS * finest) as f32
}

/// The buffers the GPU decides in whether a step re-bins: the binning's indirect dispatches, the
/// drift since the last binning, the largest displacement reported in the last step, the count
/// of steps that re-binned; and the displacement above which a sphere reports.
pub(crate) struct Skin {
    pub state: wgpu::Buffer,
    /// The displacement above which a sphere reports its own, and the drift the walk's windows
    /// reach past their spheres (two `f32`, the GPU's).
    pub limit: wgpu::Buffer,
}

impl Skin {
    pub fn new(gpu: &Gpu) -> Skin {
        let none = wgpu::BufferUsages::empty();
        Skin {
            state: gpu.storage("mochi.dem.skin", WORDS * 4, wgpu::BufferUsages::INDIRECT),
            limit: gpu.storage("mochi.dem.skin_limit", 8, none),
        }
    }

    /// Queues, ahead of a batch, the dispatches a re-binning step runs (`spheres` workgroups
    /// for the sphere passes, `blocks` for the scan's) and clears the count of re-binnings.
    pub fn prepare(&self, gpu: &Gpu, (x, y): (u32, u32), blocks: u32) {
        // This step's dispatches (x set by `begin_step`), then the whole ones.
        let args: [u32; 16] = [0, y, 1, 0, 0, 1, 1, 0, x, y, 1, 0, blocks, 1, 1, 0];
        gpu.queue
            .write_buffer(&self.state, 0, bytemuck::cast_slice(&args));
        gpu.queue
            .write_buffer(&self.state, REBINS * 4, bytemuck::bytes_of(&0u32));
    }

    /// Records `pipeline` over the spheres where this step re-bins (`begin_step` decided).
    pub fn dispatch_spheres(
        &self,
        pass: &mut wgpu::ComputePass,
        pipeline: &wgpu::ComputePipeline,
        bind: &wgpu::BindGroup,
    ) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups_indirect(&self.state, ARGS_SPHERES * 4);
    }

    /// The buffer and byte offset of the scan's dispatch of this step.
    pub fn blocks_args(&self) -> (&wgpu::Buffer, u64) {
        (&self.state, ARGS_BLOCKS * 4)
    }

    /// Byte offset of the count of steps that re-binned since [`prepare`](Self::prepare).
    pub const REBINS_AT: u64 = REBINS * 4;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader::wgsl;

    #[test]
    fn the_skin_is_a_fifth_of_the_finest_cells_and_none_when_hashed_or_rows_overflow() {
        let one = GridParams {
            inv_cell: 100.0,
            levels: 1,
            ..GridParams::default()
        };
        assert!((skin_of(&one) - 2e-3).abs() < 1e-9);
        // Three levels, level 0 refined once: cells of 1 cm / 8.
        let three = GridParams {
            levels: 3,
            refine: 1,
            ..one
        };
        assert!((skin_of(&three) - 2e-3 / 8.0).abs() < 1e-9);
        let hashed = GridParams { hashed: 1, ..one };
        assert_eq!(skin_of(&hashed), 0.0);
        // A level whose rows along z number more than 16 bits hold.
        let tall = GridParams {
            ny: 10,
            nz: (1 << 16) + 3,
            ..one
        };
        assert_eq!(skin_of(&tall), 0.0);
        assert!(
            skin_of(&GridParams {
                nz: 1 << 16,
                ..tall
            }) > 0.0
        );
    }

    #[test]
    fn the_offsets_are_the_shaders() {
        let shader = wgsl!("grid/dem_grid_frictionless.wgsl");
        for (name, at) in [
            ("ARGS_SPHERES", ARGS_SPHERES),
            ("ARGS_BLOCKS", ARGS_BLOCKS),
            ("REBINS", REBINS),
        ] {
            let declared = format!("const {name}: u32 = {at}u;");
            assert!(shader.contains(&declared), "{declared}");
        }
        assert!(shader.contains("const MOVED: u32 = 32u;"));
        assert!(shader.contains("const DRIFT_SLOTS: u32 = 64u;"));
        assert!(shader.contains("const FULL_SPHERES: u32 = 8u;"));
        assert!(shader.contains("const FULL_BLOCKS: u32 = 12u;"));
    }
}
