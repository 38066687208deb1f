//! How the ranks of a decomposed run talk: every rank sends each other rank one message and
//! receives one from each, all at once ([`Comm::exchange`]). [`LocalComm`] joins ranks that are
//! threads of one process (tests, and a machine without MPI); the `mpi` feature's
//! communicator joins processes.

use crate::error::{Error, Result};
use std::sync::{Arc, Condvar, Mutex};

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

    /// [`exchange`](Self::exchange) of large messages from buffers the caller keeps: what each
    /// rank sent this one lands in `received` (one vector a rank, resized, their buffers reused
    /// where the communicator can); the messages are left in `outgoing` for the caller to
    /// reuse, or taken out of it (this rank's own always is).
    fn exchange_into(&self, outgoing: &mut [Vec<u8>], received: &mut Vec<Vec<u8>>) -> Result<()> {
        *received = self.exchange(outgoing.iter_mut().map(std::mem::take).collect())?;
        Ok(())
    }
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
    gate: Gate,
}

/// A barrier that a rank leaving the group breaks: a rank waiting at it then gets an error
/// rather than waiting for ever.
struct Gate {
    ranks: usize,
    state: Mutex<GateState>,
    opened: Condvar,
}

#[derive(Default)]
struct GateState {
    /// Ranks waiting for the gate to open.
    arrived: usize,
    /// Times the gate has opened.
    openings: u64,
    /// Whether a rank has left the group.
    broken: bool,
}

impl Gate {
    /// Waits until every rank of the group has come (the gate opens), or a rank has left.
    fn pass(&self) -> Result<()> {
        let left = || Error::Usage("a rank left its group in the middle of the run".into());
        let mut state = self.state.lock().map_err(|_| left())?;
        if state.broken {
            return Err(left());
        }
        state.arrived += 1;
        if state.arrived == self.ranks {
            state.arrived = 0;
            state.openings += 1;
            self.opened.notify_all();
            return Ok(());
        }
        let opening = state.openings;
        while state.openings == opening && !state.broken {
            state = self.opened.wait(state).map_err(|_| left())?;
        }
        match state.openings == opening {
            true => Err(left()),
            false => Ok(()),
        }
    }

    /// Breaks the gate: a rank left.
    fn break_open(&self) {
        if let Ok(mut state) = self.state.lock() {
            state.broken = true;
        }
        self.opened.notify_all();
    }
}

/// A rank leaving its group (done, failed or panicked) leaves the others no exchange to
/// make: those that wait at one get an error. (A rank done with the run leaves after the
/// others have passed its last exchange.)
impl Drop for LocalComm {
    fn drop(&mut self) {
        self.shared.gate.break_open();
    }
}

impl LocalComm {
    /// A group of `ranks` ranks (at least 1), one [`LocalComm`] for each thread to take.
    pub fn group(ranks: usize) -> Result<Vec<LocalComm>> {
        if ranks == 0 {
            return Err(Error::Usage("a group of ranks needs at least one".into()));
        }
        let shared = Arc::new(Shared {
            boxes: Mutex::new(vec![vec![Vec::new(); ranks]; ranks]),
            gate: Gate {
                ranks,
                state: Mutex::default(),
                opened: Condvar::new(),
            },
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
        self.shared.gate.pass()?;
        let received = std::mem::take(&mut lock()?[self.rank]);
        lock()?[self.rank] = vec![Vec::new(); n];
        self.shared.gate.pass()?;
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
