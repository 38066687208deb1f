//! A rank's exchange of ghosts on the device (`wgsl/dem/halo.wgsl`), so that a round of a run
//! over ranks reads back and writes the spheres near its box's faces, not every sphere of the
//! rank: one pass lists the own spheres outside the box shrunk by the halo (with their states)
//! and the ghosts' rows, and finds the own spheres' largest speed; another writes the states
//! the owners sent into the ghosts' rows. Which spheres are the rank's own the pass reads from
//! marks by stable id, which the rank sets as ownership changes.

use crate::engines::common::flow::{NearFaces, NearRow, RowState};
use crate::error::{Error, Result};
use crate::gpu::shader::{Binding, Vec3f, WgslModule, shared_struct, wgsl};
use crate::gpu::{Gpu, Staging};
use rayon::prelude::*;

/// The shader, embedded.
const SOURCE: &str = wgsl!("dem/halo.wgsl");
const GATHER: &str = "halo_gather";
const SCATTER: &str = "halo_scatter";
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;
/// Entries of each list at first (they grow to what a round needs).
const FIRST_ROOM: u32 = 4096;

const PARAMS: Binding = Binding::uniform(0, "params");
const POS: Binding = Binding::read_write(1, "pos");
const LO: Binding = Binding::read_write(2, "lo");
const VEL: Binding = Binding::read_write(3, "vel");
const OMEGA: Binding = Binding::read_write(4, "omega");
const IDS: Binding = Binding::read(5, "ids");
const OWN: Binding = Binding::read(6, "own");
const COUNTS: Binding = Binding::read_write(7, "counts");
const NEAR: Binding = Binding::read_write(8, "near");
const GHOSTS: Binding = Binding::read_write(9, "ghosts");
const INCOMING: Binding = Binding::read(10, "incoming");

/// The exchange's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "halo",
        SOURCE,
        &[GATHER, SCATTER],
        &[
            PARAMS, POS, LO, VEL, OMEGA, IDS, OWN, COUNTS, NEAR, GHOSTS, INCOMING,
        ],
        vec![shared_struct!(
            "HaloParams",
            HaloParams {
                n,
                row,
                near_room,
                ghost_room,
                inner_lo,
                spins,
                inner_hi,
                count,
            }
        )],
    )
}

/// WGSL twin: `HaloParams` in `wgsl/dem/halo.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct HaloParams {
    n: u32,
    row: u32,
    near_room: u32,
    ghost_room: u32,
    inner_lo: Vec3f,
    spins: u32,
    inner_hi: Vec3f,
    count: u32,
}

/// Words (`vec4<u32>`) of a near sphere's entry and of a state written.
const ENTRY_VECS: u32 = 4;

/// A step's state as the exchange binds it: rows `0..n` of each buffer (`omega`: the spins and
/// materials of the granular step, `None` in the paper's).
pub(crate) struct StateBuffers<'a> {
    pub pos: &'a wgpu::Buffer,
    pub lo: &'a wgpu::Buffer,
    pub vel: &'a wgpu::Buffer,
    pub omega: Option<&'a wgpu::Buffer>,
    pub ids: &'a wgpu::Buffer,
    pub n: u32,
}

/// The exchange's pipelines and buffers (lists and marks grown on demand).
pub(crate) struct HaloExchange {
    gather: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    counts: wgpu::Buffer,
    near: wgpu::Buffer,
    ghosts: wgpu::Buffer,
    incoming: wgpu::Buffer,
    /// By stable id, 1 where the sphere is the rank's own (ids past its end: ghosts).
    own: wgpu::Buffer,
    /// Bound as the spins where the state has none; never read.
    no_spin: wgpu::Buffer,
    near_room: u32,
    ghost_room: u32,
    staging: [Staging; 3],
}

