//! The [`Stepper`] trait that every backend's DEM step implements.

use super::flow::FlowCounts;
use super::model::{NormalLaw, StepParams};
use super::walls::{WallLoad, WallSet};
use crate::error::{Error, Result};
use crate::particles::Particles;

/// Time spent per phase of the step, summed over the steps of one [`Stepper::advance`] \[ms\].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Maintaining the acceleration structure (binning, sorting, building).
    pub build_ms: f64,
    /// Collision detection with the contact forces resolved in the same pass.
    pub dcd_ms: f64,
    /// Walls, gravity and integration.
    pub update_ms: f64,
}

impl StageTimes {
    /// All three phases.
    pub fn total_ms(&self) -> f64 {
        self.build_ms + self.dcd_ms + self.update_ms
    }

    /// Adds `other` to these sums.
    pub fn add(&mut self, other: &StageTimes) {
        self.build_ms += other.build_ms;
        self.dcd_ms += other.dcd_ms;
        self.update_ms += other.update_ms;
    }
}

/// One rank's share of a run decomposed over ranks (the `distributed` module), since it opened:
/// its spheres and ghosts, and where its wall time went.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RankShare {
    /// The spheres it owns now.
    pub spheres: u64,
    /// Its ghosts in its last round.
    pub ghosts: u64,
    /// Rounds taken (one exchange of ghosts each).
    pub rounds: u64,
    /// Steps taken.
    pub steps: u64,
    /// Exchanging ghosts and handing on the spheres that left its slab \[ms\].
    pub exchange_ms: f64,
    /// Laying its spheres and ghosts out and giving them to its engine (on a GPU, opening it
    /// over them: an upload) \[ms\].
    pub open_ms: f64,
    /// Its engine's steps \[ms\].
    pub step_ms: f64,
    /// Reading its spheres back from its engine and counting their contacts \[ms\].
    pub read_back_ms: f64,
}

impl RankShare {
    /// Its wall time a step, all phases \[ms\].
    pub fn ms_a_step(&self) -> f64 {
        let total = self.exchange_ms + self.open_ms + self.step_ms + self.read_back_ms;
        total / self.steps.max(1) as f64
    }
}

/// How the stage times were taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    /// GPU timestamps: time on the device itself.
    Gpu,
    /// Host wall-clock time around each phase.
    Wall,
    /// Not measured (a GPU without timestamps).
    None,
}

/// What one [`Stepper::advance`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Advance {
    /// Steps taken.
    pub steps: u32,
    /// Touching pairs found in the last step.
    pub contacts: u64,
    /// Phase times summed over the steps.
    pub times: StageTimes,
    /// How `times` were measured.
    pub clock: Clock,
}

/// The refusal of new motion for a clump's component sphere.
pub(crate) fn clump_motion_refused() -> Error {
    Error::Usage(
        "the motion of a clump's spheres (the first spheres of a run of clumps) is its clump's: \
         they keep the rows they have (setting a clump's motion: not yet)"
            .into(),
    )
}

/// New motion for the spheres of a step, in input order, one row per sphere the step holds
/// (`None`: kept as it is). A position is where its sphere is: the step keeps it as an `f32`
/// centre and the residual of the rest ([`crate::dem::position::split`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Motion<'a> {
    /// Positions \[m\].
    pub positions: Option<&'a [[f64; 3]]>,
    /// Velocities \[m/s\].
    pub velocities: Option<&'a [[f32; 3]]>,
    /// Angular velocities \[rad/s\].
    pub angular_velocities: Option<&'a [[f32; 3]]>,
}

