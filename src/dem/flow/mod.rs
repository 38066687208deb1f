//! Spheres entering and leaving a run: `[[inflow]]` regions insert spheres at a rate,
//! `[[outflow]]` regions remove the spheres whose centres enter them, and without the box walls
//! the spheres that fall below the box are removed too.
//!
//! ```toml
//! [[inflow]]
//! lo = [0.4, 0.4, 0.9]          # a box ...
//! hi = [0.6, 0.6, 0.95]
//! # center = [0.5, 0.5, 0.9]    # ... or a disc: centre, radius, axis (its normal)
//! # radius = 0.1
//! # axis = [0, 0, 1]
//! rate = 2000                   # spheres/s, or
//! # mass_rate = 0.05            # kg/s (by the mean mass of the radius distribution)
//! sphere_radius = 0.004         # or sphere_radii = [0.003, 0.005] (uniform)
//! velocity = [0, 0, -0.5]       # m/s (default 0)
//! seed = 1                      # default 1
//! start = 0.0                   # s (default 0)
//! stop = 1.0                    # s (default: never)
//!
//! [[outflow]]
//! lo = [0, 0, 0]
//! hi = [1, 1, 0.05]
//! ```
//!
//! Flows act after every `flow_every` steps (a scene key; default [`CPU_EVERY`] on the cpu
//! backend, which holds the spheres in host memory, and [`GPU_EVERY`] on the GPU backends, where
//! each flow event reads the spheres back and reopens the step): after step s − 1, for s a
//! multiple of `flow_every`, the spheres in an outflow leave, and inflow k inserts
//! ⌊rate·t_s⌋ − ⌊rate·t_{s−every}⌋ spheres (t from its start on), at places drawn from a
//! generator seeded by (seed, k, s − 1), each where it overlaps no sphere (up to [`ATTEMPTS`]
//! places, else it is refused and counted). Everything is a function of the state and the step
//! number, so a resumed run inserts exactly what the uninterrupted run did, with no generator
//! state to save.

use crate::dem::model::mass;
use crate::error::{Error, Result};
use crate::particles::Particles;
use glam::{DVec3, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

/// Places tried per sphere before it is refused.
pub const ATTEMPTS: u32 = 32;

/// Steps between flow events on the cpu backend unless the scene says (`flow_every`).
pub const CPU_EVERY: u32 = 1;

/// Steps between flow events on the GPU backends unless the scene says (`flow_every`): each
/// event reads every sphere back and reopens the step.
pub const GPU_EVERY: u32 = 100;

/// One `[[inflow]]` table (module docs).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InflowConfig {
    /// Lower corner of a box region \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lo: Option<[f64; 3]>,
    /// Upper corner of a box region \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hi: Option<[f64; 3]>,
    /// Centre of a disc region \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 3]>,
    /// Radius of a disc region \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Normal of a disc region (default z).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<[f64; 3]>,
    /// Spheres per second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate: Option<f64>,
    /// Kilograms per second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_rate: Option<f64>,
    /// Radius of every sphere \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sphere_radius: Option<f64>,
    /// Radii drawn uniformly from this range \[m\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sphere_radii: Option<[f64; 2]>,
    /// Velocity of the new spheres \[m/s\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Seed of the places and radii (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Time the inflow starts \[s\] (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// Time the inflow stops \[s\] (default never).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop: Option<f64>,
    /// The material of its spheres, a `[[materials]]` name (default the first material).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
}

/// One `[[outflow]]` table: a box whose spheres are removed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutflowConfig {
    /// Lower corner \[m\].
    pub lo: [f64; 3],
    /// Upper corner \[m\].
    pub hi: [f64; 3],
}

/// Where an inflow puts its spheres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Region {
    /// Centres uniform in the box `lo..hi`.
    Box { lo: Vec3, hi: Vec3 },
    /// Centres uniform in the disc of `radius` about `center`, normal to `axis` (unit).
    Disc {
        center: Vec3,
        radius: f32,
        axis: Vec3,
    },
}

