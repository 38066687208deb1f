//! The simulation state: what a checkpoint saves and a frame shows.

use crate::error::{Error, Result, try_vec};
use crate::spheres::SphereSet;

/// Spheres with velocities, in the order the user gave them, and the simulation clock.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Particles {
    /// Centres \[m\].
    pub positions: Vec<[f32; 3]>,
    /// Velocities \[m/s\].
    pub velocities: Vec<[f32; 3]>,
    /// Radii \[m\].
    pub radii: Vec<f32>,
    /// Steps taken since t = 0 (the time is `step · dt`).
    pub step: u64,
}

impl Particles {
    /// Spheres at rest at step 0 ([`Error::OutOfMemory`] when their state does not fit).
    pub fn at_rest(spheres: &SphereSet) -> Result<Self> {
        let what = || format!("the state of {} spheres", spheres.len());
        let mut positions = try_vec(spheres.len(), what)?;
        let mut velocities = try_vec(spheres.len(), what)?;
        let mut radii = try_vec(spheres.len(), what)?;
        positions.extend_from_slice(spheres.centers());
        velocities.resize(spheres.len(), [0.0; 3]);
        radii.extend_from_slice(spheres.radii());
        Ok(Self {
            positions,
            velocities,
            radii,
            step: 0,
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
        if self.positions.len() != self.len() || self.velocities.len() != self.len() {
            return Err(Error::Usage(format!(
                "particles: {} positions, {} velocities, {} radii",
                self.positions.len(),
                self.velocities.len(),
                self.len()
            )));
        }
        let bad = self
            .positions
            .iter()
            .zip(&self.velocities)
            .position(|(c, v)| c.iter().chain(v).any(|x| !x.is_finite()));
        match bad {
            Some(index) => Err(Error::InvalidSphere {
                index,
                reason: format!(
                    "non-finite position {:?} or velocity {:?} at step {}",
                    self.positions[index], self.velocities[index], self.step
                ),
            }),
            None => Ok(()),
        }
    }

    /// Pairs of spheres whose centres coincide: they have no contact normal, so the step pushes
    /// each such pair apart along the direction of `dem::model::coincident_direction`.
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
}
