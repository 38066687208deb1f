//! A frame or a checkpoint of a run over ranks written in pieces ([`crate::io::piece_path`],
//! [`crate::io::checkpoint_piece_path`]): each rank writes the piece of its own spheres, then
//! every rank hears what every other wrote, so that all return alike.

use super::comm::Comm;
use super::record::{Held, SphereRecord, spheres_of};
use crate::dem::StepParams;
use crate::error::{Error, Result};
use crate::io::{self, Frame};
use crate::particles::{HistoryEntry, LoadEntry, Particles};
use rayon::prelude::*;
use std::path::Path;

/// Writes the piece of `own`, this rank's spheres (each with its contacts counted), of the
/// frame at `step` of a run of `params` in the series folder `dir`, and returns each piece's
/// spheres, by rank. Every rank of `comm` calls it alike; where a rank could not write its
/// piece, every rank returns an error (that rank its own).
pub(super) fn write_pieces<C: Comm>(
    comm: &C,
    own: Vec<SphereRecord>,
    (step, params): (u64, &StepParams),
    dir: &Path,
) -> Result<Vec<u64>> {
    let written = write_piece(own, (step, params), dir, comm.rank());
    hear_every_piece(comm, written, "piece of the frame")
}

/// Writes `own`, this rank's piece of the checkpoint, into the checkpoint's folder of pieces
/// `folder`, and returns what the index names of each piece, by rank. Every rank of `comm`
/// calls it alike; where a rank could not write its piece, every rank returns an error (that
/// rank its own).
pub(super) fn write_checkpoint_pieces<C: Comm>(
    comm: &C,
    own: &OwnPiece,
    folder: &Path,
) -> Result<Vec<io::CheckpointPiece>> {
    let share = io::PieceSpheres {
        ids: &own.ids,
        spheres: &own.spheres,
        contacts: &own.contacts,
        loads: &own.loads,
    };
    let written = io::write_checkpoint_piece(folder, comm.rank(), &share);
    hear_every_piece(comm, written, "piece of the checkpoint")
}

/// A rank's own spheres as its piece of a checkpoint holds them: their whole-run ids
/// (ascending), their state (no history), their contacts (each owner a place in the piece,
/// each partner a whole-run id or a wall's) and the contacts' load histories.
pub(super) struct OwnPiece {
    pub ids: Vec<u32>,
    pub spheres: Particles,
    pub contacts: Vec<(u32, HistoryEntry)>,
    pub loads: Vec<LoadEntry>,
}

impl OwnPiece {
    /// The spheres of `own` (in any order) at `step`.
    pub fn of_held(own: &[Held], step: u64) -> Self {
        let mut sorted: Vec<&Held> = own.iter().collect();
        sorted.par_sort_unstable_by_key(|h| h.sphere.id);
        Self {
            ids: sorted.par_iter().map(|h| h.sphere.id).collect(),
            spheres: spheres_of(&sorted, |h| &h.sphere, step),
            contacts: (sorted.par_iter().enumerate())
                .flat_map_iter(|(at, h)| h.contacts.iter().map(move |&e| (at as u32, e)))
                .collect(),
            loads: (sorted.par_iter())
                .flat_map_iter(|h| h.loads.iter().copied())
                .collect(),
        }
    }

    /// The spheres of `p` at `places`, of the whole-run ids `ids` (ascending, one a place),
    /// their contacts' partners renamed by `rename`.
    pub fn of_places(
        p: &Particles,
        (ids, places): (Vec<u32>, &[usize]),
        rename: impl Fn(&HistoryEntry) -> HistoryEntry + Sync,
    ) -> Self {
        let column = |c: &[[f32; 3]]| places.par_iter().map(|&at| c[at]).collect();
        let mut spheres = Particles {
            positions: column(&p.positions),
            position_residuals: places.par_iter().map(|&at| p.residual(at)).collect(),
            velocities: column(&p.velocities),
            angular_velocities: column(&p.angular_velocities),
            radii: places.par_iter().map(|&at| p.radii[at]).collect(),
            materials: places.par_iter().map(|&at| p.material(at) as u8).collect(),
            step: p.step,
            ..Particles::default()
        };
        // Every sphere of the first material: the list left empty, as a run of one keeps it.
        if spheres.materials.iter().all(|&m| m == 0) {
            spheres.materials.clear();
        }
        let (history, rename) = (&p.history, &rename);
        Self {
            ids,
            spheres,
            contacts: (places.par_iter().enumerate())
                .flat_map_iter(|(j, &at)| history.of(at).iter().map(move |e| (j as u32, rename(e))))
                .collect(),
            loads: (places.par_iter())
                .flat_map_iter(|&at| history.loads_of(at).iter().copied())
                .collect(),
        }
    }
}

/// Every rank's word on the piece of `what` it wrote (`written`: what it tells of the piece,
/// `T`'s bytes, or its error), by rank: where a rank could not write, an error on every rank
/// (that rank its own, the others naming it).
fn hear_every_piece<C: Comm, T: bytemuck::Pod>(
    comm: &C,
    written: Result<T>,
    what: &str,
) -> Result<Vec<T>> {
    let status = match &written {
        Ok(told) => [&[0], bytemuck::bytes_of(told)].concat(),
        Err(e) => [&[1], e.to_string().as_bytes()].concat(),
    };
    let received = comm.exchange(vec![status; comm.size()])?;
    let mut told = Vec::with_capacity(received.len());
    for (r, message) in received.into_iter().enumerate() {
        match message.split_first() {
            Some((0, word)) if word.len() == std::mem::size_of::<T>() => {
                told.push(bytemuck::pod_read_unaligned(word))
            }
            Some((1, why)) => {
                return Err(match written {
                    Err(e) if r == comm.rank() => e,
                    _ => Error::Usage(format!(
                        "process {r} could not write its {what}: {}",
                        String::from_utf8_lossy(why)
                    )),
                });
            }
            _ => {
                return Err(Error::Usage(format!(
                    "a rank's word on its {what} is not one"
                )));
            }
        }
    }
    Ok(told)
}

/// Writes `own` as piece `piece`, in the order of their ids; returns how many.
fn write_piece(
    mut own: Vec<SphereRecord>,
    (step, params): (u64, &StepParams),
    dir: &Path,
    piece: usize,
) -> Result<u64> {
    own.par_sort_unstable_by_key(|s| s.id);
    let spheres = spheres_of(&own, |s| s, step);
    let ids: Vec<u32> = own.par_iter().map(|s| s.id).collect();
    let contacts: Vec<u32> = own.par_iter().map(|s| s.contacts).collect();
    let kept = params.friction.has_history().then_some(&contacts[..]);
    let frame = Frame {
        ids: Some(&ids),
        ..Frame::of(&spheres, params.dt, kept)
    };
    let folder = io::piece_folder(dir, step);
    std::fs::create_dir_all(&folder).map_err(|error| Error::Io {
        path: folder,
        error,
    })?;
    io::write_vtu(&io::piece_path(dir, step, piece), &frame)?;
    Ok(own.len() as u64)
}
