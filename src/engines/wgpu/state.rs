//! What a wgpu engine's DEM step keeps beside its shaders, shared by the paper's step and the
//! granular one: its parameters on the GPU ([`ParamsUniform`]), how its rows map to input order
//! ([`InputOrder`]) and moving rows between places ([`move_rows`]).

use crate::dem::model::LawParams;
use crate::gpu::Gpu;
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

/// Records the move of rows within buffers through `scratch` (at least `moves.len() · bytes`
/// bytes): each `(from, to)` of `moves` copies the row `from` over the row `to` (no row is both
/// a source and a target); `at(row)` is the buffer and byte offset of a row of `bytes` bytes.
pub(crate) fn move_rows<'a>(
    encoder: &mut wgpu::CommandEncoder,
    scratch: &wgpu::Buffer,
    moves: &[(u32, u32)],
    bytes: u64,
    at: impl Fn(u32) -> (&'a wgpu::Buffer, u64),
) {
    for (k, &(from, _)) in moves.iter().enumerate() {
        let (buffer, offset) = at(from);
        encoder.copy_buffer_to_buffer(buffer, offset, scratch, k as u64 * bytes, bytes);
    }
    for (k, &(_, to)) in moves.iter().enumerate() {
        let (buffer, offset) = at(to);
        encoder.copy_buffer_to_buffer(scratch, k as u64 * bytes, buffer, offset, bytes);
    }
}
