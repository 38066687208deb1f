//! The simulation state: what a checkpoint saves and a frame shows.

use crate::error::{Error, Result};
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
    /// Spheres at rest at step 0.
    pub fn at_rest(spheres: &SphereSet) -> Self {
        Self {
            positions: spheres.centers().to_vec(),
            velocities: vec![[0.0; 3]; spheres.len()],
            radii: spheres.radii().to_vec(),
            step: 0,
        }
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
