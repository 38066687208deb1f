//! What the wgpu DEM steps share: the physics modules (`wgsl/dem/dem_params.wgsl`, its bindings
//! and parameter block, and the physics of the step's two variants: the paper's law,
//! `wgsl/dem/dem_physics.wgsl`, or the granular step's, [`granular`]), the choice of force
//! atomics and per-phase timestamps (the state's rows, which optix shares, are
//! `engines::common::rows`).

use crate::dem::model::{LawParams, NormalLaw, StepParams};
use crate::dem::stepper::{StageTimes, needs_granular_step};
use crate::dem::walls::WallSet;
use crate::engines::common::flow::Room;
pub(crate) use crate::engines::wgpu::granular::{
    BatchParts, Granular, RedoableBatch, Turn, run_batch,
};
use crate::engines::wgpu::state::ParamsUniform;
use crate::error::{Error, Result};
use crate::gpu::Gpu;
use crate::gpu::shader::{SharedStruct, shared_struct, wgsl};
use crate::gpu::timer::GpuTimer;
use crate::particles::Particles;

/// The physics shared by the GPU steps (`wgsl/dem/dem_params.wgsl` and, for the paper's law,
/// `wgsl/dem/dem_physics.wgsl`, integration kernel included) and its force accumulators: the
/// bindings it adds to the step module it ends.
pub(crate) mod physics {
    use super::Accumulators;
    use crate::engines::wgpu::granular::shader;
    use crate::gpu::shader::Binding;
    use crate::gpu::shader::wgsl;

    /// `wgsl/dem/dem_params.wgsl`: parameters, state bindings and gravity, for both variants.
    pub const PARAMS: &str = wgsl!("dem/dem_params.wgsl");
    /// `wgsl/dem/dem_physics.wgsl`: the paper's law (one stiffness, or one per pair).
    pub const LINEAR: &str = wgsl!("dem/dem_physics.wgsl");
    /// `wgsl/dem/dem_integrate.wgsl`: the integration kernel of both.
    pub const INTEGRATE: &str = wgsl!("dem/dem_integrate.wgsl");

    /// Float atomics (SHADER_FLOAT32_ATOMIC).
    pub(super) const F32: Accumulators = Accumulators {
        force: wgsl!("dem/dem_force_f32.wgsl"),
        torque: wgsl!("dem/dem_torque_f32.wgsl"),
    };
    /// Compare-and-swap loops on the bit patterns.
    pub(super) const CAS: Accumulators = Accumulators {
        force: wgsl!("dem/dem_force_cas.wgsl"),
        torque: wgsl!("dem/dem_torque_cas.wgsl"),
    };

    /// Both kinds of accumulators, by label suffix.
    pub const FORCE_VARIANTS: [(&str, Accumulators); 2] = [("f32", F32), ("cas", CAS)];

    /// The physics that ends the paper's step module, with the accumulators `atomics`.
    pub fn frictionless(atomics: Accumulators) -> String {
        format!("{PARAMS}{LINEAR}{INTEGRATE}{}", atomics.force)
    }

    /// The physics that ends the granular step module, with the accumulators `atomics`, under
    /// the tangential model of `variant` (the granular one or its Mindlin–Deresiewicz twin).
    pub fn granular(atomics: Accumulators, variant: super::Variant) -> String {
        let (contact, state) = (shader::CONTACT, shader::STATE);
        let tangential = match variant {
            super::Variant::Loaded => shader::LOAD_HISTORY,
            _ => shader::SPRING,
        };
        let walls = crate::engines::wgpu::walls::SOURCE;
        let clumps = crate::engines::wgpu::clumps::shader::SOURCE;
        format!(
            "{PARAMS}{tangential}{contact}{state}{walls}{clumps}{}{}",
            atomics.force, atomics.torque
        )
    }

