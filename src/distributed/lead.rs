//! A run over ranks driven from rank 0: rank 0 holds a [`Leader`], a [`Stepper`] that sends
//! each call to the other ranks before making it on its own [`RankStepper`], and the other
//! ranks [`follow`] (each makes the same calls on its own), so that one program written for one
//! step (the `mochi` tool's run, with its files and its output) runs on rank 0 while the others
//! keep in step. A rank that fails leaves the run: its process ends, and `mpirun` ends the
//! others.

use super::comm::Comm;
use super::rank::RankStepper;
use crate::dem::flow::FlowCounts;
use crate::dem::stepper::{Advance, ExternalLoads, Motion, RankShare, Snapshot, Stepper};
use crate::dem::walls::WallLoad;
use crate::error::{Error, Result};
use crate::io::CheckpointPiece;
use crate::particles::Particles;
use std::path::Path;

/// What rank 0 asks of the others.
#[derive(Debug, Clone, PartialEq)]
enum Call {
    /// Steps, and whether the call counts its contacts.
    Advance(u32, bool),
    Particles,
    Snapshot,
    Motion {
        positions: Option<Vec<[f64; 3]>>,
        velocities: Option<Vec<[f32; 3]>>,
        angular_velocities: Option<Vec<[f32; 3]>>,
    },
    Gravity([f32; 3]),
    Loads(ExternalLoads),
    Shares,
    /// Write the frame's pieces into this series folder (an absolute path).
    Pieces(String),
    /// Write the checkpoint's pieces into this folder of pieces (an absolute path).
    CheckpointPieces(String),
    Stop,
}