impl Region {
    fn sample(&self, rng: &mut Pcg64) -> Vec3 {
        match *self {
            Region::Box { lo, hi } => Vec3::from_array(std::array::from_fn(|a| {
                if hi[a] > lo[a] {
                    rng.random_range(lo[a]..hi[a])
                } else {
                    lo[a]
                }
            })),
            Region::Disc {
                center,
                radius,
                axis,
            } => {
                let (u, v) = axis.any_orthonormal_pair();
                let rho = radius * rng.random_range(0.0f32..1.0).sqrt();
                let phi = rng.random_range(0.0..std::f32::consts::TAU);
                center + rho * (phi.cos() * u + phi.sin() * v)
            }
        }
    }

    /// An upper bound of the spheres of radius `r` with centres in the region that overlap no
    /// other: one per cell of side 2r of a lattice over it (a disc as its square), at least 1.
    fn capacity(&self, r: f32) -> f64 {
        let per_axis = |extent: f32| (extent as f64 / (2.0 * r as f64)).floor() + 1.0;
        match *self {
            Region::Box { lo, hi } => (0..3).map(|a| per_axis(hi[a] - lo[a])).product(),
            Region::Disc { radius, .. } => per_axis(2.0 * radius).powi(2),
        }
    }

    /// The box around the region.
    fn bounds(&self) -> (Vec3, Vec3) {
        match *self {
            Region::Box { lo, hi } => (lo, hi),
            Region::Disc { center, radius, .. } => (center - radius, center + radius),
        }
    }
}

/// An inflow of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Inflow {
    /// Where.
    pub region: Region,
    /// Spheres per second.
    pub rate: f64,
    /// Smallest and largest radius (uniform between) \[m\].
    pub radii: (f32, f32),
    /// Velocity of new spheres \[m/s\].
    pub velocity: Vec3,
    /// Seed.
    pub seed: u64,
    /// Start and stop times \[s\].
    pub window: (f64, f64),
    /// The material of the spheres it inserts.
    pub material: u8,
    /// That material's density \[kg/m³\].
    pub density: f32,
}

/// The spheres' ways in and out of a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlowSet {
    /// Inflows, in the scene's order.
    pub inflows: Vec<Inflow>,
    /// Boxes whose spheres are removed.
    pub outflows: Vec<(Vec3, Vec3)>,
    /// Centres below this height are removed (a run without box walls: below its box).
    pub floor: Option<f32>,
    /// Steps between flow events (`None`: the backend's default, [`CPU_EVERY`] or
    /// [`GPU_EVERY`]).
    pub every: Option<u32>,
    /// What the flows did before the step opened: nothing for a new run, a checkpoint's
    /// totals for a resumed one. A step's [`FlowCounts`] go on from them.
    pub counted: FlowCounts,
    /// The clumps the inflows insert in the place of their spheres (a scene's `[[clump]]`
    /// tables: each scaled into its sphere, turned at random; `None`: spheres).
    pub clumps: Option<crate::dem::clump_spec::ClumpMaker>,
}

/// What the flows did, summed since the run started (a resumed run goes on from its
/// checkpoint's totals, [`FlowSet::counted`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FlowCounts {
    /// Spheres inserted.
    pub inserted: u64,
    /// Spheres an inflow found no room for.
    pub refused: u64,
    /// Spheres removed (a clump counts once).
    pub removed: u64,
    /// Their mass \[kg\].
    pub removed_mass: f64,
    /// Mass inserted \[kg\].
    pub inserted_mass: f64,
    /// Flow events taken.
    pub events: u64,
    /// Of those, the events that read every sphere back from a GPU (and reopened its step).
    pub read_backs: u64,
    /// Wall-clock time spent in them (reading back, flowing, reopening a GPU step) \[ms\].
    pub event_ms: f64,
}

impl FlowCounts {
    /// The flows' totals and cost, in words (for a run's summary).
    pub fn describe(&self) -> String {
        let each = match self.events {
            0 => 0.0,
            n => self.event_ms / n as f64,
        };
        format!(
            "flows: {} inserted, {} refused, {} removed ({:.4e} kg); {} flow events, {each:.3} ms \
             each (wall clock), {} of them reading every sphere back",
            self.inserted,
            self.refused,
            self.removed,
            self.removed_mass,
            self.events,
            self.read_backs
        )
    }
}

