//! The GPU state of the granular step (`wgsl/dem/dem_contact.wgsl`, `wgsl/dem/dem_granular.wgsl`),
//! shared by the wgpu engines: angular velocities and torque accumulators in the engine's state
//! order (one ω buffer per state set of the engine: ω is permuted with positions and velocities),
//! and the contact history (docs/method.md, "Contact history"): K slots per sphere in rows in
//! the state's order (a step reads the old row of each sphere where the previous step wrote it,
//! [`Granular::came_from`] where the engine re-sorts), each contact kept by its owner only, in
//! two sets of buffers that swap roles every step (the history's parity, apart from the state
//! set: an engine with two sets moves its state into the other only at the steps that re-sort
//! it; [`Turn`] names both). A slot is one 32-byte entry (the partner's
//! stable id and the six springs: one memory sector, written whole; 64 bytes, two sectors, under
//! the Mindlin–Deresiewicz model, whose entries hold the load history too), the entries split
//! by row range over a few bindings where they do not fit one ([`EntrySplit`]). The engine keeps its
//! own state (positions, velocities, the order of its spheres); this module saves both at the
//! start of a batch, so that a batch in which some sphere had more contacts than K is redone
//! from that state with K grown: no contact is ever dropped.

use self::shader::{
    COHESION, ENTRIES_NEW, ENTRIES_OLD, ENTRY_PARTS, HELD_NEW, HELD_OLD, HISTORY_NEED,
    MATERIAL_LAWS, OMEGA, TORQUE,
};
use crate::dem::model::law::CohesionParams;
use crate::dem::model::{LawParams, StepParams};
use crate::dem::stepper::StageTimes;
use crate::dem::walls::WallSet;
use crate::engines::common::flow::Room;
use crate::engines::common::rows::Rotation;
use crate::engines::wgpu::clumps::DeviceClumps;
use crate::engines::wgpu::clumps::shader::{CLUMP_OF, CLUMP_ROWS};
use crate::engines::wgpu::held_slots::{HeldSlots, Part, Shape, Take};
use crate::engines::wgpu::state::{InputOrder, ParamsUniform, RowMover};
use crate::engines::wgpu::walls::MeshWalls;
use crate::error::{Error, Result, try_vec};
use crate::gpu::Gpu;
use crate::gpu::shader::Binding;
use crate::particles::{ContactHistory, HistoryEntry, LoadEntry, NO_PARTNER, Particles};
use std::ops::Range;
use std::sync::OnceLock;

/// What the granular step adds to the paper's (`wgsl/dem/dem_contact.wgsl`, the contact law, and
/// `wgsl/dem/dem_granular.wgsl`, angular velocities, torques, contact history and integration):
/// sources, bindings and the structs shared with Rust.
pub(crate) mod shader {
    use crate::gpu::shader::{Binding, wgsl};

    /// `wgsl/dem/dem_contact.wgsl`.
    pub const CONTACT: &str = wgsl!("dem/dem_contact.wgsl");
    /// `wgsl/dem/dem_granular.wgsl`.
    pub const STATE: &str = wgsl!("dem/dem_granular.wgsl");
    /// `wgsl/dem/dem_tangential_mindlin.wgsl`: Mindlin's spring (`Variant::Granular`).
    pub const SPRING: &str = wgsl!("dem/dem_tangential_mindlin.wgsl");
    /// `wgsl/dem/dem_tangential_md.wgsl`: Mindlin–Deresiewicz (`Variant::Loaded`).
    pub const LOAD_HISTORY: &str = wgsl!("dem/dem_tangential_md.wgsl");

    pub const OMEGA: Binding = Binding::read_write(18, "omega");
    /// Read-only views of `vel` and [`OMEGA`] for the kernels that resolve contacts (the same
    /// bindings; naga refuses a kernel that uses a buffer through both).
    pub const VEL_RO: Binding = Binding::read(11, "vel_ro");
    pub const OMEGA_RO: Binding = Binding::read(18, "omega_ro");
    /// The material table's laws (`PairLaw` rows, [`crate::dem::model::MaterialTable::laws`]).
    pub const MATERIAL_LAWS: Binding = Binding::read(20, "material_laws");
    /// The step's cohesion laws ([`crate::dem::model::law::CohesionParams`]).
    pub const COHESION: Binding = Binding::uniform(37, "cohesion");
    /// Declared by the torque accumulator (`dem_torque_*.wgsl`).
    pub const TORQUE: Binding = Binding::read_write(19, "torque");
    pub const HELD_OLD: Binding = Binding::read(21, "held_old");
    pub const HELD_NEW: Binding = Binding::read_write(23, "held_new");
    pub const HISTORY_NEED: Binding = Binding::read_write(24, "history_need");
    /// Bindings the entries of a history may be split over, by range of rows (whole rows per
    /// binding): 20M spheres hold 26 slots each in eight bindings of 2 GiB.
    pub const ENTRY_PARTS: usize = 8;
    /// The old entries (32 bytes a slot: ξ and the partner, the rolling torque), part by part.
    pub const ENTRIES_OLD: [Binding; ENTRY_PARTS] = [
        Binding::read(50, "entries_old0"),
        Binding::read(51, "entries_old1"),
        Binding::read(52, "entries_old2"),
        Binding::read(53, "entries_old3"),
        Binding::read(54, "entries_old4"),
        Binding::read(55, "entries_old5"),
        Binding::read(56, "entries_old6"),
        Binding::read(57, "entries_old7"),
    ];
    /// The new entries, as [`ENTRIES_OLD`].
    pub const ENTRIES_NEW: [Binding; ENTRY_PARTS] = [
        Binding::read_write(58, "entries_new0"),
        Binding::read_write(59, "entries_new1"),
        Binding::read_write(60, "entries_new2"),
        Binding::read_write(61, "entries_new3"),
        Binding::read_write(62, "entries_new4"),
        Binding::read_write(63, "entries_new5"),
        Binding::read_write(64, "entries_new6"),
        Binding::read_write(65, "entries_new7"),
    ];

    /// Every binding of `wgsl/dem/dem_granular.wgsl` and its accumulators.
    pub fn bindings() -> Vec<Binding> {
        [
            OMEGA,
            VEL_RO,
            OMEGA_RO,
            MATERIAL_LAWS,
            COHESION,
            TORQUE,
            HELD_OLD,
            HELD_NEW,
            HISTORY_NEED,
        ]
        .into_iter()
        .chain(ENTRIES_OLD)
        .chain(ENTRIES_NEW)
        .chain(crate::engines::wgpu::walls::bindings())
        .chain(crate::engines::wgpu::clumps::shader::BINDINGS)
        .collect()
    }
}

/// Which of the granular state's buffers are meant: those in the order of the engine's state
/// set `set` (0 or 1; engines with one set have only 0) and the history of parity `parity`
/// (a step of parity k reads the old history from `history[k]`, writes the new to
/// `history[1 - k]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Turn {
    pub set: usize,
    pub parity: usize,
}

