//! A scene's start: the particles at t = 0 (or a checkpoint's) with the step parameters, the
//! walls and the flows its tables describe.

use super::*;
use crate::dem::equipment::Built;
use crate::dem::flow::FlowSet;
use crate::dem::material_spec::{self, material_index};
use crate::dem::model::contact::moment_of_inertia;
use crate::dem::model::time_step::{RAYLEIGH_FRACTION, rayleigh_time};
use crate::dem::model::{ContactLaw, LiquidBridge, Material, Materials, drag_dt_limit, mass};
use crate::numbers::shown;
use crate::numbers::widened;
use crate::scenes::{self, Layout, Scene, SceneSpec};
use crate::spheres::SphereSet;

/// The spheres of the generated `scene` as `g` sizes and seeds it, on its lattice.
fn generated(scene: Scene, g: &Generated) -> Result<SphereSet> {
    scenes::generate(&SceneSpec {
        scene,
        n: g.spheres,
        seed: g.seed,
        layout: Layout::Lattice,
    })
}

/// The box of the generated `scene` of `n` spheres.
fn generated_box(scene: Scene, n: usize) -> ([f64; 3], [f64; 3]) {
    ([0.0; 3], [scene.box_side(n, Layout::Lattice); 3])
}

/// Refuses spheres of radius `r_max` (the largest) whose mass or moment of inertia at
/// `density` overflows single precision, naming the largest radius that density allows.
fn check_heaviest(density: f64, r_max: f32) -> Result<()> {
    let m = mass(density as f32, r_max);
    if m.is_finite() && moment_of_inertia(m, r_max).is_finite() {
        return Ok(());
    }
    // 0.4·ρ·(4/3)π·r⁵ is the moment of inertia, the first to overflow for r > 1.
    let largest = (f32::MAX as f64 / (0.4 * density * 4.0 / 3.0 * std::f64::consts::PI))
        .powf(0.2)
        .min((f32::MAX as f64 / (density * 4.0 / 3.0 * std::f64::consts::PI)).cbrt());
    Err(Error::InvalidConfig {
        what: format!("spheres of radius {} m", shown(r_max)),
        reason: format!(
            "at density {} kg/m³ their mass ({} kg) or moment of inertia is beyond single \
             precision (3.4e38); the largest radius this density allows is {} m",
            shown(density),
            shown(m),
            shown(largest)
        ),
    })
}

/// The height of the box's floor: `box_lo`'s where the scene gives it, else the default's.
fn box_lo_z(box_lo: Option<[f64; 3]>, default_lo: [f64; 3]) -> f64 {
    box_lo.unwrap_or(default_lo)[2]
}

impl SceneConfig {
    /// Builds the particles at t = 0 and the step parameters (a built-in scene's equipment
    /// built once, for its spheres, box, flows and walls alike).
    pub fn build(&self) -> Result<Start> {
        let equipment = self.equipment()?;
        let spheres = match &self.source {
            Source::Generated(scene, g) => generated(*scene, g)?,
            Source::Rotating(g) => generated(Scene::Freefall, g)?,
            Source::Mesh(fill) => fill.spheres()?,
            Source::Hopper(_) | Source::Drum(_) | Source::Agglomerate(_) | Source::Gravel(_) => {
                equipment.as_ref().expect("built").spheres.clone()
            }
            Source::Input(file) => {
                let input = file.input.as_ref().ok_or_else(|| Error::InvalidConfig {
                    what: "scene \"input\"".into(),
                    reason: "needs input = \"FILE\" (--input)".into(),
                })?;
                if !self.clump.is_empty() {
                    return Self::inside_the_box(
                        self.start_with(self.clumps_in(input)?, None)?,
                        0.0,
                    );
                }
                let particles = crate::io::read_particles(input)?;
                // The file's materials index the scene's: an error names the file.
                let count = self.materials()?.list.len();
                particles.check_materials(count).map_err(|e| Error::Parse {
                    path: input.clone(),
                    line: None,
                    msg: e.to_string(),
                })?;
                return Self::inside_the_box(self.start_with(particles, None)?, 0.0);
            }
        };
        let mut particles = Particles::at_rest(&spheres)?;
        if let Some(built) = &equipment {
            let v = built.velocity.map(|x| x as f32);
            particles.velocities.iter_mut().for_each(|u| *u = v);
        }
        if !self.clump.is_empty() || self.scene() == SceneKind::Gravel {
            particles = self.clumps_of(&particles)?;
        }
        Self::inside_the_box(self.start_with(particles, equipment.as_ref())?, 0.0)
    }

