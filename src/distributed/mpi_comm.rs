//! The ranks of a run under `mpirun`: one process each, joined by MPI's world communicator.

use super::comm::{Comm, one_message_a_rank};
use crate::error::{Error, Result};
use mpi::Threading;
use mpi::point_to_point::{Destination, Source};
use mpi::request::WaitGuard;
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

    fn exchange(&self, mut outgoing: Vec<Vec<u8>>) -> Result<Vec<Vec<u8>>> {
        let mut received = Vec::new();
        self.exchange_into(&mut outgoing, &mut received)?;
        Ok(received)
    }

    fn exchange_into(&self, outgoing: &mut [Vec<u8>], received: &mut Vec<Vec<u8>>) -> Result<()> {
        let (n, me) = (self.size(), self.rank());
        one_message_a_rank(outgoing, n)?;
        // MPI counts in i32: a message of 2 GiB or more is refused.
        let send_counts = outgoing
            .iter()
            .map(|m| {
                i32::try_from(m.len()).map_err(|_| Error::TooLarge {
                    what: "bytes a rank sends another in one exchange".into(),
                    got: m.len() as u64,
                    limit: i32::MAX as u64,
                })
            })
            .collect::<Result<Vec<i32>>>()?;
        let mut recv_counts = vec![0i32; n];
        self.world
            .all_to_all_into(&send_counts[..], &mut recv_counts[..]);
        // Each message straight into its own buffer (kept from exchange to exchange: only
        // what one grows by is zeroed), each sent from where it lies; this rank's own moved.
        received.resize_with(n, Vec::new);
        for (buffer, &count) in received.iter_mut().zip(&recv_counts) {
            buffer.resize(count.max(0) as usize, 0);
        }
        received[me] = std::mem::take(&mut outgoing[me]);
        mpi::request::scope(|scope| {
            let mut pending = Vec::new();
            for (r, buffer) in received.iter_mut().enumerate() {
                if r != me && !buffer.is_empty() {
                    let from = self.world.process_at_rank(r as i32);
                    pending.push(WaitGuard::from(
                        from.immediate_receive_into(scope, &mut buffer[..]),
                    ));
                }
            }
            for (r, message) in outgoing.iter().enumerate() {
                if r != me && !message.is_empty() {
                    let to = self.world.process_at_rank(r as i32);
                    pending.push(WaitGuard::from(to.immediate_send(scope, &message[..])));
                }
            }
            // Dropping the guards waits for every send and receive.
        });
        Ok(())
    }
}