/// A wgpu engine's DEM step as [`run_batch`] drives it.
pub(crate) trait RedoableBatch {
    /// The GPU, the granular state (`None`: the paper's step), the state set and parity of the
    /// next step, the engine's buffers a batch begins from (restored when it is redone) and
    /// the step's parameters.
    fn batch_parts(&mut self) -> BatchParts<'_>;

    /// Records `steps` steps into `encoder`, submits it and waits for it: the contacts of the
    /// last step and the phase times.
    fn record_batch(
        &mut self,
        encoder: wgpu::CommandEncoder,
        steps: u32,
    ) -> Result<(u64, Option<StageTimes>)>;

    /// Moves the clock, the state set and the parity back to the start of the last batch of
    /// `steps` steps (their state is restored apart).
    fn rewind(&mut self, steps: u32);

    /// Binds the granular state's buffers again (the history buffers are new after a growth).
    fn rebind(&mut self);
}

/// What [`RedoableBatch::batch_parts`] lends.
pub(crate) type BatchParts<'a> = (
    &'a Gpu,
    Option<&'a mut Granular>,
    Turn,
    Vec<&'a wgpu::Buffer>,
    &'a mut ParamsUniform,
);

/// Records `steps` steps (≤ the engine's batch) into one submission and waits for it; in the
/// granular step, redoes them with more history slots from the state they began from while
/// some sphere had more contacts than slots.
pub(crate) fn run_batch(
    step: &mut impl RedoableBatch,
    steps: u32,
) -> Result<(u64, Option<StageTimes>)> {
    loop {
        let (gpu, granular, turn, state, _) = step.batch_parts();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        if let Some(g) = granular {
            g.begin_batch(gpu, &mut encoder, turn, &state);
        }
        let done = step.record_batch(encoder, steps)?;
        let (gpu, granular, ..) = step.batch_parts();
        let Some(need) = granular.map(|g| g.overflow(gpu)).transpose()?.flatten() else {
            return Ok(done);
        };
        // The batch's steps are undone: back to the state and step it began from.
        step.rewind(steps);
        let (gpu, granular, turn, state, params) = step.batch_parts();
        if let Some(g) = granular {
            g.restore_grown(gpu, (turn, &state), need, params)?;
        }
        step.rebind();
    }
}

/// History slots per sphere a run starts with, as the cpu step's (a dense monodisperse packing
/// has 12 neighbours, plus up to 3 walls).
const FIRST_SLOTS: u32 = 16;

/// Storage buffers the granular resolve kernel binds (wgpu-compute's: the state, the cell
/// table, the ids, the rows the spheres came from, the sorted places' rows and spheres, forces,
/// counters, spins, the material table, torques, two counts of the history, [`ENTRY_PARTS`]
/// entry bindings of each history, the need, the marks of contacts held across a gap and the
/// clock, the mesh walls' four and the clumps' two).
const STORAGE_BUFFERS: u32 = 21 + 2 * ENTRY_PARTS as u32;

/// Words of a slot of the history as the GPU holds it (`Entry` of `wgsl/dem_tangential_*.wgsl`),
/// as bits: ξ x, y, z and the partner's stable id, then the rolling torque's x, y, z and 0;
/// under the Mindlin–Deresiewicz model ([`LOADED_WORDS`]) the tangential force in ξ's place, the
/// normal force in the rolling torque's w, then the reversal force x, y, z, and 5 words unused.
const WORDS: usize = 8;

/// Words of a slot of the Mindlin–Deresiewicz model's history.
const LOADED_WORDS: usize = 16;

/// Bytes of a slot of Mindlin's spring (the smallest binding's).
const ENTRY_BYTES: u64 = 4 * WORDS as u64;

/// How the entries of the history of `n` spheres with `slots` slots each are split over the
/// entry bindings: row r's slots in part r / `spheres_per_part`, the first part alone wherever
/// they fit one binding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct EntrySplit {
    n: u32,
    slots: u32,
    spheres_per_part: u32,
    /// Bytes of a slot (32, or 64 under Mindlin–Deresiewicz).
    entry_bytes: u64,
}

impl EntrySplit {
    /// The split for bindings of at most `max` bytes, slots of `entry_bytes`; `Err` the most
    /// slots per sphere that fit (the entries of whole rows in [`ENTRY_PARTS`] bindings).
    fn within(max: u64, n: u32, slots: u32, entry_bytes: u64) -> std::result::Result<Self, u64> {
        let (n64, k) = (n as u64, slots as u64);
        let per_sphere = k * entry_bytes;
        let spheres_per_part = match per_sphere {
            0 => n64,
            _ => (max / per_sphere).min(n64),
        }
        .max(1);
        let fits = per_sphere <= max && n64.div_ceil(spheres_per_part) <= ENTRY_PARTS as u64;
        if !fits {
            return Err(max / (n64.div_ceil(ENTRY_PARTS as u64) * entry_bytes).max(1));
        }
        Ok(EntrySplit {
            n,
            slots,
            spheres_per_part: spheres_per_part as u32,
            entry_bytes,
        })
    }

    /// Words of a slot.
    fn width(&self) -> usize {
        self.entry_bytes as usize / 4
    }

    /// Entry bindings in use (at least one).
    fn parts(&self) -> usize {
        (self.n.div_ceil(self.spheres_per_part) as usize).max(1)
    }

    /// The slots of part `part`, numbered r·K + s over all rows.
    fn slots_of(&self, part: usize) -> Range<usize> {
        let (per, k) = (self.spheres_per_part as usize, self.slots as usize);
        let n = self.n as usize;
        (part * per).min(n) * k..((part + 1) * per).min(n) * k
    }

    /// Bytes of part `part` (at least one slot's, the smallest binding).
    fn part_bytes(&self, part: usize) -> u64 {
        (self.slots_of(part).len() as u64 * self.entry_bytes).max(self.entry_bytes)
    }
}

/// One history on the GPU: K slots per sphere in rows, slot s of row r at element r·K + s of
/// the slots, in the part of its row ([`EntrySplit`]).
struct History {
    /// The parts in use.
    parts: Vec<wgpu::Buffer>,
}

impl History {
    /// Zeroed buffers for `split`, labelled for history `k` of `engine`.
    fn new(gpu: &Gpu, engine: &str, k: usize, split: &EntrySplit) -> Self {
        History {
            parts: (0..split.parts())
                .map(|b| {
                    let label = format!("mochi.dem.{engine}.history{k}.entries{b}");
                    gpu.storage(&label, split.part_bytes(b), wgpu::BufferUsages::empty())
                })
                .collect(),
        }
    }

    /// Uploads `slots`, the first rows of `split` (the buffers are new: the rows after stay
    /// empty).
    fn write(&self, gpu: &Gpu, split: &EntrySplit, slots: &Slots) {
        for (part, buffer) in self.parts.iter().enumerate() {
            let range = split.slots_of(part);
            let w = slots.width;
            let end = range.end.min(slots.len());
            if range.start < end {
                let words = &slots.words[range.start * w..end * w];
                gpu.queue
                    .write_buffer(buffer, 0, bytemuck::cast_slice(words));
            }
        }
    }
}

