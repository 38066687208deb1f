//! The state every GPU step keeps in rows (`vec4` centres and radii, residuals, velocities and
//! masses), to and from [`Particles`], and the loop that runs a step's batches.

use crate::dem::model::MaterialTable;
use crate::dem::stepper::{Advance, Clock, StageTimes};
use crate::error::{Error, Result};
use crate::particles::{ContactHistory, Particles};
use rayon::prelude::*;

/// What the granular step adds to the particles a GPU step reads back.
pub(crate) struct Rotation {
    /// Angular velocities, in the order of the engine's state read with them \[rad/s\].
    pub angular_velocities: Vec<[f32; 3]>,
    /// Materials, in that order (empty: all of the first material).
    pub materials: Vec<u8>,
    /// The contact history in the cpu's layout (both sides of each pair).
    pub history: ContactHistory,
}

/// `vec4(x, y, z, r)` and `vec4(vx, vy, vz, mass)` rows of `particles`, in input order, each
/// mass by the density of the sphere's material in `table`, a clump's component's its clump's
/// (as the cpu step's).
pub(crate) fn rows(particles: &Particles, table: &MaterialTable) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let pos = particles
        .positions
        .iter()
        .zip(&particles.radii)
        .map(|(c, &r)| [c[0], c[1], c[2], r])
        .collect();
    let clumps = particles.clumps.component_masses();
    let vel = particles
        .velocities
        .iter()
        .enumerate()
        .map(|(i, v)| [v[0], v[1], v[2], mass_of(particles, table, &clumps, i)])
        .collect();
    (pos, vel)
}

/// Each sphere's mass as its contacts see it: by its material's density in `table`, a clump's
/// component's its clump's ([`Error::OutOfMemory`] where they do not fit).
pub(crate) fn contact_masses(particles: &Particles, table: &MaterialTable) -> Result<Vec<f32>> {
    let n = particles.len();
    let clumps = particles.clumps.component_masses();
    let mut masses = crate::error::try_vec(n, || format!("the masses of {n} spheres"))?;
    masses.extend((0..n).map(|i| mass_of(particles, table, &clumps, i)));
    Ok(masses)
}

/// Sphere `i`'s mass: its clump's (`clumps`: each component's) or its own by its material.
fn mass_of(particles: &Particles, table: &MaterialTable, clumps: &[f64], i: usize) -> f32 {
    match clumps.get(i) {
        Some(&m) => m as f32,
        None => table.mass(particles.material(i), particles.radii[i]),
    }
}

/// `vec4(lo_x, lo_y, lo_z, 0)` rows of the residuals of the centres of `particles`, in input
/// order (zeros where they have none).
pub(crate) fn residual_rows(particles: &Particles) -> Vec<[f32; 4]> {
    (0..particles.len())
        .map(|i| {
            let [x, y, z] = particles.residual(i);
            [x, y, z, 0.0]
        })
        .collect()
}

/// The state rows a GPU step reads back: centres and radii, the centres' residuals, velocities
/// and masses.
pub(crate) struct StateRows<'a> {
    pub pos: &'a [[f32; 4]],
    pub lo: &'a [[f32; 4]],
    pub vel: &'a [[f32; 4]],
}

/// Particles from rows read back in the order `ids` gives (`None`: input order), of the paper's
/// step (no rotation, no history): the optix step's.
#[cfg(feature = "optix")]
pub(crate) fn particles_from(rows: StateRows, ids: Option<&[u32]>, step: u64) -> Result<Particles> {
    particles_with(rows, ids, step, || Ok(None))
}

