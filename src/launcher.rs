//! What an MPI launcher (`mpirun`, `mpiexec`, `srun`) told this process through its
//! environment (Open MPI's, MPICH's Hydra's or MVAPICH's variables): how many processes it
//! started and which of them on this machine this one is. Read wherever a choice depends on it
//! (the run over ranks, the GPU a process opens) without starting MPI.

/// The first of `names` set to a number in the environment.
fn launcher_number(names: &[&str]) -> Option<usize> {
    names
        .iter()
        .find_map(|name| std::env::var(name).ok()?.parse().ok())
}

/// The processes an MPI launcher started this one among (1 where none did).
pub fn launched_processes() -> usize {
    launcher_number(&["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "MV2_COMM_WORLD_SIZE"]).unwrap_or(1)
}

/// This process's place among those the launcher started on this machine (0 where none did):
/// the process of local rank L opens the (L mod G)-th of the machine's G GPUs.
pub(crate) fn local_rank() -> usize {
    launcher_number(&[
        "OMPI_COMM_WORLD_LOCAL_RANK",
        "MPI_LOCALRANKID",
        "MV2_COMM_WORLD_LOCAL_RANK",
        "SLURM_LOCALID",
    ])
    .unwrap_or(0)
}