/// The slots of the first `rows` rows of `split` from `parts` (as [`History::parts`]).
fn read_slots(gpu: &Gpu, parts: &[wgpu::Buffer], split: &EntrySplit, rows: u32) -> Result<Slots> {
    let count = rows.min(split.n) as usize * split.slots as usize;
    let w = split.width();
    let mut words = try_vec(count * w, || {
        format!("the contact history of {rows} spheres")
    })?;
    for (part, buffer) in parts.iter().enumerate() {
        let range = split.slots_of(part);
        let wanted = range.end.min(count).saturating_sub(range.start);
        if wanted > 0 {
            words.extend(gpu.read::<u32>(buffer, wanted * w)?);
        }
    }
    Ok(Slots { words, width: w })
}

/// History slots in the GPU's layout, on the host: `width` words each ([`WORDS`], or
/// [`LOADED_WORDS`] with the load history).
#[derive(Debug, Default, PartialEq)]
struct Slots {
    words: Vec<u32>,
    width: usize,
}

impl Slots {
    /// `count` empty slots of `width` words.
    fn empty(count: usize, n: usize, width: usize) -> Result<Self> {
        let mut words = try_vec(count * width, || {
            format!("the contact history of {n} spheres")
        })?;
        words.resize(count * width, 0);
        Ok(Slots { words, width })
    }

    /// Slots held.
    fn len(&self) -> usize {
        self.words.len() / self.width.max(1)
    }

    /// The words of slot `slot`.
    fn slot(&mut self, slot: usize) -> &mut [u32] {
        &mut self.words[slot * self.width..(slot + 1) * self.width]
    }

    /// Writes entry `e` with its load history `load` (kept only in slots that hold one).
    fn set(&mut self, slot: usize, e: &HistoryEntry, load: &LoadEntry) {
        let [x, y, z] = e.tangential.map(f32::to_bits);
        let [u, v, w] = e.rolling.map(f32::to_bits);
        let loaded = self.width == LOADED_WORDS;
        let at = self.slot(slot);
        at[..WORDS].copy_from_slice(&[x, y, z, e.partner, u, v, w, 0]);
        if loaded {
            at[7] = load.normal.to_bits();
            let [a, b, c] = load.reversal.map(f32::to_bits);
            at[WORDS..WORDS + 4].copy_from_slice(&[a, b, c, 0]);
        }
    }

    /// The entry in slot `slot` and its load history (zero where slots hold none).
    fn get(&self, slot: usize) -> (HistoryEntry, LoadEntry) {
        let at = &self.words[slot * self.width..(slot + 1) * self.width];
        let f = |k: usize| f32::from_bits(at[k]);
        let entry = HistoryEntry {
            partner: at[3],
            tangential: [f(0), f(1), f(2)],
            rolling: [f(4), f(5), f(6)],
        };
        let load = match self.width == LOADED_WORDS {
            true => LoadEntry {
                reversal: [f(8), f(9), f(10)],
                normal: f(7),
            },
            false => LoadEntry::default(),
        };
        (entry, load)
    }

    /// The first `held[i]` of the `from` slots of each row i moved to the first of `to` slots
    /// of row `row(i)`.
    fn moved(
        &self,
        held: &[u32],
        from: usize,
        to: usize,
        row: impl Fn(usize) -> usize,
    ) -> Result<Self> {
        let (n, w) = (held.len(), self.width);
        let mut moved = Self::empty(n * to, n, w)?;
        for (i, &c) in held.iter().enumerate() {
            let r = row(i);
            let (old, new) = (
                i * from * w..(i * from + c as usize) * w,
                r * to * w..(r * to + c as usize) * w,
            );
            moved.words[new].copy_from_slice(&self.words[old]);
        }
        Ok(moved)
    }
}

/// The granular step's buffers beyond the paper's.
pub(crate) struct Granular {
    /// `vec4(ω, material)` in the order of each of the engine's state sets (one or two): each
    /// sphere's material travels with its spin through every move of the state, as a whole
    /// f32 number (exact below 2²⁴; a number, not bits, which no f32 operation may flush as it
    /// may flush a denormal's).
    omega: Vec<wgpu::Buffer>,
    /// The material table's laws, row by row ([`MATERIAL_LAWS`]).
    laws: wgpu::Buffer,
    /// The step's cohesion laws ([`COHESION`]).
    cohesion: wgpu::Buffer,
    /// Torque accumulators in state order (zero between steps).
    torque: wgpu::Buffer,
    /// History slots, `split.slots` per sphere in rows in state order: the old ones of a step
    /// of parity k are `history[k]` (in the order of the state set the step starts from), its
    /// new ones `history[1 - k]` (in the order of the set it resolves).
    history: [History; 2],
    /// How both histories' entries are split over the entry bindings.
    split: EntrySplit,
    /// Bound where a history uses fewer entry bindings than the shader declares: one for the
    /// old entries' (read), one for the new entries' (written); never accessed.
    spare: [wgpu::Buffer; 2],
    /// Contacts held per row, beside `history`.
    held: [wgpu::Buffer; 2],
    /// By state index, the index in the previous state set of the sphere now there: its row
    /// of the old history (written by the re-sort of engines with two state sets).
    came_from: wgpu::Buffer,
    /// The most contacts with history any sphere had in the batch.
    need: wgpu::Buffer,
    /// Copies of the state at the start of the batch (with history only): the old history's
    /// buffers (as [`History::parts`]; each row's held slots, the rest left as they were) and
    /// its counts, the angular velocities, the engine's own buffers, then the clumps' states
    /// (where there are clumps).
    saved: Vec<wgpu::Buffer>,
    /// The history as given, returned as it is where contacts keep no springs (as the cpu
    /// step does).
    given: ContactHistory,
    /// The mesh walls (and whether the box's hold the spheres in).
    mesh: MeshWalls,
    /// The clumps (`None`: the contact pass binds other buffers of the step in their place, which
    /// it never reads or writes there).
    clumps: Option<DeviceClumps>,
    /// Saves the held slots a batch begins from and packs them, or their partners, for a
    /// read-back (made at the first use).
    held_slots: OnceLock<HeldSlots>,
    n: u32,
    /// The engine's backend name, for labels and errors.
    engine: &'static str,
}