/// Whether `x` is a finite `f32` (what the step stores) once converted.
fn fits_f32(x: f64) -> bool {
    (x as f32).is_finite()
}

impl InflowConfig {
    /// The inflow of spheres of material `material` (density `density`, which turns a mass
    /// rate into spheres); `index` names it in errors. Every
    /// value must be a finite `f32` (radii positive ones), the window must start at a time ≥ 0.
    pub fn build(&self, index: usize, density: f64, material: u8) -> Result<Inflow> {
        let bad = |reason: String| Error::InvalidConfig {
            what: format!("inflow {index}"),
            reason,
        };
        let finite = |v: &[f64]| v.iter().all(|&x| fits_f32(x));
        let region = match (self.lo, self.hi, self.center, self.radius) {
            (Some(lo), Some(hi), None, None) => {
                if !(finite(&lo) && finite(&hi) && (0..3).all(|a| lo[a] <= hi[a])) {
                    return Err(bad(format!(
                        "needs lo <= hi, finite in single precision (|x| < 3.4e38), got {lo:?} \
                         .. {hi:?}"
                    )));
                }
                if self.axis.is_some() {
                    return Err(bad("axis belongs to a disc (center, radius)".into()));
                }
                Region::Box {
                    lo: DVec3::from(lo).as_vec3(),
                    hi: DVec3::from(hi).as_vec3(),
                }
            }
            (None, None, Some(center), Some(radius)) => {
                let axis = self.axis.unwrap_or([0.0, 0.0, 1.0]);
                let unit = DVec3::from(axis).try_normalize().filter(|_| finite(&axis));
                match unit {
                    Some(axis) if finite(&center) && fits_f32(radius) && radius >= 0.0 => {
                        Region::Disc {
                            center: DVec3::from(center).as_vec3(),
                            radius: radius as f32,
                            axis: axis.as_vec3(),
                        }
                    }
                    _ => {
                        return Err(bad(format!(
                            "a disc needs a center and a radius >= 0, finite in single precision \
                             (|x| < 3.4e38), and a non-zero axis, got center {center:?}, radius \
                             {radius}, axis {axis:?}"
                        )));
                    }
                }
            }
            _ => {
                return Err(bad(
                    "give a box (lo and hi) or a disc (center and radius), one of the two".into(),
                ));
            }
        };
        let radii = match (self.sphere_radius, self.sphere_radii) {
            (Some(r), None) => (r, r),
            (None, Some([a, b])) => (a, b),
            _ => {
                return Err(bad(
                    "give sphere_radius or sphere_radii, one of the two".into()
                ));
            }
        };
        let positive = |r: f64| fits_f32(r) && r as f32 > 0.0;
        if !(positive(radii.0) && positive(radii.1) && radii.0 <= radii.1) {
            return Err(bad(format!(
                "radii must be positive and ordered, each a finite single-precision number \
                 (from 1.2e-38 to 3.4e38 m), got {radii:?}"
            )));
        }
        let rate = match (self.rate, self.mass_rate) {
            (Some(n), None) => n,
            (None, Some(kg)) => {
                // E[r³] of r uniform in a..b is (b⁴ − a⁴) / (4(b − a)) (a³ when a = b).
                let (a, b) = radii;
                let r3 = if b > a {
                    (b.powi(4) - a.powi(4)) / (4.0 * (b - a))
                } else {
                    a.powi(3)
                };
                kg / (density * 4.0 / 3.0 * std::f64::consts::PI * r3)
            }
            _ => {
                return Err(bad(
                    "give rate (spheres/s) or mass_rate (kg/s), one of the two".into(),
                ));
            }
        };
        if !(rate.is_finite() && rate >= 0.0) {
            return Err(bad(format!(
                "the rate must be finite and at least 0, got {rate} spheres/s"
            )));
        }
        let velocity = self.velocity.unwrap_or_default();
        let window = (
            self.start.unwrap_or(0.0),
            self.stop.unwrap_or(f64::INFINITY),
        );
        if !finite(&velocity) {
            return Err(bad(format!(
                "velocity must be finite in single precision (|v| < 3.4e38), got {velocity:?}"
            )));
        }
        if !(window.0.is_finite() && window.0 >= 0.0 && window.1 >= window.0) {
            return Err(bad(format!(
                "start must be a finite time >= 0 and stop a time >= start (or left out: \
                 never), got start {} and stop {}",
                window.0, window.1
            )));
        }
        Ok(Inflow {
            region,
            rate,
            radii: (radii.0 as f32, radii.1 as f32),
            velocity: DVec3::from(velocity).as_vec3(),
            seed: self.seed.unwrap_or(1),
            window,
            material,
            density: density as f32,
        })
    }
}

