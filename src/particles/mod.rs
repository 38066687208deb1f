//! The simulation state: what a checkpoint saves and a frame shows.

pub mod history;

use crate::error::{Error, Result, try_vec};
use crate::spheres::SphereSet;
use glam::Vec3;
pub use history::{ContactHistory, FIRST_MESH_WALL, FIRST_WALL, HistoryEntry, MESH_WALLS};

/// Spheres with velocities, in the order the user gave them, their contact history and the
/// simulation clock.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Particles {
    /// Centres \[m\].
    pub positions: Vec<[f32; 3]>,
    /// Velocities \[m/s\].
    pub velocities: Vec<[f32; 3]>,
    /// Angular velocities \[rad/s\].
    pub angular_velocities: Vec<[f32; 3]>,
    /// Radii \[m\].
    pub radii: Vec<f32>,
    /// The springs of the contacts that have friction or rolling resistance (empty without).
    pub history: ContactHistory,
    /// Steps taken since t = 0 (the time is `step · dt`).
    pub step: u64,
}

impl Particles {
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
            velocities,
            angular_velocities,
            radii,
            history: ContactHistory::default(),
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
            velocities: copy(&self.velocities)?,
            angular_velocities: copy(&self.angular_velocities)?,
            radii,
            history: self.history.try_clone()?,
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

    /// Checks that every value is finite and the lengths agree; names the first bad sphere.
    pub fn validate(&self) -> Result<()> {
        if self.positions.len() != self.len()
            || self.velocities.len() != self.len()
            || self.angular_velocities.len() != self.len()
        {
            return Err(Error::Usage(format!(
                "particles: {} positions, {} velocities, {} angular velocities, {} radii",
                self.positions.len(),
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
        match bad {
            Some(index) => Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "non-finite position {:?}, velocity {:?} or angular velocity {:?} at step {}",
                    self.positions[index],
                    self.velocities[index],
                    self.angular_velocities[index],
                    self.step
                ),
            }),
            None => self.history.validate(self.len()),
        }
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

    /// Moves apart spheres whose centres coincide, so that every touching pair has a contact
    /// normal: of each group sharing a centre, the sphere of the smallest index stays and every
    /// other sphere k moves by a thousandth of the group's smallest radius (at least a few `f32`
    /// steps of the centre's coordinates) along `coincident_direction`
    /// of the two indices. The contact forces then push the group apart radially. Deterministic,
    /// and a no-op where no centres coincide. Returns how many pairs coincided.
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
        let mut pairs = 0;
        for group in keys.chunk_by(|a, b| a.0 == b.0).filter(|g| g.len() > 1) {
            pairs += (group.len() as u64) * (group.len() as u64 - 1) / 2;
            let first = group[0].1;
            let centre = self.positions[first as usize];
            let r = group
                .iter()
                .map(|&(_, k)| self.radii[k as usize])
                .fold(f32::INFINITY, f32::min);
            let coarsest = centre
                .iter()
                .map(|x| x.abs().next_up() - x.abs())
                .fold(0.0f32, f32::max);
            let step = (1e-3 * r).max(8.0 * coarsest);
            for &(_, k) in &group[1..] {
                let u = coincident_direction(first, k);
                self.positions[k as usize] = (Vec3::from(centre) + step * u).to_array();
            }
        }
        Ok(pairs)
    }

    /// Adds a sphere at `c` with velocity `v`, radius `r`, no spin and no contacts; refuses
    /// more spheres than ids below the walls'.
    pub fn push(&mut self, c: [f32; 3], v: [f32; 3], r: f32) -> Result<()> {
        let n = self.len() + 1;
        if n > FIRST_MESH_WALL as usize {
            return Err(Error::TooLarge {
                what: "spheres of a run (ids above are the walls')".into(),
                got: n as u64,
                limit: FIRST_MESH_WALL as u64,
            });
        }
        self.positions.push(c);
        self.velocities.push(v);
        self.angular_velocities.push([0.0; 3]);
        self.radii.push(r);
        self.history.grow_to(n)
    }

    /// Keeps the spheres `i` with `keep[i]`, in order: later spheres move up and take new
    /// numbers (their contact history follows them; contacts with removed spheres are
    /// dropped).
    pub fn retain(&mut self, keep: &[bool]) -> Result<()> {
        if keep.len() != self.len() {
            return Err(Error::Usage(format!(
                "{} flags to keep for {} spheres",
                keep.len(),
                self.len()
            )));
        }
        fn kept<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
            let mut k = keep.iter();
            v.retain(|_| *k.next().expect("one flag per sphere"));
        }
        kept(&mut self.positions, keep);
        kept(&mut self.velocities, keep);
        kept(&mut self.angular_velocities, keep);
        kept(&mut self.radii, keep);
        self.history.retain(keep);
        Ok(())
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
}

/// A unit vector picked by a hash of two sphere indices `lo < hi`: the direction in which
/// [`Particles::separate_coincident`] moves sphere `hi`
/// away from the sphere `lo` whose centre it shares. Different pairs take different directions,
/// the same pair always the same.
#[inline]
fn coincident_direction(lo: u32, hi: u32) -> Vec3 {
    let mut h = lo.wrapping_mul(0x9E37_79B9) ^ hi.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    // Components (k − 511.5) for k in 0..1024: never all zero.
    let d = Vec3::from([0, 10, 20].map(|shift| ((h >> shift) & 1023) as f32 - 511.5));
    d / d.length()
}

#[cfg(test)]
mod tests {
    use super::*;

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
        // The others moved a thousandth of their group's smallest radius, each its own way.
        for (k, r) in [(2, 0.1f32), (4, 0.1), (3, 0.25)] {
            let d = (0..3)
                .map(|a| (p.positions[k][a] - before[k][a]).powi(2))
                .sum::<f32>();
            assert!((d.sqrt() - 1e-3 * r).abs() < 1e-6 * r, "{k}: {}", d.sqrt());
        }
        assert_ne!(p.positions[2], p.positions[4]);
        // Deterministic, and a no-op once apart.
        let once = p.positions.clone();
        assert_eq!(p.separate_coincident().unwrap(), 0);
        assert_eq!(p.positions, once);
    }

    #[test]
    fn coincident_directions_are_unit_and_differ_by_pair() {
        let u = coincident_direction(3, 7);
        assert!((u.length_squared() - 1.0).abs() < 1e-6);
        assert_ne!(u, coincident_direction(3, 8));
        assert_eq!(u, coincident_direction(3, 7));
    }
}