impl Granular {
    /// The buffers for `particles` on `gpu` for the engine named `engine` (its backend's name),
    /// whose state is in `sets` sets of buffers (1: one set in input order; 2: two sets, a step
    /// that re-sorts the state moving it from one into the other) with `room` (for spheres
    /// appended later, see [`append`](Self::append)); the angular velocities go
    /// into set 0, in input order, the history as the old history of a step of parity 0 (rows
    /// in input order; of each pair the cpu's layout holds on both sides, one side: [`owned`]).
    pub fn new(
        gpu: &Gpu,
        particles: &Particles,
        params: &StepParams,
        walls: &WallSet,
        engine: &'static str,
        (sets, room): (usize, Room),
    ) -> Result<Self> {
        let stage = gpu.limits.max_storage_buffers_per_shader_stage;
        if stage < STORAGE_BUFFERS {
            return Err(Error::BackendUnavailable {
                backend: engine,
                reason: format!(
                    "its granular DEM step binds {STORAGE_BUFFERS} storage buffers, {} allows {stage}",
                    gpu.info.name
                ),
            });
        }
        let n64 = particles.len() as u64;
        let room = room.holding(particles);
        let rows = room.spheres as u64;
        let f = &params.friction;
        let keeps = f.has_history();
        if keeps && rows > NO_PARTNER as u64 {
            return Err(Error::TooLarge {
                what: "spheres of a run with contact history (ids above name the walls)".into(),
                got: rows,
                limit: NO_PARTNER as u64,
            });
        }
        let slots = match keeps {
            true => FIRST_SLOTS.max(most_owned(&particles.history, &particles.radii) as u32),
            false => 0,
        };
        let n = n64 as u32;
        let entry_bytes = match f.keeps_load() {
            true => 4 * LOADED_WORDS as u64,
            false => ENTRY_BYTES,
        };
        let split = entry_split(gpu, rows as u32, slots, entry_bytes, engine)?;
        let table = &params.materials;
        let none = wgpu::BufferUsages::empty();
        let label = |what: &str| format!("mochi.dem.{engine}.{what}");
        let make = |what: &str, bytes: u64| gpu.storage(&label(what), bytes, none);
        let reach = room.radii.1 + params.search_margin(room.radii.1);
        let mesh = MeshWalls::new(gpu, walls, table, rows as usize, reach, engine)?;
        let clumps = match particles.clumps.clumps.is_empty() {
            true => None,
            false => Some(DeviceClumps::new(gpu, &particles.clumps, engine)?),
        };
        let granular = gpu.checked("allocating the granular step's buffers", || Self {
            omega: (0..sets)
                .map(|k| make(&format!("omega{k}"), rows * 16))
                .collect(),
            laws: {
                let entries = table.device_laws();
                let laws = make("material_laws", size_of_val(&entries[..]) as u64);
                gpu.queue
                    .write_buffer(&laws, 0, bytemuck::cast_slice(&entries));
                laws
            },
            cohesion: gpu.uniform(&label("cohesion"), &CohesionParams::of(params)),
            torque: make("torque", rows * 12),
            history: [0, 1].map(|k| History::new(gpu, engine, k, &split)),
            split,
            spare: [
                make("entries_spare_old", entry_bytes),
                make("entries_spare_new", entry_bytes),
            ],
            held: [make("held0", rows * 4), make("held1", rows * 4)],
            came_from: make("came_from", if sets == 2 { rows * 4 } else { 4 }),
            need: make("history_need", 4),
            saved: Vec::new(),
            given: if keeps {
                ContactHistory::default()
            } else {
                particles.history.clone()
            },
            mesh,
            clumps,
            held_slots: OnceLock::new(),
            n,
            engine,
        })?;
        let omega: Vec<[f32; 4]> = particles
            .angular_velocities
            .iter()
            .enumerate()
            .map(|(i, w)| [w[0], w[1], w[2], particles.material(i) as f32])
            .collect();
        gpu.queue
            .write_buffer(&granular.omega[0], 0, bytemuck::cast_slice(&omega));
        // New buffers are zeroed: an empty history needs no upload.
        if keeps && !particles.history.is_empty() {
            let (slots, held) = lay_out(
                &particles.history,
                &particles.radii,
                slots as usize,
                split.width(),
            )?;
            granular.history[0].write(gpu, &split, &slots);
            gpu.queue
                .write_buffer(&granular.held[0], 0, bytemuck::cast_slice(&held));
        }
        Ok(granular)
    }

    /// The angular velocities (and materials) in the order of state set `set`.
    pub fn omega_of(&self, set: usize) -> &wgpu::Buffer {
        &self.omega[set % self.omega.len()]
    }