    pub const DEM: Binding = Binding::uniform(1, "dem");
    pub const POS: Binding = Binding::read_write(10, "pos");
    pub const VEL: Binding = Binding::read_write(11, "vel");
    /// Declared by the force accumulator (`dem_force_*.wgsl`).
    pub const FORCE: Binding = Binding::read_write(13, "force");
    pub const CLOCK: Binding = Binding::read_write(16, "clock");
    /// The residuals of the centres `pos` holds (`Particles::position_residuals`), which only
    /// the integration and the passes that move the state bind.
    pub const POS_LO: Binding = Binding::read_write(34, "pos_lo");
    /// The external loads by stable id, which only the integration binds.
    pub const EXTERNAL: Binding = Binding::read(36, "external_loads");
    pub const BINDINGS: &[Binding] = &[DEM, POS, VEL, FORCE, CLOCK, POS_LO, EXTERNAL];
}

/// Which physics a wgpu engine's DEM step runs, each in a module of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Variant {
    /// The paper's law (`wgsl/dem/dem_physics.wgsl`): one stiffness, no friction, no rotation.
    Paper,
    /// The paper's kernels with the stiffness of each pair from its effective mass
    /// (`wgsl/dem/dem_physics.wgsl` with `PER_PAIR`): `stiffness = "per-pair"` without friction,
    /// rolling resistance, spin, history or a second material.
    PerPair,
    /// The granular step ([`Granular`]) with Mindlin's spring.
    Granular,
    /// The granular step under the Mindlin–Deresiewicz tangential model: its law, and its load
    /// history in entries of twice the size (`wgsl/dem/dem_tangential_md.wgsl`).
    Loaded,
}

impl Variant {
    /// The lightest variant that steps `particles` with `params` as the cpu step does.
    pub fn of(particles: &Particles, params: &StepParams, walls: &WallSet) -> Self {
        if !needs_granular_step(particles, params, walls) {
            return Variant::Paper;
        }
        let frictionless = !params.friction.turns()
            && !params.adheres()
            && !particles.spin()
            && particles.history.is_empty()
            && walls.is_box_only()
            && params.materials.count == 1;
        match params.law {
            NormalLaw::LinearPerPair { .. } if frictionless => Variant::PerPair,
            _ if params.friction.keeps_load() => Variant::Loaded,
            _ => Variant::Granular,
        }
    }

    /// Whether it is a variant of the granular step.
    pub fn granular(self) -> bool {
        matches!(self, Variant::Granular | Variant::Loaded)
    }
}

/// Workgroup size of every 256-wide kernel of the steps (as in the shaders).
pub(crate) const GROUP: u32 = 256;

/// Most steps recorded into one submission (and timed by one query set).
pub(crate) const MAX_BATCH: u32 = 200;

/// [`LawParams`] as a [`SharedStruct`] (`LawParams` in `wgsl/dem/dem_params.wgsl`).
fn law_params() -> SharedStruct {
    crate::dem::model::law::law_params_fields!(shared_struct)
}

/// [`LawParams`] with the struct it holds, as [`SharedStruct`]s: what every DEM module checks.
pub(crate) fn law_structs() -> [SharedStruct; 2] {
    [law_params(), pair_law()]
}

/// [`CohesionParams`](crate::dem::model::law::CohesionParams), the granular modules'
/// `cohesion` uniform, as a [`SharedStruct`].
pub(crate) fn cohesion_params() -> SharedStruct {
    use crate::dem::model::law::CohesionParams;
    crate::dem::model::law::cohesion_params_fields!(shared_struct, "CohesionParams")
}

/// The material table's entries as the granular modules bind them (`material_laws` of
/// `wgsl/dem/dem_contact.wgsl`): [`TableLaw`](crate::dem::model::TableLaw) and the
/// [`PairBridge`](crate::dem::model::PairBridge) it holds, as [`SharedStruct`]s.
pub(crate) fn material_table() -> [SharedStruct; 2] {
    use crate::dem::model::{PairBridge, TableLaw};
    [
        crate::dem::model::materials::pair_bridge_fields!(shared_struct, "PairBridge"),
        crate::dem::model::materials::table_law_fields!(shared_struct, "TableLaw"),
    ]
}