impl Call {
    /// The bytes of this call: a tag, then its values.
    fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let rows = |out: &mut Vec<u8>, rows: Option<&[u8]>| match rows {
            None => out.push(0),
            Some(bytes) => {
                out.push(1);
                out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
                out.extend_from_slice(bytes);
            }
        };
        match self {
            Call::Advance(steps, counted) => {
                out.push(0);
                out.extend_from_slice(&steps.to_le_bytes());
                out.push(*counted as u8);
            }
            Call::Particles => out.push(1),
            Call::Motion {
                positions,
                velocities,
                angular_velocities,
            } => {
                out.push(2);
                rows(&mut out, positions.as_deref().map(bytemuck::cast_slice));
                rows(&mut out, velocities.as_deref().map(bytemuck::cast_slice));
                rows(
                    &mut out,
                    angular_velocities.as_deref().map(bytemuck::cast_slice),
                );
            }
            Call::Gravity(g) => {
                out.push(3);
                out.extend_from_slice(bytemuck::cast_slice(g));
            }
            Call::Loads(loads) => {
                out.push(4);
                rows(&mut out, Some(bytemuck::cast_slice(&loads.forces)));
                rows(&mut out, Some(bytemuck::cast_slice(&loads.torques)));
            }
            Call::Stop => out.push(5),
            Call::Shares => out.push(6),
            Call::Snapshot => out.push(7),
            Call::Pieces(dir) => {
                out.push(8);
                out.extend_from_slice(dir.as_bytes());
            }
            Call::CheckpointPieces(folder) => {
                out.push(9);
                out.extend_from_slice(folder.as_bytes());
            }
        }
        out
    }

    /// The call of `bytes` ([`encode`](Self::encode)).
    fn decode(bytes: &[u8]) -> Result<Self> {
        let bad = || Error::Usage("rank 0 sent a call this rank cannot read".into());
        let mut rest = bytes;
        let mut take = |n: usize| -> Result<&[u8]> {
            if rest.len() < n {
                return Err(bad());
            }
            let (head, tail) = rest.split_at(n);
            rest = tail;
            Ok(head)
        };
        let tag = take(1)?[0];
        let call = match tag {
            0 => {
                let steps = u32::from_le_bytes(take(4)?.try_into().map_err(|_| bad())?);
                Call::Advance(steps, take(1)?[0] != 0)
            }
            1 => Call::Particles,
            2 | 4 => {
                let mut lists: Vec<Option<Vec<u8>>> = Vec::new();
                for _ in 0..if tag == 2 { 3 } else { 2 } {
                    match take(1)?[0] {
                        0 => lists.push(None),
                        _ => {
                            let n = u64::from_le_bytes(take(8)?.try_into().map_err(|_| bad())?);
                            lists.push(Some(take(n as usize)?.to_vec()));
                        }
                    }
                }
                fn of<T: bytemuck::Pod>(bytes: &Option<Vec<u8>>) -> Option<Vec<T>> {
                    bytes.as_ref().map(|b| {
                        b.chunks_exact(std::mem::size_of::<T>())
                            .map(bytemuck::pod_read_unaligned)
                            .collect()
                    })
                }
                match tag {
                    2 => Call::Motion {
                        positions: of(&lists[0]),
                        velocities: of(&lists[1]),
                        angular_velocities: of(&lists[2]),
                    },
                    _ => Call::Loads(ExternalLoads {
                        forces: of(&lists[0]).unwrap_or_default(),
                        torques: of(&lists[1]).unwrap_or_default(),
                    }),
                }
            }
            3 => {
                let g: [f32; 3] = bytemuck::pod_read_unaligned(take(12)?);
                Call::Gravity(g)
            }
            5 => Call::Stop,
            6 => Call::Shares,
            7 => Call::Snapshot,
            8 | 9 => {
                let path = String::from_utf8(rest.to_vec()).map_err(|_| bad())?;
                match tag {
                    8 => Call::Pieces(path),
                    _ => Call::CheckpointPieces(path),
                }
            }
            _ => return Err(bad()),
        };
        Ok(call)
    }

    /// Makes this call on `rank`.
    fn make<C: Comm + Send>(&self, rank: &mut RankStepper<C>) -> Result<()> {
        match self {
            Call::Advance(steps, true) => rank.advance(*steps).map(|_| ()),
            Call::Advance(steps, false) => rank.advance_uncounted(*steps).map(|_| ()),
            Call::Particles => rank.gather().map(|_| ()),
            Call::Snapshot => rank.gather_snapshot().map(|_| ()),
            Call::Motion {
                positions,
                velocities,
                angular_velocities,
            } => rank.set_motion(&Motion {
                positions: positions.as_deref(),
                velocities: velocities.as_deref(),
                angular_velocities: angular_velocities.as_deref(),
            }),
            Call::Gravity(g) => rank.set_gravity(*g),
            Call::Loads(loads) => rank.set_external_loads(loads),
            Call::Shares => rank.rank_shares().map(|_| ()),
            Call::Pieces(dir) => rank.write_pieces(Path::new(dir)).map(|_| ()),
            Call::CheckpointPieces(folder) => {
                rank.write_checkpoint_pieces(Path::new(folder)).map(|_| ())
            }
            Call::Stop => Ok(()),
        }
    }
}

/// Rank 0's step of a run over ranks: each call goes to the other ranks first.
pub struct Leader<C: Comm> {
    rank: RankStepper<C>,
    /// Whether the other ranks follow still (no call failed here, no stop sent).
    followed: bool,
}

impl<C: Comm + Send> Leader<C> {
    /// Leads the other ranks of `rank`'s group (this is rank 0).
    pub fn new(rank: RankStepper<C>) -> Result<Self> {
        if rank.comm().rank() != 0 {
            return Err(Error::Usage("rank 0 leads a run over ranks".into()));
        }
        Ok(Self {
            rank,
            followed: true,
        })
    }

    /// Sends `call` to the other ranks, then makes it here; a failure here ends the lead.
    fn lead<T>(
        &mut self,
        call: Call,
        here: impl FnOnce(&mut RankStepper<C>) -> Result<T>,
    ) -> Result<T> {
        if !self.followed {
            return Err(Error::Usage("the other ranks left the run".into()));
        }
        let comm = self.rank.comm();
        let mut outgoing = vec![call.encode(); comm.size()];
        outgoing[0].clear();
        comm.exchange(outgoing)?;
        let result = here(&mut self.rank);
        self.followed = result.is_ok();
        result
    }
}

impl<C: Comm> Drop for Leader<C> {
    /// Tells the other ranks the run is over, where they follow still.
    fn drop(&mut self) {
        if self.followed {
            let comm = self.rank.comm();
            let mut outgoing = vec![Call::Stop.encode(); comm.size()];
            outgoing[0].clear();
            let _ = comm.exchange(outgoing);
        }
    }
}

