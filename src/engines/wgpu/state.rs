//! What a wgpu engine's DEM step keeps beside its shaders, shared by the paper's step and the
//! granular one: its parameters on the GPU ([`ParamsUniform`]), how its rows map to input order
//! ([`InputOrder`]), moving rows between places ([`RowMover`]) and writing new motion into
//! them ([`write_motion`]).

use crate::dem::model::LawParams;
use crate::dem::stepper::{ExternalLoads, Motion};
use crate::engines::common::rows::{no_spin, not_fixed, place_positions, place_triples};
use crate::error::Result;
use crate::gpu::Gpu;
use crate::gpu::shader::{Binding, WgslModule, shared_struct, wgsl};
use crate::particles::FIRST_MESH_WALL;
use rayon::prelude::*;

/// A step's [`LawParams`] on the GPU (the uniform `dem` of `wgsl/dem/dem_params.wgsl`) and the
/// value it holds: every change writes the whole value, so no part of it can be stale.
pub(crate) struct ParamsUniform {
    params: LawParams,
    buffer: wgpu::Buffer,
}

impl ParamsUniform {
    /// `params` in a new uniform labelled `label`.
    pub fn new(gpu: &Gpu, label: &str, params: LawParams) -> Self {
        Self {
            params,
            buffer: gpu.uniform(label, &params),
        }
    }

    /// Changes the parameters by `change` and writes them.
    pub fn update(&mut self, gpu: &Gpu, change: impl FnOnce(&mut LawParams)) {
        change(&mut self.params);
        gpu.write_uniform(&self.buffer, &self.params);
    }

    /// The uniform.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }
}

/// A step's external loads on the GPU (binding `EXTERNAL`): [`ExternalLoads::rows`] by stable
/// id, or one pair of zero rows until a load is given.
pub(crate) struct ExternalRows {
    buffer: wgpu::Buffer,
    /// Rows the buffer holds.
    rows: usize,
}

impl ExternalRows {
    /// No loads.
    pub fn new(gpu: &Gpu) -> Self {
        let none = wgpu::BufferUsages::empty();
        Self {
            buffer: gpu.storage("mochi.dem.loaded", 32, none),
            rows: 2,
        }
    }

    /// The buffer.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Writes `loads` of a step of `n` spheres that turns them or not, whose stable ids are
    /// their input indices where `fixed` (no sphere entered or left); returns whether the
    /// buffer is a new one (the bind groups naming it are then made again). Refuses loads
    /// of other than `n` spheres, values that are not finite, a torque where the step does not
    /// turn its spheres and any load where the spheres are not fixed.
    pub fn set(
        &mut self,
        gpu: &Gpu,
        loads: &ExternalLoads,
        (n, turns, fixed): (u32, bool, bool),
    ) -> Result<bool> {
        loads.check(n as usize)?;
        if loads.turns() && !turns {
            return Err(no_spin());
        }
        if loads.is_empty() {
            return Ok(false);
        }
        if !fixed {
            return Err(not_fixed());
        }
        let rows = loads.rows(n as usize);
        let grown = rows.len() > self.rows;
        if grown {
            let bytes = rows.len() as u64 * 16;
            self.buffer = gpu.storage("mochi.dem.loaded", bytes, wgpu::BufferUsages::empty());
            self.rows = rows.len();
        }
        gpu.queue
            .write_buffer(&self.buffer, 0, bytemuck::cast_slice(&rows));
        Ok(grown)
    }
}

/// How the rows of a state whose spheres have the stable ids `ids` (distinct; with gaps where
/// spheres left on the device) map to input order, the ids' ascending order.
pub(crate) struct InputOrder {
    /// Each row's index in input order (its id's rank among the ids).
    pub rank: Vec<u32>,
    /// The ids ascending, where they have gaps (`None`: they are `0..n`, each its own rank).
    sorted: Option<Vec<u32>>,
}

