//! Files: spheres (CSV `x,y,z,r` or NumPy `.npy` float32 N×4, optionally with velocities,
//! angular velocities and materials), pairs (CSV `i,j`), simulation
//! frames for ParaView (`.vtu` files indexed by a `.pvd` collection, see [`FrameSeries`]; a run
//! over several processes may write each frame in pieces, one a process, named by a `.pvtu`) and
//! checkpoints; the clumps of a run of clumps at each frame (`clumps.pvd`); mesh walls' surfaces
//! and loads (`walls.pvd`, `walls.csv`); the logs a run appends to per frame; checkpoints, whole
//! or (over several processes) in pieces.
//!
//! Every reader names the file, the line (CSV) or row (`.npy`) and the problem in its error.
//! Every writer goes through [`write_atomically`] (or [`AtomicFile`]): a failed write leaves no
//! partial file behind.

mod atomic;
mod checkpoint;
mod checkpoint_bytes;
mod checkpoint_pieces;
mod clump_frames;
mod clumps;
mod collection;
mod frame_layout;
mod frame_read;
mod frames;
mod log;
mod pairs;
mod pieces;
mod run_folder;
mod spheres;
mod vtk_arrays;
mod vtu_read;
mod vtu_write;
mod walls;

pub use atomic::{AtomicFile, remove_stale_temp_files, write_atomically};
pub use checkpoint::{
    Checkpoint, read_checkpoint, read_checkpoint_keeping_history, write_checkpoint,
};
pub use checkpoint_bytes::{HistoryFilter, KeptHistory};
pub use checkpoint_pieces::{
    CheckpointPiece, PieceSpheres, checkpoint_piece_path, piece_folder_for,
    remove_other_piece_folders, write_checkpoint_index, write_checkpoint_piece,
};
pub use clump_frames::{CLUMPS_INDEX, clump_frame_name, is_clump_frame_name, write_clumps_vtu};
pub use clumps::{CLUMP_HEADER, ClumpRow, is_clump_file, read_clumps};
pub use collection::{append_entries, entry_line, write_collection};
pub use frame_read::{OwnedFrame, read_frame, read_pvtu, read_vtu};
pub use frames::{
    Frame, FrameSeries, SERIES_INDEX, SeriesEntry, read_series_index, write_frame, write_frame_csv,
    write_frame_npy, write_vtu,
};
pub use log::{FLOW_LOG, FLOW_LOG_HEADER, append_log, start_log};
pub use pairs::{read_pairs, write_pairs};
pub use pieces::{piece_folder, piece_path};
pub use run_folder::{
    CHECKPOINT_FILE, LOCK_FILE, RunFolder, SCENE_FILE, is_run_file_name, is_run_file_of,
    run_files_in, same_file,
};
pub use spheres::{read_particles, read_spheres, write_spheres};
pub use walls::{
    WALL_LOADS, WALL_LOADS_HEADER, WALLS_INDEX, WallLoadRow, is_wall_file_name, wall_file_name,
    wall_load_lines, write_surface_vtp,
};

use crate::error::Error;
use std::path::Path;

/// The sphere file formats, chosen by file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Csv,
    Npy,
}

impl Format {
    fn of(path: &Path) -> Result<Self, Error> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("csv") => Ok(Format::Csv),
            Some("npy") => Ok(Format::Npy),
            other => Err(Error::Parse {
                path: path.to_owned(),
                line: None,
                msg: format!(
                    "unknown sphere file type {:?}: use .csv (header x,y,z,r, optionally with \
                     vx,vy,vz and wx,wy,wz, then material) or .npy (float32, N×4, N×7, N×10 or \
                     N×11)",
                    other.unwrap_or("")
                ),
            }),
        }
    }
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |error| Error::Io {
        path: path.to_owned(),
        error,
    }
}

fn parse_error(path: &Path, line: Option<u64>, msg: impl Into<String>) -> Error {
    Error::Parse {
        path: path.to_owned(),
        line,
        msg: msg.into(),
    }
}