    /// Bindings of the resolve kernel of a step of parity `on.parity` that resolves state set
    /// `on.set`.
    pub fn resolve_bindings<'a>(&'a self, on: Turn) -> Vec<(Binding, &'a wgpu::Buffer)> {
        let parity = on.parity;
        let (old, new) = (&self.history[parity], &self.history[1 - parity]);
        let mut all = vec![
            (OMEGA, self.omega_of(on.set)),
            (MATERIAL_LAWS, &self.laws),
            (COHESION, &self.cohesion),
            (TORQUE, &self.torque),
            (HELD_OLD, &self.held[parity]),
            (HELD_NEW, &self.held[1 - parity]),
            (HISTORY_NEED, &self.need),
            self.mesh.params_binding(),
        ];
        let [spare_old, spare_new] = &self.spare;
        let parts = |h: &'a History, spare| h.parts.iter().chain(std::iter::repeat(spare));
        all.extend(ENTRIES_OLD.into_iter().zip(parts(old, spare_old)));
        all.extend(ENTRIES_NEW.into_iter().zip(parts(new, spare_new)));
        all
    }

    /// Bindings of the mesh walls' kernels of a step as [`resolve_bindings`](Self::resolve_bindings), in the order of
    /// [`ENTRY_POINTS`](crate::engines::wgpu::walls::ENTRY_POINTS), beside the state's (the listing reads
    /// `dem`, `pos` and `clock`; the contacts read what the contact pass reads); `None` without
    /// mesh walls (the kernels are not dispatched).
    pub fn mesh_bindings(&self, on: Turn) -> Option<[Vec<(Binding, &wgpu::Buffer)>; 2]> {
        let mut contacts = self.resolve_bindings(on);
        contacts.extend(self.mesh.bindings());
        let near = self.mesh.near_bindings().to_vec();
        self.mesh.any().then_some([near, contacts])
    }

    /// Bindings of the integration kernel of a step that integrates state set `set` (a run
    /// with clumps: each component's clump too).
    pub fn integrate_bindings(&self, set: usize) -> Vec<(Binding, &wgpu::Buffer)> {
        let own = [(OMEGA, self.omega_of(set)), (TORQUE, &self.torque)];
        let clumps = self.clumps.as_ref().map(DeviceClumps::of_binding);
        own.into_iter().chain(clumps).collect()
    }

    /// What the contact pass binds beside [`resolve_bindings`](Self::resolve_bindings): the
    /// clumps' (no two components of one clump are a pair; each component notes its row).
    pub fn contact_bindings(&self) -> [(Binding, &wgpu::Buffer); 2] {
        match &self.clumps {
            Some(c) => c.contact_bindings(),
            None => [(CLUMP_OF, &self.laws), (CLUMP_ROWS, &self.need)],
        }
    }

    /// What a walk that only lists candidates binds of the clumps.
    pub fn listing_binding(&self) -> (Binding, &wgpu::Buffer) {
        self.contact_bindings()[0]
    }

    /// The clumps (`None`: the run has none).
    pub fn clumps(&self) -> Option<&DeviceClumps> {
        self.clumps.as_ref()
    }

    /// Bindings of `advance_clumps` on state set `set` beside the state's and the forces'
    /// (`None` without clumps: the kernel is not dispatched).
    pub fn advance_bindings(&self, set: usize) -> Option<Vec<(Binding, &wgpu::Buffer)>> {
        let own = [(OMEGA, self.omega_of(set)), (TORQUE, &self.torque)];
        let clumps = self.clumps.as_ref()?.advance_bindings();
        Some([&own[..], &clumps[..]].concat())
    }

    /// The angular velocities a step that re-sorts the state moves from set `from` (first) to
    /// set `1 - from` (engines with two sets).
    pub fn sorted_omega(&self, from: usize) -> [&wgpu::Buffer; 2] {
        [self.omega_of(from), self.omega_of(1 - from)]
    }

    /// Where the re-sort of an engine with two state sets writes, and its resolve kernel reads,
    /// the index each sphere had in the previous state set (its row of the old history).
    pub fn came_from(&self) -> &wgpu::Buffer {
        &self.came_from
    }

    /// The mesh walls.
    pub fn mesh(&self) -> &MeshWalls {
        &self.mesh
    }

    /// The mesh walls, to set up an advance and read its loads.
    pub fn mesh_mut(&mut self) -> &mut MeshWalls {
        &mut self.mesh
    }

    /// Makes the rows after the spheres there (rows kept at opening) those of new spheres of
    /// the materials `materials` for the next step (`next`): no spin, no history.
    pub fn append(&mut self, gpu: &Gpu, next: Turn, materials: &[u8]) -> Result<()> {
        let k = materials.len() as u32;
        let (first, count) = (self.n as u64, k as u64);
        let omega: Vec<[f32; 4]> = materials
            .iter()
            .map(|&m| [0.0, 0.0, 0.0, m as f32])
            .collect();
        gpu.checked("appending spheres", || {
            gpu.queue.write_buffer(
                self.omega_of(next.set),
                first * 16,
                bytemuck::cast_slice(&omega),
            );
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let held = &self.held[next.parity];
            encoder.clear_buffer(held, first * 4, Some(count * 4));
            gpu.queue.submit([encoder.finish()]);
        })?;
        self.n += k;
        Ok(())
    }

    /// The parts of the history of parity `parity`, with their rows of the spheres there are.
    fn parts(&self, parity: usize) -> Vec<Part<'_>> {
        let (per, n) = (self.split.spheres_per_part, self.n);
        (self.history[parity].parts.iter().zip(0u32..))
            .map(|(entries, k)| Part {
                entries,
                rows: (k.saturating_mul(per)).min(n)..((k + 1).saturating_mul(per)).min(n),
            })
            .collect()
    }

    /// The history's slots a row and bytes a slot.
    fn shape(&self) -> Shape {
        Shape {
            slots: self.split.slots,
            entry_bytes: self.split.entry_bytes,
        }
    }

    /// The kernels on the held slots, made at the first use.
    fn kernels(&self, gpu: &Gpu) -> &HeldSlots {
        self.held_slots.get_or_init(|| HeldSlots::new(gpu))
    }

    /// Each row's count of held slots in the history of parity `parity`, and what `take` asks
    /// of those slots, row after row.
    fn pack_held(&self, gpu: &Gpu, parity: usize, take: Take) -> Result<(Vec<u32>, Vec<u32>)> {
        let counts = &self.held[parity];
        // A step that met more contacts than its slots is redone with more (`need`): a row
        // holds at most its slots.
        let mut held: Vec<u32> = gpu.read(counts, self.n as usize)?;
        held.iter_mut()
            .for_each(|c| *c = (*c).min(self.split.slots));
        let parts = self.parts(parity);
        let packed =
            (self.kernels(gpu)).pack(gpu, (&held, counts), &parts, (self.shape(), take))?;
        Ok((held, packed))
    }

    /// Whether contacts keep springs (then batches are saved and may be redone).
    pub fn keeps_history(&self) -> bool {
        self.split.slots > 0
    }

    /// `law` with this history's layout: its slots a sphere and rows an entry binding.
    pub fn history_layout(&self, law: LawParams) -> LawParams {
        law.with_history(self.split.slots, self.split.spheres_per_part)
    }

    /// The history's size in words, for an engine's description: slots a sphere, and the bytes
    /// a sphere of both histories and their counts (`None` without history).
    pub fn describe_history(&self) -> Option<String> {
        let slots = self.split.slots as u64;
        self.keeps_history().then(|| {
            let bytes = 2 * (slots * self.split.entry_bytes + size_of::<u32>() as u64);
            format!("history {slots} slots a sphere, {bytes} B a sphere")
        })
    }

    /// Records, ahead of a batch whose first step starts from `first`, the clearing of the
    /// history count and (with history) the copy of the state it starts from: the old history's
    /// held slots and counts, the angular velocities, the engine's buffers `state` and the
    /// clumps' states.
    pub fn begin_batch(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        first: Turn,
        state: &[&wgpu::Buffer],
    ) {
        encoder.clear_buffer(&self.need, 0, None);
        self.mesh.clear_sums(encoder);
        if !self.keeps_history() {
            return;
        }
        let sources: Vec<&wgpu::Buffer> = self.history[first.parity]
            .parts
            .iter()
            .chain([
                &self.held[first.parity],
                &self.omega[first.set % self.omega.len()],
            ])
            .chain(state.iter().copied())
            .chain(self.clumps.as_ref().map(DeviceClumps::bodies))
            .collect();
        let fits = self.saved.len() == sources.len()
            && self
                .saved
                .iter()
                .zip(&sources)
                .all(|(a, b)| a.size() == b.size());
        if !fits {
            self.saved = sources
                .iter()
                .enumerate()
                .map(|(k, b)| {
                    let label = format!("mochi.dem.{}.saved{k}", self.engine);
                    gpu.storage(&label, b.size(), wgpu::BufferUsages::empty())
                })
                .collect();
        }
        // The history's parts: each row's held slots alone; the rest whole.
        let fields = self.split.parts();
        let parts = self.parts(first.parity);
        let saved = (&parts[..], &self.saved[..fields]);
        let held = &self.held[first.parity];
        (self.kernels(gpu)).save(gpu, encoder, held, saved, self.shape());
        for (from, to) in sources[fields..].iter().zip(&self.saved[fields..]) {
            encoder.copy_buffer_to_buffer(from, 0, to, 0, from.size());
        }
    }

    /// After a batch (submitted): `None` when every sphere's contacts fit, else the most
    /// contacts a sphere needed.
    pub fn overflow(&self, gpu: &Gpu) -> Result<Option<u32>> {
        if !self.keeps_history() {
            return Ok(None);
        }
        let need = gpu.read::<u32>(&self.need, 1)?[0];
        Ok((need > self.split.slots).then_some(need))
    }

    /// Puts back the state a batch began from (`first`, the engine's buffers `state` as given
    /// to [`begin_batch`](Self::begin_batch)) with room for `need` contacts per sphere
    /// and some more (a quarter, as the cpu step), the new layout written into `params`. The
    /// history buffers are new: the engine binds them again.
    pub fn restore_grown(
        &mut self,
        gpu: &Gpu,
        (first, state): (Turn, &[&wgpu::Buffer]),
        need: u32,
        params: &mut ParamsUniform,
    ) -> Result<()> {
        let parity = first.parity;
        let engine = self.engine;
        let (n, old) = (self.n as usize, self.split);
        let slots = need.saturating_add(need / 4);
        let split = entry_split(gpu, old.n, slots, old.entry_bytes, engine)?;
        // The saved copies: the old history's buffers, its counts, then the rest.
        let fields = old.parts();
        let held: Vec<u32> = gpu.read(&self.saved[fields], n)?;
        // Each sphere's held slots moved to its first slots of the wider rows.
        let moved = read_slots(gpu, &self.saved[..fields], &old, self.n)?.moved(
            &held,
            old.slots as usize,
            slots as usize,
            |row| row,
        )?;
        let history = gpu.checked("allocating the contact history", || {
            [0, 1].map(|b| History::new(gpu, engine, b, &split))
        })?;
        self.history = history;
        self.history[parity].write(gpu, &split, &moved);
        self.split = split;
        params.update(gpu, |p| *p = self.history_layout(*p));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.saved[fields], 0, &self.held[parity], 0, n as u64 * 4);
        let targets = [self.omega_of(first.set)]
            .into_iter()
            .chain(state.iter().copied())
            .chain(self.clumps.as_ref().map(DeviceClumps::bodies));
        for (from, to) in self.saved[fields + 1..].iter().zip(targets) {
            encoder.copy_buffer_to_buffer(from, 0, to, 0, from.size());
        }
        gpu.checked("restoring the state of a batch", || {
            gpu.queue.submit([encoder.finish()])
        })?;
        Ok(())
    }

    /// Moves the rows of `moves` (as [`RowMover::run`]) of the angular velocities and the
    /// history that the next step (`next`) reads.
    pub fn move_rows(
        &self,
        gpu: &Gpu,
        mover: &mut RowMover,
        next: Turn,
        moves: &[(u32, u32)],
    ) -> Result<()> {
        let (omega, parity) = (self.omega_of(next.set), next.parity);
        mover.run(gpu, moves, 4, |r| (omega, r))?;
        if !self.keeps_history() {
            return Ok(());
        }
        let held = &self.held[parity];
        mover.run(gpu, moves, 1, |r| (held, r))?;
        let (per, k) = (self.split.spheres_per_part, self.split.slots as u64);
        let parts = &self.history[parity].parts;
        let words = (k * self.split.entry_bytes / 4) as u32;
        mover.run(gpu, moves, words, |r| (&parts[(r / per) as usize], r % per))
    }

    /// Forgets the last `k` rows (the engine moved the rows it keeps before them).
    pub fn shrink(&mut self, k: u32) {
        self.n -= k;
    }

    /// The angular velocities, the materials and (where `springs`; else none) the history in
    /// the cpu's layout that the next step (`next`) reads; `order` maps the rows of state set
    /// `next.set` to input order (`None`: the state is in input order).
    pub fn read(
        &self,
        gpu: &Gpu,
        next: Turn,
        order: Option<&InputOrder>,
        springs: bool,
    ) -> Result<Rotation> {
        let (n, parity) = (self.n as usize, next.parity);
        let omega: Vec<[f32; 4]> = gpu.read(self.omega_of(next.set), n)?;
        let angular_velocities = omega.iter().map(|w| [w[0], w[1], w[2]]).collect();
        let materials = omega.iter().map(|w| w[3] as u8).collect();
        let history = if !springs {
            ContactHistory::default()
        } else if self.keeps_history() {
            let (held, words) = self.pack_held(gpu, parity, Take::Slots)?;
            let packed = Slots {
                words,
                width: self.split.width(),
            };
            let rows = HeldRows::packed(&held, rows_of(order, n));
            both_sides(n, &packed, &rows, |id| partner_of(order, id))?
        } else {
            self.given.clone()
        };
        Ok(Rotation {
            angular_velocities,
            materials,
            history,
        })
    }

    /// The contacts each sphere holds in the history [`read`](Self::read) gives for `next` and
    /// `order` (its contacts with walls too where `walls`), in input order, counted from the
    /// slots' partners alone.
    pub fn contact_counts(
        &self,
        gpu: &Gpu,
        next: Turn,
        order: Option<&InputOrder>,
        walls: bool,
    ) -> Result<Vec<u32>> {
        let n = self.n as usize;
        if !self.keeps_history() {
            // The history as given holds both sides of each contact.
            let kept = |i: usize| {
                self.given
                    .of(i)
                    .iter()
                    .filter(|e| walls || (e.partner as usize) < n)
            };
            return Ok((0..n).map(|i| kept(i).count() as u32).collect());
        }
        let (held, slot_partners) = self.pack_held(gpu, next.parity, Take::Partners)?;
        let rows = HeldRows::packed(&held, rows_of(order, n));
        let partners = |i: usize| {
            (slot_partners[rows.of(i)].iter())
                .filter(|&&p| p != NO_PARTNER)
                .filter_map(|&p| partner_of(order, p))
                .filter(|&p| walls || (p as usize) < n)
        };
        Ok(ContactHistory::counts_of_owner_rows(n, partners))
    }
}

