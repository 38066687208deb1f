//! A rank's exchange of ghosts on the device (`wgsl/dem/halo.wgsl`), so that a round of a run
//! over ranks moves the layer near its box's faces as records written and placed by the GPUs,
//! none of its spheres handled one by one on the host: one pass writes the records of the own
//! spheres near the faces into a list for each neighbouring box and finds the own spheres'
//! largest speed; three place the records that came (each stable id's row; the ghosts' states,
//! the spheres now in the box made the rank's own; the spheres that leave listed, the own ones
//! beyond the box made ghosts). The device keeps, by stable id, each sphere's whole-run id and
//! whether it is the rank's own, and by whole-run id the stable id, as the rank names them.

use crate::engines::common::flow::{DIRECTIONS, Layer, LayerBounds, LayerRecord, Named, Placed};
use crate::error::Result;
use crate::gpu::shader::{Binding, Vec3f, WgslModule, shared_struct, wgsl};
use crate::gpu::{Gpu, Staging, copy_into};

/// The shader, embedded.
const SOURCE: &str = wgsl!("dem/halo.wgsl");
const GATHER: &str = "halo_gather";
const ROWS: &str = "halo_rows";
const PLACE: &str = "halo_place";
const LEAVING_PASS: &str = "halo_leaving";
const NAME: &str = "halo_name";
/// Workgroup size (as in the shader).
const GROUP: u32 = 256;
/// Records of each direction's list at first (they grow to what a round needs).
const FIRST_ROOM: u32 = 1024;

const PARAMS: Binding = Binding::uniform(0, "params");
const POS: Binding = Binding::read_write(1, "pos");
const LO: Binding = Binding::read_write(2, "lo");
const VEL: Binding = Binding::read_write(3, "vel");
const OMEGA: Binding = Binding::read_write(4, "omega");
const IDS: Binding = Binding::read(5, "ids");
const OWN: Binding = Binding::read_write(6, "own");
const WHOLE: Binding = Binding::read(7, "whole");
const STABLE_OF: Binding = Binding::read_write(8, "stable_of");
const ROW_OF: Binding = Binding::read_write(9, "row_of");
const TOUCHED: Binding = Binding::read_write(10, "touched");
const COUNTS: Binding = Binding::read_write(11, "counts");
const RECORDS: Binding = Binding::read_write(12, "records");
const INCOMING: Binding = Binding::read(13, "incoming");
const LEAVING: Binding = Binding::read_write(14, "leaving");
const COMING: Binding = Binding::read_write(15, "coming");
const LIST_OF: Binding = Binding::read(16, "list_of");
const NAMED: Binding = Binding::read(17, "named");

/// Words of the counts: one a list, then the largest speed, the leaving, the coming, the
/// ghosts made own and the own spheres made ghosts (as in the shader).
const COUNT_WORDS: usize = 32;
const FASTEST: usize = 27;
const LEAVING_AT: usize = 28;
const COMING_AT: usize = 29;
const MADE_OWN: usize = 30;
const MADE_GHOSTS: usize = 31;

/// The exchange's WGSL module, exactly as the device gets it.
pub fn module() -> WgslModule {
    WgslModule::new(
        "halo",
        SOURCE,
        &[GATHER, ROWS, PLACE, LEAVING_PASS, NAME],
        &[
            PARAMS, POS, LO, VEL, OMEGA, IDS, OWN, WHOLE, STABLE_OF, ROW_OF, TOUCHED, COUNTS,
            RECORDS, INCOMING, LEAVING, COMING, LIST_OF, NAMED,
        ],
        vec![shared_struct!(
            "HaloParams",
            HaloParams {
                n,
                row,
                room,
                count,
                near_lo,
                stamp,
                near_hi,
                spins,
                box_lo,
                leave_room,
                box_hi,
                coming_room,
                keep_lo,
                pad0,
                keep_hi,
                pad1,
            }
        )],
    )
}

/// WGSL twin: `HaloParams` in `wgsl/dem/halo.wgsl`.
#[derive(Debug, Clone, Copy, Default, encase::ShaderType)]
struct HaloParams {
    n: u32,
    row: u32,
    room: u32,
    count: u32,
    near_lo: Vec3f,
    stamp: u32,
    near_hi: Vec3f,
    spins: u32,
    box_lo: Vec3f,
    leave_room: u32,
    box_hi: Vec3f,
    coming_room: u32,
    keep_lo: Vec3f,
    pad0: u32,
    keep_hi: Vec3f,
    pad1: u32,
}