impl InputOrder {
    /// The order of the rows with stable ids `ids`.
    pub fn of(ids: &[u32]) -> Self {
        let n = ids.len();
        if ids.iter().all(|&id| (id as usize) < n) {
            // Distinct and below n: a permutation of 0..n.
            return InputOrder {
                rank: ids.to_vec(),
                sorted: None,
            };
        }
        let mut sorted = ids.to_vec();
        sorted.par_sort_unstable();
        let rank = ids
            .par_iter()
            .map(|&id| sorted.partition_point(|&x| x < id) as u32)
            .collect();
        InputOrder {
            rank,
            sorted: Some(sorted),
        }
    }

    /// Whether the ids have gaps (history partners are then renamed).
    pub fn renames(&self) -> bool {
        self.sorted.is_some()
    }

    /// A history partner's name in input order: a wall keeps its own, a sphere gets its
    /// rank, and one that has left gets none.
    pub fn partner(&self, id: u32) -> Option<u32> {
        match &self.sorted {
            Some(sorted) if id < FIRST_MESH_WALL => {
                sorted.binary_search(&id).ok().map(|k| k as u32)
            }
            _ => Some(id),
        }
    }
}

/// Moves rows of a step's buffers to other places on the GPU (`wgsl/dem/move_rows.wgsl`): one
/// pass a buffer (or a pair of buffers, where rows move from one part of a buffer split in
/// parts to another), one thread a word, where copying row by row took a command a row.
pub(crate) struct RowMover {
    within: wgpu::ComputePipeline,
    across: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    pairs: wgpu::Buffer,
}

/// The mover's shader, embedded.
const MOVE_SOURCE: &str = wgsl!("dem/move_rows.wgsl");
const MOVE_PARAMS: Binding = Binding::uniform(0, "params");
const MOVE_PAIRS: Binding = Binding::read(1, "pairs");
const MOVE_ROWS: Binding = Binding::read_write(2, "rows");
const MOVE_FROM: Binding = Binding::read(3, "from_rows");
const MOVE_TO: Binding = Binding::read_write(4, "to_rows");
/// Workgroup size (as in the shader).
const MOVE_GROUP: u32 = 256;

/// The mover's WGSL module, exactly as the device gets it.
pub fn move_module() -> WgslModule {
    WgslModule::new(
        "move_rows",
        MOVE_SOURCE,
        &["move_within", "move_across"],
        &[MOVE_PARAMS, MOVE_PAIRS, MOVE_ROWS, MOVE_FROM, MOVE_TO],
        vec![shared_struct!(
            "MoveParams",
            MoveParams {
                moves,
                words,
                row,
                pad,
            }
        )],
    )
}

/// WGSL twin: `MoveParams` in `wgsl/dem/move_rows.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct MoveParams {
    moves: u32,
    words: u32,
    row: u32,
    pad: u32,
}