impl Motion<'_> {
    /// Refuses motion that changes a clump's component (the first spheres of a run of
    /// clumps, as `now` holds them): its motion is its clump's, so its rows must be as they are.
    pub fn check_clumps(&self, now: &Particles) -> Result<()> {
        let components = now.clumps.component_count().min(now.len());
        if components == 0 {
            return Ok(());
        }
        let same = |given: Option<&[[f32; 3]]>, now: &[[f32; 3]]| {
            given.is_none_or(|g| g.len() < components || g[..components] == now[..components])
        };
        let placed = self.positions.is_none_or(|g| {
            g.len() < components || (0..components).all(|k| g[k] == now.exact_position(k))
        });
        match placed
            && same(self.velocities, &now.velocities)
            && same(self.angular_velocities, &now.angular_velocities)
        {
            true => Ok(()),
            false => Err(clump_motion_refused()),
        }
    }

    /// Refuses motion for other than `n` spheres, values that are not finite and positions
    /// beyond `f32`'s range, naming the sphere.
    pub fn check(&self, n: usize) -> Result<()> {
        let rows: [(&str, Option<Vec<[f64; 3]>>); 3] = [
            ("positions", self.positions.map(<[_]>::to_vec)),
            ("velocities", self.velocities.map(widened_rows)),
            (
                "angular velocities",
                self.angular_velocities.map(widened_rows),
            ),
        ];
        for (what, values) in rows {
            let Some(values) = values else { continue };
            if values.len() != n {
                return Err(Error::Usage(format!(
                    "{what} of {} spheres given to a step of {n}",
                    values.len()
                )));
            }
            let bad = values.iter().position(|v| {
                v.iter()
                    .any(|x| !x.is_finite() || (*x as f32).is_infinite())
            });
            if let Some(index) = bad {
                return Err(Error::InvalidSphere {
                    index,
                    reason: format!(
                        "its {what} {:?} are not finite in single precision",
                        values[index]
                    ),
                });
            }
        }
        Ok(())
    }

    /// Whether nothing changes.
    pub fn is_empty(&self) -> bool {
        self.positions.is_none() && self.velocities.is_none() && self.angular_velocities.is_none()
    }

    /// Whether the motion turns some sphere (an angular velocity not zero).
    pub fn turns(&self) -> bool {
        self.angular_velocities
            .is_some_and(|w| w.iter().flatten().any(|&x| x != 0.0))
    }

    /// Writes the motion into `particles` (in input order; [`check`](Self::check)ed).
    pub fn apply(&self, particles: &mut Particles) -> Result<()> {
        self.check(particles.len())?;
        if let Some(positions) = self.positions {
            for (i, &x) in positions.iter().enumerate() {
                particles.set_exact_position(i, x)?;
            }
        }
        if let Some(v) = self.velocities {
            particles.velocities.copy_from_slice(v);
        }
        if let Some(w) = self.angular_velocities {
            particles.angular_velocities.copy_from_slice(w);
        }
        Ok(())
    }
}

/// Forces and torques applied to the spheres every step besides their contacts and gravity, in
/// input order, until changed: the loads of user code (a fluid's drag, a controller's push).
/// Each list holds one row per sphere or none (no load of that kind).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExternalLoads {
    /// Forces \[N\].
    pub forces: Vec<[f32; 3]>,
    /// Torques about the centres \[N·m\].
    pub torques: Vec<[f32; 3]>,
}

impl ExternalLoads {
    /// Refuses lists of other than `n` rows and values that are not finite, naming the sphere.
    pub fn check(&self, n: usize) -> Result<()> {
        for (what, rows) in [("forces", &self.forces), ("torques", &self.torques)] {
            if !rows.is_empty() && rows.len() != n {
                return Err(Error::Usage(format!(
                    "external {what} of {} spheres given to a step of {n}",
                    rows.len()
                )));
            }
            if let Some(index) = rows.iter().position(|r| r.iter().any(|x| !x.is_finite())) {
                return Err(Error::InvalidSphere {
                    index,
                    reason: format!("its external {what} {:?} are not finite", rows[index]),
                });
            }
        }
        Ok(())
    }

    /// Whether no sphere has a load.
    pub fn is_empty(&self) -> bool {
        let zero = |rows: &[[f32; 3]]| rows.iter().flatten().all(|&x| x == 0.0);
        zero(&self.forces) && zero(&self.torques)
    }

    /// Whether some torque is not zero.
    pub fn turns(&self) -> bool {
        self.torques.iter().flatten().any(|&x| x != 0.0)
    }

    /// The force on sphere `i` (zero where there are none).
    pub fn force(&self, i: usize) -> [f32; 3] {
        self.forces.get(i).copied().unwrap_or_default()
    }

    /// The torque on sphere `i` (zero where there are none).
    pub fn torque(&self, i: usize) -> [f32; 3] {
        self.torques.get(i).copied().unwrap_or_default()
    }

    /// The loads of `n` spheres as GPU rows by input index: sphere i's force at row 2·i and its
    /// torque at row 2·i + 1, each `vec4(x, y, z, 0)`.
    pub fn rows(&self, n: usize) -> Vec<[f32; 4]> {
        (0..n)
            .flat_map(|i| {
                let ([fx, fy, fz], [tx, ty, tz]) = (self.force(i), self.torque(i));
                [[fx, fy, fz, 0.0], [tx, ty, tz, 0.0]]
            })
            .collect()
    }
}

