//! The GPU state of the granular step (`wgsl/dem_contact.wgsl`, `wgsl/dem_granular.wgsl`),
//! shared by the wgpu engines: angular velocities and torque accumulators by stable id, and the
//! contact history (docs/method.md, "Contact history"): K slots per sphere indexed by stable id,
//! each contact kept by its owner only, in two buffers that swap roles every step. The engine
//! keeps its own state (positions, velocities, the order of its spheres); this module saves
//! both at the start of a batch, so that a batch in which some sphere had more contacts than K
//! is redone from that state with K grown: no contact is ever dropped.

use super::gpu_step::granular::{
    GRANULAR, GranularParams, HELD_NEW, HELD_OLD, HISTORY_NEED, HISTORY_NEW, HISTORY_OLD, OMEGA,
    TORQUE,
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
/// table, the ids, forces, counters, spins, torques, two histories and their counts, the need).
const STORAGE_BUFFERS: u32 = 13;

/// What the granular step adds to the particles a GPU step reads back.
pub(crate) struct Rotation {
    /// Angular velocities, in input order \[rad/s\].
    pub angular_velocities: Vec<[f32; 3]>,
    /// The contact history in the cpu's layout (both sides of each pair).
    pub history: ContactHistory,
}

/// The granular step's buffers beyond the paper's.
pub(crate) struct Granular {
    params: GranularParams,
    uniform: wgpu::Buffer,
    /// `vec4(ω, 0)` by stable id.
    omega: wgpu::Buffer,
    /// Torque accumulators by stable id (zero between steps).
    torque: wgpu::Buffer,
    /// History slots, `params.slots` per sphere by stable id: the old ones of a step of parity
    /// k are `history[k]`, its new ones `history[1 - k]`.
    history: [wgpu::Buffer; 2],
    /// Contacts held per sphere, by stable id, beside `history`.
    held: [wgpu::Buffer; 2],
    /// The most contacts with history any sphere had in the batch.
    need: wgpu::Buffer,
    /// Copies of the state at the start of the batch (with history only): the old history and
    /// its counts, the angular velocities, then the engine's own buffers.
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
    /// their history uploaded as the old history of a
    /// step of parity 0 (the cpu's layout, both sides of each pair, is usable as it is: each
    /// owner finds its own entry first).
    pub fn new(
        gpu: &Gpu,
        particles: &Particles,
        params: &StepParams,
        engine: &'static str,
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
        let history_bytes = history_bytes(gpu, n, slots, engine)?;
        let none = wgpu::BufferUsages::empty();
        let label = |what: &str| format!("mochi.dem.{engine}.{what}");
        let make = |what: &str, bytes: u64| gpu.storage(&label(what), bytes, none);
        let granular = gpu.checked("allocating the granular step's buffers", || Self {
            params: gpu_params,
            uniform: gpu.uniform(&label("granular"), &gpu_params),
            omega: make("omega", n64 * 16),
            torque: make("torque", n64 * 12),
            history: [
                make("history0", history_bytes),
                make("history1", history_bytes),
            ],
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
            .write_buffer(&granular.omega, 0, bytemuck::cast_slice(&omega));
        if keeps {
            let (entries, held) = lay_out(&particles.history, n as usize, slots as usize)?;
            gpu.queue
                .write_buffer(&granular.history[0], 0, bytemuck::cast_slice(&entries));
            gpu.queue
                .write_buffer(&granular.held[0], 0, bytemuck::cast_slice(&held));
        }
        Ok(granular)
    }

    /// Bindings of the resolve kernel of a step of parity `parity`.
    pub fn resolve_bindings(&self, parity: usize) -> [(Binding, &wgpu::Buffer); 8] {
        [
            (GRANULAR, &self.uniform),
            (OMEGA, &self.omega),
            (TORQUE, &self.torque),
            (HISTORY_OLD, &self.history[parity]),
            (HELD_OLD, &self.held[parity]),
            (HISTORY_NEW, &self.history[1 - parity]),
            (HELD_NEW, &self.held[1 - parity]),
            (HISTORY_NEED, &self.need),
        ]
    }

    /// Bindings of the integration kernel.
    pub fn integrate_bindings(&self) -> [(Binding, &wgpu::Buffer); 3] {
        [
            (GRANULAR, &self.uniform),
            (OMEGA, &self.omega),
            (TORQUE, &self.torque),
        ]
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
        let sources: Vec<&wgpu::Buffer> = [&self.history[parity], &self.held[parity], &self.omega]
            .into_iter()
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
        let bytes = history_bytes(gpu, self.n, slots, engine)?;
        let saved: Vec<HistoryEntry> = gpu.read(&self.saved[0], n * old_k)?;
        let held: Vec<u32> = gpu.read(&self.saved[1], n)?;
        let k = slots as usize;
        let mut entries = try_vec(n * k, || format!("the contact history of {n} spheres"))?;
        entries.resize(n * k, HistoryEntry::default());
        for i in 0..n {
            let c = held[i] as usize;
            entries[i * k..i * k + c].copy_from_slice(&saved[i * old_k..i * old_k + c]);
        }
        let none = wgpu::BufferUsages::empty();
        self.history = gpu.checked("allocating the contact history", || {
            [0, 1].map(|b| gpu.storage(&format!("mochi.dem.{engine}.history{b}"), bytes, none))
        })?;
        self.params.slots = slots;
        gpu.write_uniform(&self.uniform, &self.params);
        gpu.queue
            .write_buffer(&self.history[parity], 0, bytemuck::cast_slice(&entries));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.saved[1], 0, &self.held[parity], 0, n as u64 * 4);
        let targets = [&self.omega].into_iter().chain(state.iter().copied());
        for (from, to) in self.saved[2..].iter().zip(targets) {
            encoder.copy_buffer_to_buffer(from, 0, to, 0, from.size());
        }
        gpu.checked("restoring the state of a batch", || {
            gpu.queue.submit([encoder.finish()])
        })?;
        Ok(())
    }

    /// The angular velocities (input order) and the history in the cpu's layout, after a step
    /// of parity `1 - parity` (the history of parity `parity` is the one the next step reads).
    pub fn read(&self, gpu: &Gpu, parity: usize) -> Result<Rotation> {
        let n = self.n as usize;
        let omega: Vec<[f32; 4]> = gpu.read(&self.omega, n)?;
        let angular_velocities = omega.iter().map(|w| [w[0], w[1], w[2]]).collect();
        let history = if self.keeps_history() {
            let k = self.params.slots as usize;
            let held: Vec<u32> = gpu.read(&self.held[parity], n)?;
            let entries: Vec<HistoryEntry> = gpu.read(&self.history[parity], n * k)?;
            both_sides(n, k, &held, &entries)?
        } else {
            self.given.clone()
        };
        Ok(Rotation {
            angular_velocities,
            history,
        })
    }
}

/// Bytes of the history of `n` spheres with `slots` slots each (at least one entry, the
/// smallest binding), or [`Error::TooLarge`] when they do not fit one binding of `gpu`.
fn history_bytes(gpu: &Gpu, n: u32, slots: u32, engine: &str) -> Result<u64> {
    let row = size_of::<HistoryEntry>() as u64;
    let max = gpu
        .limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size);
    let bytes = n as u64 * slots as u64 * row;
    if bytes > max {
        return Err(Error::TooLarge {
            what: format!(
                "contact history slots per sphere for {n} spheres on the {engine} DEM of {} \
                 ({row} bytes each, in one binding of {max} bytes)",
                gpu.info.name
            ),
            got: slots as u64,
            limit: max / (n as u64 * row).max(1),
        });
    }
    Ok(bytes.max(row))
}

/// `history` laid out in `slots` slots per sphere, and the count of each.
fn lay_out(
    history: &ContactHistory,
    n: usize,
    slots: usize,
) -> Result<(Vec<HistoryEntry>, Vec<u32>)> {
    let what = || format!("the contact history of {n} spheres");
    let mut entries = try_vec(n * slots, what)?;
    entries.resize(n * slots, HistoryEntry::default());
    let mut held = try_vec(n, what)?;
    for i in 0..n {
        let own = history.of(i);
        entries[i * slots..i * slots + own.len()].copy_from_slice(own);
        held.push(own.len() as u32);
    }
    Ok((entries, held))
}

/// The owner-only history of the GPU (`held[i]` entries of sphere i in `entries[i·slots..]`)
/// in the cpu's layout: each sphere pair also in the partner's slots, springs negated (unless
/// the partner holds it already, as an uploaded history does before the first step).
fn both_sides(
    n: usize,
    slots: usize,
    held: &[u32],
    entries: &[HistoryEntry],
) -> Result<ContactHistory> {
    let own = |i: usize| &entries[i * slots..i * slots + held[i] as usize];
    let mut contacts = Vec::new();
    for i in 0..n {
        for e in own(i) {
            contacts.push((i as u32, *e));
            let j = e.partner;
            if j < FIRST_WALL && !own(j as usize).iter().any(|back| back.partner == i as u32) {
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

    #[test]
    fn owner_only_entries_read_back_on_both_sides() {
        // Sphere 0 owns its contact with 2 and a wall; sphere 1 and 2 hold both sides of theirs.
        let slots = 3;
        let mut entries = vec![HistoryEntry::default(); 3 * slots];
        entries[0] = entry(2, 1.0);
        entries[1] = entry(FIRST_WALL + 4, 2.0);
        entries[slots] = entry(2, 3.0);
        entries[2 * slots] = entry(1, -3.0);
        let h = both_sides(3, slots, &[2, 1, 1], &entries).unwrap();
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
        let (entries, held) = lay_out(&h, 2, 4).unwrap();
        assert_eq!(held, [0, 2]);
        assert_eq!(entries[4..6], [entry(0, 1.0), entry(FIRST_WALL, 2.0)]);
        assert_eq!(
            both_sides(2, 4, &held, &entries).unwrap().of(0),
            &[entry(1, -1.0)]
        );
    }
}