impl<C: Comm + Send> Stepper for Leader<C> {
    fn describe(&self) -> String {
        self.rank.describe()
    }

    fn advance(&mut self, steps: u32) -> Result<Advance> {
        self.lead(Call::Advance(steps, true), |r| r.advance(steps))
    }

    fn advance_uncounted(&mut self, steps: u32) -> Result<Advance> {
        self.lead(Call::Advance(steps, false), |r| r.advance_uncounted(steps))
    }

    fn step(&self) -> u64 {
        self.rank.step()
    }

    fn particles(&mut self) -> Result<Particles> {
        self.lead(Call::Particles, |r| r.gather()?.ok_or_else(not_gathered))
    }

    fn snapshot(&mut self) -> Result<Snapshot> {
        self.lead(Call::Snapshot, |r| {
            r.gather_snapshot()?.ok_or_else(not_gathered)
        })
    }

    fn set_motion(&mut self, motion: &Motion<'_>) -> Result<()> {
        let call = Call::Motion {
            positions: motion.positions.map(<[_]>::to_vec),
            velocities: motion.velocities.map(<[_]>::to_vec),
            angular_velocities: motion.angular_velocities.map(<[_]>::to_vec),
        };
        self.lead(call, |r| r.set_motion(motion))
    }

    fn set_gravity(&mut self, gravity: [f32; 3]) -> Result<()> {
        self.lead(Call::Gravity(gravity), |r| r.set_gravity(gravity))
    }

    fn set_external_loads(&mut self, loads: &ExternalLoads) -> Result<()> {
        self.lead(Call::Loads(loads.clone()), |r| r.set_external_loads(loads))
    }

    fn wall_loads(&self) -> Vec<WallLoad> {
        self.rank.wall_loads()
    }

    fn rank_shares(&mut self) -> Result<Vec<RankShare>> {
        self.lead(Call::Shares, |r| r.rank_shares())
    }

    fn steps_a_round(&self) -> u32 {
        self.rank.steps_a_round()
    }

    fn write_pieces(&mut self, dir: &Path) -> Result<Option<Vec<u64>>> {
        let (dir, text) = absolute_utf8(dir, "frames")?;
        self.lead(Call::Pieces(text), |r| r.write_pieces(&dir))
    }

    fn write_checkpoint_pieces(&mut self, folder: &Path) -> Result<Option<Vec<CheckpointPiece>>> {
        let (folder, text) = absolute_utf8(folder, "checkpoints")?;
        self.lead(Call::CheckpointPieces(text), |r| {
            r.write_checkpoint_pieces(&folder)
        })
    }

    fn flow_counts(&self) -> Option<FlowCounts> {
        self.rank.flow_counts()
    }
}

/// `path` made absolute (the other ranks may not share this one's working folder), and as
/// UTF-8, which the other ranks are sent; refused, naming the run's `files`, where it is not.
fn absolute_utf8(path: &Path, files: &str) -> Result<(std::path::PathBuf, String)> {
    let path = std::path::absolute(path).map_err(|error| Error::Io {
        path: path.to_owned(),
        error,
    })?;
    let text = path.to_str().map(str::to_owned).ok_or_else(|| {
        let shown = path.display();
        Error::Usage(format!(
            "a run over ranks writes {files} in pieces into a folder named in UTF-8, not {shown}"
        ))
    })?;
    Ok((path, text))
}

/// Rank 0's refusal where a gathered run did not come to it.
fn not_gathered() -> Error {
    Error::Usage("the run was not gathered on rank 0".into())
}

/// Makes on `rank` (not rank 0) each call rank 0's [`Leader`] sends, until it stops.
pub fn follow<C: Comm + Send>(mut rank: RankStepper<C>) -> Result<()> {
    loop {
        let n = rank.comm().size();
        let received = rank.comm().exchange(vec![Vec::new(); n])?;
        let call = Call::decode(&received[0])?;
        if call == Call::Stop {
            return Ok(());
        }
        call.make(&mut rank)?;
    }
}
