//! The simulation state: what a checkpoint saves and a frame shows.

pub mod history;
pub mod position;

use crate::clump::{Clump, ClumpKind, ClumpSet, RigidBody};
use crate::error::{Error, Result, try_vec};
use crate::spheres::SphereSet;
pub use history::{
    ContactHistory, FIRST_MESH_WALL, FIRST_WALL, HistoryEntry, LoadEntry, LoadedEntry, MESH_WALLS,
    NO_PARTNER, Slot,
};

/// Spheres with velocities, in the order the user gave them, their contact history and the
/// simulation clock.
///
/// Two states are equal where every field is, an empty `position_residuals` counting as zeros
/// and an empty `materials` as the first material's (0) for every sphere.
#[derive(Debug, Clone, Default)]
pub struct Particles {
    /// Centres \[m\], as `f32`: what detection, the contacts and the walls use. Each is its
    /// sphere's position rounded to `f32`; the position itself is the centre plus its residual
    /// ([`Self::position_residuals`], [`position`]).
    pub positions: Vec<[f32; 3]>,
    /// Residuals of the centres \[m\]: sphere i is at `positions[i] + position_residuals[i]`
    /// (summed exactly), each coordinate a normalised pair ([`position`]: the centre is the sum
    /// rounded to `f32`, so |residual| ≤ half the `f32` spacing at the centre). Empty, or one
    /// per sphere; empty means every residual is 0 (the centres are exact, as a new scene's
    /// are). Every step adds its displacement to the pair, so no displacement is lost however
    /// small it is beside the spacing of `f32` far from the origin. A sphere is moved by
    /// [`Self::set_exact_position`] (a centre changed alone would keep a residual that may no
    /// longer be within half a spacing of it, which [`Self::validate`] refuses).
    pub position_residuals: Vec<[f32; 3]>,
    /// Velocities \[m/s\].
    pub velocities: Vec<[f32; 3]>,
    /// Angular velocities \[rad/s\].
    pub angular_velocities: Vec<[f32; 3]>,
    /// Radii \[m\].
    pub radii: Vec<f32>,
    /// Each sphere's material, its index in the scene's materials. Empty, or one per sphere;
    /// empty means every sphere is of the first material.
    pub materials: Vec<u8>,
    /// The springs of the contacts that have friction or rolling resistance (empty without).
    pub history: ContactHistory,
    /// The clumps, rigid bodies of component spheres (empty: none). The first
    /// [`ClumpSet::component_count`] spheres are their components, clump by clump in each
    /// template's order: a component's centre, velocity and angular velocity are its clump's at
    /// its place ([`Self::place_clump_components`]), and the step moves it with its clump. The
    /// other spheres are free.
    pub clumps: ClumpSet,
    /// Steps taken since t = 0 (the time is `step · dt`).
    pub step: u64,
}

/// The kinetic energy of a set of spheres \[J\], its two parts.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Energies {
    /// Σ ½ m v² (a clump's m its mass, v its centre's velocity).
    pub translational: f64,
    /// Σ ½ I ω², I = 2/5 m r² (solid spheres; a clump's Σ L_k²/(2I_k)).
    pub rotational: f64,
}

impl Particles {
    /// The kinetic energy of the free spheres, each sphere's mass from its radius and the
    /// density of its material in `densities` (indexed by material), and of the clumps (their
    /// rigid bodies'), summed in `f64`.
    pub fn energies(&self, densities: &[f32]) -> Energies {
        let mut sum = Energies::default();
        for clump in &self.clumps.clumps {
            let inertia = &self.clumps.kinds[clump.kind].inertia;
            let b = &clump.body;
            sum.translational += 0.5 * inertia.mass * b.velocity.length_squared();
            sum.rotational += b.rotational_energy(inertia);
        }
        let components = self.clumps.component_count();
        for (i, &r) in self.radii.iter().enumerate().skip(components) {
            let density = densities[self.material(i) as usize] as f64;
            let r = r as f64;
            let m = density * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
            let square = |v: [f32; 3]| v.iter().map(|&x| x as f64 * x as f64).sum::<f64>();
            sum.translational += 0.5 * m * square(self.velocities[i]);
            sum.rotational += 0.5 * 0.4 * m * r * r * square(self.angular_velocities[i]);
        }
        sum
    }