impl HaloExchange {
    /// The pipelines (compiled once per device) and first buffers.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.module("mochi.halo", SOURCE);
        let none = wgpu::BufferUsages::empty();
        let vec4 = 16 * ENTRY_VECS as u64;
        HaloExchange {
            gather: gpu.pipeline("mochi.halo.gather", &module, GATHER),
            scatter: gpu.pipeline("mochi.halo.scatter", &module, SCATTER),
            params: gpu.uniform("mochi.halo.params", &HaloParams::default()),
            counts: gpu.storage("mochi.halo.counts", 16, none),
            near: gpu.storage("mochi.halo.near", FIRST_ROOM as u64 * vec4, none),
            ghosts: gpu.storage("mochi.halo.ghosts", FIRST_ROOM as u64 * 8, none),
            incoming: gpu.storage("mochi.halo.incoming", FIRST_ROOM as u64 * vec4, none),
            own: gpu.storage("mochi.halo.own", FIRST_ROOM as u64 * 4, none),
            no_spin: gpu.storage("mochi.halo.no_spin", 16, none),
            near_room: FIRST_ROOM,
            ghost_room: FIRST_ROOM,
            staging: Default::default(),
        }
    }

    /// Marks each stable id of `marks` as the rank's own sphere (`true`) or a ghost.
    pub fn mark(&mut self, gpu: &Gpu, marks: &[(u32, bool)]) -> Result<()> {
        let Some(last) = marks.iter().map(|&(k, _)| k).max() else {
            return Ok(());
        };
        let words = last as u64 + 1;
        if self.own.size() < words * 4 {
            // Grown with the marks set so far; new words are zero (ghosts).
            let bytes = (words * 4).next_power_of_two();
            let grown = gpu.checked("growing a rank's marks of its own spheres", || {
                gpu.storage("mochi.halo.own", bytes, wgpu::BufferUsages::empty())
            })?;
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(&self.own, 0, &grown, 0, self.own.size());
            gpu.queue.submit([encoder.finish()]);
            self.own = grown;
        }
        let mut sorted = marks.to_vec();
        sorted.sort_unstable_by_key(|&(k, _)| k);
        // Runs of consecutive ids, one write each.
        for run in sorted.chunk_by(|a, b| b.0 == a.0 + 1) {
            let values: Vec<u32> = run.iter().map(|&(_, own)| own as u32).collect();
            gpu.queue.write_buffer(
                &self.own,
                run[0].0 as u64 * 4,
                bytemuck::cast_slice(&values),
            );
        }
        Ok(())
    }

    /// The own spheres of `state` whose centres lie outside `inner` (`lo <= c < hi` along every
    /// axis; an infinite side never holds one outside), the rows of its ghosts and its own
    /// spheres' largest speed.
    pub fn gather(
        &mut self,
        gpu: &Gpu,
        state: &StateBuffers,
        inner: ([f32; 3], [f32; 3]),
    ) -> Result<NearFaces> {
        let groups = gpu.grid(state.n, GROUP);
        loop {
            let params = HaloParams {
                n: state.n,
                row: groups.0 * GROUP,
                near_room: self.near_room,
                ghost_room: self.ghost_room,
                inner_lo: Vec3f(inner.0),
                spins: state.omega.is_some() as u32,
                inner_hi: Vec3f(inner.1),
                count: 0,
            };
            gpu.write_uniform(&self.params, &params);
            let bind = gpu.bind(
                "mochi.halo.gather",
                &self.gather,
                &[
                    (PARAMS, &self.params),
                    (POS, state.pos),
                    (LO, state.lo),
                    (VEL, state.vel),
                    (OMEGA, state.omega.unwrap_or(&self.no_spin)),
                    (IDS, state.ids),
                    (OWN, &self.own),
                    (COUNTS, &self.counts),
                    (NEAR, &self.near),
                    (GHOSTS, &self.ghosts),
                ],
            );
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&self.counts, 0, None);
            gpu.dispatch(
                &mut encoder,
                "mochi.halo.gather",
                &self.gather,
                &bind,
                groups,
            );
            gpu.queue.submit([encoder.finish()]);
            let [staging_counts, staging_near, staging_ghosts] = &mut self.staging;
            let counts: Vec<u32> = gpu.read_through(staging_counts, &self.counts, 4)?;
            let (near, ghosts) = (counts[0], counts[1]);
            if near > self.near_room || ghosts > self.ghost_room {
                // A list overflowed: again with room for all.
                let none = wgpu::BufferUsages::empty();
                if near > self.near_room {
                    self.near_room = near.next_power_of_two();
                    let bytes = self.near_room as u64 * 16 * ENTRY_VECS as u64;
                    self.near = gpu
                        .checked("growing a rank's list of spheres near its faces", || {
                            gpu.storage("mochi.halo.near", bytes, none)
                        })?;
                }
                if ghosts > self.ghost_room {
                    self.ghost_room = ghosts.next_power_of_two();
                    let bytes = self.ghost_room as u64 * 8;
                    self.ghosts = gpu.checked("growing a rank's list of ghosts", || {
                        gpu.storage("mochi.halo.ghosts", bytes, none)
                    })?;
                }
                continue;
            }
            let entries = (near * ENTRY_VECS) as usize;
            let near = gpu.read_through_with(
                staging_near,
                &self.near,
                entries,
                |words: &[[u32; 4]]| words.chunks_exact(4).map(near_row).collect(),
            )?;
            let ghosts: Vec<[u32; 2]> =
                gpu.read_through(staging_ghosts, &self.ghosts, ghosts as usize)?;
            let fastest = f32::from_bits(counts[2]);
            if !fastest.is_finite() {
                return Err(Error::Usage(
                    "a rank's sphere moves at a speed that is not finite".into(),
                ));
            }
            return Ok(NearFaces {
                rows: state.n,
                near,
                ghosts,
                fastest,
            });
        }
    }

    /// Writes each of `states` into its row of `state` (radius, mass and material as they are).
    pub fn scatter(&mut self, gpu: &Gpu, state: &StateBuffers, states: &[RowState]) -> Result<()> {
        let count = states.len() as u32;
        if count == 0 {
            return Ok(());
        }
        if states.iter().any(|s| s.row >= state.n) {
            return Err(Error::Usage(
                "a ghost's state was sent to a row its step does not hold".into(),
            ));
        }
        let bytes = count as u64 * 16 * ENTRY_VECS as u64;
        if self.incoming.size() < bytes {
            self.incoming = gpu.checked("growing a rank's list of ghosts' states", || {
                let size = bytes.next_power_of_two();
                gpu.storage("mochi.halo.incoming", size, wgpu::BufferUsages::empty())
            })?;
        }
        let entries: Vec<[[u32; 4]; 4]> = states.par_iter().map(entry_of).collect();
        gpu.queue
            .write_buffer(&self.incoming, 0, bytemuck::cast_slice(&entries));
        let groups = gpu.grid(count, GROUP);
        let params = HaloParams {
            n: state.n,
            row: groups.0 * GROUP,
            spins: state.omega.is_some() as u32,
            count,
            ..HaloParams::default()
        };
        gpu.write_uniform(&self.params, &params);
        let bind = gpu.bind(
            "mochi.halo.scatter",
            &self.scatter,
            &[
                (PARAMS, &self.params),
                (POS, state.pos),
                (LO, state.lo),
                (VEL, state.vel),
                (OMEGA, state.omega.unwrap_or(&self.no_spin)),
                (INCOMING, &self.incoming),
            ],
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        gpu.dispatch(
            &mut encoder,
            "mochi.halo.scatter",
            &self.scatter,
            &bind,
            groups,
        );
        gpu.queue.submit([encoder.finish()]);
        Ok(())
    }
}

/// A near sphere's entry (four `vec4<u32>`, as the shader writes it) read.
fn near_row(words: &[[u32; 4]]) -> NearRow {
    let f = |w: [u32; 4]| w.map(f32::from_bits);
    let [pos, lo, vel, omega] = [words[0], words[1], words[2], words[3]];
    let [lx, ly, lz, _] = f(lo);
    let [vx, vy, vz, _] = f(vel);
    NearRow {
        row: lo[3],
        stable: vel[3],
        pos: f(pos),
        lo: [lx, ly, lz],
        vel: [vx, vy, vz],
        omega: f(omega),
    }
}

/// A state's entry as the shader reads it: the centre with the row, residual, velocity, spin.
fn entry_of(s: &RowState) -> [[u32; 4]; 4] {
    let bits = |v: [f32; 3], w: u32| [v[0].to_bits(), v[1].to_bits(), v[2].to_bits(), w];
    [
        bits(s.position, s.row),
        bits(s.residual, 0),
        bits(s.velocity, 0),
        bits(s.spin, 0),
    ]
}