/// A direction no box lies in (as in the shader).
const NO_BOX: u32 = u32::MAX;

/// Bytes of a record.
const RECORD: u64 = size_of::<LayerRecord>() as u64;

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

/// The exchange's pipelines and buffers (grown on demand).
pub(crate) struct HaloExchange {
    gather: wgpu::ComputePipeline,
    rows: wgpu::ComputePipeline,
    place: wgpu::ComputePipeline,
    leaving_pass: wgpu::ComputePipeline,
    name: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    counts: wgpu::Buffer,
    /// By stable id: own marks, whole-run ids, rows, stamps (`stables` words each).
    own: wgpu::Buffer,
    whole: wgpu::Buffer,
    row_of: wgpu::Buffer,
    touched: wgpu::Buffer,
    stables: u64,
    /// By whole-run id: the stable id + 1 (`wholes` words).
    stable_of: wgpu::Buffer,
    wholes: u64,
    /// The `(whole-run id, stable id + 1)` pairs `halo_name` writes into `stable_of`.
    named_pairs: wgpu::Buffer,
    /// `room` records a list, one list a neighbouring box.
    records: wgpu::Buffer,
    room: u32,
    /// By direction, the list of the box that lies that way ([`NO_BOX`]: none does).
    list_of: wgpu::Buffer,
    incoming: wgpu::Buffer,
    /// The host's copy of the records that came, copied into `incoming` (kept from round to
    /// round, grown on demand).
    upload: Option<wgpu::Buffer>,
    leaving: wgpu::Buffer,
    coming: wgpu::Buffer,
    /// Bound as the spins where the state has none; never read.
    no_spin: wgpu::Buffer,
    /// The stable ids named so far (the own marks read back cover them).
    named: u32,
    /// The round's stamp of the ghosts it placed.
    stamp: u32,
    staging: [Staging; 4],
}

impl HaloExchange {
    /// The pipelines (compiled once per device) and first buffers.
    pub fn new(gpu: &Gpu) -> Self {
        let module = gpu.own_module("mochi.halo", SOURCE);
        let words = |label, n: u64| gpu.storage(label, n * 4, wgpu::BufferUsages::empty());
        let first = FIRST_ROOM as u64;
        HaloExchange {
            gather: gpu.pipeline("mochi.halo.gather", &module, GATHER),
            rows: gpu.pipeline("mochi.halo.rows", &module, ROWS),
            place: gpu.pipeline("mochi.halo.place", &module, PLACE),
            leaving_pass: gpu.pipeline("mochi.halo.leaving", &module, LEAVING_PASS),
            name: gpu.pipeline("mochi.halo.name", &module, NAME),
            params: gpu.uniform("mochi.halo.params", &HaloParams::default()),
            counts: words("mochi.halo.counts", COUNT_WORDS as u64),
            own: words("mochi.halo.own", first),
            whole: words("mochi.halo.whole", first),
            row_of: words("mochi.halo.row_of", first),
            touched: words("mochi.halo.touched", first),
            stables: first,
            stable_of: words("mochi.halo.stable_of", first),
            wholes: first,
            named_pairs: words("mochi.halo.named", first * 2),
            records: words("mochi.halo.records", first * RECORD / 4),
            room: FIRST_ROOM,
            list_of: words("mochi.halo.list_of", DIRECTIONS as u64),
            incoming: words("mochi.halo.incoming", first * RECORD / 4),
            upload: None,
            leaving: words("mochi.halo.leaving", first * 4),
            coming: words("mochi.halo.coming", first),
            no_spin: words("mochi.halo.no_spin", 4),
            named: 0,
            stamp: 0,
            staging: Default::default(),
        }
    }