    /// Spheres at rest at step 0 ([`Error::OutOfMemory`] when their state does not fit).
    pub fn at_rest(spheres: &SphereSet) -> Result<Self> {
        let what = || format!("the state of {} spheres", spheres.len());
        let mut positions = try_vec(spheres.len(), what)?;
        let mut velocities = try_vec(spheres.len(), what)?;
        let mut angular_velocities = try_vec(spheres.len(), what)?;
        let mut radii = try_vec(spheres.len(), what)?;
        positions.extend_from_slice(spheres.centers());
        velocities.resize(spheres.len(), [0.0; 3]);
        angular_velocities.resize(spheres.len(), [0.0; 3]);
        radii.extend_from_slice(spheres.radii());
        Ok(Self {
            positions,
            position_residuals: Vec::new(),
            velocities,
            angular_velocities,
            radii,
            materials: Vec::new(),
            history: ContactHistory::default(),
            clumps: ClumpSet::default(),
            step: 0,
        })
    }

    /// A copy, or [`Error::OutOfMemory`] where it does not fit.
    pub fn try_clone(&self) -> Result<Self> {
        let what = || format!("a copy of the state of {} spheres", self.len());
        let copy = |v: &Vec<[f32; 3]>| -> Result<Vec<[f32; 3]>> {
            let mut out = try_vec(v.len(), what)?;
            out.extend_from_slice(v);
            Ok(out)
        };
        let mut radii = try_vec(self.radii.len(), what)?;
        radii.extend_from_slice(&self.radii);
        Ok(Self {
            positions: copy(&self.positions)?,
            position_residuals: copy(&self.position_residuals)?,
            velocities: copy(&self.velocities)?,
            angular_velocities: copy(&self.angular_velocities)?,
            radii,
            materials: {
                let mut m = try_vec(self.materials.len(), what)?;
                m.extend_from_slice(&self.materials);
                m
            },
            history: self.history.try_clone()?,
            clumps: self.clumps.clone(),
            step: self.step,
        })
    }

    /// Number of spheres.
    pub fn len(&self) -> usize {
        self.radii.len()
    }

    /// Whether there are no spheres.
    pub fn is_empty(&self) -> bool {
        self.radii.is_empty()
    }

