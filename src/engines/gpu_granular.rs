//! The GPU state of the granular step (`wgsl/dem_contact.wgsl`, `wgsl/dem_granular.wgsl`),
//! shared by the wgpu engines: angular velocities and torque accumulators in the engine's state
//! order (one ω buffer per state set of the engine: ω is permuted with positions and velocities),
//! and the contact history (docs/method.md, "Contact history"): K slots per sphere indexed by
//! stable id, each contact kept by its owner only, in two sets of buffers that swap roles every
//! step, one buffer per field (partners, then each spring component: each fits one binding
//! where a whole entry would not). The engine keeps its own state (positions, velocities, the
//! order of its spheres); this module saves both at the start of a batch, so that a batch in
//! which some sphere had more contacts than K is redone from that state with K grown: no
//! contact is ever dropped.

use super::gpu_step::granular::{
    GRANULAR, GranularParams, HELD_NEW, HELD_OLD, HISTORY_NEED, OMEGA, PARTNERS_NEW, PARTNERS_OLD,
    SPRINGS_NEW, SPRINGS_OLD, TORQUE,
};
use crate::dem::model::{NormalLaw, RollingModel, StepParams};
use crate::dem::stepper::StageTimes;
use crate::error::{Error, Result, try_vec};
use crate::gpu::Gpu;
use crate::gpu::shader::Binding;
use crate::particles::{ContactHistory, FIRST_WALL, HistoryEntry, Particles};

/// A wgpu engine's DEM step as [`run_batch`] drives it.
pub(crate) trait RedoableBatch {
    /// The GPU, the granular state (`None`: the paper's step), the parity of the next step and
    /// the engine's buffers a batch begins from (restored when it is redone).
    fn batch_parts(&mut self) -> (&Gpu, Option<&mut Granular>, usize, Vec<&wgpu::Buffer>);

    /// Records `steps` steps into `encoder`, submits it and waits for it: the contacts of the
    /// last step and the phase times.
    fn record_batch(
        &mut self,
        encoder: wgpu::CommandEncoder,
        steps: u32,
    ) -> Result<(u64, Option<StageTimes>)>;

    /// Moves the clock and the parity back by `steps` steps (their state is restored apart).
    fn rewind(&mut self, steps: u32);

    /// Binds the granular state's buffers again (the history buffers are new after a growth).
    fn rebind(&mut self);
}

/// Records `steps` steps (≤ the engine's batch) into one submission and waits for it; in the
/// granular step, redoes them with more history slots from the state they began from while
/// some sphere had more contacts than slots.
pub(crate) fn run_batch(
    step: &mut impl RedoableBatch,
    steps: u32,
) -> Result<(u64, Option<StageTimes>)> {
    loop {
        let (gpu, granular, parity, state) = step.batch_parts();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        if let Some(g) = granular {
            g.begin_batch(gpu, &mut encoder, parity, &state);
        }
        let done = step.record_batch(encoder, steps)?;
        let (gpu, granular, ..) = step.batch_parts();
        let Some(need) = granular.map(|g| g.overflow(gpu)).transpose()?.flatten() else {
            return Ok(done);
        };
        // The batch's steps are undone: back to the state and step it began from.
        step.rewind(steps);
        let (gpu, granular, parity, state) = step.batch_parts();
        if let Some(g) = granular {
            g.restore_grown(gpu, parity, &state, need)?;
        }
        step.rebind();
    }
}

/// History slots per sphere a run starts with, as the cpu step's (a dense monodisperse packing
/// has 12 neighbours, plus up to 3 walls).
const FIRST_SLOTS: u32 = 16;

/// Storage buffers the granular resolve kernel binds (wgpu-compute's: the state, the cell
/// table, the ids, forces, counters, spins, torques, two histories of 7 fields and their
/// counts, the need).
const STORAGE_BUFFERS: u32 = 25;

/// Fields of a history slot on the GPU, one buffer each: the partner and six spring components.
const FIELDS: usize = 7;

/// Bytes of one field of one slot.
const FIELD_BYTES: u64 = 4;

/// What the granular step adds to the particles a GPU step reads back.
pub(crate) struct Rotation {
    /// Angular velocities, in the order of the engine's state read with them \[rad/s\].
    pub angular_velocities: Vec<[f32; 3]>,
    /// The contact history in the cpu's layout (both sides of each pair).
    pub history: ContactHistory,
}

/// One history on the GPU: K slots per sphere by stable id, slot s of sphere a at element
/// a·K + s of every field's buffer.
struct History {
    partners: wgpu::Buffer,
    /// ξ x, y, z, then the rolling torque's x, y, z.
    springs: [wgpu::Buffer; 6],
}

