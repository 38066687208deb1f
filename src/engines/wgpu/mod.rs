//! The two wgpu engines, `compute` (sorted proxy grids in compute shaders) and `rq` (proxy boxes
//! in a hardware BVH searched with ray queries), and what they share: the detection layer over
//! a structure (`detection`), the DEM step's physics modules and timers (`step`), the
//! granular state (`granular`) and its clumps (`clumps`), the history's held slots saved for a
//! redo or read back, whole or their partners alone (`held_slots`), the state's rows and their
//! order (`state`), the mesh walls' buffers (`walls`), flows scanned on the device (`flow`), a
//! rank's ghosts exchanged on the device (`halo`) and batches read back while the next runs
//! (`readback`).

pub(crate) mod clumps;
pub mod compute;
pub(crate) mod detection;
pub(crate) mod flow;
pub(crate) mod granular;
pub(crate) mod halo;
pub(crate) mod held_slots;
pub(crate) mod readback;
pub mod rq;
pub(crate) mod state;
pub(crate) mod step;
pub(crate) mod walls;