    /// Names the spheres of `names`' stable ids ([`Named`]).
    pub fn name(&mut self, gpu: &Gpu, state: &StateBuffers, names: &[Named]) -> Result<()> {
        let (Some(stable), Some(whole)) = (
            names.iter().map(|n| n.stable).max(),
            names.iter().map(|n| n.whole).max(),
        ) else {
            return Ok(());
        };
        self.grow_stables(gpu, stable as u64 + 1)?;
        self.grow_wholes(gpu, whole as u64 + 1)?;
        self.named = self.named.max(stable + 1);
        let mut by_stable = names.to_vec();
        by_stable.sort_unstable_by_key(|n| n.stable);
        for run in by_stable.chunk_by(|a, b| b.stable == a.stable + 1) {
            let at = run[0].stable as u64 * 4;
            let own: Vec<u32> = run.iter().map(|n| n.own as u32).collect();
            let whole: Vec<u32> = run.iter().map(|n| n.whole).collect();
            gpu.queue
                .write_buffer(&self.own, at, bytemuck::cast_slice(&own));
            gpu.queue
                .write_buffer(&self.whole, at, bytemuck::cast_slice(&whole));
        }
        let stable_of: Vec<[u32; 2]> = names.iter().map(|n| [n.whole, n.stable + 1]).collect();
        self.write_stable_of(gpu, state, &stable_of)
    }

    /// Forgets the whole-run ids `wholes` (distinct, each named before).
    pub fn forget(&mut self, gpu: &Gpu, state: &StateBuffers, wholes: &[u32]) -> Result<()> {
        let gone: Vec<[u32; 2]> = wholes.iter().map(|&w| [w, 0]).collect();
        self.write_stable_of(gpu, state, &gone)
    }