/// `rows` in `f64`.
fn widened_rows(rows: &[[f32; 3]]) -> Vec<[f64; 3]> {
    rows.iter().map(|r| r.map(f64::from)).collect()
}

/// What a frame or a picture shows of a run ([`Stepper::snapshot`]): its particles without
/// their springs, and the contacts each sphere holds.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    /// The particles, in input order, their history empty.
    pub particles: Particles,
    /// The contacts each sphere holds in the run's history, by sphere (all zero where the run
    /// keeps none).
    pub contacts: Vec<u32>,
}

impl Snapshot {
    /// The snapshot of `particles`: their history's counts, the history dropped.
    pub fn of(mut particles: Particles) -> Self {
        let contacts = particles.history.counts(particles.len());
        particles.history = Default::default();
        Self {
            particles,
            contacts,
        }
    }
}

/// One backend's DEM step: keeps the particles (on the GPU for GPU backends) and advances them.
/// `Send`, as the detection `Backend` is, so that a caller may step it on another thread (Python
/// releases its interpreter lock while it steps).
pub trait Stepper: Send {
    /// Backend name and device, in words.
    fn describe(&self) -> String;

    /// Takes `steps` time steps.
    fn advance(&mut self, steps: u32) -> Result<Advance>;

    /// [`advance`](Self::advance) for a caller that needs not this call's contacts: a step that
    /// counts them at a cost (a run over GPU ranks reads every sphere back) reports those it
    /// counted last instead; the others count them as `advance` does.
    fn advance_uncounted(&mut self, steps: u32) -> Result<Advance> {
        self.advance(steps)
    }

    /// Steps taken since t = 0 (the particles' step).
    fn step(&self) -> u64;

    /// The particles now, in input order (a read-back on GPU backends).
    fn particles(&mut self) -> Result<Particles>;

    /// The particles now without their springs, each sphere's contacts counted: what frames
    /// and pictures show. Default: [`particles`](Self::particles), counted; a GPU step reads no
    /// springs back, a run over ranks gathers none.
    fn snapshot(&mut self) -> Result<Snapshot> {
        Ok(Snapshot::of(self.particles()?))
    }

    /// Sets the spheres' positions, velocities or angular velocities before the next step, the
    /// rest of their state (radii, materials, contact history) kept. A GPU step writes them
    /// where its state lies, in its own order of the spheres. Refuses an angular velocity in a
    /// step that does not turn its spheres (the paper's frictionless law).
    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()>;

    /// Sets gravity at t = 0 \[m/s²\] (turned by the scene's gravity spin from there) from the
    /// next step on ([`StepParams::with_gravity`] checks a value first).
    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()>;

    /// Applies `loads` ([`check`](ExternalLoads::check)ed by the caller) every step from the
    /// next on, until changed; replaces the loads given before. Refuses a torque in a step that
    /// does not turn its spheres (the paper's frictionless law). A GPU step keeps them on the
    /// device, read by its integration only while some sphere has a load.
    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()>;

    /// The force and torque the spheres exerted on each mesh wall in the last step, in the
    /// scene's order of walls (default: none, for a step without mesh walls).
    fn wall_loads(&self) -> Vec<WallLoad> {
        Vec::new()
    }

    /// What the inflows and outflows did since the step opened (default: `None`, a step
    /// without them).
    fn flow_counts(&self) -> Option<FlowCounts> {
        None
    }

    /// Whether this step refits its acceleration structure between rebuilds, and so obeys the
    /// engines' `Options::rebuild` (default: no; grids re-bin and `wgpu-rq` rebuilds every
    /// step).
    fn refits(&self) -> bool {
        false
    }