/// The split of the history of `n` spheres with `slots` slots each of `entry_bytes` over the
/// bindings of `gpu` ([`EntrySplit`]), or [`Error::TooLarge`] naming the most slots that fit.
fn entry_split(
    gpu: &Gpu,
    n: u32,
    slots: u32,
    entry_bytes: u64,
    engine: &str,
) -> Result<EntrySplit> {
    let max = gpu
        .limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size);
    let place = format!("the {engine} DEM of {}", gpu.info.name);
    split_or_refuse(max, n, slots, entry_bytes, &place)
}

/// [`EntrySplit::within`] as the error [`entry_split`] gives on `place`.
fn split_or_refuse(
    max: u64,
    n: u32,
    slots: u32,
    entry_bytes: u64,
    place: &str,
) -> Result<EntrySplit> {
    EntrySplit::within(max, n, slots, entry_bytes).map_err(|limit| Error::TooLarge {
        what: format!(
            "contact history slots per sphere for {n} spheres on {place} ({entry_bytes} bytes \
             per slot, whole spheres' slots in at most {ENTRY_PARTS} bindings of {max} bytes)"
        ),
        got: slots as u64,
        limit,
    })
}

/// The contacts of `history` that sphere `i` (of spheres of `radii`) keeps on the GPU: its walls,
/// the pairs it alone holds, and of each pair both hold (the cpu's layout) the one of its smaller
/// sphere (of two as large, the lower index). Either sphere's row will do, whichever finds the
/// pair: a step looks it up in its partner's old row too (`wgsl/dem/dem_granular.wgsl`). A sphere
/// then keeps about what it owns on the GPU, not all it touches, which sets the rows' length.
fn owned<'a>(
    history: &'a ContactHistory,
    radii: &'a [f32],
    i: usize,
) -> impl Iterator<Item = (usize, &'a HistoryEntry)> + 'a {
    history.of(i).iter().enumerate().filter(move |(_, e)| {
        let j = e.partner as usize;
        j >= radii.len()
            || (radii[i], i) < (radii[j], j)
            || !history.of(j).iter().any(|back| back.partner == i as u32)
    })
}

/// The most contacts a sphere keeps of `history` ([`owned`]).
fn most_owned(history: &ContactHistory, radii: &[f32]) -> usize {
    (0..radii.len())
        .map(|i| owned(history, radii, i).count())
        .max()
        .unwrap_or(0)
}

/// The contacts of `history` the spheres of `radii` keep ([`owned`]) laid out in `slots` slots
/// of `width` words per sphere (with their load histories where the slots hold them), and the
/// count of each.
fn lay_out(
    history: &ContactHistory,
    radii: &[f32],
    slots: usize,
    width: usize,
) -> Result<(Slots, Vec<u32>)> {
    let n = radii.len();
    let mut laid_out = Slots::empty(n * slots, n, width)?;
    let mut held = try_vec(n, || format!("the contact history of {n} spheres"))?;
    for i in 0..n {
        let loads = history.loads_of(i);
        let mut count = 0;
        for (s, (k, e)) in owned(history, radii, i).enumerate() {
            let load = loads.get(k).copied().unwrap_or_default();
            laid_out.set(i * slots + s, e, &load);
            count += 1;
        }
        held.push(count);
    }
    Ok((laid_out, held))
}

/// Each sphere's row, by its input index (as `order` gives each row's; empty: each its own).
fn rows_of(order: Option<&InputOrder>, n: usize) -> Vec<u32> {
    let mut rows = Vec::new();
    if let Some(order) = order {
        rows.resize(n, 0);
        for (row, &i) in order.rank.iter().enumerate() {
            rows[i as usize] = row as u32;
        }
    }
    rows
}

/// A slot's partner `id` in input order (`order`, where it renames; `None`: one that left).
fn partner_of(order: Option<&InputOrder>, id: u32) -> Option<u32> {
    order
        .filter(|o| o.renames())
        .map_or(Some(id), |o| o.partner(id))
}

/// Where each sphere's held slots lie among slots laid out: sphere i's are the `held[r]` from
/// slot `first[r]` on, r its row `rows[i]` (each sphere its own where `rows` is empty).
struct HeldRows<'a> {
    held: &'a [u32],
    first: Vec<usize>,
    rows: Vec<u32>,
}

