//! Mailboxes in shared memory for the ranks of one host ([`MpiComm`](super::MpiComm)): each
//! rank writes what it sends to its neighbours on the host into a file of its own in
//! `/dev/shm`, mapped by every rank of the host, and each reads its part out of the sender's
//! file. A message then crosses once per side as a copy on every core, where MPI's shared
//! memory transport copies it on one thread.
//!
//! The files are only written and read between the collectives of an exchange: every rank has
//! finished reading the last exchange's messages before any enters the next one's all-to-all,
//! and writes its own before the barrier after which the others read them. A file only grows
//! (a reader maps it again when a message lies beyond what it mapped), and is unlinked once
//! every rank of the host has it open, so nothing is left behind when the processes end.

use crate::error::{Error, Result};
use memmap2::{Mmap, MmapMut};
use mpi::collective::SystemOperation;
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::{CommunicatorCollectives, Root};
use rayon::prelude::*;
use std::fs::{File, OpenOptions};
use std::path::PathBuf;

/// Where the mailboxes live: memory, not a disk.
const FOLDER: &str = "/dev/shm";

/// A mailbox's first size \[bytes\] (it grows to what an exchange needs).
const FIRST_BYTES: u64 = 1 << 20;

/// Messages above this size go through MPI (a mailbox holds at most this much for each
/// neighbour on the host).
pub(super) const MOST_BYTES: u64 = 256 << 20;

/// Bytes copied by one task of a parallel copy.
const PIECE: usize = 1 << 18;

/// This rank's mailbox and its neighbours' on the host.
pub(super) struct SharedMail {
    /// This rank's file and its mapping.
    own: (File, MmapMut),
    /// By world rank: the neighbour's file and this rank's mapping of it (`None`: not on this
    /// host, or this rank).
    peers: Vec<Option<(File, Mmap)>>,
}

impl SharedMail {
    /// The mailboxes of the ranks of `world` on this host (every rank of `world` calls it
    /// together); `None` on every rank where any rank cannot make or open them.
    pub fn open(world: &SimpleCommunicator) -> Option<Self> {
        let base = run_name(world);
        let host = world.split_shared(world.rank());
        // The world ranks of this host's ranks, in the host's order.
        let mut on_host = vec![0i32; host.size() as usize];
        host.all_gather_into(&world.rank(), &mut on_host[..]);
        let path = |rank: i32| PathBuf::from(FOLDER).join(format!("{base}-{rank}"));
        let own = make_own(&path(world.rank()));
        host.barrier();
        let peers: Option<Vec<(i32, File, Mmap)>> = (on_host.iter())
            .filter(|&&r| r != world.rank())
            .map(|&r| {
                let file = File::open(path(r)).ok()?;
                let map = map_read(&file).ok()?;
                Some((r, file, map))
            })
            .collect();
        // Every rank has opened its neighbours' files: they need no name from now on.
        host.barrier();
        let _ = std::fs::remove_file(path(world.rank()));
        let made = (own.is_some() && peers.is_some()) as i32;
        let mut everywhere = 0;
        world.all_reduce_into(&made, &mut everywhere, SystemOperation::min());
        if everywhere == 0 {
            return None;
        }
        let (own, peers) = (own?, peers?);
        let mut by_rank: Vec<Option<(File, Mmap)>> = (0..world.size()).map(|_| None).collect();
        for (r, file, map) in peers {
            by_rank[r as usize] = Some((file, map));
        }
        Some(SharedMail {
            own,
            peers: by_rank,
        })
    }

    /// Whether `rank` (of the world) reads this rank's mailbox.
    pub fn on_host(&self, rank: usize) -> bool {
        self.peers.get(rank).is_some_and(Option::is_some)
    }

    /// Grows this rank's mailbox to hold `end` bytes, its memory reserved (a mapping of memory
    /// the host has not got would fail at its first write); an error leaves it as it was.
    pub fn reserve(&mut self, end: u64) -> Result<()> {
        if end <= self.own.1.len() as u64 {
            return Ok(());
        }
        let size = end.next_power_of_two();
        reserve_file(&self.own.0, size).map_err(|e| shared_error("grow", e))?;
        self.own.1 = map_write(&self.own.0)?;
        Ok(())
    }

