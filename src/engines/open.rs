//! Opening a backend: its detection ([`BackendKind::open_with`], [`open`]) or its DEM step
//! ([`open_stepper`], [`open_choice`], [`open_scene`]), each through the one opener of its
//! engine ([`Engine`]): the one place that knows how every backend is opened.

use super::common::flow::{DeviceFlow, FlowStep, Reopen};
use super::cpu;
use super::registry::{BackendChoice, BackendKind, Opened, Options, open_auto};
use super::setup::DemSetup;
use super::wgpu::step::KernelSet;
use super::wgpu::{compute as wgpu_compute, rq as wgpu_rq};
use crate::dem::flow::FlowSet;
use crate::dem::model::StepParams;
use crate::dem::scene::Start;
use crate::dem::stepper::Stepper;
use crate::detect::Backend;
use crate::error::{Error, Result};
use crate::gpu::{Gpu, Need};
use crate::particles::Particles;
use crate::proxy::ProxyMode;

/// How one backend is opened: its detection, its DEM step, and its DEM step with spheres
/// flowing in and out.
trait Engine: Sync {
    /// The backend's detection with `options`.
    fn detector(&self, options: &Options) -> Result<Box<dyn Backend>>;

    /// The backend's DEM step of `setup` with `options` (a GPU step with the kernels that
    /// make the most of the adapter).
    fn stepper(&self, setup: DemSetup, options: &Options) -> Result<Box<dyn Stepper>>;

    /// How a flowing run opens this GPU step again over new spheres (each time with room for
    /// those to come), on the device opened now; `setup`'s own spheres are not used.
    fn reopener(&self, setup: DemSetup, options: &Options) -> Result<Reopen>;

    /// The DEM step of `setup` with `options` and spheres flowing by `flow`: a GPU step,
    /// wrapped in a [`FlowStep`] that opens it again at every flow event.
    fn flowing(
        &self,
        setup: DemSetup,
        options: &Options,
        flow: FlowSet,
    ) -> Result<Box<dyn Stepper>> {
        let (dt, densities) = (setup.params.dt, setup.params.materials.densities.clone());
        let (particles, rest) = setup.split();
        let reopen = self.reopener(rest, options)?;
        Ok(Box::new(FlowStep::new(
            particles, flow, dt, densities, reopen,
        )?))
    }
}

/// The engine of backend `kind`: the one table of the backends' openers.
fn engine(kind: BackendKind) -> Result<&'static dyn Engine> {
    Ok(match kind {
        BackendKind::Cpu => &CpuEngine,
        BackendKind::WgpuCompute => &ComputeEngine,
        BackendKind::WgpuRq => &RqEngine,
        #[cfg(feature = "optix")]
        BackendKind::Optix => &OptixEngine,
        #[cfg(not(feature = "optix"))]
        BackendKind::Optix => {
            return Err(Error::BackendUnavailable {
                backend: "optix",
                reason: super::registry::NO_OPTIX_FEATURE.into(),
            });
        }
    })
}

/// The settings of a `wgpu-compute` step of `options`, with the kernels that make the most of
/// the adapter.
fn grid_options(options: &Options) -> wgpu_compute::GridStepOptions {
    wgpu_compute::GridStepOptions {
        kernels: KernelSet::Auto,
        grid_build: options.grid_build,
        structure: options.structure,
    }
}

/// The `cpu` backend, whose step runs its flows itself.
struct CpuEngine;

impl Engine for CpuEngine {
    fn detector(&self, _: &Options) -> Result<Box<dyn Backend>> {
        Ok(Box::new(cpu::CpuBackend::new()))
    }

    fn stepper(&self, setup: DemSetup, _: &Options) -> Result<Box<dyn Stepper>> {
        Ok(Box::new(cpu::CpuStepper::open(setup)?))
    }

    fn reopener(&self, _: DemSetup, _: &Options) -> Result<Reopen> {
        Err(Error::Usage(
            "the cpu step runs its flows itself (CpuStepper::with_flow)".into(),
        ))
    }

