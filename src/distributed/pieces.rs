//! A frame of a run over ranks written in pieces ([`crate::io::piece_path`]): each rank writes
//! the piece of its own spheres, then every rank hears what every other wrote, so that all
//! return alike.

use super::comm::Comm;
use super::record::{SphereRecord, spheres_of};
use crate::dem::StepParams;
use crate::error::{Error, Result};
use crate::io::{self, Frame};
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
    let status = match &written {
        Ok(spheres) => [&[0], &spheres.to_le_bytes()[..]].concat(),
        Err(e) => [&[1], e.to_string().as_bytes()].concat(),
    };
    let received = comm.exchange(vec![status; comm.size()])?;
    let mut spheres = Vec::with_capacity(received.len());
    for (r, message) in received.iter().enumerate() {
        match message.split_first() {
            Some((0, count)) if count.len() == 8 => {
                spheres.push(u64::from_le_bytes(count.try_into().expect("8 bytes")));
            }
            Some((1, what)) => {
                return Err(match written {
                    Err(e) if r == comm.rank() => e,
                    _ => Error::Usage(format!(
                        "process {r} could not write its piece of the frame: {}",
                        String::from_utf8_lossy(what)
                    )),
                });
            }
            _ => return Err(Error::Usage("a rank's word on its piece is not one".into())),
        }
    }
    Ok(spheres)
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
