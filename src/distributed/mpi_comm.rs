//! The ranks of a run under `mpirun`: one process each, joined by MPI's world communicator;
//! the ranks of one host pass their messages through mailboxes in shared memory
//! ([`SharedMail`]), the others through MPI.

use super::comm::{Comm, one_message_a_rank};
use super::shared_mail::{MOST_BYTES, SharedMail};
use crate::error::{Error, Result};
use mpi::Threading;
use mpi::collective::SystemOperation;
use mpi::point_to_point::{Destination, Source};
use mpi::request::WaitGuard;
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::CommunicatorCollectives;

/// This process's rank of MPI's world. MPI is finalised when the universe it holds is
/// dropped (on the thread that made it, as MPI asks).
pub struct MpiComm {
    _universe: mpi::environment::Universe,
    world: SimpleCommunicator,
    /// The mailboxes of this host's ranks (`None` on every rank where some rank could not
    /// make them: then every message goes through MPI).
    mail: std::cell::RefCell<Option<SharedMail>>,
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
        let mail = std::cell::RefCell::new(SharedMail::open(&world));
        Ok(Self {
            _universe: universe,
            world,
            mail,
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
        if let Some(m) = outgoing.iter().find(|m| i32::try_from(m.len()).is_err()) {
            return Err(Error::TooLarge {
                what: "bytes a rank sends another in one exchange".into(),
                got: m.len() as u64,
                limit: i32::MAX as u64,
            });
        }
        let mut mail = self.mail.borrow_mut();
        // Each message's length and where it lies in this rank's mailbox (`THROUGH_MPI`: sent
        // by MPI), one after the other.
        let mut layout = vec![0u64; 2 * n];
        let mut end = 0;
        for (r, m) in outgoing.iter().enumerate() {
            let bytes = m.len() as u64;
            let shared = r != me
                && (1..=MOST_BYTES).contains(&bytes)
                && mail.as_ref().is_some_and(|mail| mail.on_host(r));
            layout[2 * r] = bytes;
            layout[2 * r + 1] = match shared {
                true => {
                    end += bytes;
                    end - bytes
                }
                false => THROUGH_MPI,
            };
        }
        // Where the mailbox cannot grow to hold them (the host's shared memory is short),
        // every message goes through MPI.
        if let Some(mail) = mail.as_mut().filter(|_| end > 0)
            && mail.reserve(end).is_err()
        {
            (layout.iter_mut().skip(1).step_by(2)).for_each(|at| *at = THROUGH_MPI);
        }
        let mut coming = vec![0u64; 2 * n];
        self.world.all_to_all_into(&layout[..], &mut coming[..]);
        // Each message straight into its own buffer (kept from exchange to exchange: only
        // what one grows by is zeroed); this rank's own moved.
        received.resize_with(n, Vec::new);
        for (buffer, r) in received.iter_mut().zip(0..) {
            buffer.resize(coming[2 * r] as usize, 0);
        }
        received[me] = std::mem::take(&mut outgoing[me]);
        // Every rank writes its mailbox, then (once every rank has, or one could not) reads
        // its part of its neighbours'.
        let written = match mail.as_mut() {
            Some(mail) => {
                let parts: Vec<(u64, &[u8])> = (outgoing.iter().enumerate())
                    .filter(|&(r, _)| layout[2 * r + 1] != THROUGH_MPI)
                    .map(|(r, m)| (layout[2 * r + 1], &m[..]))
                    .collect();
                mail.write(&parts)
            }
            None => Ok(()),
        };
        let mut everywhere = 0;
        let ok = written.is_ok() as i32;
        self.world
            .all_reduce_into(&ok, &mut everywhere, SystemOperation::min());
        written?;
        if everywhere == 0 {
            return Err(Error::Usage(
                "a rank could not write its mailbox in shared memory".into(),
            ));
        }
        mpi::request::scope(|scope| {
            let mut read = Ok(());
            let mut pending = Vec::new();
            for (r, buffer) in received.iter_mut().enumerate() {
                if r == me || buffer.is_empty() {
                    continue;
                }
                match (coming[2 * r + 1], mail.as_mut()) {
                    (THROUGH_MPI, _) => {
                        let from = self.world.process_at_rank(r as i32);
                        pending.push(WaitGuard::from(
                            from.immediate_receive_into(scope, &mut buffer[..]),
                        ));
                    }
                    (at, Some(mail)) => read = read.and_then(|()| mail.read(r, at, buffer)),
                    (_, None) => {
                        read = Err(Error::Usage(format!(
                            "rank {r} wrote a mailbox this rank has not"
                        )));
                    }
                }
            }
            for (r, message) in outgoing.iter().enumerate() {
                if r != me && !message.is_empty() && layout[2 * r + 1] == THROUGH_MPI {
                    let to = self.world.process_at_rank(r as i32);
                    pending.push(WaitGuard::from(to.immediate_send(scope, &message[..])));
                }
            }
            // Dropping the guards (after `read` is taken) waits for every send and receive.
            read
        })
    }
}

/// Where a message sent by MPI lies in the sender's mailbox: nowhere.
const THROUGH_MPI: u64 = u64::MAX;