/// [`PairLaw`](crate::dem::model::PairLaw), the law of an entry of the material table and
/// `LawParams::sphere_law`, as a [`SharedStruct`].
fn pair_law() -> SharedStruct {
    use crate::dem::model::PairLaw;
    crate::dem::model::materials::pair_law_fields!(shared_struct, "PairLaw")
}

/// The WGSL of one kind of force and torque accumulators.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Accumulators {
    /// `wgsl/dem_force_*.wgsl`.
    pub force: &'static str,
    /// `wgsl/dem_torque_*.wgsl` (granular step only).
    pub torque: &'static str,
}

/// Which kernels a GPU step runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelSet {
    /// Float atomics and subgroup operations where the adapter has them.
    Auto,
    /// Those any adapter runs: compare-and-swap loops on the bit patterns for the forces, and
    /// every thread a subgroup of its own.
    Portable,
}

impl KernelSet {
    /// The accumulators' WGSL for `gpu` and their name, in words, and how threads share work
    /// with their subgroup.
    pub(crate) fn pick(self, gpu: &Gpu) -> (&'static str, Accumulators, Lanes) {
        let features = gpu.device.features();
        let auto = self == KernelSet::Auto;
        let lanes = if auto && features.contains(wgpu::Features::SUBGROUP) {
            Lanes::Subgroups
        } else {
            Lanes::Single
        };
        if auto && features.contains(wgpu::Features::SHADER_FLOAT32_ATOMIC) {
            ("float atomics", physics::F32, lanes)
        } else {
            ("compare-and-swap", physics::CAS, lanes)
        }
    }
}

/// How a kernel's threads share work with the other lanes of their subgroup
/// (`wgsl/core/lanes_subgroups.wgsl`, `wgsl/core/lanes_single.wgsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Lanes {
    /// On subgroup operations (wgpu's SUBGROUP feature).
    Subgroups,
    /// Every thread a subgroup of one lane (any adapter).
    Single,
}

impl Lanes {
    /// Both, by label suffix.
    pub const ALL: [(&'static str, Lanes); 2] =
        [("", Lanes::Subgroups), ("_single", Lanes::Single)];

    /// The WGSL that defines `Lanes` and its functions.
    pub fn source(self) -> &'static str {
        match self {
            Lanes::Subgroups => wgsl!("core/lanes_subgroups.wgsl"),
            Lanes::Single => wgsl!("core/lanes_single.wgsl"),
        }
    }
}

/// GPU timestamps of a batch of steps: the four phase boundaries (start, built, resolved,
/// integrated) of each of its first *profiled* steps, then the batch's end, in the slots of one
/// [`GpuTimer`]. A step's phases are told apart only by recording them in passes of their own
/// between timestamps, and every pass boundary and timestamp costs the GPU time
/// (docs/performance-log/). So a stepper may profile only its batch's first step and record the
/// others in one compute pass; [`read`](Self::read) then splits the batch's whole time in the
/// profiled steps' proportions.
pub(crate) struct StepTimer(GpuTimer);

impl StepTimer {
    /// A timer, or `None` where the device cannot write timestamps inside encoders.
    pub fn new(gpu: &Gpu) -> Option<Self> {
        GpuTimer::with_slots(gpu, "mochi.dem.timer", 4 * MAX_BATCH + 1).map(StepTimer)
    }

    /// Marks phase boundary `k` (0..4) of profiled step `s` of the batch (step 0 first).
    pub fn mark(timer: Option<&Self>, encoder: &mut wgpu::CommandEncoder, s: u32, k: u32) {
        if let Some(t) = timer {
            t.0.mark(encoder, 4 * s + k);
        }
    }

    /// Marks the end of a batch whose first `profiled` steps (at least one) were marked, in
    /// the slot after theirs, and records the resolve of its timestamps.
    pub fn end(&self, encoder: &mut wgpu::CommandEncoder, profiled: u32) {
        self.0.mark(encoder, 4 * profiled);
        self.0.resolve(encoder, 0..4 * profiled + 1);
    }