impl OutflowConfig {
    /// The box, checked; `index` names it in errors.
    pub fn build(&self, index: usize) -> Result<(Vec3, Vec3)> {
        let (lo, hi) = (self.lo, self.hi);
        if !(0..3).all(|a| fits_f32(lo[a]) && fits_f32(hi[a]) && lo[a] <= hi[a]) {
            return Err(Error::InvalidConfig {
                what: format!("outflow {index}"),
                reason: format!(
                    "needs lo <= hi, finite in single precision (|x| < 3.4e38), got {lo:?} .. \
                     {hi:?}"
                ),
            });
        }
        Ok((DVec3::from(lo).as_vec3(), DVec3::from(hi).as_vec3()))
    }
}

/// A flow event: after the step that brought the run to `step`, closing the `every` steps since
/// the last (time step `dt`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// The step count after the event's step.
    pub step: u64,
    /// Steps since the last event.
    pub every: u32,
    /// Time step \[s\].
    pub dt: f32,
}

impl Event {
    /// The steps the event closes, `from..to`.
    fn steps(&self) -> (u64, u64) {
        (self.step.saturating_sub(self.every as u64), self.step)
    }
}

/// A sphere an inflow inserts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewSphere {
    /// Centre \[m\].
    pub centre: [f32; 3],
    /// Velocity \[m/s\].
    pub velocity: [f32; 3],
    /// Radius \[m\].
    pub radius: f32,
    /// Material.
    pub material: u8,
}