    /// The error of `[[clump]]` tables in a scene of kind `scene`, whose spheres are not
    /// generated.
    fn no_clumps_of(&self, scene: &str) -> Error {
        Error::InvalidConfig {
            what: "scene table [[clump]]".into(),
            reason: format!(
                "makes clumps of generated spheres (freefall, slab, poly*, pour, rotating, \
                 mesh, drum, hopper): not of scene \"{scene}\"'s yet"
            ),
        }
    }

    /// The clumps of the clump file `input` (`crate::io::read_clumps`), of the `[[clump]]`
    /// tables at their own size, of the first material.
    fn clumps_in(&self, input: &std::path::Path) -> Result<Particles> {
        if !crate::io::is_clump_file(input) {
            return Err(Error::Parse {
                path: input.to_owned(),
                line: None,
                msg: format!(
                    "with [[clump]] tables the input is a clump file, its header {}",
                    crate::io::CLUMP_HEADER
                ),
            });
        }
        let rows = crate::io::read_clumps(input)?;
        let densities = self.densities()?;
        crate::dem::clump_spec::clumps_of_rows(
            input,
            &rows,
            &self.clump,
            &self.materials,
            &densities,
        )
    }

    /// The generated `spheres` made clumps of the `[[clump]]` tables (`dem::clump_spec`):
    /// scenes whose spheres are generated.
    fn clumps_of(&self, spheres: &Particles) -> Result<Particles> {
        let seed = match &self.source {
            Source::Generated(_, g) | Source::Rotating(g) => g.seed,
            Source::Mesh(fill) => fill.seed,
            Source::Drum(drum) | Source::Gravel(drum) => drum.seed,
            Source::Hopper(hopper) => hopper.seed,
            Source::Agglomerate(_) => return Err(self.no_clumps_of("agglomerate")),
            Source::Input(_) => return Err(self.no_clumps_of("input")),
        };
        let densities = self.densities()?;
        // The gravel scene's own mix, where it gives no tables.
        let tables = match self.clump.is_empty() {
            true => crate::dem::clump_spec::gravel(),
            false => self.clump.clone(),
        };
        crate::dem::clump_spec::clumps_in_place_of(
            spheres,
            &tables,
            &self.materials,
            &densities,
            seed,
        )
    }

    /// The density of each of the scene's materials \[kg/m³\], in their order.
    fn densities(&self) -> Result<Vec<f32>> {
        let materials = self.materials()?;
        Ok(materials.list.iter().map(|m| m.density as f32).collect())
    }

    /// The start of this scene (`input`, without its file) from `particles` given in memory:
    /// checked as a sphere file's are (finite values, valid radii, materials the scene has, the
    /// size limits, every centre in the box).
    pub fn build_from(&self, particles: Particles) -> Result<Start> {
        particles.validate()?;
        SphereSet::new(particles.positions.clone(), particles.radii.clone())?;
        particles.check_materials(self.materials()?.list.len())?;
        Self::inside_the_box(self.start_with(particles, None)?, 0.0)
    }

    /// The start of a run resumed from a checkpoint of this scene: `particles` pass the checks
    /// of a fresh run's input (finite values, valid radii, the size limits) and the parameters
    /// those of a fresh run. A centre may lie outside the box, as soft walls let spheres sink
    /// into them (with a soft stiffness, by more than a radius), but by no more than the box's
    /// own extent along that axis.
    pub fn resume_from(&self, particles: Particles) -> Result<Start> {
        particles.validate()?;
        SphereSet::new(particles.positions.clone(), particles.radii.clone())?;
        Self::inside_the_box(self.start_from(particles)?, 1.0)
    }