/// As [`particles_from`], with the angular velocities and materials (in the rows' order) and
/// contact history of a granular step (`None`: the paper's step, whose spheres are all of the
/// first material).
pub(crate) fn particles_with(
    rows: StateRows,
    ids: Option<&[u32]>,
    step: u64,
    rotation: impl FnOnce() -> Result<Option<Rotation>>,
) -> Result<Particles> {
    let StateRows { pos, lo, vel } = rows;
    let n = pos.len();
    // A run that blew up says so by its state before its history says anything.
    let finite = |row: &[f32; 4]| row.iter().all(|x| x.is_finite());
    let unstable = (0..n).into_par_iter();
    if let Some(k) = unstable.find_first(|&k| !(finite(&pos[k]) && finite(&vel[k]))) {
        return Err(Error::Unstable {
            step,
            sphere: ids.map_or(k, |ids| ids[k] as usize),
            what: format!(
                "has position {:?} and velocity {:?}",
                &pos[k][..3],
                &vel[k][..3]
            ),
        });
    }
    let rotation = rotation()?.unwrap_or_else(|| Rotation {
        angular_velocities: vec![[0.0; 3]; n],
        materials: Vec::new(),
        history: Default::default(),
    });
    // The row of each sphere (of input index i): the rows gathered into input order on every
    // core.
    let row_of: Option<Vec<u32>> = ids.map(|ids| {
        let mut rows = vec![0; n];
        for (k, &i) in ids.iter().enumerate() {
            rows[i as usize] = k as u32;
        }
        rows
    });
    let row = |i: usize| row_of.as_ref().map_or(i, |rows| rows[i] as usize);
    let spins = rotation.angular_velocities;
    let materials = rotation.materials;
    let mut out = Particles {
        positions: vec![[0.0; 3]; n],
        position_residuals: vec![[0.0; 3]; n],
        velocities: vec![[0.0; 3]; n],
        angular_velocities: vec![[0.0; 3]; n],
        radii: vec![0.0; n],
        // Every sphere of the first material: none listed.
        materials: Vec::new(),
        history: rotation.history,
        // The engine that runs clumps reads them apart.
        clumps: Default::default(),
        step,
    };
    // Each sphere's row read once for all its columns, a piece of the spheres a task.
    const PIECE: usize = 1 << 14;
    let triple = |r: &[f32; 4]| [r[0], r[1], r[2]];
    (out.positions.par_chunks_mut(PIECE))
        .zip(out.position_residuals.par_chunks_mut(PIECE))
        .zip(out.velocities.par_chunks_mut(PIECE))
        .zip(out.angular_velocities.par_chunks_mut(PIECE))
        .zip(out.radii.par_chunks_mut(PIECE))
        .enumerate()
        .for_each(|(piece, ((((x, l), v), w), r))| {
            for j in 0..x.len() {
                let k = row(piece * PIECE + j);
                (x[j], l[j], v[j]) = (triple(&pos[k]), triple(&lo[k]), triple(&vel[k]));
                (w[j], r[j]) = (spins[k], pos[k][3]);
            }
        });
    if materials.par_iter().any(|&m| m != 0) {
        out.materials = (0..n).into_par_iter().map(|i| materials[row(i)]).collect();
    }
    out.check_stable()?;
    Ok(out)
}

/// Runs `steps` steps as batches: `batch(left)` runs some of the `left` steps and returns how
/// many, the contacts of its last step and its phase times (`None` without timestamps).
pub(crate) fn advance_in_batches(
    steps: u32,
    timed: bool,
    mut batch: impl FnMut(u32) -> Result<(u32, u64, Option<StageTimes>)>,
) -> Result<Advance> {
    let mut times = StageTimes::default();
    let mut timed = timed;
    let mut contacts = 0;
    let mut left = steps;
    while left > 0 {
        let (done, c, t) = batch(left)?;
        contacts = c;
        match t {
            Some(t) => times.add(&t),
            None => timed = false,
        }
        left -= done;
    }
    Ok(Advance {
        steps,
        contacts,
        times,
        clock: if timed { Clock::Gpu } else { Clock::None },
    })
}

/// Writes `positions` (in input order) into a step's rows of centres `pos` (x, y, z, r) and
/// residuals `lo` (x, y, z, 0), row k holding sphere `order[k]` (sphere k where `None`); each
/// row's `w` kept.
pub(crate) fn place_positions(
    positions: &[[f64; 3]],
    order: Option<&[u32]>,
    pos: &mut [[f32; 4]],
    lo: &mut [[f32; 4]],
) {
    for (k, (centre, residual)) in pos.iter_mut().zip(lo.iter_mut()).enumerate() {
        let pairs = positions[sphere_of(order, k)].map(crate::particles::position::split);
        for a in 0..3 {
            (centre[a], residual[a]) = pairs[a];
        }
    }
}

/// Writes `values` (three per sphere, in input order) into a step's `rows` (x, y, z, w: a
/// velocity and its mass, an angular velocity and its material), row k holding sphere
/// `order[k]` (sphere k where `None`); each row's `w` kept.
pub(crate) fn place_triples(values: &[[f32; 3]], order: Option<&[u32]>, rows: &mut [[f32; 4]]) {
    for (k, row) in rows.iter_mut().enumerate() {
        row[..3].copy_from_slice(&values[sphere_of(order, k)]);
    }
}

/// The sphere row `k` holds.
fn sphere_of(order: Option<&[u32]>, k: usize) -> usize {
    order.map_or(k, |ids| ids[k] as usize)
}

/// The error of an angular velocity or a torque given to a step that does not turn its
/// spheres.
pub(crate) fn no_spin() -> Error {
    Error::Usage(
        "this run's step does not turn its spheres (the paper's frictionless law, no spin at \
         its start): start a run whose spheres spin, or with friction or rolling resistance, to \
         set angular velocities or torques"
            .into(),
    )
}

/// The error of external loads given to a step whose spheres enter or leave.
pub(crate) fn not_fixed() -> Error {
    Error::Usage(
        "external loads are given per sphere, and this run's inflows or outflows change its \
         spheres: run without flows to apply external loads"
            .into(),
    )
}