    /// Checks that every value is finite, the lengths agree and every position is a normalised
    /// pair (its centre the position rounded to `f32`); names the first bad sphere.
    pub fn validate(&self) -> Result<()> {
        if self.positions.len() != self.len()
            || self.velocities.len() != self.len()
            || self.angular_velocities.len() != self.len()
            || !(self.position_residuals.is_empty() || self.position_residuals.len() == self.len())
            || !(self.materials.is_empty() || self.materials.len() == self.len())
        {
            return Err(Error::Usage(format!(
                "particles: {} positions, {} position residuals (none or one per sphere), {} \
                 materials (none or one per sphere), {} velocities, {} angular velocities, {} \
                 radii",
                self.positions.len(),
                self.position_residuals.len(),
                self.materials.len(),
                self.velocities.len(),
                self.angular_velocities.len(),
                self.len()
            )));
        }
        let bad = self
            .positions
            .iter()
            .zip(&self.velocities)
            .zip(&self.angular_velocities)
            .position(|((c, v), w)| c.iter().chain(v).chain(w).any(|x| !x.is_finite()));
        if let Some(index) = bad {
            return Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "non-finite position {:?}, velocity {:?} or angular velocity {:?} at step {}",
                    self.positions[index],
                    self.velocities[index],
                    self.angular_velocities[index],
                    self.step
                ),
            });
        }
        self.validate_residuals()?;
        self.validate_clumps()
    }

    /// Checks the clumps: their components are spheres of these particles, of their templates'
    /// radii, and their bodies' states are finite.
    fn validate_clumps(&self) -> Result<()> {
        let set = &self.clumps;
        let components = set.component_count();
        if components > self.len() {
            return Err(Error::Usage(format!(
                "particles: {} clumps of {components} component spheres, but {} spheres",
                set.clumps.len(),
                self.len()
            )));
        }
        if let Some(k) = set.clumps.iter().position(|c| c.kind >= set.kinds.len()) {
            return Err(Error::Usage(format!(
                "particles: clump {k} is of kind {}, but there are {} kinds",
                set.clumps[k].kind,
                set.kinds.len()
            )));
        }
        let radii = set.clumps.iter().flat_map(|c| {
            set.kinds[c.kind]
                .template
                .components
                .iter()
                .map(|t| t.radius as f32)
        });
        if let Some(index) = radii.zip(&self.radii).position(|(want, &r)| want != r) {
            return Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "a clump's component of radius {}, but its template's is {}",
                    self.radii[index],
                    set.components()[index].radius
                ),
            });
        }
        let finite = |b: &crate::clump::RigidBody| {
            b.position.is_finite()
                && b.orientation.is_finite()
                && b.velocity.is_finite()
                && b.angular_momentum.is_finite()
        };
        match set.clumps.iter().position(|c| !finite(&c.body)) {
            Some(k) => Err(Error::Usage(format!(
                "particles: clump {k} has a state that is not finite: {:?}",
                set.clumps[k].body
            ))),
            None => Ok(()),
        }
    }

    /// The clumps of `clumps` (their components first, of the first material, placed by their
    /// clumps) and then the free spheres of `free` (which may have no contact history yet: its
    /// partners would be renumbered).
    pub fn with_clumps(clumps: ClumpSet, free: Particles) -> Result<Self> {
        if !free.history.is_empty() || !free.clumps.clumps.is_empty() {
            return Err(Error::Usage(
                "clumps join free spheres without contact history or clumps of their own".into(),
            ));
        }
        let components = clumps.components();
        let k = components.len();
        let mut out = Particles {
            positions: vec![[0.0; 3]; k],
            position_residuals: Vec::new(),
            velocities: vec![[0.0; 3]; k],
            angular_velocities: vec![[0.0; 3]; k],
            radii: components.iter().map(|c| c.radius as f32).collect(),
            materials: Vec::new(),
            history: ContactHistory::default(),
            clumps,
            step: free.step,
        };
        out.place_clump_components()?;
        out.fill_residuals()?;
        out.positions.extend_from_slice(&free.positions);
        out.position_residuals
            .extend((0..free.len()).map(|i| free.residual(i)));
        out.velocities.extend_from_slice(&free.velocities);
        out.angular_velocities
            .extend_from_slice(&free.angular_velocities);
        out.radii.extend_from_slice(&free.radii);
        if !free.materials.is_empty() {
            out.materials = vec![0; k];
            out.materials.extend_from_slice(&free.materials);
        }
        out.validate()?;
        Ok(out)
    }

    /// Adds the clumps `new` (each of its kind, with its body, of its material): their kinds
    /// and bodies after the others', their components after the other clumps' (the free
    /// spheres after them take numbers that much higher, their contact history with them),
    /// placed where their clumps put them.
    pub fn insert_clumps(&mut self, new: Vec<(ClumpKind, RigidBody, u8)>) -> Result<()> {
        let at = self.clumps.component_count();
        let mut radii = Vec::new();
        let mut materials = Vec::new();
        for (kind, body, material) in new {
            let count = kind.template.components.len();
            radii.extend(kind.template.components.iter().map(|c| c.radius as f32));
            materials.extend(std::iter::repeat_n(material, count));
            self.clumps.kinds.push(kind);
            let kind = self.clumps.kinds.len() - 1;
            self.clumps.clumps.push(Clump { kind, body });
        }
        let m = radii.len();
        let zeros = || std::iter::repeat_n([0.0f32; 3], m);
        self.fill_residuals()?;
        self.positions.splice(at..at, zeros());
        self.position_residuals.splice(at..at, zeros());
        self.velocities.splice(at..at, zeros());
        self.angular_velocities.splice(at..at, zeros());
        self.radii.splice(at..at, radii);
        if self.materials.is_empty() && materials.iter().any(|&k| k != 0) {
            self.materials = vec![0; self.positions.len() - m];
        }
        if !self.materials.is_empty() {
            self.materials.splice(at..at, materials);
        }
        self.history.insert_empty(at, m)?;
        self.place_clump_components()
    }

    /// Writes each clump's components (the first spheres) where their clump puts them: centre
    /// (split into an `f32` centre and its residual), velocity and angular velocity.
    pub fn place_clump_components(&mut self) -> Result<()> {
        if self.clumps.clumps.is_empty() {
            return Ok(());
        }
        self.fill_residuals()?;
        let Self {
            clumps,
            positions,
            position_residuals,
            velocities,
            angular_velocities,
            ..
        } = self;
        clumps.for_each_component(|k, c| {
            let halves = c.centre.to_array().map(position::split);
            positions[k] = halves.map(|h| h.0);
            position_residuals[k] = halves.map(|h| h.1);
            velocities[k] = c.velocity.as_vec3().to_array();
            angular_velocities[k] = c.angular_velocity.as_vec3().to_array();
        });
        Ok(())
    }

    /// Checks that every centre is its position rounded to `f32` (its pair is normalised), then
    /// the history.
    fn validate_residuals(&self) -> Result<()> {
        let off = self
            .position_residuals
            .iter()
            .zip(&self.positions)
            .position(|(lo, hi)| (0..3).any(|a| !position::normalised(hi[a], lo[a])));
        if let Some(index) = off {
            return Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "position residual {:?} is not within half an f32 spacing of the centre \
                     {:?} (the centre must be the position rounded to f32)",
                    self.position_residuals[index], self.positions[index]
                ),
            });
        }
        self.history.validate(self.len())
    }

    /// Checks a state a stepper computed: [`Error::Unstable`] names the first sphere (in the
    /// order of these particles, the input order) whose position, velocity or angular velocity is
    /// not finite.
    pub fn check_stable(&self) -> Result<()> {
        let finite = |v: &[f32; 3]| v.iter().all(|x| x.is_finite());
        let bad = (0..self.len()).find(|&i| {
            !(finite(&self.positions[i])
                && finite(&self.velocities[i])
                && finite(&self.angular_velocities[i]))
        });
        match bad {
            Some(sphere) => Err(Error::Unstable {
                step: self.step,
                sphere,
                what: format!(
                    "has position {:?}, velocity {:?} and angular velocity {:?}",
                    self.positions[sphere],
                    self.velocities[sphere],
                    self.angular_velocities[sphere]
                ),
            }),
            None => Ok(()),
        }
    }

    /// Whether any sphere turns.
    pub fn spin(&self) -> bool {
        self.angular_velocities
            .iter()
            .any(|w| w.iter().any(|&x| x != 0.0))
    }

    /// Pairs of spheres whose centres coincide: they have no contact normal, so every stepper
    /// moves them apart first ([`Self::separate_coincident`]).
    pub fn coincident_pairs(&self) -> Result<u64> {
        use rayon::slice::ParallelSliceMut;
        let n = self.positions.len();
        let mut keys: Vec<[u32; 3]> = try_vec(n, || format!("the centres of {n} spheres"))?;
        // Bits of the centre, with −0 read as +0 (they are the same point).
        keys.extend(
            self.positions
                .iter()
                .map(|c| c.map(|x| (x + 0.0).to_bits())),
        );
        keys.par_sort_unstable();
        Ok(keys
            .chunk_by(|a, b| a == b)
            .map(|same| (same.len() as u64) * (same.len() as u64 - 1) / 2)
            .sum())
    }

    /// Moves apart spheres whose centres coincide, so that every pair has a contact normal and
    /// no group starts piled into one sphere's volume: of each group sharing a centre, the
    /// sphere of the smallest index stays and the others, in order of index, take the next
    /// points of a cubic lattice about the centre (`lattice_points`: nearest first), spaced
    /// by the group's largest diameter and a thousandth of its largest radius (at least 8
    /// `f32` steps of the coordinates there). The group's spheres then overlap none of their
    /// own group, as a cluster about the centre. Moved apart by a fraction of a radius, a group
    /// of N would start with N(N − 1)/2 overlaps of almost 2r, whose contacts store an energy
    /// growing as N² per sphere and a collective stiffness growing as N: from a few dozen
    /// spheres up the first step flings them out faster than any time step for their contacts
    /// resolves, and a Hertz contact stiffens without bound as they cross the walls.
    /// Deterministic (so every backend starts from the same centres), and a no-op where no
    /// centres coincide. Returns how many pairs coincided.
    pub fn separate_coincident(&mut self) -> Result<u64> {
        use rayon::slice::ParallelSliceMut;
        let n = self.positions.len();
        let mut keys: Vec<([u32; 3], u32)> = try_vec(n, || format!("the centres of {n} spheres"))?;
        keys.extend(
            self.positions
                .iter()
                .enumerate()
                .map(|(k, c)| (c.map(|x| (x + 0.0).to_bits()), k as u32)),
        );
        keys.par_sort_unstable();
        let groups = || keys.chunk_by(|a, b| a.0 == b.0).filter(|g| g.len() > 1);
        let largest = groups().map(|g| g.len()).max().unwrap_or(0);
        if largest == 0 {
            return Ok(0);
        }
        let points = lattice_points(largest)?;
        let mut pairs = 0;
        for group in groups() {
            pairs += (group.len() as u64) * (group.len() as u64 - 1) / 2;
            let centre = self.positions[group[0].1 as usize];
            let r = group
                .iter()
                .map(|&(_, k)| self.radii[k as usize])
                .fold(0.0f32, f32::max);
            // The farthest point's distance along an axis, at a spacing of about 2r.
            let reach = points[group.len() - 1]
                .iter()
                .map(|&i| i.unsigned_abs())
                .max()
                .unwrap_or(0) as f32
                * 2.1
                * r;
            let coarsest = centre
                .iter()
                .map(|x| {
                    let far = x.abs() + reach;
                    far.next_up() - far
                })
                .fold(0.0f32, f32::max);
            let spacing = (2.0 * r + (1e-3 * r).max(8.0 * coarsest)) as f64;
            for (&(_, k), p) in group.iter().zip(&points).skip(1) {
                let at = std::array::from_fn(|a| centre[a] as f64 + spacing * p[a] as f64);
                self.set_exact_position(k as usize, at)?;
            }
        }
        Ok(pairs)
    }

    /// Adds a sphere of the first material at `c` with velocity `v`, radius `r`, no spin and no
    /// contacts; refuses more spheres than ids below the walls'.
    pub fn push(&mut self, c: [f32; 3], v: [f32; 3], r: f32) -> Result<()> {
        self.push_of(c, v, r, 0)
    }

    /// As [`Self::push`], a sphere of material `material`.
    pub fn push_of(&mut self, c: [f32; 3], v: [f32; 3], r: f32, material: u8) -> Result<()> {
        let n = self.len() + 1;
        if n > FIRST_MESH_WALL as usize {
            return Err(Error::TooLarge {
                what: "spheres of a run (ids above are the walls')".into(),
                got: n as u64,
                limit: FIRST_MESH_WALL as u64,
            });
        }
        self.positions.push(c);
        if !self.position_residuals.is_empty() {
            self.position_residuals.push([0.0; 3]);
        }
        self.velocities.push(v);
        self.angular_velocities.push([0.0; 3]);
        self.radii.push(r);
        if material != 0 && self.materials.is_empty() {
            self.materials.resize(n - 1, 0);
        }
        if !self.materials.is_empty() {
            self.materials.push(material);
        }
        self.history.grow_to(n)
    }

    /// Keeps the spheres `i` with `keep[i]`, in order: later spheres move up and take new
    /// numbers (their contact history follows them; contacts with removed spheres are
    /// dropped). A clump goes with its components, which are kept or removed together.
    pub fn retain(&mut self, keep: &[bool]) -> Result<()> {
        if keep.len() != self.len() {
            return Err(Error::Usage(format!(
                "{} flags to keep for {} spheres",
                keep.len(),
                self.len()
            )));
        }
        if !self.clumps.clumps.is_empty() {
            let owners = self.clumps.owners();
            let mut kept = vec![None; self.clumps.clumps.len()];
            for (i, &k) in owners.iter().enumerate() {
                match kept[k as usize] {
                    None => kept[k as usize] = Some(keep[i]),
                    Some(whole) if whole != keep[i] => {
                        return Err(Error::Usage(format!(
                            "clump {k} keeps some of its spheres and not others: a clump is \
                             kept or removed whole"
                        )));
                    }
                    Some(_) => {}
                }
            }
            let mut kept = kept.into_iter();
            self.clumps
                .clumps
                .retain(|_| kept.next().flatten().unwrap_or(true));
        }
        fn kept<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
            let mut k = keep.iter();
            v.retain(|_| *k.next().expect("one flag per sphere"));
        }
        kept(&mut self.positions, keep);
        if !self.position_residuals.is_empty() {
            kept(&mut self.position_residuals, keep);
        }
        kept(&mut self.velocities, keep);
        kept(&mut self.angular_velocities, keep);
        kept(&mut self.radii, keep);
        if !self.materials.is_empty() {
            kept(&mut self.materials, keep);
        }
        self.history.retain(keep);
        Ok(())
    }

    /// Sphere `i`'s material ([`Self::materials`]; 0 where there are none).
    #[inline(always)]
    pub fn material(&self, i: usize) -> u32 {
        self.materials.get(i).map_or(0, |&m| m as u32)
    }

    /// Checks every sphere's material is one of `count`; names the first that is not.
    pub fn check_materials(&self, count: usize) -> Result<()> {
        match self.materials.iter().position(|&m| m as usize >= count) {
            Some(index) => Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "material {}, but the scene has {count} material{} (a sphere's material is \
                     the place of a [[materials]] table in the scene, from 0)",
                    self.materials[index],
                    if count == 1 { "" } else { "s" }
                ),
            }),
            None => Ok(()),
        }
    }

    /// Smallest and largest radius (0 for no spheres).
    pub fn radius_range(&self) -> (f32, f32) {
        self.radii
            .iter()
            .fold(None, |acc: Option<(f32, f32)>, &r| {
                Some(acc.map_or((r, r), |(a, b)| (a.min(r), b.max(r))))
            })
            .unwrap_or((0.0, 0.0))
    }

    /// The residual of sphere `i`'s centre ([`Self::position_residuals`]; 0 where there are
    /// none).
    pub fn residual(&self, i: usize) -> [f32; 3] {
        match self.position_residuals.is_empty() {
            true => [0.0; 3],
            false => self.position_residuals[i],
        }
    }

    /// Where sphere `i` is: its centre plus its residual, in `f64` ([`position::join`]: exact
    /// but where the residual is below 2⁻⁵³ of the coordinate).
    pub fn exact_position(&self, i: usize) -> [f64; 3] {
        let (hi, lo) = (self.positions[i], self.residual(i));
        std::array::from_fn(|a| position::join(hi[a], lo[a]))
    }

    /// Every sphere's [`exact_position`](Self::exact_position), in order ([`Error::OutOfMemory`]
    /// where they do not fit).
    pub fn exact_positions(&self) -> Result<Vec<[f64; 3]>> {
        let n = self.len();
        let mut out = try_vec(n, || format!("the positions of {n} spheres"))?;
        out.extend((0..self.positions.len()).map(|i| self.exact_position(i)));
        Ok(out)
    }

    /// Puts sphere `i` at `x`: its centre `x` rounded to `f32`, its residual the rest
    /// ([`position::split`]).
    pub fn set_exact_position(&mut self, i: usize, x: [f64; 3]) -> Result<()> {
        let pairs = x.map(position::split);
        self.positions[i] = pairs.map(|(hi, _)| hi);
        let lo = pairs.map(|(_, lo)| lo);
        if lo != [0.0; 3] || !self.position_residuals.is_empty() {
            self.fill_residuals()?;
            self.position_residuals[i] = lo;
        }
        Ok(())
    }

    /// Gives every sphere its residual (0 where there were none), as a stepper keeps them
    /// ([`Error::OutOfMemory`] where they do not fit).
    pub fn fill_residuals(&mut self) -> Result<()> {
        let n = self.positions.len();
        if self.position_residuals.len() != n {
            let what = || format!("the position residuals of {n} spheres");
            crate::error::try_resize(&mut self.position_residuals, n, [0.0; 3], what)?;
        }
        Ok(())
    }
}