impl RowMover {
    /// The pipelines (compiled once per device) and first buffers.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.move_rows", MOVE_SOURCE);
        RowMover {
            within: gpu.pipeline("mochi.move_rows.within", &module, "move_within"),
            across: gpu.pipeline("mochi.move_rows.across", &module, "move_across"),
            params: gpu.uniform("mochi.move_rows.params", &MoveParams::default()),
            pairs: gpu.storage(
                "mochi.move_rows.pairs",
                8 * 1024,
                wgpu::BufferUsages::empty(),
            ),
        }
    }

    /// Moves rows of `words` 4-byte words: each `(from, to)` of `moves` copies the row `from`
    /// over the row `to` (no row is both a source and a target); `at(row)` is the buffer that
    /// holds a row and the row's place in it. Submitted before it returns, one submission a pair
    /// of buffers.
    pub fn run<'a>(
        &mut self,
        gpu: &Gpu,
        moves: &[(u32, u32)],
        words: u32,
        at: impl Fn(u32) -> (&'a wgpu::Buffer, u32),
    ) -> Result<()> {
        // The moves by the buffers they move between (a buffer split in parts has several).
        let mut groups: Vec<(&wgpu::Buffer, &wgpu::Buffer, Vec<[u32; 2]>)> = Vec::new();
        for &(from, to) in moves {
            let ((source, from), (target, to)) = (at(from), at(to));
            let same = |g: &&mut (&wgpu::Buffer, &wgpu::Buffer, Vec<[u32; 2]>)| {
                std::ptr::eq(g.0, source) && std::ptr::eq(g.1, target)
            };
            match groups.iter_mut().find(same) {
                Some(group) => group.2.push([from, to]),
                None => groups.push((source, target, vec![[from, to]])),
            }
        }
        for (source, target, pairs) in groups {
            let bytes = pairs.len() as u64 * 8;
            if self.pairs.size() < bytes {
                self.pairs = gpu.checked("growing the list of rows to move", || {
                    let size = bytes.next_power_of_two();
                    gpu.storage("mochi.move_rows.pairs", size, wgpu::BufferUsages::empty())
                })?;
            }
            gpu.queue
                .write_buffer(&self.pairs, 0, bytemuck::cast_slice(&pairs));
            let threads = u32::try_from(pairs.len() as u64 * words as u64)
                .map_err(|_| crate::error::Error::Usage("too many rows to move at once".into()))?;
            let groups = gpu.grid(threads, MOVE_GROUP);
            let params = MoveParams {
                moves: pairs.len() as u32,
                words,
                row: groups.0 * MOVE_GROUP,
                pad: 0,
            };
            gpu.write_uniform(&self.params, &params);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let both = [(MOVE_PARAMS, &self.params), (MOVE_PAIRS, &self.pairs)];
            match std::ptr::eq(source, target) {
                true => {
                    let bound = [&both[..], &[(MOVE_ROWS, source)]].concat();
                    gpu.pass(
                        &mut encoder,
                        "mochi.move_rows",
                        &self.within,
                        &bound,
                        groups,
                    );
                }
                false => {
                    let bound = [&both[..], &[(MOVE_FROM, source), (MOVE_TO, target)]].concat();
                    gpu.pass(
                        &mut encoder,
                        "mochi.move_rows",
                        &self.across,
                        &bound,
                        groups,
                    );
                }
            }
            gpu.queue.submit([encoder.finish()]);
        }
        Ok(())
    }
}

/// Writes `motion` (in input order) into a wgpu step's rows `pos`, `lo` and `vel` of `n`
/// spheres and its angular velocities `omega` (`None`: a step that does not turn its spheres),
/// row k holding sphere `order[k]` (sphere k where `None`); returns whether the positions
/// changed.
pub(crate) fn write_motion(
    gpu: &Gpu,
    (pos, lo, vel, omega): StateBuffers<'_>,
    n: usize,
    order: Option<&[u32]>,
    motion: &Motion<'_>,
) -> Result<bool> {
    motion.check(n)?;
    if motion.turns() && omega.is_none() {
        return Err(no_spin());
    }
    if n == 0 {
        return Ok(false);
    }
    let rewrite = |buffer: &wgpu::Buffer, place: &dyn Fn(&mut [[f32; 4]])| -> Result<()> {
        let mut rows: Vec<[f32; 4]> = gpu.read(buffer, n)?;
        place(&mut rows);
        gpu.queue
            .write_buffer(buffer, 0, bytemuck::cast_slice(&rows));
        Ok(())
    };
    if let Some(positions) = motion.positions {
        let mut centres: Vec<[f32; 4]> = gpu.read(pos, n)?;
        let mut residuals = vec![[0.0f32; 4]; n];
        place_positions(positions, order, &mut centres, &mut residuals);
        gpu.queue
            .write_buffer(pos, 0, bytemuck::cast_slice(&centres));
        gpu.queue
            .write_buffer(lo, 0, bytemuck::cast_slice(&residuals));
    }
    if let Some(v) = motion.velocities {
        rewrite(vel, &|rows| place_triples(v, order, rows))?;
    }
    if let (Some(w), Some(omega)) = (motion.angular_velocities, omega) {
        rewrite(omega, &|rows| place_triples(w, order, rows))?;
    }
    Ok(motion.positions.is_some())
}

/// A wgpu step's state buffers [`write_motion`] writes: centres, residuals, velocities and
/// angular velocities (where the step has them).
pub(crate) type StateBuffers<'a> = (
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    &'a wgpu::Buffer,
    Option<&'a wgpu::Buffer>,
);
