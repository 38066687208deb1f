//! How the ranks of a decomposed run talk: every rank sends each other rank one message and
//! receives one from each, all at once ([`Comm::exchange`]). [`LocalComm`] joins ranks that are
//! threads of one process (tests, and a machine without MPI); the `mpi` feature's
//! communicator joins processes.

use crate::error::{Error, Result};
use std::sync::{Arc, Barrier, Mutex};

/// One rank's end of a group of ranks.
pub trait Comm {
    /// This rank, from 0.
    fn rank(&self) -> usize;
    /// The ranks of the group.
    fn size(&self) -> usize;
    /// Sends `outgoing[s]` to each rank s (`size` messages; this rank's own is handed back)
    /// and returns what each rank sent this one, by rank. Every rank of the group calls it
    /// the same number of times.
    fn exchange(&self, outgoing: Vec<Vec<u8>>) -> Result<Vec<Vec<u8>>>;
}

/// The ranks of a group of threads of one process.
pub struct LocalComm {
    rank: usize,
    size: usize,
    shared: Arc<Shared>,
}

/// The mailboxes of a group of [`LocalComm`]s: `boxes[to][from]`.
struct Shared {
    boxes: Mutex<Vec<Vec<Vec<u8>>>>,
    barrier: Barrier,
}

impl LocalComm {
    /// A group of `ranks` ranks (at least 1), one [`LocalComm`] for each thread to take.
    pub fn group(ranks: usize) -> Result<Vec<LocalComm>> {
        if ranks == 0 {
            return Err(Error::Usage("a group of ranks needs at least one".into()));
        }
        let shared = Arc::new(Shared {
            boxes: Mutex::new(vec![vec![Vec::new(); ranks]; ranks]),
            barrier: Barrier::new(ranks),
        });
        Ok((0..ranks)
            .map(|rank| LocalComm {
                rank,
                size: ranks,
                shared: Arc::clone(&shared),
            })
            .collect())
    }
}

impl Comm for LocalComm {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn exchange(&self, outgoing: Vec<Vec<u8>>) -> Result<Vec<Vec<u8>>> {
        let n = self.size();
        one_message_a_rank(&outgoing, n)?;
        let lock = || {
            self.shared
                .boxes
                .lock()
                .map_err(|_| Error::Usage("a rank of the group panicked".into()))
        };
        {
            let mut boxes = lock()?;
            for (to, message) in outgoing.into_iter().enumerate() {
                boxes[to][self.rank] = message;
            }
        }
        // Every message is in its box before any is taken, and every rank has taken its own
        // before the next exchange fills the boxes again.
        self.shared.barrier.wait();
        let received = std::mem::take(&mut lock()?[self.rank]);
        lock()?[self.rank] = vec![Vec::new(); n];
        self.shared.barrier.wait();
        Ok(received)
    }
}

/// Refuses `outgoing` unless it holds one message for each of `ranks` ranks.
pub(super) fn one_message_a_rank(outgoing: &[Vec<u8>], ranks: usize) -> Result<()> {
    match outgoing.len() == ranks {
        true => Ok(()),
        false => Err(Error::Usage(format!(
            "{} messages for a group of {ranks} ranks",
            outgoing.len()
        ))),
    }
}
