//! The contact law as the GPU steps read it: one block of parameters, [`LawParams`], laid out
//! once for every device copy of the law (`LawParams` in `wgsl/dem/dem_params.wgsl`, checked by
//! `tests/bindings.rs`; in `optix/physics.cuh`, checked by the CUDA layout asserts of
//! `src/engines/optix/launches.rs`), and the law's code on the devices, [`LawCode`].

use super::StepParams;
use super::material::NormalLaw;
use super::materials::PairLaw;
use crate::gpu::shader::Vec3f;
use bytemuck::{Pod, Zeroable};

/// The normal law's code on the devices (`LAW_*` in `wgsl/dem/dem_contact.wgsl`, `MOCHI_LAW_*` in
/// `optix/contact.cuh`): the one place its numbers are given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum LawCode {
    /// [`NormalLaw::Linear`].
    Linear = 0,
    /// [`NormalLaw::LinearPerPair`].
    LinearPerPair = 1,
    /// [`NormalLaw::Hertz`].
    Hertz = 2,
}

impl NormalLaw {
    /// The law's code on the devices ([`LawCode`]).
    pub fn code(&self) -> u32 {
        let code = match self {
            NormalLaw::Linear => LawCode::Linear,
            NormalLaw::LinearPerPair { .. } => LawCode::LinearPerPair,
            NormalLaw::Hertz { .. } => LawCode::Hertz,
        };
        code as u32
    }
}

/// A GPU step's parameters: the box, gravity and time step, and the contact law with its
/// models, the material table's shape and the contact history's layout. One value per step,
/// written whole: the wgpu engines bind it as a uniform, the optix engine passes it by value.
/// Plain `#[repr(C)]` data whose `vec3`s take 16 bytes with the scalar that follows, as WGSL
/// lays out a uniform, so both device copies read the same bytes.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable, encase::ShaderType)]
pub struct LawParams {
    /// Lower corner of the box \[m\].
    pub box_lo: Vec3f,
    /// Spheres stepped.
    pub n: u32,
    /// Upper corner of the box \[m\].
    pub box_hi: Vec3f,
    /// Invocations per dispatch row of a 256-wide wgpu kernel (unused by the optix step).
    pub row: u32,
    /// Gravity at t = 0 \[m/s²\].
    pub gravity: Vec3f,
    /// Time step \[s\].
    pub dt: f32,
    /// The linear law's stiffness \[N/m\].
    pub stiffness: f32,
    /// The first material's damping ratio (the paper's law).
    pub damping_ratio: f32,
    /// Rate at which gravity turns about the y axis \[rad/s\].
    pub gravity_spin: f32,
    /// [`LawCode`].
    pub law: u32,
    /// [`RollingModel::code`](super::RollingModel::code).
    pub rolling_model: u32,
    /// 1 where any contact exerts a torque.
    pub turns: u32,
    /// History slots per sphere (0: contacts keep no springs).
    pub slots: u32,
    /// History rows one entry binding of a wgpu engine holds (at least 1 where `slots` is not
    /// 0; unused by the optix step).
    pub spheres_per_part: u32,
    /// Laws in a row of the material table: the materials and a rigid wall.
    pub columns: u32,
    /// The table's column of the six box walls.
    pub box_column: u32,
    /// How far past touching a contact may hold \[m\] ([`StepParams::search_margin`] of the
    /// largest radius; 0 where contacts do not adhere): the searches widen by it.
    pub reach: f32,
    /// 1 while some sphere has an external load (the stepper's `ExternalLoads`): the
    /// integration reads them only then.
    pub loaded: u32,
    /// The law of two spheres of the first material (the table's row 0, column 0): with one
    /// material every pair's.
    pub sphere_law: PairLaw,
}
// 128 bytes: a uniform that grew to 144 cost the paper's integration on the H200 (the cohesion
// laws' parameters live apart, in `CohesionParams`).
const _: () = assert!(size_of::<LawParams>() == 128, "the device copies' size");

/// The cohesion laws that are the step's, not a material pair's, as the devices read them:
/// [`Bridge`](super::Bridge) (a volume of 0: no bridges) and the cohesion energy density. Apart
/// from [`LawParams`], so that a dry step's parameters stay as small as they were: the wgpu
/// granular steps bind it as a uniform of its own (`cohesion` in `wgsl/dem/dem_contact.wgsl`),
/// the optix step passes it in its law (`MochiLaw` in `optix/contact.cuh`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable, encase::ShaderType)]
pub struct CohesionParams {
    /// Liquid volume V of a bridge \[m³\] (0: no liquid bridges).
    pub bridge_volume: f32,
    /// γ·cos θ of two spheres of the first material \[N/m\] (the table's first
    /// [`PairBridge`](super::materials::PairBridge): with one material every pair's, which the
    /// wgpu steps then read here rather than in the table).
    pub bridge_tension: f32,
    /// The gap at which their bridge ruptures \[m\] (as `bridge_tension`).
    pub bridge_rupture: f32,
    /// The cohesion energy density of LIGGGHTS' simplified JKR \[J/m³\] (0: none).
    pub density: f32,
    /// The bridges' liquid viscosity η \[Pa·s\] (0: no lubrication force).
    pub bridge_viscosity: f32,
}