    /// The phase times of the last batch (after it completed): see [`phases`](Self::phases).
    pub fn read(&self, gpu: &Gpu, profiled: u32) -> Result<StageTimes> {
        let ticks = self.0.ticks(gpu, 0..4 * profiled + 1)?;
        Ok(Self::phases(gpu, &ticks, profiled, 1.0))
    }

    /// Records a copy of a batch's ticks (after [`end`](Self::end)) into `dst` at `offset`:
    /// [`ticks_bytes`](Self::ticks_bytes) bytes for [`phases`](Self::phases).
    pub fn copy_ticks(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiled: u32,
        dst: &wgpu::Buffer,
        offset: u64,
    ) {
        self.0.copy_ticks(encoder, 0..4 * profiled + 1, dst, offset);
    }

    /// Bytes of the ticks of a batch with `profiled` marked steps.
    pub const fn ticks_bytes(profiled: u32) -> u64 {
        (4 * profiled as u64 + 1) * 8
    }

    /// The phase times of a batch from its `ticks`: its whole time, from the first step's
    /// start to its end, split in the proportions of its `profiled` steps' phases, their builds
    /// weighed by `build_share` (1 where every step builds as they did; the share of the steps
    /// that re-binned where only those did, the profiled ones among them).
    pub fn phases(gpu: &Gpu, ticks: &[u64], profiled: u32, build_share: f64) -> StageTimes {
        let marks = 4 * profiled as usize;
        let period = GpuTimer::ms_per_tick(gpu);
        let span = |a: u64, b: u64| b.saturating_sub(a) as f64 * period;
        let mut phases = StageTimes::default();
        for t in ticks[..marks].chunks_exact(4) {
            phases.build_ms += span(t[0], t[1]) * build_share;
            phases.dcd_ms += span(t[1], t[2]);
            phases.update_ms += span(t[2], t[3]);
        }
        let whole = span(ticks[0], ticks[marks]);
        let scale = whole / phases.total_ms().max(f64::MIN_POSITIVE);
        StageTimes {
            build_ms: phases.build_ms * scale,
            dcd_ms: phases.dcd_ms * scale,
            update_ms: phases.update_ms * scale,
        }
    }
}

/// What opening a wgpu engine's DEM step compiles: the accumulators chosen, the state of the
/// variant the scene needs ([`Variant::of`]), and the step's module in that variant.
pub(crate) struct DemModule {
    /// The accumulators, in words (for `describe`).
    pub atomics: &'static str,
    /// The granular step's state (`None`: a variant of the paper's step).
    pub granular: Option<Granular>,
    /// The step's parameters ([`LawParams`], its history's layout included), for its spheres
    /// at the start; the engine sets the count and the dispatch rows.
    pub params: ParamsUniform,
    /// The step's WGSL, compiled.
    pub module: crate::gpu::Module,
    /// The values of its `override` constants its pipelines take ([`Gpu::pipeline_with`]).
    pub constants: Vec<(&'static str, f64)>,
}

impl DemModule {
    /// Refuses room for more than `limit` spheres ([`Error::TooLarge`], naming `backend` and
    /// the adapter) and spheres of materials the table lacks, picks the accumulators and the
    /// variant, opens its state (the granular one for an engine with `sets` state sets of room
    /// for `capacity` spheres, at least the particles', see [`Granular::new`]) and the step's
    /// parameters ([`LawParams`], with the history's layout), and compiles
    /// `source(accumulators, lanes, variant)` with the variant's constants.
    #[allow(clippy::too_many_arguments)]
    pub fn open(
        gpu: &Gpu,
        backend: &'static str,
        particles: &Particles,
        params: &StepParams,
        walls: &WallSet,
        limit: u64,
        (sets, room): (usize, Room),
        kernels: KernelSet,
        source: impl FnOnce(Accumulators, Lanes, Variant) -> String,
    ) -> Result<Self> {
        let room = room.holding(particles);
        let n = room.spheres as u64;
        if n > limit {
            return Err(Error::TooLarge {
                what: format!("spheres for the {backend} DEM on {}", gpu.info.name),
                got: n,
                limit,
            });
        }
        particles.check_materials(params.materials.count)?;
        let (atomics, accumulators, lanes) = kernels.pick(gpu);
        let variant = Variant::of(particles, params, walls);
        let granular = variant
            .granular()
            .then(|| Granular::new(gpu, particles, params, walls, backend, (sets, room)))
            .transpose()?;
        let mut law = LawParams::new(params, particles.len() as u32, 0);
        if let Some(g) = &granular {
            law = g.history_layout(law).reaching(params, room.radii.1);
        }
        let params_uniform = ParamsUniform::new(gpu, &format!("mochi.dem.{backend}.params"), law);
        let source = source(accumulators, lanes, variant);
        let module = gpu.own_module(&format!("mochi.dem.{backend}"), &source);
        // The paper's law (wgsl/dem/dem_physics.wgsl) with a stiffness per pair, or the granular
        // step's (wgsl/dem/dem_contact.wgsl) specialised for one material.
        let constants = match variant {
            Variant::PerPair => vec![("PER_PAIR", 1.0)],
            _ if granular.is_some() => [
                ("ONE_MATERIAL", params.materials.count == 1),
                ("COHESIVE", params.adheres()),
                ("VISCOUS", params.bridge.is_some_and(|b| b.viscosity > 0.0)),
            ]
            .into_iter()
            .filter(|(_, on)| *on)
            .chain([("CLUMPED", !particles.clumps.clumps.is_empty())])
            .filter(|(_, on)| *on)
            .map(|(name, _)| (name, 1.0))
            .collect(),
            _ => Vec::new(),
        };
        Ok(DemModule {
            atomics,
            granular,
            params: params_uniform,
            module,
            constants,
        })
    }
}

/// Most spheres a GPU step takes on `gpu` (16-byte rows in one binding, indices in u32).
pub(crate) fn max_spheres(gpu: &Gpu) -> u64 {
    (gpu.limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size)
        / 16)
        .min(u32::MAX as u64 / 4)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::model::{ContactLaw, Material};