impl History {
    /// Zeroed buffers of `bytes` each, labelled for history `k` of `engine`.
    fn new(gpu: &Gpu, engine: &str, k: usize, bytes: u64) -> Self {
        let make = |field: &str| {
            let label = format!("mochi.dem.{engine}.history{k}.{field}");
            gpu.storage(&label, bytes, wgpu::BufferUsages::empty())
        };
        History {
            partners: make("partners"),
            springs: ["xi_x", "xi_y", "xi_z", "roll_x", "roll_y", "roll_z"].map(make),
        }
    }

    /// The fields' buffers: partners first.
    fn fields(&self) -> [&wgpu::Buffer; FIELDS] {
        let [a, b, c, d, e, f] = &self.springs;
        [&self.partners, a, b, c, d, e, f]
    }

    /// Uploads `columns` (of as many slots as the buffers hold).
    fn write(&self, gpu: &Gpu, columns: &Columns) {
        gpu.queue
            .write_buffer(&self.partners, 0, bytemuck::cast_slice(&columns.partners));
        for (buffer, column) in self.springs.iter().zip(&columns.springs) {
            gpu.queue
                .write_buffer(buffer, 0, bytemuck::cast_slice(column));
        }
    }

    /// The first `slots` slots of every field.
    fn read(&self, gpu: &Gpu, slots: usize) -> Result<Columns> {
        let mut springs: [Vec<f32>; 6] = Default::default();
        for (column, buffer) in springs.iter_mut().zip(&self.springs) {
            *column = gpu.read(buffer, slots)?;
        }
        Ok(Columns {
            partners: gpu.read(&self.partners, slots)?,
            springs,
        })
    }
}

/// History slots in the GPU's layout, on the host: one vector per field.
#[derive(Debug, Default, PartialEq)]
struct Columns {
    partners: Vec<u32>,
    /// ξ x, y, z, then the rolling torque's x, y, z.
    springs: [Vec<f32>; 6],
}

impl Columns {
    /// `slots` empty slots.
    fn empty(slots: usize, n: usize) -> Result<Self> {
        let what = || format!("the contact history of {n} spheres");
        let mut partners = try_vec(slots, what)?;
        partners.resize(slots, 0);
        let mut springs: [Vec<f32>; 6] = Default::default();
        for column in &mut springs {
            *column = try_vec(slots, what)?;
            column.resize(slots, 0.0);
        }
        Ok(Columns { partners, springs })
    }

    fn set(&mut self, slot: usize, e: &HistoryEntry) {
        self.partners[slot] = e.partner;
        let values = [e.tangential, e.rolling].concat();
        for (column, x) in self.springs.iter_mut().zip(values) {
            column[slot] = x;
        }
    }

    fn get(&self, slot: usize) -> HistoryEntry {
        let x = |c: usize| self.springs[c][slot];
        HistoryEntry {
            partner: self.partners[slot],
            tangential: [x(0), x(1), x(2)],
            rolling: [x(3), x(4), x(5)],
        }
    }
}

/// The granular step's buffers beyond the paper's.
pub(crate) struct Granular {
    params: GranularParams,
    uniform: wgpu::Buffer,
    /// `vec4(ω, 0)` in the order of each of the engine's state sets (one or two).
    omega: Vec<wgpu::Buffer>,
    /// Torque accumulators in state order (zero between steps).
    torque: wgpu::Buffer,
    /// History slots, `params.slots` per sphere by stable id: the old ones of a step of parity
    /// k are `history[k]`, its new ones `history[1 - k]`.
    history: [History; 2],
    /// Contacts held per sphere, by stable id, beside `history`.
    held: [wgpu::Buffer; 2],
    /// The most contacts with history any sphere had in the batch.
    need: wgpu::Buffer,
    /// Copies of the state at the start of the batch (with history only): the old history's
    /// fields and its counts, the angular velocities, then the engine's own buffers.
    saved: Vec<wgpu::Buffer>,
    /// The history as given, returned as it is where contacts keep no springs (as the cpu
    /// step does).
    given: ContactHistory,
    n: u32,
    /// The engine's backend name, for labels and errors.
    engine: &'static str,
}

impl Granular {
    /// Whether the particles and parameters need the granular step; without, the paper's step
    /// runs them, with the same work as before the granular step existed.
    pub fn needed(particles: &Particles, params: &StepParams) -> bool {
        params.law != NormalLaw::Linear
            || params.friction.turns()
            || particles.spin()
            || !particles.history.is_empty()
    }

