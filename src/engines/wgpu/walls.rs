//! The mesh walls' buffers and kernels of the wgpu engines' granular step
//! (`wgsl/dem/dem_mesh_walls.wgsl`): the tables of [`WallTables`] on the device, and the list of
//! the spheres near a wall, which the walls' first kernel makes each step for their second.
//! Every granular step binds these (with no mesh walls: a wall count of 0 and minimal buffers).

use crate::dem::model::MaterialTable;
use crate::dem::walls::{WallLoad, WallSet};
use crate::engines::common::walls::{MeshParams, WallTables, wall_loads};
use crate::error::Result;
use crate::gpu::Gpu;
use crate::gpu::shader::{Binding, Vec3f, storage_bytes, wgsl};

/// `wgsl/dem/dem_mesh_walls.wgsl`.
pub const SOURCE: &str = wgsl!("dem/dem_mesh_walls.wgsl");

pub const MESH: Binding = Binding::uniform(70, "mesh");
pub const MESH_WALLS: Binding = Binding::read(71, "mesh_walls");
pub const MESH_GRID: Binding = Binding::read(72, "mesh_grid");
pub const MESH_TRIS: Binding = Binding::read(73, "mesh_tris");
pub const MESH_LOADS: Binding = Binding::read_write(74, "mesh_loads");
pub const MESH_NEAR_LIST: Binding = Binding::read_write(75, "mesh_near");

/// The bindings the mesh walls add to the granular module (the contact pass reads [`MESH`],
/// whether the box walls hold; the mesh walls' kernels read the others).
pub fn bindings() -> [Binding; 6] {
    [
        MESH,
        MESH_WALLS,
        MESH_GRID,
        MESH_TRIS,
        MESH_LOADS,
        MESH_NEAR_LIST,
    ]
}

/// The mesh walls' kernels, in the order a step dispatches them: the listing of the spheres
/// near a wall, then their contacts.
pub const ENTRY_POINTS: [&str; 2] = ["mesh_walls_near", "mesh_wall_contacts"];

/// The mesh walls' buffers and the loads of the last advance.
pub(crate) struct MeshWalls {
    params: MeshParams,
    uniform: wgpu::Buffer,
    walls: wgpu::Buffer,
    grid: wgpu::Buffer,
    tris: wgpu::Buffer,
    loads: wgpu::Buffer,
    near: wgpu::Buffer,
    last: Vec<WallLoad>,
    engine: &'static str,
}

impl MeshWalls {
    /// The walls of `walls` for a step of `spheres` spheres whose centres act on a wall from at
    /// most `reach` away ([`WallTables::new`]), on `gpu`, for the engine `engine`.
    pub fn new(
        gpu: &Gpu,
        walls: &WallSet,
        table: &MaterialTable,
        spheres: usize,
        reach: f32,
        engine: &'static str,
    ) -> Result<Self> {
        let max_words = gpu.limits.max_storage_buffer_binding_size / 4;
        let tables = WallTables::new(walls, table, reach, max_words, engine)?;
        let params = tables.params;
        let none = wgpu::BufferUsages::empty();
        let label = |what: &str| format!("mochi.dem.{engine}.{what}");
        let filled = |what: &str, bytes: &[u8]| {
            let buffer = gpu.storage(&label(what), bytes.len() as u64, none);
            gpu.queue.write_buffer(&buffer, 0, bytes);
            buffer
        };
        let walls = tables.rows.len();
        gpu.checked("allocating the mesh walls' buffers", || Self {
            params,
            uniform: gpu.uniform(&label("mesh"), &params),
            walls: filled("mesh_walls", &storage_bytes(&tables.rows)),
            grid: filled("mesh_grid", bytemuck::cast_slice(&tables.grid)),
            tris: filled("mesh_tris", bytemuck::cast_slice(&tables.tris)),
            loads: gpu.storage(&label("mesh_loads"), tables.load_words() as u64 * 4, none),
            near: gpu.storage(
                &label("mesh_near"),
                (2 + if walls == 0 { 0 } else { spheres as u64 }) * 4,
                none,
            ),
            last: vec![WallLoad::default(); walls],
            engine,
        })
    }

    /// The uniform, which the contact pass reads too (whether the box walls hold).
    pub fn params_binding(&self) -> (Binding, &wgpu::Buffer) {
        (MESH, &self.uniform)
    }

    /// Bindings of the listing kernel (`mesh_walls_near`) besides the state's.
    pub fn near_bindings(&self) -> [(Binding, &wgpu::Buffer); 4] {
        [
            (MESH, &self.uniform),
            (MESH_WALLS, &self.walls),
            (MESH_GRID, &self.grid),
            (MESH_NEAR_LIST, &self.near),
        ]
    }

    /// Bindings of the contacts kernel (`mesh_wall_contacts`) besides
    /// [`params_binding`](Self::params_binding) and the contact pass's.
    pub fn bindings(&self) -> [(Binding, &wgpu::Buffer); 5] {
        [
            (MESH_WALLS, &self.walls),
            (MESH_GRID, &self.grid),
            (MESH_TRIS, &self.tris),
            (MESH_LOADS, &self.loads),
            (MESH_NEAR_LIST, &self.near),
        ]
    }

    /// Whether there are mesh walls.
    pub fn any(&self) -> bool {
        self.params.walls > 0
    }

    /// Sums the loads on the walls in step `step` (the last of the advance to come).
    pub fn sum_loads_in(&mut self, gpu: &Gpu, step: u64) {
        if self.any() {
            self.params.loads_step = step as u32;
            gpu.write_uniform(&self.uniform, &self.params);
        }
    }

    /// Sums the loads of the spheres whose centres lie in `lo <= c < hi` only (a rank's box).
    pub fn sum_loads_within(&mut self, gpu: &Gpu, (lo, hi): ([f32; 3], [f32; 3])) {
        if self.any() {
            (self.params.own_lo, self.params.own_hi) = (Vec3f(lo), Vec3f(hi));
            gpu.write_uniform(&self.uniform, &self.params);
        }
    }

    /// Records the clearing of the loads and of the near lists' counts ahead of a batch.
    pub fn clear_sums(&self, encoder: &mut wgpu::CommandEncoder) {
        if self.any() {
            encoder.clear_buffer(&self.loads, 0, None);
            encoder.clear_buffer(&self.near, 0, Some(8));
        }
    }

    /// Reads the loads summed in the last advance, refusing a step in which some sphere came
    /// within its radius of more triangles of one wall than the shader keeps.
    pub fn read_loads(&mut self, gpu: &Gpu) -> Result<()> {
        if !self.any() {
            return Ok(());
        }
        let walls = self.last.len();
        let lanes = self.params.load_lanes as usize;
        let words: Vec<u32> = gpu.read(&self.loads, 8 * walls * lanes + 1)?;
        self.last = wall_loads(&words, walls, lanes, self.engine)?;
        Ok(())
    }

    /// The loads on each wall in the last step of the last advance.
    pub fn loads(&self) -> &[WallLoad] {
        &self.last
    }
}