/// A seed for inflow `k`'s draws in step `step` (splitmix64 of the three).
fn step_seed(seed: u64, k: usize, step: u64) -> u64 {
    let mut z = seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ step.rotate_left(32);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Inflow {
    /// An upper bound of the spheres its region holds: one of its smallest radius r per cell of
    /// side 2r of a lattice over the region (a disc as its square). An event tries to insert at
    /// most this many, counting the rest refused.
    pub fn capacity(&self) -> f64 {
        self.region.capacity(self.radii.0)
    }

    /// Spheres due in the steps from `from` to `to` (time step `dt`).
    fn due(&self, (from, to): (u64, u64), dt: f64) -> u64 {
        let (start, stop) = self.window;
        let inserted_by = |s: u64| {
            let t = (s as f64 * dt).min(stop) - start;
            if t <= 0.0 {
                0.0
            } else {
                (self.rate * t).floor()
            }
        };
        (inserted_by(to) - inserted_by(from)) as u64
    }
}

impl FlowSet {
    /// Whether nothing flows.
    pub fn is_empty(&self) -> bool {
        self.inflows.is_empty() && self.outflows.is_empty() && self.floor.is_none()
    }

    /// The largest radius an inflow inserts (0 without any).
    pub fn largest_radius(&self) -> f32 {
        self.inflows.iter().map(|f| f.radii.1).fold(0.0, f32::max)
    }

    /// The box around every inflow's region (`None` without any).
    pub fn inflow_bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        self.inflows
            .iter()
            .map(|f| f.region.bounds())
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
            .map(|(lo, hi)| (lo.to_array(), hi.to_array()))
    }

    /// The smallest radius an inflow inserts (`None` without any).
    pub fn smallest_radius(&self) -> Option<f32> {
        self.inflows.iter().map(|f| f.radii.0).reduce(f32::min)
    }

    /// Steps between flow events on a backend that holds its spheres on a GPU (`gpu`) or in
    /// host memory.
    pub fn every(&self, gpu: bool) -> u32 {
        self.every
            .unwrap_or(if gpu { GPU_EVERY } else { CPU_EVERY })
            .max(1)
    }

    /// Refuses inflows a run with time step `dt` in the box `lo..hi` cannot take: a region
    /// not inside the box, or a rate that owes more spheres in one step than the region holds.
    pub fn check(&self, dt: f64, lo: [f32; 3], hi: [f32; 3]) -> Result<()> {
        for (k, inflow) in self.inflows.iter().enumerate() {
            let bad = |reason: String| Error::InvalidConfig {
                what: format!("inflow {k}"),
                reason,
            };
            let (a, b) = inflow.region.bounds();
            if (0..3).any(|x| a[x] < lo[x] || b[x] > hi[x]) {
                return Err(bad(format!(
                    "its region {:?} .. {:?} is not inside the box {lo:?} .. {hi:?}, where the \
                     run's spheres live: move the region or widen the box (box_lo, box_hi)",
                    a.to_array(),
                    b.to_array()
                )));
            }
            let per_step = inflow.rate * dt;
            let capacity = inflow.capacity();
            if per_step > capacity {
                return Err(bad(format!(
                    "a rate of {:.4e} spheres/s owes {per_step:.4e} spheres a step (dt {dt:.4e} \
                     s), more than its region holds ({capacity} spheres of radius {:.4e} m): \
                     lower the rate or widen the region",
                    inflow.rate, inflow.radii.0
                )));
            }
        }
        Ok(())
    }

    /// A warning where an inflow owes more spheres at one flow event (`every` steps of `dt`)
    /// than its region holds: the excess is refused.
    pub fn rate_warning(&self, dt: f64, every: u32) -> Option<String> {
        let crowded: Vec<String> = (self.inflows.iter().enumerate())
            .filter(|(_, f)| f.rate * dt * every as f64 > f.capacity())
            .map(|(k, f)| format!("inflow {k} ({:.4e} spheres/s)", f.rate))
            .collect();
        (!crowded.is_empty()).then(|| {
            format!(
                "{} owes more spheres per flow event ({every} steps) than its region holds: \
                 each event inserts at most what fits and counts the rest refused",
                crowded.join(", ")
            )
        })
    }

    /// Whether a flow event follows the step that brought the run to `step` (`every` steps
    /// apart).
    pub fn due_after(step: u64, every: u32) -> bool {
        step > 0 && step.is_multiple_of(every as u64)
    }

    /// Whether a sphere at `c` leaves: in an outflow (closed box) or below the floor.
    pub fn leaves(&self, c: Vec3) -> bool {
        self.floor.is_some_and(|z| c.z < z)
            || self
                .outflows
                .iter()
                .any(|&(lo, hi)| c.cmpge(lo).all() && c.cmple(hi).all())
    }

    /// The flow event after step `parts.step − 1` (taken with time step `dt`), closing the
    /// `every` steps since the last: removes the spheres in an outflow (or below the floor),
    /// a clump whole where its centre is (counted once, at its mass), then inserts what each
    /// inflow owes for those steps (each a clump in its place where [`Self::clumps`] says, at
    /// its mass); `densities` (of each material) give the masses counted.
    /// Returns whether any sphere came or went.
    pub fn apply(
        &self,
        parts: &mut Particles,
        every: u32,
        dt: f32,
        densities: &[f32],
        counts: &mut FlowCounts,
    ) -> Result<bool> {
        let before = (counts.inserted, counts.removed);
        let mut keep: Vec<bool> = parts
            .positions
            .iter()
            .map(|c| !self.leaves(Vec3::from(*c)))
            .collect();
        // A clump's components go where its centre goes.
        let clumps = &parts.clumps;
        let mut first = 0;
        for clump in &clumps.clumps {
            let kind = &clumps.kinds[clump.kind];
            let n = kind.template.components.len();
            let leaves = self.leaves(clump.body.position.as_vec3());
            keep[first..first + n].fill(!leaves);
            if leaves {
                counts.removed += 1;
                counts.removed_mass += kind.inertia.mass;
            }
            first += n;
        }
        if keep.iter().any(|k| !k) {
            for (i, _) in keep.iter().enumerate().skip(first).filter(|(_, k)| !**k) {
                let density = densities[parts.material(i) as usize];
                counts.removed += 1;
                counts.removed_mass += mass(density, parts.radii[i]) as f64;
            }
            parts.retain(&keep)?;
        }
        let r_max = parts.radius_range().1;
        let near = |lo: Vec3, hi: Vec3| -> Vec<(Vec3, f32)> {
            parts
                .positions
                .iter()
                .zip(&parts.radii)
                .map(|(c, &r)| (Vec3::from(*c), r))
                .filter(|(c, _)| c.cmpge(lo).all() && c.cmple(hi).all())
                .collect()
        };
        let step = Event {
            step: parts.step,
            every,
            dt,
        };
        let new = self.insert(step, r_max, near, counts);
        match &self.clumps {
            None => {
                for s in new {
                    parts.push_of(s.centre, s.velocity, s.radius, s.material)?;
                }
            }
            Some(maker) => {
                let mut rand = crate::dem::clump_spec::clump_stream(step_seed(0, 0, step.step));
                let mut clumps = Vec::with_capacity(new.len());
                for s in new {
                    let at = DVec3::from_array(s.centre.map(f64::from));
                    let v = DVec3::from_array(s.velocity.map(f64::from));
                    let (kind, body, material) =
                        maker.make(&mut rand, (at, s.radius, v), s.material, densities);
                    // Counted as a clump at its mass, not as the sphere it replaces.
                    let sphere = mass(densities[s.material as usize], s.radius) as f64;
                    counts.inserted_mass += kind.inertia.mass - sphere;
                    clumps.push((kind, body, material));
                }
                parts.insert_clumps(clumps)?;
            }
        }
        Ok((counts.inserted, counts.removed) != before)
    }

    /// The boxes around each inflow that owes spheres at `event` within which a sphere of
    /// radius up to `r_max` could touch one it inserts (`None` for an inflow that owes none).
    pub fn reach(&self, event: Event, r_max: f32) -> Vec<Option<(Vec3, Vec3)>> {
        self.inflows
            .iter()
            .map(|inflow| {
                let (lo, hi) = inflow.region.bounds();
                let reach = r_max + inflow.radii.1;
                (inflow.due(event.steps(), event.dt as f64) > 0).then_some((lo - reach, hi + reach))
            })
            .collect()
    }

    /// What each inflow inserts at `event`, in order, each where it overlaps no sphere that
    /// `near(lo, hi)` lists (it lists at least every sphere with its centre in the box
    /// `lo..hi` that [`reach`](Self::reach) gives, `r_max` the largest radius present) nor one
    /// inserted before it; counts them (and those refused).
    pub fn insert(
        &self,
        event: Event,
        r_max: f32,
        mut near: impl FnMut(Vec3, Vec3) -> Vec<(Vec3, f32)>,
        counts: &mut FlowCounts,
    ) -> Vec<NewSphere> {
        let mut inserted: Vec<NewSphere> = Vec::new();
        let reach = self.reach(event, r_max);
        for ((k, inflow), bounds) in self.inflows.iter().enumerate().zip(reach) {
            let Some((lo, hi)) = bounds else {
                continue;
            };
            let owed = inflow.due(event.steps(), event.dt as f64);
            // What cannot fit is refused untried.
            let due = owed.min(inflow.capacity() as u64);
            counts.refused += owed - due;
            let mut rng = Pcg64::seed_from_u64(step_seed(inflow.seed, k, event.step - 1));
            let mut near = near(lo, hi);
            near.extend(inserted.iter().map(|s| (Vec3::from(s.centre), s.radius)));
            for _ in 0..due {
                let (a, b) = inflow.radii;
                let r = if b > a { rng.random_range(a..=b) } else { a };
                let free = (0..ATTEMPTS)
                    .map(|_| inflow.region.sample(&mut rng))
                    .find(|&c| {
                        near.iter()
                            .all(|&(d, s)| (d - c).length_squared() >= (r + s) * (r + s))
                    });
                match free {
                    Some(c) => {
                        near.push((c, r));
                        inserted.push(NewSphere {
                            centre: c.to_array(),
                            velocity: inflow.velocity.to_array(),
                            radius: r,
                            material: inflow.material,
                        });
                        counts.inserted += 1;
                        counts.inserted_mass += mass(inflow.density, r) as f64;
                    }
                    None => counts.refused += 1,
                }
            }
        }
        inserted
    }
}