    /// The buffers for `particles` on `gpu` for the engine named `engine` (its backend's name),
    /// whose state is in `sets` sets of buffers (1: one set in input order; 2: two sets that a
    /// step of parity k reads from set k and writes in set 1 − k); the angular velocities go
    /// into set 0, in input order, the history as the old history of a step of parity 0 (the
    /// cpu's layout, both sides of each pair, is usable as it is: each owner finds its own
    /// entry first).
    pub fn new(
        gpu: &Gpu,
        particles: &Particles,
        params: &StepParams,
        engine: &'static str,
        sets: usize,
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
        let f = &params.friction;
        let keeps = f.has_history();
        if keeps && n64 > FIRST_WALL as u64 {
            return Err(Error::TooLarge {
                what: "spheres of a run with contact history (ids above are the walls')".into(),
                got: n64,
                limit: FIRST_WALL as u64,
            });
        }
        let zero = crate::dem::model::Elastic {
            e_star: 0.0,
            g_star: 0.0,
        };
        let (law, rate, pair, wall) = match params.law {
            NormalLaw::Linear => (0, 0.0, zero, zero),
            NormalLaw::LinearPerPair { rate, .. } => (1, rate, zero, zero),
            NormalLaw::Hertz { pair, wall } => (2, 0.0, pair, wall),
        };
        let slots = match keeps {
            true => FIRST_SLOTS.max(particles.history.most() as u32),
            false => 0,
        };
        let gpu_params = GranularParams {
            law,
            rate,
            pair_e_star: pair.e_star,
            pair_g_star: pair.g_star,
            wall_e_star: wall.e_star,
            wall_g_star: wall.g_star,
            sliding: f.sliding,
            wall_sliding: f.wall_sliding,
            rolling: f.rolling,
            rolling_model: match f.rolling_model {
                RollingModel::Epsd => 0,
                RollingModel::ConstantTorque => 1,
            },
            turns: f.turns() as u32,
            slots,
        };
        let n = n64 as u32;
        let field_bytes = field_bytes(gpu, n, slots, engine)?;
        let none = wgpu::BufferUsages::empty();
        let label = |what: &str| format!("mochi.dem.{engine}.{what}");
        let make = |what: &str, bytes: u64| gpu.storage(&label(what), bytes, none);
        let granular = gpu.checked("allocating the granular step's buffers", || Self {
            params: gpu_params,
            uniform: gpu.uniform(&label("granular"), &gpu_params),
            omega: (0..sets)
                .map(|k| make(&format!("omega{k}"), n64 * 16))
                .collect(),
            torque: make("torque", n64 * 12),
            history: [0, 1].map(|k| History::new(gpu, engine, k, field_bytes)),
            held: [make("held0", n64 * 4), make("held1", n64 * 4)],
            need: make("history_need", 4),
            saved: Vec::new(),
            given: if keeps {
                ContactHistory::default()
            } else {
                particles.history.clone()
            },
            n,
            engine,
        })?;
        let omega: Vec<[f32; 4]> = particles
            .angular_velocities
            .iter()
            .map(|w| [w[0], w[1], w[2], 0.0])
            .collect();
        gpu.queue
            .write_buffer(&granular.omega[0], 0, bytemuck::cast_slice(&omega));
        // New buffers are zeroed: an empty history needs no upload.
        if keeps && !particles.history.is_empty() {
            let (columns, held) = lay_out(&particles.history, n as usize, slots as usize)?;
            granular.history[0].write(gpu, &columns);
            gpu.queue
                .write_buffer(&granular.held[0], 0, bytemuck::cast_slice(&held));
        }
        Ok(granular)
    }

    /// The angular velocities in the order of state set `set`.
    fn omega_of(&self, set: usize) -> &wgpu::Buffer {
        &self.omega[set % self.omega.len()]
    }

    /// Bindings of the resolve kernel of a step of parity `parity`.
    pub fn resolve_bindings(&self, parity: usize) -> Vec<(Binding, &wgpu::Buffer)> {
        let (old, new) = (&self.history[parity], &self.history[1 - parity]);
        let mut all = vec![
            (GRANULAR, &self.uniform),
            (OMEGA, self.omega_of(1 - parity)),
            (TORQUE, &self.torque),
            (PARTNERS_OLD, &old.partners),
            (HELD_OLD, &self.held[parity]),
            (PARTNERS_NEW, &new.partners),
            (HELD_NEW, &self.held[1 - parity]),
            (HISTORY_NEED, &self.need),
        ];
        all.extend(SPRINGS_OLD.into_iter().zip(&old.springs));
        all.extend(SPRINGS_NEW.into_iter().zip(&new.springs));
        all
    }

