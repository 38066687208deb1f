//! The ranks of a run under `mpirun`: one process each, joined by MPI's world communicator.

use super::comm::{Comm, one_message_a_rank};
use crate::error::{Error, Result};
use mpi::Threading;
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::CommunicatorCollectives;

/// This process's rank of MPI's world. MPI is finalised when the universe it holds is
/// dropped (on the thread that made it, as MPI asks).
pub struct MpiComm {
    _universe: mpi::environment::Universe,
    world: SimpleCommunicator,
}

// SAFETY: MPI was initialised with `MPI_THREAD_SERIALIZED` or more (`world` checks), so any
// thread may call it while no two call at once; `MpiComm` is not `Sync` and its calls take
// `&self`, so only the one thread that holds it calls MPI through it.
#[allow(unsafe_code)]
unsafe impl Send for MpiComm {}

impl MpiComm {
    /// Initialises MPI (once a process) with calls from any one thread at a time allowed,
    /// and takes its world. Refuses where MPI was initialised already or cannot allow that.
    pub fn world() -> Result<Self> {
        let (universe, threading) = mpi::initialize_with_threading(Threading::Serialized)
            .ok_or_else(|| Error::Usage("MPI was initialised already".into()))?;
        if threading < Threading::Serialized {
            return Err(Error::Usage(format!(
                "this MPI allows calls from {threading:?} threads, not from any one at a time"
            )));
        }
        let world = universe.world();
        Ok(Self {
            _universe: universe,
            world,
        })
    }
}

impl Comm for MpiComm {
    fn rank(&self) -> usize {
        self.world.rank() as usize
    }

    fn size(&self) -> usize {
        self.world.size() as usize
    }

    fn exchange(&self, outgoing: Vec<Vec<u8>>) -> Result<Vec<Vec<u8>>> {
        let n = self.size();
        one_message_a_rank(&outgoing, n)?;
        // MPI counts in i32: a message of 2 GiB or more is refused.
        let count = |bytes: usize| {
            i32::try_from(bytes).map_err(|_| Error::TooLarge {
                what: "bytes a rank sends another in one exchange".into(),
                got: bytes as u64,
                limit: i32::MAX as u64,
            })
        };
        let send_counts = outgoing
            .iter()
            .map(|m| count(m.len()))
            .collect::<Result<Vec<i32>>>()?;
        let mut recv_counts = vec![0i32; n];
        self.world
            .all_to_all_into(&send_counts[..], &mut recv_counts[..]);
        let offsets = |counts: &[i32]| -> Result<Vec<i32>> {
            let mut at = 0usize;
            counts
                .iter()
                .map(|&c| {
                    let here = count(at)?;
                    at += c as usize;
                    Ok(here)
                })
                .collect()
        };
        let (send_at, recv_at) = (offsets(&send_counts)?, offsets(&recv_counts)?);
        // Buffers of at least a byte: MPI refuses the dangling pointer of an empty one.
        let mut flat: Vec<u8> = outgoing.concat();
        flat.push(0);
        let total: usize = recv_counts.iter().map(|&c| c as usize).sum();
        let mut received = vec![0u8; total + 1];
        {
            let send = Partition::new(&flat[..], &send_counts[..], &send_at[..]);
            let mut recv = PartitionMut::new(&mut received[..], &recv_counts[..], &recv_at[..]);
            self.world.all_to_all_varcount_into(&send, &mut recv);
        }
        Ok(recv_at
            .iter()
            .zip(&recv_counts)
            .map(|(&at, &c)| received[at as usize..at as usize + c as usize].to_vec())
            .collect())
    }
}