    /// The box a run resumed from a checkpoint of this scene steps in, in `f32` as its step
    /// parameters hold it (a checkpoint's scene names its box: [`Self::resolved`]).
    pub(crate) fn resumed_box(&self) -> Result<([f32; 3], [f32; 3])> {
        match (self.domain.box_lo, self.domain.box_hi) {
            (Some(lo), Some(hi)) => Ok((lo.map(|x| x as f32), hi.map(|x| x as f32))),
            _ => Err(Error::InvalidConfig {
                what: "the checkpoint's scene".into(),
                reason: "it names no box (box_lo and box_hi)".into(),
            }),
        }
    }

    /// `start`, if every centre lies in its box widened by `slack` times its extent on every
    /// side (0 at t = 0; a resumed scene without box walls is not checked).
    fn inside_the_box(start: Start, slack: f32) -> Result<Start> {
        if slack > 0.0 && !start.walls.box_walls {
            // Without the box walls spheres leave the box: it only bounds the grid.
            return Ok(start);
        }
        let (lo, hi) = (start.params.box_lo, start.params.box_hi);
        let grown: [(f32, f32); 3] = std::array::from_fn(|a| {
            let margin = slack * (hi[a] - lo[a]);
            (lo[a] - margin, hi[a] + margin)
        });
        let outside = start
            .particles
            .positions
            .iter()
            .position(|c| (0..3).any(|a| !(grown[a].0..=grown[a].1).contains(&c[a])));
        if let Some(index) = outside {
            let far = match slack > 0.0 {
                true => ", farther out than the box's own size",
                false => "",
            };
            return Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "centre {:?} is outside the box {lo:?} .. {hi:?}{far}",
                    start.particles.positions[index]
                ),
            });
        }
        Ok(start)
    }

    /// The step parameters for `particles` (at t = 0, or from a checkpoint of this scene).
    pub fn start_from(&self, particles: Particles) -> Result<Start> {
        self.start_with(particles, self.equipment()?.as_ref())
    }

    /// [`Self::start_from`] with the scene's equipment built already (`None`: no built-in
    /// scene).
    fn start_with(&self, particles: Particles, equipment: Option<&Built>) -> Result<Start> {
        let (r_min, r_max) = particles.radius_range();
        let (default_lo, default_hi) = match &self.source {
            Source::Generated(scene, _) => generated_box(*scene, particles.len()),
            Source::Rotating(_) => generated_box(Scene::Freefall, particles.len()),
            Source::Mesh(fill) => ([0.0; 3], [fill.box_side()?; 3]),
            Source::Hopper(_) | Source::Drum(_) | Source::Agglomerate(_) | Source::Gravel(_) => {
                let built = equipment.expect("a built-in scene's equipment");
                (built.box_lo, built.box_hi)
            }
            // A file: its bounds with a margin of two largest diameters, as the step starts
            // them (spheres sharing a centre spread about it).
            Source::Input(_) => {
                let mut centres = particles.positions.clone();
                if particles.coincident_pairs()? > 0 {
                    let mut spread = particles.clone();
                    spread.separate_coincident()?;
                    centres = spread.positions;
                }
                match SphereSet::new(centres, particles.radii.clone())?.bounds() {
                    Some((lo, hi)) => {
                        let m = 4.0 * r_max as f64;
                        (lo.map(|x| x as f64 - m), hi.map(|x| x as f64 + m))
                    }
                    None => ([0.0; 3], [1.0; 3]),
                }
            }
        };
        let materials = self.materials()?;
        let material = *materials.first();
        // The materials' values, before the time step is derived from them.
        materials.check()?;
        particles.check_materials(materials.list.len())?;
        let r_max = particles.radius_range().1;
        check_heaviest(materials.heaviest_density(), r_max)?;
        let floor = box_lo_z(self.domain.box_lo, default_lo);
        let flow = self.flow(&materials, floor, equipment)?;
        // The smallest sphere, inserted ones included, sets the time step.
        let r_min = match (particles.is_empty(), flow.smallest_radius()) {
            (true, None) => 1.0,
            (true, Some(r)) => r,
            (false, None) => r_min,
            (false, Some(r)) => r_min.min(r),
        };
        let dt = match (self.run.dt, material.contact) {
            (Some(dt), _) => dt,
            // The Rayleigh rule where the parameters make sense (else `StepParams::new` says
            // what is wrong with them).
            // The fastest material's Rayleigh time (materials.check() passed: the parameters
            // make sense).
            (None, ContactLaw::HertzMindlin { .. }) => {
                let t_r = materials
                    .list
                    .iter()
                    .map(|m| match m.contact {
                        ContactLaw::HertzMindlin {
                            young_modulus,
                            poisson_ratio,
                        } => rayleigh_time(r_min as f64, m.density, young_modulus, poisson_ratio),
                        _ => f64::INFINITY,
                    })
                    .fold(f64::INFINITY, f64::min);
                RAYLEIGH_FRACTION * t_r
            }
            (None, _) => match &self.source {
                Source::Generated(
                    Scene::Poly1_2 | Scene::Poly12 | Scene::Poly120 | Scene::Polylog,
                    _,
                ) => 5e-5,
                Source::Mesh(_) => 2.5e-5,
                _ => 1e-4,
            },
        };
        // A default time step stays (a thousandth) under the viscous bridges' limit too.
        let lightest = mass(materials.lightest_density() as f32, r_min) as f64;
        let dt = match (self.run.dt, material.bridge) {
            (None, Some(b)) => {
                drag_dt_limit(&b, lightest, r_min as f64).map_or(dt, |limit| dt.min(0.999 * limit))
            }
            _ => dt,
        };
        let spin =
            self.domain
                .gravity_spin
                .unwrap_or(if matches!(self.source, Source::Rotating(_)) {
                    0.25 * std::f64::consts::PI
                } else {
                    0.0
                });
        let (lo, hi) = (
            self.domain.box_lo.unwrap_or(default_lo),
            self.domain.box_hi.unwrap_or(default_hi),
        );
        let box_material = match &self.domain.box_material {
            Some(name) => Some(material_index(&self.materials, name, "box_material")?),
            None => None,
        };
        let params = StepParams::with_materials(
            &materials,
            box_material,
            dt,
            lo,
            hi,
            self.domain.gravity,
            spin,
            r_min,
        )?;
        flow.check(params.dt as f64, params.box_lo, params.box_hi)?;
        let walls = self.walls_with(equipment)?;
        walls.check_speed(params.dt as f64, r_min)?;
        Ok(Start {
            particles,
            params,
            mode: self.run.mode,
            walls,
            flow,
        })
    }

    /// The built-in scene this scene names, as it sizes it (`None`: not a built-in scene).
    fn equipment(&self) -> Result<Option<Built>> {
        match &self.source {
            Source::Hopper(hopper) => hopper.build().map(Some),
            Source::Drum(drum) | Source::Gravel(drum) => drum.build().map(Some),
            Source::Agglomerate(agglomerate) => agglomerate.build().map(Some),
            _ => Ok(None),
        }
    }

    /// The inflows and outflows of the scene (with those of its `equipment`); without the box
    /// walls, spheres below the box's floor (at `floor`) leave too.
    fn flow(
        &self,
        materials: &Materials,
        floor: f64,
        equipment: Option<&Built>,
    ) -> Result<FlowSet> {
        let inflows = self
            .inflow
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let material = match &f.material {
                    Some(name) => material_index(&self.materials, name, "inflow.material")?,
                    None => 0,
                };
                f.build(k, materials.list[material].density, material as u8)
            })
            .collect::<Result<Vec<_>>>()?;
        let mut outflow = self.outflow.clone();
        if let Some(built) = equipment {
            outflow.extend(built.outflows.iter().cloned());
        }
        let outflows = outflow
            .iter()
            .enumerate()
            .map(|(k, f)| f.build(k))
            .collect::<Result<Vec<_>>>()?;
        if self.run.flow_every == Some(0) {
            return Err(Error::InvalidConfig {
                what: "scene".into(),
                reason: "flow_every must be at least 1 step, got 0".into(),
            });
        }
        // The inflows of a scene with clumps insert clumps (of its tables, or the gravel's).
        let tables = match (&self.source, self.clump.is_empty()) {
            (Source::Gravel(_), true) => crate::dem::clump_spec::gravel(),
            _ => self.clump.clone(),
        };
        let clumps = (!tables.is_empty() && !inflows.is_empty())
            .then(|| crate::dem::clump_spec::ClumpMaker::new(&tables, &self.materials))
            .transpose()?;
        Ok(FlowSet {
            inflows,
            outflows,
            floor: (!self.domain.box_walls).then_some(floor as f32),
            every: self.run.flow_every,
            counted: Default::default(),
            clumps,
        })
    }

    /// The walls of the scene: the box (or not), a built-in scene's, and each `[[wall]]` read
    /// and posed, with its material.
    pub fn walls(&self) -> Result<WallSet> {
        self.walls_with(self.equipment()?.as_ref())
    }

    /// [`Self::walls`] with the scene's equipment built already (`None`: no built-in scene).
    fn walls_with(&self, equipment: Option<&Built>) -> Result<WallSet> {
        let mut meshes = Vec::new();
        let material_of = |w: &WallConfig| match &w.material {
            Some(name) => {
                material_index(&self.materials, name, "wall.material").map(|m| Some(m as u32))
            }
            None => Ok(None),
        };
        if let Some(built) = equipment {
            for (config, mesh) in &built.walls {
                let material = material_of(config)?;
                meshes.push(config.build_from(meshes.len(), mesh, material)?);
            }
        }
        for w in &self.wall {
            meshes.push(w.build(meshes.len(), material_of(w)?)?);
        }
        WallSet::new(self.domain.box_walls, meshes)
    }

    /// The materials of the scene: its `[[materials]]` tables, or the one its `[material]`
    /// describes.
    pub fn materials(&self) -> Result<Materials> {
        material_spec::materials(&self.material()?, &self.materials, &self.material_pairs)
    }

    /// `[material]` with the defaults of the scene's source: an `agglomerate` whose material
    /// names no cohesion is bonded by liquid bridges (water, of its grains' `liquid_volume`).
    fn scene_material(&self) -> SceneMaterial {
        let mut m = self.material.clone();
        let dry = m.cohesion.is_none()
            && m.surface_energy.is_none()
            && m.cohesion_energy_density.is_none();
        if let (Source::Agglomerate(a), true) = (&self.source, dry) {
            m.cohesion = Some(CohesionKind::Capillary);
            m.liquid_volume = m.liquid_volume.or(Some(a.liquid_volume()));
        }
        m
    }

    /// The material the scene describes, its defaults filled in; refuses keys that do not
    /// apply to its contact law (each would be silently ignored).
    pub fn material(&self) -> Result<Material> {
        let this = &self.scene_material();
        let hertz = this.contact == ContactKind::HertzMindlin;
        let refuse = |key: &str, law: &str| {
            Err(Error::InvalidConfig {
                what: format!("scene key {key}"),
                reason: format!(
                    "applies to contact = \"{law}\" only, and this scene's contact is \"{}\"",
                    if hertz { "hertz-mindlin" } else { "linear" }
                ),
            })
        };
        let contact = if hertz {
            if this.stiffness.is_some() {
                return refuse("stiffness", "linear");
            }
            if this.contact_time.is_some() {
                return refuse("contact_time", "linear");
            }
            ContactLaw::HertzMindlin {
                young_modulus: this.young_modulus.unwrap_or(DEFAULT_YOUNG_MODULUS),
                poisson_ratio: this.poisson_ratio.unwrap_or(DEFAULT_POISSON_RATIO),
            }
        } else {
            if this.young_modulus.is_some() {
                return refuse("young_modulus", "hertz-mindlin");
            }
            if this.poisson_ratio.is_some() {
                return refuse("poisson_ratio", "hertz-mindlin");
            }
            match this.stiffness {
                Some(Stiffness::PerPair) => ContactLaw::LinearPerPair {
                    contact_time: this.contact_time,
                },
                _ if this.contact_time.is_some() => {
                    return Err(Error::InvalidConfig {
                        what: "scene key contact_time".into(),
                        reason: "applies to stiffness = \"per-pair\" only".into(),
                    });
                }
                _ => ContactLaw::Linear,
            }
        };
        let stiffness = match this.stiffness {
            Some(Stiffness::Fixed(k)) => Some(k),
            _ => None,
        };
        let (friction, rolling) = match hertz {
            true => (DEFAULT_FRICTION, DEFAULT_ROLLING_FRICTION),
            false => (0.0, 0.0),
        };
        let of_law = |key: &str, law: &str| {
            Err(Error::InvalidConfig {
                what: format!("scene key {key}"),
                reason: format!("applies to cohesion = \"{law}\": give it as well"),
            })
        };
        let jkr = this.cohesion == Some(CohesionKind::Jkr);
        let capillary = this.cohesion == Some(CohesionKind::Capillary);
        if this.surface_energy.is_some() && !jkr {
            return of_law("surface_energy", "jkr");
        }
        for (key, given) in [
            ("liquid_volume", this.liquid_volume),
            ("surface_tension", this.surface_tension),
            ("contact_angle", this.contact_angle),
            ("liquid_viscosity", this.liquid_viscosity),
        ] {
            if given.is_some() && !capillary {
                return of_law(key, "capillary");
            }
        }
        let needs = |key: &str, what: &str| {
            Err(Error::InvalidConfig {
                what: "scene key cohesion".into(),
                reason: format!("needs {key}, {what}"),
            })
        };
        let adhesion = match (jkr, this.surface_energy) {
            (false, _) => 0.0,
            (true, Some(gamma)) if hertz => gamma,
            (true, Some(_)) => return refuse("cohesion", "hertz-mindlin"),
            (true, None) => return needs("surface_energy", "the work of adhesion Γ in J/m²"),
        };
        let sjkr = this.cohesion == Some(CohesionKind::Sjkr);
        if this.cohesion_energy_density.is_some() && !sjkr {
            return of_law("cohesion_energy_density", "sjkr");
        }
        let cohesion_density = match (sjkr, this.cohesion_energy_density) {
            (false, _) => 0.0,
            (true, Some(k)) => k,
            (true, None) => {
                return needs(
                    "cohesion_energy_density",
                    "the cohesion energy density in J/m³",
                );
            }
        };
        let bridge = match (capillary, this.liquid_volume) {
            (false, _) => None,
            (true, None) => return needs("liquid_volume", "the liquid of a bridge in m³"),
            (true, Some(volume)) => Some(LiquidBridge {
                volume,
                surface_tension: this.surface_tension.unwrap_or(WATER_SURFACE_TENSION),
                contact_angle: this.contact_angle.unwrap_or(0.0).to_radians(),
                viscosity: this.liquid_viscosity.unwrap_or(0.0),
            }),
        };
        Ok(Material {
            density: this.density,
            restitution: this.restitution,
            stiffness,
            contact,
            friction: this.friction.unwrap_or(friction),
            wall_friction: this.wall_friction,
            rolling_friction: this.rolling_friction.unwrap_or(rolling),
            rolling_model: this.rolling_model.unwrap_or_default(),
            tangential_model: this.tangential_model.unwrap_or_default(),
            adhesion,
            bridge,
            cohesion_density,
        })
    }

    /// This scene with every derived value (time step, box, gravity spin, stiffness, the
    /// material's defaults) written out as `start` resolved it, so a checkpoint resumes with
    /// exactly the same parameters.
    pub fn resolved(&self, start: &Start) -> SceneConfig {
        let p = &start.params;
        // `start` was built from this scene, so its material is valid.
        let m = self
            .material()
            .expect("the scene of a start has a valid material");
        let (young_modulus, poisson_ratio) = match m.contact {
            ContactLaw::HertzMindlin {
                young_modulus,
                poisson_ratio,
            } => (Some(young_modulus), Some(poisson_ratio)),
            _ => (None, None),
        };
        // Friction written out where it acts (a frictionless linear scene stays as it was).
        let acting = |given: Option<f64>, value: f64| match p.friction.turns() {
            true => Some(value),
            false => given,
        };
        // The step's `f32` values by their shortest decimals (box_hi = [0.8, ...], not
        // 0.800000011920929), each of which reads back as the same `f32`.
        let this = &self.scene_material();
        SceneConfig {
            run: RunConfig {
                dt: Some(widened(p.dt)),
                ..self.run.clone()
            },
            domain: DomainConfig {
                box_lo: Some(p.box_lo.map(widened)),
                box_hi: Some(p.box_hi.map(widened)),
                gravity_spin: Some(widened(p.gravity_spin)),
                ..self.domain.clone()
            },
            material: SceneMaterial {
                stiffness: match m.contact {
                    ContactLaw::Linear => Some(Stiffness::Fixed(widened(p.stiffness))),
                    _ => this.stiffness,
                },
                young_modulus,
                poisson_ratio,
                friction: acting(this.friction, m.friction),
                wall_friction: acting(this.wall_friction, m.wall_friction.unwrap_or(m.friction)),
                rolling_friction: acting(this.rolling_friction, m.rolling_friction),
                rolling_model: match p.friction.turns() {
                    true => Some(m.rolling_model),
                    false => this.rolling_model,
                },
                ..this.clone()
            },
            ..self.clone()
        }
    }
}

