//! A run decomposed over ranks: the box cut into a grid of boxes ([`Grid`]: [`Slabs`] along
//! one axis or more), one a rank, each rank stepping the spheres of its box with the ghosts of
//! its neighbours' ([`RankStepper`]; a clump with all its components on the rank whose box
//! holds its centre), the ranks joined by a communicator ([`Comm`]: threads of one process,
//! [`LocalComm`]). On the cpu backend a decomposed run is the whole run bit for bit, on any
//! number of ranks: every sphere sums its contacts in an order that its place and the
//! spheres' ids alone decide.

mod clumps;
mod comm;
mod grid;
mod lead;
#[cfg(feature = "mpi")]
mod mpi_comm;
mod pieces;
mod rank;
mod record;
mod resident;
#[cfg(feature = "mpi")]
mod shared_mail;
mod slabs;

pub use comm::{Comm, LocalComm};
pub use grid::Grid;
pub use lead::{Leader, follow};
#[cfg(feature = "mpi")]
pub use mpi_comm::MpiComm;
pub use rank::RankStepper;
pub(crate) use rank::give_back_freed_memory;
pub use rank::owned_at_opening;
pub use slabs::Slabs;

pub use crate::launcher::launched_processes;

/// Steps between two moves of the grid's faces in a run that `mochi simulate` (or
/// `RunStart::open_on_ranks`) opens over ranks ([`RankStepper::rebalancing_every`]).
pub const REBALANCE_STEPS: u64 = 500;
