//! The clumps of the wgpu engines' granular step on the GPU (`wgsl/dem/dem_clumps.wgsl`): their
//! rows ([`ClumpRows`]) in buffers, the bindings the contact pass, the integration and the clumps'
//! own kernel (`advance_clumps`) take, and the bodies read back. A run without clumps binds one
//! unread row for each of the buffers the contact pass and the integration name.

use crate::clump::ClumpSet;
use crate::engines::common::clumps::{ClumpBodyRow, ClumpRows};
use crate::error::Result;
use crate::gpu::Gpu;
use crate::gpu::shader::Binding;
use shader::{CLUMP_BODIES, CLUMP_OF, CLUMP_PARTS, CLUMP_ROWS, CLUMP_SHAPES};

/// `wgsl/dem/dem_clumps.wgsl`'s source, bindings and entry point.
pub(crate) mod shader {
    use crate::gpu::shader::{Binding, wgsl};

    /// `wgsl/dem/dem_clumps.wgsl`.
    pub const SOURCE: &str = wgsl!("dem/dem_clumps.wgsl");
    /// The clumps' own kernel.
    pub const ENTRY: &str = "advance_clumps";
    pub const CLUMP_OF: Binding = Binding::read(80, "clump_of");
    pub const CLUMP_ROWS: Binding = Binding::read_write(81, "clump_rows");
    pub const CLUMP_BODIES: Binding = Binding::read_write(82, "clump_bodies");
    pub const CLUMP_SHAPES: Binding = Binding::read(83, "clump_shapes");
    pub const CLUMP_PARTS: Binding = Binding::read(84, "clump_parts");

    /// Every binding of the file.
    pub const BINDINGS: [Binding; 5] = [
        CLUMP_OF,
        CLUMP_ROWS,
        CLUMP_BODIES,
        CLUMP_SHAPES,
        CLUMP_PARTS,
    ];
}

/// A run's clumps on the GPU.
pub(crate) struct DeviceClumps {
    /// Each component's clump, by stable id.
    of: wgpu::Buffer,
    /// Each component's state row in the step (written by the contact pass).
    rows: wgpu::Buffer,
    /// The clumps' states.
    bodies: wgpu::Buffer,
    shapes: wgpu::Buffer,
    parts: wgpu::Buffer,
    /// The clumps as given: their kinds, and the bodies the rows read back replace.
    set: ClumpSet,
}

impl DeviceClumps {
    /// The clumps of `set` on `gpu` for the engine named `engine`.
    pub fn new(gpu: &Gpu, set: &ClumpSet, engine: &str) -> Result<Self> {
        let rows = ClumpRows::of(set);
        let none = wgpu::BufferUsages::empty();
        let make = |what: &str, bytes: &[u8]| {
            let buffer = gpu.storage(
                &format!("mochi.dem.{engine}.{what}"),
                bytes.len() as u64,
                none,
            );
            gpu.queue.write_buffer(&buffer, 0, bytes);
            buffer
        };
        // Past the components, whole 16-byte rows of NO_CLUMP (the shader's).
        let mut of = rows.of.clone();
        of.resize(of.len().max(1).next_multiple_of(4), u32::MAX);
        gpu.checked("allocating the clumps' buffers", || Self {
            of: make("clump_of", bytemuck::cast_slice(&of)),
            rows: make("clump_rows", &vec![0; rows.of.len() * 4]),
            bodies: make("clump_bodies", bytemuck::cast_slice(&rows.bodies)),
            shapes: make("clump_shapes", bytemuck::cast_slice(&rows.shapes)),
            parts: make("clump_parts", bytemuck::cast_slice(&rows.parts)),
            set: set.clone(),
        })
    }

    /// The number of clumps.
    pub fn count(&self) -> u32 {
        self.set.clumps.len() as u32
    }

    /// What the contact pass binds: each component's clump and its row.
    pub fn contact_bindings(&self) -> [(Binding, &wgpu::Buffer); 2] {
        [(CLUMP_OF, &self.of), (CLUMP_ROWS, &self.rows)]
    }

    /// Each component's clump, as the integration of a run with clumps binds it.
    pub fn of_binding(&self) -> (Binding, &wgpu::Buffer) {
        (CLUMP_OF, &self.of)
    }

    /// What `advance_clumps` binds of the clumps (besides the state's and accumulators').
    pub fn advance_bindings(&self) -> [(Binding, &wgpu::Buffer); 4] {
        [
            (CLUMP_ROWS, &self.rows),
            (CLUMP_BODIES, &self.bodies),
            (CLUMP_SHAPES, &self.shapes),
            (CLUMP_PARTS, &self.parts),
        ]
    }

    /// The clumps' states, which a batch that may be redone saves and restores.
    pub fn bodies(&self) -> &wgpu::Buffer {
        &self.bodies
    }

    /// The clumps as the GPU holds them now (the kinds as given).
    pub fn read(&self, gpu: &Gpu) -> Result<ClumpSet> {
        let rows: Vec<ClumpBodyRow> = gpu.read(&self.bodies, self.set.clumps.len())?;
        Ok(ClumpRows::bodies_into(&self.set, &rows))
    }
}