impl MeshFill {
    /// Copies per row and layers of the `mesh` scene, and the side of its cell per copy.
    fn layout(&self) -> Result<(u32, u32, f64)> {
        let copies = self.copies;
        if copies == 0 || copies as usize > crate::MAX_SPHERES {
            return Err(Error::InvalidConfig {
                what: "scene key mesh_copies".into(),
                reason: format!(
                    "must be from 1 to {} (each copy holds a sphere at least), got {copies}",
                    crate::MAX_SPHERES
                ),
            });
        }
        let per_row = (copies as f64).sqrt().ceil() as u32;
        // Spheres reach past the mesh by up to their radius: keep 4.4 radii between copies.
        let cell = self.size * 1.05 + 4.4 * self.radius as f64;
        let layers = (copies as u64).div_ceil(per_row as u64 * per_row as u64) as u32;
        Ok((per_row, layers, cell))
    }

    /// The `mesh` scene's box side: the unit cube, or larger to hold every copy.
    pub fn box_side(&self) -> Result<f64> {
        let (per_row, layers, cell) = self.layout()?;
        Ok((per_row as f64 * cell)
            .max(layers as f64 * cell + 2.2 * self.radius as f64)
            .max(1.0))
    }

    /// Fills the mesh (or the torus) and places the copies on the floor of the box, side by side.
    pub fn spheres(&self) -> Result<SphereSet> {
        let r = self.radius;
        if !(r.is_finite() && r > 0.0 && self.size.is_finite() && self.size > 0.0) {
            return Err(Error::InvalidConfig {
                what: "scene".into(),
                reason: format!(
                    "mesh_radius and mesh_size must be positive, got {r} and {}",
                    self.size
                ),
            });
        }
        let (per_row, _, cell) = self.layout()?;
        let mesh = match &self.mesh {
            Some(path) => crate::mesh::load(path)?,
            None => crate::mesh::torus(1.0, 0.4, 64, 32),
        };
        let size = self.size;
        let shape = mesh.fitted([0.0; 3], [size; 3]);
        let radii = if self.mixed {
            vec![(r, 1.0), (r / 2.0, 1.0)]
        } else {
            vec![(r, 1.0)]
        };
        let spec = crate::mesh::FillSpec {
            spacing: 2.2 * r as f64,
            radii,
            jitter: true,
            seed: self.seed,
        };
        let (one_c, one_r) = crate::mesh::fill(&shape, &spec)?;
        let side = self.box_side()?;
        let edge = (side - per_row as f64 * cell) / 2.0 + (cell - size) / 2.0;
        let copies = self.copies as usize;
        let total = one_c.len().saturating_mul(copies);
        if total > crate::MAX_SPHERES {
            return Err(Error::TooLarge {
                what: format!("spheres in {copies} filled copies of the mesh (mesh_copies)"),
                got: total as u64,
                limit: crate::MAX_SPHERES as u64,
            });
        }
        let mut centers = Vec::with_capacity(total);
        let mut all_radii = Vec::with_capacity(total);
        let per_row = per_row as usize;
        for k in 0..copies {
            let at = [
                k % per_row,
                (k / per_row) % per_row,
                k / (per_row * per_row),
            ];
            let offset: [f64; 3] = std::array::from_fn(|a| {
                let base = if a == 2 { 2.2 * r as f64 } else { edge };
                base + at[a] as f64 * cell
            });
            centers.extend(
                one_c
                    .iter()
                    .map(|c| std::array::from_fn(|a| (c[a] as f64 + offset[a]) as f32)),
            );
            all_radii.extend_from_slice(&one_r);
        }
        SphereSet::new(centers, all_radii)
    }
}