    /// Bindings of the integration kernel of a step of parity `parity`.
    pub fn integrate_bindings(&self, parity: usize) -> [(Binding, &wgpu::Buffer); 3] {
        [
            (GRANULAR, &self.uniform),
            (OMEGA, self.omega_of(1 - parity)),
            (TORQUE, &self.torque),
        ]
    }

    /// The angular velocities a step of parity `parity` moves from set `parity` (first) to
    /// set `1 - parity` as it re-sorts the state (engines with two sets).
    pub fn sorted_omega(&self, parity: usize) -> [&wgpu::Buffer; 2] {
        [self.omega_of(parity), self.omega_of(1 - parity)]
    }

    /// Whether contacts keep springs (then batches are saved and may be redone).
    pub fn keeps_history(&self) -> bool {
        self.params.slots > 0
    }

    /// Records, ahead of a batch whose first step has parity `parity`, the clearing of the
    /// history count and (with history) the copy of the state it starts from: the old history,
    /// the angular velocities and the engine's buffers `state`.
    pub fn begin_batch(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        parity: usize,
        state: &[&wgpu::Buffer],
    ) {
        encoder.clear_buffer(&self.need, 0, None);
        if !self.keeps_history() {
            return;
        }
        let sources: Vec<&wgpu::Buffer> = self.history[parity]
            .fields()
            .into_iter()
            .chain([&self.held[parity], &self.omega[parity % self.omega.len()]])
            .chain(state.iter().copied())
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
        for (from, to) in sources.iter().zip(&self.saved) {
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
        Ok((need > self.params.slots).then_some(need))
    }

    /// Puts back the state a batch began from (parity `parity`, the engine's buffers `state`
    /// as given to [`begin_batch`](Self::begin_batch)) with room for `need` contacts per sphere
    /// and some more (a quarter, as the cpu step). The history buffers are new: the engine
    /// binds them again.
    pub fn restore_grown(
        &mut self,
        gpu: &Gpu,
        parity: usize,
        state: &[&wgpu::Buffer],
        need: u32,
    ) -> Result<()> {
        let engine = self.engine;
        let (n, old_k) = (self.n as usize, self.params.slots as usize);
        let slots = need.saturating_add(need / 4);
        let bytes = field_bytes(gpu, self.n, slots, engine)?;
        let held: Vec<u32> = gpu.read(&self.saved[FIELDS], n)?;
        let k = slots as usize;
        let history = gpu.checked("allocating the contact history", || {
            [0, 1].map(|b| History::new(gpu, engine, b, bytes))
        })?;
        self.history = history;
        // Field by field, each sphere's held slots moved to its first slots of the wider rows.
        for (field, target) in self.history[parity].fields().into_iter().enumerate() {
            let what = || format!("the contact history of {n} spheres");
            let saved: Vec<u32> = gpu.read(&self.saved[field], n * old_k)?;
            let mut grown = try_vec(n * k, what)?;
            grown.resize(n * k, 0u32);
            for i in 0..n {
                let c = held[i] as usize;
                grown[i * k..i * k + c].copy_from_slice(&saved[i * old_k..i * old_k + c]);
            }
            gpu.queue
                .write_buffer(target, 0, bytemuck::cast_slice(&grown));
        }
        self.params.slots = slots;
        gpu.write_uniform(&self.uniform, &self.params);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.saved[FIELDS], 0, &self.held[parity], 0, n as u64 * 4);
        let targets = [self.omega_of(parity)]
            .into_iter()
            .chain(state.iter().copied());
        for (from, to) in self.saved[FIELDS + 1..].iter().zip(targets) {
            encoder.copy_buffer_to_buffer(from, 0, to, 0, from.size());
        }
        gpu.checked("restoring the state of a batch", || {
            gpu.queue.submit([encoder.finish()])
        })?;
        Ok(())
    }

    /// The angular velocities (in the order of state set `parity`) and the history in the
    /// cpu's layout, after a step of parity `1 - parity` (the history of parity `parity` is
    /// the one the next step reads).
    pub fn read(&self, gpu: &Gpu, parity: usize) -> Result<Rotation> {
        let n = self.n as usize;
        let omega: Vec<[f32; 4]> = gpu.read(self.omega_of(parity), n)?;
        let angular_velocities = omega.iter().map(|w| [w[0], w[1], w[2]]).collect();
        let history = if self.keeps_history() {
            let k = self.params.slots as usize;
            let held: Vec<u32> = gpu.read(&self.held[parity], n)?;
            let columns = self.history[parity].read(gpu, n * k)?;
            both_sides(n, k, &held, &columns)?
        } else {
            self.given.clone()
        };
        Ok(Rotation {
            angular_velocities,
            history,
        })
    }
}