    /// Writes `parts` (each an `(offset, bytes)`, within what [`reserve`](Self::reserve) made
    /// room for) into this rank's mailbox.
    pub fn write(&mut self, parts: &[(u64, &[u8])]) -> Result<()> {
        for &(at, bytes) in parts {
            let at = at as usize;
            let into = (self.own.1.get_mut(at..at + bytes.len()))
                .ok_or_else(|| Error::Usage("a message lies beyond this rank's mailbox".into()))?;
            copy(into, bytes);
        }
        Ok(())
    }

    /// Copies the `into.len()` bytes at `at` of `rank`'s mailbox into `into` (mapped again
    /// first where the mailbox grew past this rank's mapping of it).
    pub fn read(&mut self, rank: usize, at: u64, into: &mut [u8]) -> Result<()> {
        let Some((file, map)) = self.peers.get_mut(rank).and_then(Option::as_mut) else {
            return Err(Error::Usage(format!(
                "rank {rank} has no mailbox on this host"
            )));
        };
        let (at, end) = (at as usize, at as usize + into.len());
        if end > map.len() {
            *map = map_read(file)?;
        }
        let bytes = map.get(at..end).ok_or_else(|| {
            Error::Usage(format!("rank {rank}'s message lies beyond its mailbox"))
        })?;
        copy(into, bytes);
        Ok(())
    }
}

/// A name for this run's mailboxes, the same on every rank (rank 0's process id and clock).
fn run_name(world: &SimpleCommunicator) -> String {
    let mut words = [0u64; 2];
    if world.rank() == 0 {
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
        words = [
            std::process::id() as u64,
            now.map_or(0, |d| d.as_nanos() as u64),
        ];
    }
    world.process_at_rank(0).broadcast_into(&mut words[..]);
    format!("mochi-mail-{}-{}", words[0], words[1])
}

/// This rank's mailbox at `path`, made new, and its mapping; `None` where it cannot be made.
fn make_own(path: &PathBuf) -> Option<(File, MmapMut)> {
    let file = (OpenOptions::new().read(true).write(true).create_new(true))
        .open(path)
        .ok()?;
    reserve_file(&file, FIRST_BYTES).ok()?;
    let map = map_write(&file).ok()?;
    Some((file, map))
}

/// `file` grown to `size` bytes, its memory reserved where the system can (on unix; a
/// mapping of memory the host has not got fails at its first write, with no error to return).
fn reserve_file(file: &File, size: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    return rustix::fs::fallocate(file, rustix::fs::FallocateFlags::empty(), 0, size)
        .map_err(Into::into);
    #[cfg(not(unix))]
    file.set_len(size)
}

/// `file` mapped for this rank to write.
#[allow(unsafe_code)]
fn map_write(file: &File) -> Result<MmapMut> {
    // SAFETY: the file is this rank's own mailbox; other ranks only read it, and only between
    // the barrier that follows this rank's writes and the next exchange's all-to-all, which
    // this rank enters before it writes again; no rank truncates it.
    unsafe { MmapMut::map_mut(file) }.map_err(|e| shared_error("map", e))
}

/// `file` (a neighbour's mailbox) mapped for this rank to read.
#[allow(unsafe_code)]
fn map_read(file: &File) -> Result<Mmap> {
    // SAFETY: the neighbour writes its mailbox only before the barrier after which this rank
    // reads it, and not again before this rank has entered the next exchange; it only grows
    // the file, so what this rank mapped stays in it.
    unsafe { Mmap::map(file) }.map_err(|e| shared_error("map", e))
}

fn shared_error(what: &str, e: std::io::Error) -> Error {
    Error::Usage(format!(
        "could not {what} a rank's mailbox in {FOLDER}: {e}"
    ))
}

/// `from` copied into `to` (as long) on every core.
fn copy(to: &mut [u8], from: &[u8]) {
    (to.par_chunks_mut(PIECE))
        .zip(from.par_chunks(PIECE))
        .for_each(|(to, from)| to.copy_from_slice(from));
}