    fn two_spheres() -> Particles {
        Particles {
            positions: vec![[0.2; 3], [0.5; 3]],
            velocities: vec![[0.0; 3]; 2],
            angular_velocities: vec![[0.0; 3]; 2],
            radii: vec![0.01; 2],
            ..Particles::default()
        }
    }

    fn params(contact: ContactLaw, friction: f64, rolling_friction: f64) -> StepParams {
        let material = Material {
            contact,
            friction,
            rolling_friction,
            ..Material::default()
        };
        StepParams::new(&material, 1e-5, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, 0.01).unwrap()
    }

    #[test]
    fn a_frictionless_stiffness_per_pair_runs_the_papers_kernels() {
        let per_pair = ContactLaw::LinearPerPair { contact_time: None };
        let spheres = two_spheres();
        let box_only = WallSet::default();
        let variant =
            |p: &Particles, law, mu, mu_r| Variant::of(p, &params(law, mu, mu_r), &box_only);
        assert_eq!(
            variant(&spheres, ContactLaw::Linear, 0.0, 0.0),
            Variant::Paper
        );
        assert_eq!(variant(&spheres, per_pair, 0.0, 0.0), Variant::PerPair);
        // Friction, rolling resistance or a spin need the granular step.
        assert_eq!(variant(&spheres, per_pair, 0.5, 0.0), Variant::Granular);
        assert_eq!(variant(&spheres, per_pair, 0.0, 0.1), Variant::Granular);
        let mut spinning = two_spheres();
        spinning.angular_velocities[1] = [0.0, 1.0, 0.0];
        assert_eq!(variant(&spinning, per_pair, 0.0, 0.0), Variant::Granular);
    }
}