    /// The grid build this step chose, in words (`dense` or `sorted`), where the backend has a
    /// choice (`wgpu-compute`); default `None`.
    fn grid_build(&self) -> Option<&'static str> {
        None
    }

    /// Each rank's share of a run decomposed over ranks, by rank (default: none, a run of one
    /// process). Every rank of the run calls it alike.
    fn rank_shares(&mut self) -> Result<Vec<RankShare>> {
        Ok(Vec::new())
    }

    /// The steps that one exchange of a run over ranks covers (default 1): a caller that
    /// advances in calls of a multiple of it lets each call end where a round does.
    fn steps_a_round(&self) -> u32 {
        1
    }

    /// Where this is a run over ranks: writes the frame of the spheres now in pieces in the
    /// series folder `dir`, each rank the piece of its own spheres
    /// ([`crate::io::piece_path`]), none gathered, and returns each piece's spheres, by rank
    /// (the `.pvtu` that names them is [`crate::io::FrameSeries::add_pieces`]'s). Every rank
    /// of the run calls it alike. Default: `None`, a run of one process, which writes whole
    /// frames.
    fn write_pieces(&mut self, _dir: &std::path::Path) -> Result<Option<Vec<u64>>> {
        Ok(None)
    }

    /// Where this is a run over ranks: writes the checkpoint of the spheres now (their contact
    /// history with them) in pieces into the checkpoint's folder of pieces `folder`
    /// ([`crate::io::piece_folder_for`]), each rank the piece of its own spheres, none
    /// gathered, and returns what the index names of each piece, by rank (the index is
    /// [`crate::io::write_checkpoint_index`]'s). Every rank of the run calls it alike.
    /// Default: `None`, a run of one process, which writes whole checkpoints.
    fn write_checkpoint_pieces(
        &mut self,
        _folder: &std::path::Path,
    ) -> Result<Option<Vec<crate::io::CheckpointPiece>>> {
        Ok(None)
    }
}

/// Whether a run needs more than the paper's step (the engines' granular step): anything beyond
/// the paper's law (linear, one stiffness, one material, no friction, no rolling resistance, no
/// spin, no history, no clumps) or the box walls alone. Without, the paper's kernels run it with the same
/// work as before the granular step existed (they read one law: a scene of several materials
/// needs the granular step, which reads each contact's from the material table).
pub fn needs_granular_step(particles: &Particles, params: &StepParams, walls: &WallSet) -> bool {
    !walls.is_box_only()
        || params.law != NormalLaw::Linear
        || params.materials.count > 1
        || params.friction.turns()
        || particles.spin()
        || !particles.history.is_empty()
        || params.adheres()
        || !particles.clumps.clumps.is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::{ContactHistory, FIRST_WALL, HistoryEntry};

    #[test]
    fn only_the_papers_law_in_the_box_runs_the_papers_step() {
        use crate::dem::model::{ContactLaw, Material};
        let params = |m: Material| {
            StepParams::new(&m, 1e-6, [0.0; 3], [1.0; 3], [0.0, 0.0, -9.81], 0.0, 5e-4).unwrap()
        };
        let still = Particles {
            positions: vec![[0.5; 3]],
            velocities: vec![[0.0; 3]],
            angular_velocities: vec![[0.0; 3]],
            radii: vec![5e-4],
            ..Particles::default()
        };
        let paper = params(Material::default());
        let in_box = WallSet::default();
        assert!(!needs_granular_step(&still, &paper, &in_box));
        let open_box = WallSet::new(false, Vec::new()).unwrap();
        assert!(needs_granular_step(&still, &paper, &open_box));
        let more = [
            Material {
                friction: 0.5,
                ..Material::default()
            },
            Material {
                wall_friction: Some(0.5),
                ..Material::default()
            },
            Material {
                rolling_friction: 0.1,
                ..Material::default()
            },
            Material {
                contact: ContactLaw::LinearPerPair { contact_time: None },
                ..Material::default()
            },
            Material {
                contact: ContactLaw::HertzMindlin {
                    young_modulus: 1e7,
                    poisson_ratio: 0.3,
                },
                ..Material::default()
            },
        ];
        for m in more {
            assert!(needs_granular_step(&still, &params(m), &in_box), "{m:?}");
        }
        // Two materials of the paper's law: each pair's damping from the table.
        let two = crate::dem::model::Materials {
            list: vec![Material::default(), Material::default()],
            names: vec!["a".into(), "b".into()],
            pairs: Vec::new(),
        };
        let p2 = StepParams::with_materials(
            &two,
            None,
            1e-6,
            [0.0; 3],
            [1.0; 3],
            [0.0, 0.0, -9.81],
            0.0,
            5e-4,
        )
        .unwrap();
        assert!(needs_granular_step(&still, &p2, &in_box));
        let spinning = Particles {
            angular_velocities: vec![[0.0, 1.0, 0.0]],
            ..still.clone()
        };
        assert!(needs_granular_step(&spinning, &paper, &in_box));
        let remembering = Particles {
            history: ContactHistory::from_contacts(
                1,
                &[(
                    0,
                    HistoryEntry {
                        partner: FIRST_WALL,
                        ..HistoryEntry::default()
                    },
                )],
            )
            .unwrap(),
            ..still
        };
        assert!(needs_granular_step(&remembering, &paper, &in_box));
    }
}