    fn flowing(&self, setup: DemSetup, _: &Options, flow: FlowSet) -> Result<Box<dyn Stepper>> {
        let mode = setup.mode;
        Ok(Box::new(
            cpu::CpuStepper::open(setup)?.with_flow(flow, mode),
        ))
    }
}

/// The `wgpu-compute` backend (sorted grids).
struct ComputeEngine;

impl Engine for ComputeEngine {
    fn detector(&self, options: &Options) -> Result<Box<dyn Backend>> {
        Ok(Box::new(
            wgpu_compute::WgpuComputeBackend::new()?
                .with_structure(options.structure)
                .with_grid_build(options.grid_build),
        ))
    }

    fn stepper(&self, setup: DemSetup, options: &Options) -> Result<Box<dyn Stepper>> {
        let options = grid_options(options);
        Ok(Box::new(wgpu_compute::GridStepper::open(setup, options)?))
    }

    fn reopener(&self, setup: DemSetup, options: &Options) -> Result<Reopen> {
        let (gpu, options) = (Gpu::open(Need::Compute)?, grid_options(options));
        Ok(Box::new(move |particles, room| {
            let setup = setup.over(particles);
            let step = wgpu_compute::GridStepper::flowing_on(gpu.clone(), setup, room, options)?;
            Ok(Box::new(step) as Box<dyn DeviceFlow>)
        }))
    }
}

/// The `wgpu-rq` backend (ray queries).
struct RqEngine;

impl Engine for RqEngine {
    fn detector(&self, _: &Options) -> Result<Box<dyn Backend>> {
        Ok(Box::new(wgpu_rq::WgpuRqBackend::new()?))
    }

    fn stepper(&self, setup: DemSetup, _: &Options) -> Result<Box<dyn Stepper>> {
        Ok(Box::new(wgpu_rq::RqStepper::open(setup, KernelSet::Auto)?))
    }

    fn reopener(&self, setup: DemSetup, _: &Options) -> Result<Reopen> {
        let gpu = Gpu::open(Need::RayQuery)?;
        Ok(Box::new(move |particles, _room| {
            let setup = setup.over(particles);
            let step = wgpu_rq::RqStepper::open_on(gpu.clone(), setup, KernelSet::Auto)?;
            Ok(Box::new(step) as Box<dyn DeviceFlow>)
        }))
    }
}

/// The `optix` backend (cargo feature `optix`).
#[cfg(feature = "optix")]
struct OptixEngine;

#[cfg(feature = "optix")]
impl Engine for OptixEngine {
    fn detector(&self, _: &Options) -> Result<Box<dyn Backend>> {
        Ok(Box::new(super::optix::OptixBackend::new()?))
    }

    fn stepper(&self, setup: DemSetup, options: &Options) -> Result<Box<dyn Stepper>> {
        let step = super::optix::OptixStepper::open(setup, options.rebuild)?;
        Ok(Box::new(step))
    }

    fn reopener(&self, setup: DemSetup, options: &Options) -> Result<Reopen> {
        let rebuild = options.rebuild;
        Ok(Box::new(move |particles, _room| {
            let setup = setup.over(particles);
            let step = super::optix::OptixStepper::open(setup, rebuild)?;
            Ok(Box::new(step) as Box<dyn DeviceFlow>)
        }))
    }
}

impl BackendKind {
    /// Opens the backend's detection with default options, or says why it cannot run here.
    pub fn open(self) -> Result<Box<dyn Backend>> {
        self.open_with(&Options::default())
    }

    /// Opens the backend's detection with `options`, or says why it cannot run here.
    pub fn open_with(self, options: &Options) -> Result<Box<dyn Backend>> {
        self.probe().map_err(|reason| Error::BackendUnavailable {
            backend: self.name(),
            reason,
        })?;
        engine(self)?.detector(options)
    }
}

/// Opens the detection the user chose; `auto` tries each backend in order of preference.
pub fn open(choice: BackendChoice, options: &Options) -> Result<Opened<Box<dyn Backend>>> {
    choosing(choice, &BackendKind::ALL, |kind| kind.open_with(options))
}

