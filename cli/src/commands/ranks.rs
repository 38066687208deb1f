//! Whether this process is one of several that `mpirun` (or another MPI launcher) started,
//! as its environment says, and the ranks they form: with the `mpi` feature, a run decomposed
//! over them; without it, a refusal (each process would run the whole scene).

use anyhow::Result;
use mochi::distributed::launched_processes;

/// The ranks of the processes `mpirun` started, where it started several.
#[cfg(feature = "mpi")]
pub fn launched() -> Result<Option<mochi::distributed::MpiComm>> {
    match launched_processes() {
        0 | 1 => Ok(None),
        _ => Ok(Some(mochi::distributed::MpiComm::world()?)),
    }
}

/// Refuses to run as one of several processes: this build cannot share a run between them.
#[cfg(not(feature = "mpi"))]
pub fn launched() -> Result<Option<mochi::distributed::LocalComm>> {
    match launched_processes() {
        0 | 1 => Ok(None),
        n => anyhow::bail!(
            "this mochi was built without the mpi feature, so under mpirun each of the {n} \
             processes would run the whole scene: build it with `cargo build --release \
             --features mpi`, or run one process"
        ),
    }
}