impl<'a> HeldRows<'a> {
    /// Rows of `slots` slots each, row r from slot r·`slots` on (the history's layout), each
    /// sphere its own row.
    #[cfg(test)]
    fn strided(held: &'a [u32], slots: usize) -> Self {
        let first = (0..held.len()).map(|r| r * slots).collect();
        HeldRows {
            held,
            first,
            rows: Vec::new(),
        }
    }

    /// The held slots of the rows alone, one row after the other, sphere i's row `rows[i]`.
    fn packed(held: &'a [u32], rows: Vec<u32>) -> Self {
        let mut at = 0;
        let first = (held.iter())
            .map(|&c| {
                let first = at;
                at += c as usize;
                first
            })
            .collect();
        HeldRows { held, first, rows }
    }

    /// The slots sphere `i` holds.
    fn of(&self, i: usize) -> Range<usize> {
        let r = self.rows.get(i).map_or(i, |&r| r as usize);
        self.first[r]..self.first[r] + self.held[r] as usize
    }
}

/// The history of `n` spheres from the slots `laid_out` that `rows` places, each contact held by
/// one side (its owner) or both, as [`ContactHistory::from_owner_rows`] takes it: each partner
/// named by `partner` (`None`: one that left, whose contacts are dropped).
fn both_sides(
    n: usize,
    laid_out: &Slots,
    rows: &HeldRows,
    partner: impl Fn(u32) -> Option<u32>,
) -> Result<ContactHistory> {
    let row = |i: usize| {
        (rows.of(i).map(|s| laid_out.get(s)))
            .filter(|(e, _)| e.partner != NO_PARTNER)
            .filter_map(|(mut e, load)| {
                e.partner = partner(e.partner)?;
                Some((e, load))
            })
    };
    ContactHistory::from_owner_rows(n, laid_out.width == LOADED_WORDS, row)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::FIRST_WALL;

    fn entry(partner: u32, x: f32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: [x, 0.0, 0.0],
            rolling: [0.0, x, 0.0],
        }
    }

    fn laid_out(entries: &[HistoryEntry]) -> Slots {
        let mut laid_out = Slots::empty(entries.len(), 1, WORDS).unwrap();
        for (s, e) in entries.iter().enumerate() {
            laid_out.set(s, e, &LoadEntry::default());
        }
        laid_out
    }

    #[test]
    fn the_entries_split_by_row_range_where_one_binding_cannot_hold_them() {
        // wgpu's largest storage binding on the H100 (docs/performance-log/).
        let max = 2_147_483_644;
        // 1M spheres at K = 16: 512 MB of entries, one binding.
        let one = EntrySplit::within(max, 1_000_000, FIRST_SLOTS, ENTRY_BYTES).unwrap();
        assert_eq!((one.parts(), one.spheres_per_part), (1, 1_000_000));
        assert_eq!(one.slots_of(0), 0..16_000_000);
        assert_eq!(one.part_bytes(0), 512_000_000);
        // 20M at K = 16: 10.24 GB, 512 bytes a sphere, in five bindings.
        let n = 20_000_000;
        let five = EntrySplit::within(max, n, FIRST_SLOTS, ENTRY_BYTES).unwrap();
        assert_eq!((five.parts(), five.spheres_per_part), (5, 4_194_303));
        assert_eq!(five.slots_of(4), 4 * 4_194_303 * 16..n as usize * 16);
        assert!((0..5).all(|b| five.part_bytes(b) <= max));
        // Grown by a quarter from 20 contacts, as a settled pile's worst sphere may need.
        assert_eq!(
            EntrySplit::within(max, n, 25, ENTRY_BYTES).unwrap().parts(),
            8
        );
        // Eight bindings hold 26 slots a sphere.
        assert_eq!(
            EntrySplit::within(max, n, 26, ENTRY_BYTES).unwrap().parts(),
            8
        );
        let refused = split_or_refuse(max, n, 27, ENTRY_BYTES, "an H100").unwrap_err();
        assert!(
            matches!(
                refused,
                Error::TooLarge {
                    got: 27,
                    limit: 26,
                    ..
                }
            ),
            "{refused}"
        );
        assert!(refused.to_string().contains("exceeds the limit of 26"));
        // Where whole rows leave the bindings short first: 9 spheres, bindings of 1000 bytes
        // (two rows of 15 slots each, but one of 16).
        assert_eq!(
            EntrySplit::within(1000, 9, 15, ENTRY_BYTES)
                .unwrap()
                .parts(),
            5
        );
        assert_eq!(EntrySplit::within(1000, 9, 16, ENTRY_BYTES), Err(15));
        // No history: one smallest binding.
        let none = EntrySplit::within(max, 0, 0, ENTRY_BYTES).unwrap();
        assert_eq!((none.parts(), none.part_bytes(0)), (1, ENTRY_BYTES));
    }

    #[test]
    fn an_entry_keeps_its_partner_and_springs_bit_for_bit() {
        let wall = HistoryEntry {
            partner: FIRST_WALL + 5,
            tangential: [f32::MIN_POSITIVE, -0.0, 1e-30],
            rolling: [-3.5, f32::MAX, 0.25],
        };
        let load = LoadEntry {
            reversal: [1e-20, -2.0, f32::MIN_POSITIVE],
            normal: 7.5,
        };
        let none = (HistoryEntry::default(), LoadEntry::default());
        // Mindlin's spring: no load history kept.
        let mut laid_out = Slots::empty(2, 1, WORDS).unwrap();
        laid_out.set(1, &wall, &load);
        assert_eq!(laid_out.get(1), (wall, LoadEntry::default()));
        assert_eq!(laid_out.get(0), none);
        // Mindlin–Deresiewicz: twice the words, the load history kept.
        let mut laid_out = Slots::empty(2, 1, LOADED_WORDS).unwrap();
        laid_out.set(1, &wall, &load);
        assert_eq!(laid_out.get(1), (wall, load));
        assert_eq!(laid_out.get(0), none);
        // The 64-byte entries halve the rows a binding holds.
        let max = 2_147_483_644;
        let loaded = EntrySplit::within(max, 1_000_000, FIRST_SLOTS, 64).unwrap();
        assert_eq!((loaded.parts(), loaded.part_bytes(0)), (1, 1_024_000_000));
        assert_eq!(
            EntrySplit::within(max, 20_000_000, 13, 64).unwrap().parts(),
            8
        );
        assert!(EntrySplit::within(max, 20_000_000, 14, 64).is_err());
    }

    #[test]
    fn load_histories_read_back_on_both_sides_with_their_reversal_negated() {
        let mut laid_out = Slots::empty(2, 1, LOADED_WORDS).unwrap();
        let load = LoadEntry {
            reversal: [0.5, -0.25, 0.0],
            normal: 3.0,
        };
        laid_out.set(0, &entry(1, 1.0), &load);
        let h = both_sides(2, &laid_out, &HeldRows::strided(&[1, 0], 1), Some).unwrap();
        assert_eq!(h.loads_of(0), &[load]);
        let mirrored = LoadEntry {
            reversal: [-0.5, 0.25, -0.0],
            normal: 3.0,
        };
        assert_eq!(h.of(1), &[entry(0, -1.0)]);
        assert_eq!(h.loads_of(1), &[mirrored]);
        // Laid out again from the cpu's layout: the owner's entry and load history.
        let (again, held) = lay_out(&h, &[1.0; 2], 1, LOADED_WORDS).unwrap();
        assert_eq!(held, [1, 0]);
        assert_eq!(again.get(0), (entry(1, 1.0), load));
    }

    #[test]
    fn owner_only_entries_read_back_on_both_sides() {
        // Sphere 0 owns its contact with 2 and a wall; sphere 1 and 2 hold both sides of theirs.
        let slots = 3;
        let mut entries = vec![HistoryEntry::default(); 3 * slots];
        entries[0] = entry(2, 1.0);
        entries[1] = entry(FIRST_WALL + 4, 2.0);
        entries[slots] = entry(2, 3.0);
        entries[2 * slots] = entry(1, -3.0);
        let h = both_sides(
            3,
            &laid_out(&entries),
            &HeldRows::strided(&[2, 1, 1], slots),
            Some,
        )
        .unwrap();
        assert_eq!(h.of(0), &[entry(2, 1.0), entry(FIRST_WALL + 4, 2.0)]);
        assert_eq!(h.of(1), &[entry(2, 3.0)]);
        // Mirrored entries come in the order of their owners.
        assert_eq!(h.of(2), &[entry(0, -1.0), entry(1, -3.0)]);
    }

    #[test]
    fn a_history_lays_out_in_more_slots() {
        let h =
            ContactHistory::from_contacts(2, &[(1, entry(0, 1.0)), (1, entry(FIRST_WALL, 2.0))])
                .unwrap();
        let (laid_out, held) = lay_out(&h, &[1.0; 2], 4, WORDS).unwrap();
        assert_eq!(held, [0, 2]);
        assert_eq!(
            [laid_out.get(4).0, laid_out.get(5).0],
            [entry(0, 1.0), entry(FIRST_WALL, 2.0)]
        );
        assert_eq!(laid_out.get(6).0, HistoryEntry::default());
        assert_eq!(
            both_sides(2, &laid_out, &HeldRows::strided(&held, 4), Some)
                .unwrap()
                .of(0),
            &[entry(1, -1.0)]
        );
    }

    #[test]
    fn a_pair_both_spheres_hold_lays_out_once_by_its_smaller_sphere() {
        // Spheres 0 and 2 large, 1 small: 1 touches both and a wall, 0 and 2 (as large) touch.
        let h = ContactHistory::from_contacts(
            3,
            &[
                (0, entry(1, 1.0)),
                (0, entry(2, 4.0)),
                (1, entry(0, -1.0)),
                (1, entry(2, -2.0)),
                (1, entry(FIRST_WALL, 3.0)),
                (2, entry(1, 2.0)),
                (2, entry(0, -4.0)),
            ],
        )
        .unwrap();
        let radii = [2.0, 1.0, 2.0];
        assert_eq!(most_owned(&h, &radii), 3);
        let (laid_out, held) = lay_out(&h, &radii, 3, WORDS).unwrap();
        assert_eq!(held, [1, 3, 0]);
        assert_eq!(laid_out.get(0).0, entry(2, 4.0));
        assert_eq!(
            [laid_out.get(3).0, laid_out.get(4).0, laid_out.get(5).0],
            [entry(0, -1.0), entry(2, -2.0), entry(FIRST_WALL, 3.0)]
        );
        // Read back, each sphere holds what it was given (in another order).
        let back = both_sides(3, &laid_out, &HeldRows::strided(&held, 3), Some).unwrap();
        for i in 0..3 {
            let by_partner = |h: &ContactHistory| {
                let mut held = h.of(i).to_vec();
                held.sort_by_key(|e| e.partner);
                held
            };
            assert_eq!(by_partner(&back), by_partner(&h), "sphere {i}");
        }
    }
}