/// Bytes of one field of the history of `n` spheres with `slots` slots each (at least one
/// slot, the smallest binding), or [`Error::TooLarge`] when a field does not fit one binding
/// of `gpu`.
fn field_bytes(gpu: &Gpu, n: u32, slots: u32, engine: &str) -> Result<u64> {
    let max = gpu
        .limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size);
    field_bytes_within(max, n, slots).map_err(|limit| Error::TooLarge {
        what: format!(
            "contact history slots per sphere for {n} spheres on the {engine} DEM of {} \
             ({FIELD_BYTES} bytes per field of a slot, each field in one binding of {max} bytes)",
            gpu.info.name
        ),
        got: slots as u64,
        limit,
    })
}

/// [`field_bytes`] for bindings of at most `max` bytes; `Err` the most slots that fit.
fn field_bytes_within(max: u64, n: u32, slots: u32) -> std::result::Result<u64, u64> {
    let bytes = n as u64 * slots as u64 * FIELD_BYTES;
    if bytes > max {
        return Err(max / (n as u64 * FIELD_BYTES).max(1));
    }
    Ok(bytes.max(FIELD_BYTES))
}

/// `history` laid out in `slots` slots per sphere, and the count of each.
fn lay_out(history: &ContactHistory, n: usize, slots: usize) -> Result<(Columns, Vec<u32>)> {
    let mut columns = Columns::empty(n * slots, n)?;
    let mut held = try_vec(n, || format!("the contact history of {n} spheres"))?;
    for i in 0..n {
        let own = history.of(i);
        for (s, e) in own.iter().enumerate() {
            columns.set(i * slots + s, e);
        }
        held.push(own.len() as u32);
    }
    Ok((columns, held))
}

/// The owner-only history of the GPU (`held[i]` slots of sphere i from slot i·slots on) in the
/// cpu's layout: each sphere pair also in the partner's slots, springs negated (unless the
/// partner holds it already, as an uploaded history does before the first step).
fn both_sides(n: usize, slots: usize, held: &[u32], columns: &Columns) -> Result<ContactHistory> {
    let own = |i: usize| (i * slots..i * slots + held[i] as usize).map(|s| columns.get(s));
    let mut contacts = Vec::new();
    for i in 0..n {
        for e in own(i) {
            contacts.push((i as u32, e));
            let j = e.partner;
            if j < FIRST_WALL && !own(j as usize).any(|back| back.partner == i as u32) {
                let negated = HistoryEntry {
                    partner: i as u32,
                    tangential: e.tangential.map(|x| -x),
                    rolling: e.rolling.map(|x| -x),
                };
                contacts.push((j, negated));
            }
        }
    }
    ContactHistory::from_contacts(n, &contacts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(partner: u32, x: f32) -> HistoryEntry {
        HistoryEntry {
            partner,
            tangential: [x, 0.0, 0.0],
            rolling: [0.0, x, 0.0],
        }
    }

    fn columns(entries: &[HistoryEntry]) -> Columns {
        let mut c = Columns::empty(entries.len(), 1).unwrap();
        for (s, e) in entries.iter().enumerate() {
            c.set(s, e);
        }
        c
    }

    #[test]
    fn the_history_of_20m_spheres_fits_the_bindings_of_an_h100() {
        // wgpu's largest storage binding on the H100 (docs/PERFORMANCE.md).
        let max = 2_147_483_644;
        let n = 20_000_000;
        assert_eq!(field_bytes_within(max, n, FIRST_SLOTS), Ok(1_280_000_000));
        // Grown by a quarter from 20 contacts, as a settled pile's worst sphere may need.
        assert!(field_bytes_within(max, n, 25).is_ok());
        assert_eq!(field_bytes_within(max, n, 27), Err(26));
        assert_eq!(field_bytes_within(max, 0, 0), Ok(FIELD_BYTES));
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
        let h = both_sides(3, slots, &[2, 1, 1], &columns(&entries)).unwrap();
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
        let (laid_out, held) = lay_out(&h, 2, 4).unwrap();
        assert_eq!(held, [0, 2]);
        assert_eq!(
            [laid_out.get(4), laid_out.get(5)],
            [entry(0, 1.0), entry(FIRST_WALL, 2.0)]
        );
        assert_eq!(laid_out.get(6), HistoryEntry::default());
        assert_eq!(
            both_sides(2, 4, &held, &laid_out).unwrap().of(0),
            &[entry(1, -1.0)]
        );
    }
}