/// What `open` opens of the backend the user chose; for `auto`, of the first of `candidates`
/// the registry's one rule takes, saying why.
fn choosing<T>(
    choice: BackendChoice,
    candidates: &[BackendKind],
    mut open: impl FnMut(BackendKind) -> Result<T>,
) -> Result<Opened<T>> {
    if let Some(kind) = choice.kind() {
        return Ok(Opened {
            value: open(kind)?,
            kind,
            reason: None,
        });
    }
    let ((value, kind), reason) = open_auto(candidates, |kind| Ok((open(kind)?, kind)))?;
    Ok(Opened {
        value,
        kind,
        reason: Some(reason),
    })
}

/// Opens the DEM step of backend `kind` over `particles` in the box.
pub fn open_stepper(
    kind: BackendKind,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<Box<dyn Stepper>> {
    open_setup(kind, DemSetup::new(particles, params, mode), options)
}

/// Opens the DEM step of backend `kind` of `setup` with `options`, its spheres validated.
pub fn open_setup(
    kind: BackendKind,
    setup: DemSetup,
    options: &Options,
) -> Result<Box<dyn Stepper>> {
    setup.particles.validate()?;
    engine(kind)?.stepper(setup, options)
}

/// Opens the DEM step the user chose, and names the backend it runs on; `auto` follows the
/// registry's one rule (`open_auto` in the registry) and says why it passed over the faster
/// backends.
pub fn open_choice(
    choice: BackendChoice,
    particles: Particles,
    params: StepParams,
    mode: ProxyMode,
    options: &Options,
) -> Result<Opened<Box<dyn Stepper>>> {
    choose(choice, DemSetup::new(particles, params, mode), options)
}

/// [`open_choice`] of `setup`.
fn choose(
    choice: BackendChoice,
    setup: DemSetup,
    options: &Options,
) -> Result<Opened<Box<dyn Stepper>>> {
    choosing(choice, &BackendKind::ALL, |kind| {
        open_setup(kind, setup.clone(), options)
    })
}

/// How each rank of a run decomposed over ranks (the `distributed` module) steps its spheres and
/// their ghosts on the backend the user chose (`auto`: the registry's one rule): `None` for
/// the cpu, whose step the rank keeps and gives each round's spheres itself; for a GPU backend,
/// its step opened again over each round's spheres on the device opened now (under an MPI
/// launcher, the GPU of the process's local rank). `setup`'s own spheres are not used.
pub(crate) fn open_rank_step(
    choice: BackendChoice,
    setup: DemSetup,
    options: &Options,
) -> Result<Opened<Option<Reopen>>> {
    choosing(choice, &BackendKind::ALL, |kind| {
        kind.probe().map_err(|reason| Error::BackendUnavailable {
            backend: kind.name(),
            reason,
        })?;
        match kind {
            BackendKind::Cpu => Ok(None),
            _ => engine(kind)?.reopener(setup.clone(), options).map(Some),
        }
    })
}

/// Opens the DEM step the user chose for the scene `start` (`auto`: in the order of
/// [`BackendKind::FLOWING`] where spheres flow). The box walls, mesh walls and a box switched
/// off run on every backend; spheres flowing in and out on every backend, the GPU ones through
/// `FlowStep` (`engines/common/flow.rs`).
pub fn open_scene(
    choice: BackendChoice,
    start: Start,
    options: &Options,
) -> Result<Opened<Box<dyn Stepper>>> {
    let (setup, flow) = DemSetup::of_start(start);
    if flow.is_empty() {
        return choose(choice, setup, options);
    }
    let open = |kind: BackendKind| -> Result<Box<dyn Stepper>> {
        setup.particles.validate()?;
        engine(kind)?.flowing(setup.clone(), options, flow.clone())
    };
    let mut opened = choosing(choice, &BackendKind::FLOWING, open)?;
    let why = "wgpu-compute first where spheres flow: its flow events stay on the device";
    opened.reason = opened.reason.map(|reason| format!("{reason} ({why})"));
    Ok(opened)
}