impl PartialEq for Particles {
    fn eq(&self, other: &Self) -> bool {
        let residuals = |p: &Particles| -> Vec<[f32; 3]> {
            (0..p.positions.len())
                .map(|i| p.position_residuals.get(i).copied().unwrap_or([0.0; 3]))
                .collect()
        };
        let lengths = |p: &Particles| p.position_residuals.len().max(p.positions.len());
        let materials = |p: &Particles| (0..p.len()).map(|i| p.material(i)).collect::<Vec<_>>();
        self.positions == other.positions
            && lengths(self) == lengths(other)
            && residuals(self) == residuals(other)
            && self.velocities == other.velocities
            && self.angular_velocities == other.angular_velocities
            && self.radii == other.radii
            && materials(self) == materials(other)
            && self.materials.len().max(self.len()) == other.materials.len().max(other.len())
            && self.history == other.history
            && self.clumps == other.clumps
            && self.step == other.step
    }
}

/// The first `n` points of the integer lattice ℤ³ in order of distance from the origin (ties
/// in the order of z, then y, then x): the origin first, then its 6 neighbours, its 12
/// diagonal ones, and so on, filling a ball. [`Particles::separate_coincident`] lays a group of
/// spheres sharing a centre on them.
fn lattice_points(n: usize) -> Result<Vec<[i32; 3]>> {
    // The ball of radius h holds about 4/3·π·h³ points: the smallest h whose ball holds n.
    let mut h = ((n as f64 * 3.0 / (4.0 * std::f64::consts::PI)).cbrt() as i32).max(1);
    loop {
        let side = 2 * h as usize + 1;
        let what = || format!("the lattice points of {n} spheres sharing a centre");
        let mut points: Vec<[i32; 3]> = try_vec(side * side * side, what)?;
        for z in -h..=h {
            for y in -h..=h {
                for x in -h..=h {
                    if x * x + y * y + z * z <= h * h {
                        points.push([x, y, z]);
                    }
                }
            }
        }
        if points.len() >= n {
            points.sort_by_key(|&[x, y, z]| (x * x + y * y + z * z, z, y, x));
            points.truncate(n);
            return Ok(points);
        }
        h += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn the_kinetic_energy_sums_each_sphere_s_translation_and_spin_by_its_material() {
        let spheres = SphereSet::new(vec![[0.0; 3], [1.0, 0.0, 0.0]], vec![0.5, 0.25]).unwrap();
        let mut p = Particles::at_rest(&spheres).unwrap();
        p.velocities = vec![[3.0, 0.0, 4.0], [0.0, 0.0, 0.0]];
        p.angular_velocities = vec![[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        p.materials = vec![0, 1];
        let e = p.energies(&[1000.0, 8000.0]);
        let volume = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        let (m0, m1) = (1000.0 * volume(0.5), 8000.0 * volume(0.25));
        assert!(
            (e.translational / (0.5 * m0 * 25.0) - 1.0).abs() < 1e-12,
            "{e:?}"
        );
        let spin = 0.5 * 0.4 * m1 * 0.25f64.powi(2) * 4.0;
        assert!((e.rotational / spin - 1.0).abs() < 1e-12, "{e:?}");
    }

    #[test]
    fn coincident_pairs_are_counted_per_shared_centre() {
        let mut p = Particles {
            positions: vec![[1.0, 2.0, 3.0], [0.0; 3], [1.0, 2.0, 3.0], [-0.0, 0.0, 0.0]],
            ..Particles::default()
        };
        p.positions.extend([[1.0, 2.0, 3.0], [5.0; 3]]);
        assert_eq!(p.coincident_pairs().unwrap(), 3 + 1);
        p.positions.truncate(2);
        assert_eq!(p.coincident_pairs().unwrap(), 0);
    }

    #[test]
    fn coincident_spheres_are_separated_and_nothing_else_moves() {
        let mut p = Particles {
            positions: vec![[1.0, 2.0, 3.0], [0.0; 3], [1.0, 2.0, 3.0], [-0.0, 0.0, 0.0]],
            radii: vec![0.5, 0.25, 0.1, 0.25],
            ..Particles::default()
        };
        p.positions.extend([[1.0, 2.0, 3.0], [5.0; 3]]);
        p.radii.extend([0.3, 1.0]);
        let before = p.positions.clone();
        assert_eq!(p.separate_coincident().unwrap(), 3 + 1);
        assert_eq!(p.coincident_pairs().unwrap(), 0);
        // The smallest index of each group and the lone sphere stay.
        for k in [0, 1, 5] {
            assert_eq!(p.positions[k], before[k]);
        }
        // The others took the nearest lattice points, a diameter of the group's largest sphere
        // and a thousandth of its radius apart: the first two neighbours along −z, then −y.
        let spacing = |r: f32| 2.0 * r + 1e-3 * r;
        let offset =
            |k: usize| -> [f32; 3] { std::array::from_fn(|a| p.positions[k][a] - before[k][a]) };
        let close = |a: [f32; 3], b: [f32; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6);
        assert!(
            close(offset(2), [0.0, 0.0, -spacing(0.5)]),
            "{:?}",
            offset(2)
        );
        assert!(
            close(offset(4), [0.0, -spacing(0.5), 0.0]),
            "{:?}",
            offset(4)
        );
        assert!(
            close(offset(3), [0.0, 0.0, -spacing(0.25)]),
            "{:?}",
            offset(3)
        );
        // Deterministic, and a no-op once apart.
        let once = p.positions.clone();
        assert_eq!(p.separate_coincident().unwrap(), 0);
        assert_eq!(p.positions, once);
    }

    #[test]
    fn a_large_coincident_group_becomes_a_cluster_with_no_overlap() {
        let n = 2000;
        let r = 0.01f32;
        let mut p = Particles {
            positions: vec![[0.5; 3]; n],
            radii: (0..n)
                .map(|k| r * (1.0 - 0.5 * (k % 3) as f32 / 3.0))
                .collect(),
            ..Particles::default()
        };
        assert_eq!(p.separate_coincident().unwrap(), (n * (n - 1) / 2) as u64);
        let mut farthest = 0.0f32;
        for i in 0..n {
            let a = Vec3::from(p.positions[i]);
            farthest = farthest.max((a - Vec3::splat(0.5)).length());
            for j in i + 1..n {
                let d = (Vec3::from(p.positions[j]) - a).length();
                assert!(d >= 2.0 * r, "spheres {i} and {j} {d} m apart");
            }
        }
        // A ball about the centre: 2000 lattice points of spacing 2r fill a ball of radius
        // about 7.8 spacings.
        assert!(farthest < 8.5 * 2.002 * r, "{farthest}");
    }

    #[test]
    fn lattice_points_fill_a_ball_nearest_first() {
        let points = lattice_points(27).unwrap();
        assert_eq!(points[0], [0, 0, 0]);
        let d2: Vec<i32> = points
            .iter()
            .map(|p| p.iter().map(|x| x * x).sum())
            .collect();
        assert!(d2.windows(2).all(|w| w[0] <= w[1]), "{d2:?}");
        // 1 + 6 + 12 + 8 points within √3.
        assert_eq!(d2.iter().filter(|&&x| x <= 3).count(), 27);
        let mut unique = points.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), 27);
        assert_eq!(lattice_points(1).unwrap(), vec![[0, 0, 0]]);
        assert_eq!(lattice_points(5000).unwrap().len(), 5000);
    }
}