    /// Writes each `[whole, value]` of `entries` (distinct whole-run ids, within
    /// `stable_of`) into `stable_of`, on the GPU (the ids lie anywhere in it).
    fn write_stable_of(
        &mut self,
        gpu: &Gpu,
        state: &StateBuffers,
        entries: &[[u32; 2]],
    ) -> Result<()> {
        if entries.is_empty() {
            return Ok(());
        }
        let bytes = size_of_val(entries) as u64;
        if self.named_pairs.size() < bytes {
            let size = bytes.next_power_of_two();
            self.named_pairs = gpu.checked("growing a rank's list of named spheres", || {
                gpu.storage("mochi.halo.named", size, wgpu::BufferUsages::empty())
            })?;
        }
        gpu.queue
            .write_buffer(&self.named_pairs, 0, bytemuck::cast_slice(entries));
        let count = entries.len() as u32;
        let groups = gpu.grid(count, GROUP);
        let params = HaloParams {
            row: groups.0 * GROUP,
            count,
            ..HaloParams::default()
        };
        gpu.write_uniform(&self.params, &params);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let uses = [PARAMS, STABLE_OF, NAMED];
        self.pass(gpu, &mut encoder, (&self.name, &uses), state, groups);
        gpu.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// The own marks of the stable ids named so far.
    pub fn own_marks(&mut self, gpu: &Gpu) -> Result<Vec<u32>> {
        gpu.read_through(&mut self.staging[0], &self.own, self.named as usize)
    }

    /// The buffers by stable id grown to hold `words` ids, what they hold kept.
    fn grow_stables(&mut self, gpu: &Gpu, words: u64) -> Result<()> {
        if words <= self.stables {
            return Ok(());
        }
        let size = words.next_power_of_two();
        for buffer in [
            &mut self.own,
            &mut self.whole,
            &mut self.row_of,
            &mut self.touched,
        ] {
            *buffer = grown(gpu, buffer, size * 4)?;
        }
        self.stables = size;
        Ok(())
    }

    /// `stable_of` grown to hold `words` whole-run ids, what it holds kept.
    fn grow_wholes(&mut self, gpu: &Gpu, words: u64) -> Result<()> {
        if words > self.wholes {
            let size = words.next_power_of_two();
            self.stable_of = grown(gpu, &self.stable_of, size * 4)?;
            self.wholes = size;
        }
        Ok(())
    }

    /// Writes the uniform for `state` within `bounds` and `count` records received; returns
    /// the workgroups of every pass (each checks its own bound).
    fn params(
        &self,
        gpu: &Gpu,
        state: &StateBuffers,
        bounds: &LayerBounds,
        count: u32,
    ) -> (u32, u32) {
        let groups = gpu.grid(state.n.max(count), GROUP);
        let params = HaloParams {
            n: state.n,
            row: groups.0 * GROUP,
            room: self.room,
            count,
            near_lo: Vec3f(bounds.near.0),
            stamp: self.stamp,
            near_hi: Vec3f(bounds.near.1),
            spins: state.omega.is_some() as u32,
            box_lo: Vec3f(bounds.own.0),
            leave_room: (self.leaving.size() / 16) as u32,
            box_hi: Vec3f(bounds.own.1),
            coming_room: (self.coming.size() / 4) as u32,
            keep_lo: Vec3f(bounds.keep.0),
            pad0: 0,
            keep_hi: Vec3f(bounds.keep.1),
            pad1: 0,
        };
        gpu.write_uniform(&self.params, &params);
        groups
    }

    /// Every buffer the passes bind, `state`'s among them.
    fn bindings<'a>(&'a self, state: &StateBuffers<'a>) -> [(Binding, &'a wgpu::Buffer); 18] {
        [
            (PARAMS, &self.params),
            (POS, state.pos),
            (LO, state.lo),
            (VEL, state.vel),
            (OMEGA, state.omega.unwrap_or(&self.no_spin)),
            (IDS, state.ids),
            (OWN, &self.own),
            (WHOLE, &self.whole),
            (STABLE_OF, &self.stable_of),
            (ROW_OF, &self.row_of),
            (TOUCHED, &self.touched),
            (COUNTS, &self.counts),
            (RECORDS, &self.records),
            (INCOMING, &self.incoming),
            (LEAVING, &self.leaving),
            (COMING, &self.coming),
            (LIST_OF, &self.list_of),
            (NAMED, &self.named_pairs),
        ]
    }

    /// Records a pass of `pipeline` over the workgroups `groups`, with the bindings its entry
    /// uses.
    fn pass(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        (pipeline, uses): (&wgpu::ComputePipeline, &[Binding]),
        state: &StateBuffers,
        groups: (u32, u32),
    ) {
        let bound: Vec<(Binding, &wgpu::Buffer)> = (self.bindings(state).into_iter())
            .filter(|(b, _)| uses.contains(b))
            .collect();
        gpu.pass(encoder, "mochi.halo", pipeline, &bound, groups);
    }

    /// The records of the own spheres of `state` near the faces of `bounds`, by direction,
    /// and the own spheres' largest speed, into `layer` (its lists' buffers reused).
    pub fn gather(
        &mut self,
        gpu: &Gpu,
        state: &StateBuffers,
        bounds: &LayerBounds,
        layer: &mut Layer,
    ) -> Result<()> {
        // One list a box that lies next to the rank's.
        let mut list_of = [NO_BOX; DIRECTIONS];
        let mut lists = 0;
        for (list, _) in list_of.iter_mut().zip(bounds.ways).filter(|(_, way)| *way) {
            *list = lists;
            lists += 1;
        }
        gpu.queue
            .write_buffer(&self.list_of, 0, bytemuck::cast_slice(&list_of));
        loop {
            let groups = self.params(gpu, state, bounds, 0);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&self.counts, 0, None);
            let uses = [
                PARAMS, POS, LO, VEL, OMEGA, IDS, OWN, WHOLE, COUNTS, RECORDS, LIST_OF,
            ];
            self.pass(gpu, &mut encoder, (&self.gather, &uses), state, groups);
            gpu.queue.submit([encoder.finish()]);
            let counts: Vec<u32> =
                gpu.read_through(&mut self.staging[1], &self.counts, COUNT_WORDS)?;
            let most = counts[..lists as usize].iter().copied().max().unwrap_or(0);
            let bytes = lists.max(1) as u64 * most.max(self.room) as u64 * RECORD;
            if most > self.room || self.records.size() < bytes {
                // A list overflowed (or a box more lies next to the rank's): again with room.
                self.room = self.room.max(most.next_power_of_two());
                let bytes = lists.max(1) as u64 * self.room as u64 * RECORD;
                self.records = gpu.checked("growing a rank's lists of records", || {
                    gpu.storage("mochi.halo.records", bytes, wgpu::BufferUsages::empty())
                })?;
                continue;
            }
            let ranges: Vec<std::ops::Range<u64>> = (list_of.iter())
                .map(|&list| match list {
                    NO_BOX => 0..0,
                    _ => {
                        let start = list as u64 * self.room as u64 * RECORD;
                        start..start + counts[list as usize] as u64 * RECORD
                    }
                })
                .collect();
            gpu.read_ranges(
                &mut self.staging[2],
                &self.records,
                &ranges,
                &mut layer.lists,
            )?;
            layer.fastest = f32::from_bits(counts[FASTEST]);
            return Ok(());
        }
    }

    /// Places the records of `received` in `state` within `bounds` ([`Placed`]).
    pub fn place(
        &mut self,
        gpu: &Gpu,
        state: &StateBuffers,
        bounds: &LayerBounds,
        received: &[Vec<u8>],
    ) -> Result<Placed> {
        let bytes: u64 = received.iter().map(|m| m.len() as u64).sum();
        let count = (bytes / RECORD) as u32;
        let none = wgpu::BufferUsages::empty();
        if self.incoming.size() < bytes {
            let size = bytes.next_power_of_two();
            self.incoming = gpu.checked("growing a rank's records received", || {
                gpu.storage("mochi.halo.incoming", size, none)
            })?;
        }
        // Room for every row leaving and every record coming: the lists never overflow.
        if self.leaving.size() < state.n as u64 * 16 {
            let size = (state.n as u64 * 16).next_power_of_two();
            self.leaving = gpu.checked("growing a rank's list of leaving spheres", || {
                gpu.storage("mochi.halo.leaving", size, none)
            })?;
        }
        if self.coming.size() < count as u64 * 4 {
            let size = (count as u64 * 4).next_power_of_two();
            self.coming = gpu.checked("growing a rank's list of coming spheres", || {
                gpu.storage("mochi.halo.coming", size, none)
            })?;
        }
        let upload = match self.upload.take() {
            Some(kept) if kept.size() >= bytes => kept,
            _ => gpu.checked("growing a rank's upload of records", || {
                gpu.upload_buffer("mochi.halo.upload", bytes.next_power_of_two())
            })?,
        };
        // Every message copied on the rayon pool into one mapped buffer, one after the other.
        let filled = gpu.fill_upload(&upload, 0..bytes, |mut view| {
            for message in received {
                let (head, rest) = view.split_at(message.len());
                copy_into(head, message);
                view = rest;
            }
            Ok(())
        });
        self.upload = Some(upload);
        filled?;
        self.stamp = self.stamp.wrapping_add(1).max(1);
        let groups = self.params(gpu, state, bounds, count);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        if let Some(upload) = self.upload.as_ref().filter(|_| bytes > 0) {
            encoder.copy_buffer_to_buffer(upload, 0, &self.incoming, 0, bytes);
        }
        encoder.clear_buffer(&self.counts, LEAVING_AT as u64 * 4, None);
        let rows = [PARAMS, IDS, ROW_OF];
        self.pass(gpu, &mut encoder, (&self.rows, &rows), state, groups);
        let place = [
            PARAMS, POS, LO, VEL, OMEGA, OWN, STABLE_OF, ROW_OF, TOUCHED, COUNTS, INCOMING, COMING,
        ];
        self.pass(gpu, &mut encoder, (&self.place, &place), state, groups);
        let leaving = [PARAMS, POS, LO, IDS, OWN, TOUCHED, COUNTS, LEAVING];
        self.pass(
            gpu,
            &mut encoder,
            (&self.leaving_pass, &leaving),
            state,
            groups,
        );
        gpu.queue.submit([encoder.finish()]);
        let counts: Vec<u32> = gpu.read_through(&mut self.staging[1], &self.counts, COUNT_WORDS)?;
        let left: Vec<[u32; 4]> = gpu.read_through(
            &mut self.staging[3],
            &self.leaving,
            counts[LEAVING_AT] as usize,
        )?;
        let coming: Vec<u32> = gpu.read_through(
            &mut self.staging[0],
            &self.coming,
            counts[COMING_AT] as usize,
        )?;
        Ok(Placed {
            leaving: left.into_iter().map(|[r, k, own, _]| [r, k, own]).collect(),
            coming,
            made_own: counts[MADE_OWN],
            made_ghosts: counts[MADE_GHOSTS],
        })
    }
}

/// A buffer of `size` bytes holding what `old` holds, the rest zero.
fn grown(gpu: &Gpu, old: &wgpu::Buffer, size: u64) -> Result<wgpu::Buffer> {
    let new = gpu.checked("growing a rank's marks of its spheres", || {
        gpu.storage("mochi.halo.by_id", size, wgpu::BufferUsages::empty())
    })?;
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(old, 0, &new, 0, old.size());
    gpu.queue.submit([encoder.finish()]);
    Ok(new)
}