/// `$check!("CohesionParams", CohesionParams { every field })`: the one list of
/// [`CohesionParams`]' fields, for the WGSL and the CUDA layout checks.
macro_rules! cohesion_params_fields {
    ($check:ident, $cuda:literal) => {
        $check!(
            $cuda,
            CohesionParams {
                bridge_volume,
                bridge_tension,
                bridge_rupture,
                density,
                bridge_viscosity,
            }
        )
    };
}
pub(crate) use cohesion_params_fields;

impl CohesionParams {
    /// The cohesion laws of `p`.
    pub fn of(p: &StepParams) -> Self {
        Self {
            bridge_volume: p.bridge.map_or(0.0, |b| b.volume),
            bridge_tension: p.materials.bridge(0, 0).tension,
            bridge_rupture: p.materials.bridge(0, 0).rupture,
            density: p.cohesion_density,
            bridge_viscosity: p.bridge.map_or(0.0, |b| b.viscosity),
        }
    }
}

impl crate::gpu::shader::FirstWord for CohesionParams {
    fn first_word(&self) -> u32 {
        self.bridge_volume.to_bits()
    }
}

/// `$check!("LawParams", LawParams { every field })`: the one list of [`LawParams`]' fields,
/// which the WGSL layout check (`shared_struct!`, whose pattern fails to compile for a field
/// it does not list) and the CUDA one (`cuda_layout!`) both take.
macro_rules! law_params_fields {
    ($check:ident) => {
        $check!(
            "LawParams",
            LawParams {
                box_lo,
                n,
                box_hi,
                row,
                gravity,
                dt,
                stiffness,
                damping_ratio,
                gravity_spin,
                law,
                rolling_model,
                turns,
                slots,
                spheres_per_part,
                columns,
                box_column,
                reach,
                loaded,
                sphere_law,
            }
        )
    };
}
pub(crate) use law_params_fields;

impl LawParams {
    /// The parameters of a step with `p` over `n` spheres, dispatched in rows of `row`
    /// invocations, its contacts keeping no history (see [`with_history`](Self::with_history)).
    pub fn new(p: &StepParams, n: u32, row: u32) -> Self {
        let f = &p.friction;
        Self {
            box_lo: p.box_lo.into(),
            n,
            box_hi: p.box_hi.into(),
            row,
            gravity: p.gravity.into(),
            dt: p.dt,
            stiffness: p.stiffness,
            damping_ratio: p.damping_ratio,
            gravity_spin: p.gravity_spin,
            law: p.law.code(),
            rolling_model: f.rolling_model.code(),
            turns: f.turns() as u32,
            slots: 0,
            spheres_per_part: 0,
            columns: p.materials.count as u32 + 1,
            box_column: p.box_column,
            reach: 0.0,
            loaded: 0,
            sphere_law: *p.materials.law(0, 0),
        }
    }

    /// These parameters with a contact history of `slots` slots per sphere, `spheres_per_part`
    /// rows to an entry binding.
    pub fn with_history(self, slots: u32, spheres_per_part: u32) -> Self {
        Self {
            slots,
            spheres_per_part,
            ..self
        }
    }

    /// These parameters for spheres of radii up to `r_max`: with the reach of the contacts
    /// that adhere ([`StepParams::search_margin`]).
    pub fn reaching(self, p: &StepParams, r_max: f32) -> Self {
        Self {
            reach: p.search_margin(r_max),
            ..self
        }
    }

    /// Whether contacts carry springs from one step to the next.
    pub fn keeps(&self) -> bool {
        self.slots != 0
    }
}

#[cfg(test)]
mod tests {
    use super::LawCode;
    use crate::dem::model::RollingModel;
    use crate::gpu::shader::wgsl;

    #[test]
    fn the_device_codes_are_the_kernels() {
        let wgsl = wgsl!("dem/dem_contact.wgsl");
        let cuda = include_str!("../../../optix/contact.cuh");
        let laws = [
            ("LAW_LINEAR", "MOCHI_LAW_LINEAR", LawCode::Linear as u32),
            (
                "LAW_PER_PAIR",
                "MOCHI_LAW_LINEAR_PER_PAIR",
                LawCode::LinearPerPair as u32,
            ),
            ("LAW_HERTZ", "MOCHI_LAW_HERTZ", LawCode::Hertz as u32),
        ];
        let rolling = [
            ("ROLLING_EPSD", "MOCHI_ROLLING_EPSD", RollingModel::Epsd),
            (
                "ROLLING_CONSTANT_TORQUE",
                "MOCHI_ROLLING_CONSTANT_TORQUE",
                RollingModel::ConstantTorque,
            ),
        ]
        .map(|(w, c, model)| (w, c, model.code()));
        for (in_wgsl, in_cuda, code) in laws.into_iter().chain(rolling) {
            let declared = format!("const {in_wgsl}: u32 = {code}u;");
            assert!(
                wgsl.contains(&declared),
                "wgsl/dem/dem_contact.wgsl: {declared}"
            );
            let defined = format!("#define {in_cuda} {code}u");
            assert!(cuda.contains(&defined), "optix/contact.cuh: {defined}");
        }
    }
}
