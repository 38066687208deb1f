//! The output folder of a simulation run: locked while the run writes into it, and told apart
//! from a folder that holds an earlier run.

use super::pieces::{folders_in, holds_only_pieces, is_piece_folder_name};
use super::{
    CLUMPS_INDEX, FLOW_LOG, SERIES_INDEX, WALL_LOADS, WALLS_INDEX, io_error, is_clump_frame_name,
    is_wall_file_name, remove_stale_temp_files,
};
use crate::error::{Error, Result};
use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

/// The lock file in a run folder. The lock is an advisory lock on this file, held by the open
/// file of [`RunFolder`]: the operating system releases it when the process ends, however it
/// ends, so the file itself left behind holds nothing.
pub const LOCK_FILE: &str = ".mochi.lock";

/// The scene file of a run folder.
pub const SCENE_FILE: &str = "scene.toml";

/// The checkpoint of a run folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";

/// Whether `name` is the name of a file `mochi simulate` writes into its output folder: the
/// index, the scene, the checkpoint, a frame `frame_<step>.vtu`, `.pvtu` (of pieces, which lie
/// in the folder `frame_<step>`), `.csv` or `.png`, the clumps' frames and index, the walls'
/// surfaces, index and loads, or the flows' log.
pub fn is_run_file_name(name: &str) -> bool {
    let logs = [WALLS_INDEX, WALL_LOADS, FLOW_LOG];
    if [SERIES_INDEX, SCENE_FILE, CHECKPOINT_FILE, CLUMPS_INDEX].contains(&name)
        || logs.contains(&name)
        || is_wall_file_name(name)
        || is_clump_frame_name(name)
    {
        return true;
    }
    let step = name.strip_prefix("frame_").and_then(|rest| {
        rest.strip_suffix(".vtu")
            .or_else(|| rest.strip_suffix(".pvtu"))
            .or_else(|| rest.strip_suffix(".csv"))
            .or_else(|| rest.strip_suffix(".png"))
    });
    step.is_some_and(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
}

/// Whether `a` and `b` name the same existing file, after following links (the same device and
/// inode on Unix, the same canonical path elsewhere). A path that does not exist is no file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

/// Whether `file` is (or would be, once written) a run file of the folder `dir`: its name is a
/// run file's name and its folder is `dir`.
pub fn is_run_file_of(file: &Path, dir: &Path) -> bool {
    let named = file
        .file_name()
        .and_then(|n| n.to_str())
        .is_some_and(is_run_file_name);
    let parent = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    named && same_file(parent, dir)
}

/// The run files ([`is_run_file_name`]) in the folder `dir`, in name order; none where `dir`
/// does not exist.
pub fn run_files_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let listing = match std::fs::read_dir(dir) {
        Ok(listing) => listing,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io_error(dir)(e)),
    };
    let mut files = Vec::new();
    for entry in listing {
        let entry = entry.map_err(io_error(dir))?;
        let is_run_file = entry.file_name().to_str().is_some_and(is_run_file_name);
        if is_run_file && !entry.file_type().is_ok_and(|t| t.is_dir()) {
            files.push(entry.path());
        }
    }
    files.sort();
    Ok(files)
}

/// The folders of frames' and checkpoints' pieces in `dir` that hold nothing but pieces (see
/// [`super::pieces`], [`super::checkpoint_pieces`]).
fn piece_folders_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut folders = folders_in(dir, is_piece_folder_name, holds_only_pieces)?;
    folders.extend(super::checkpoint_pieces::piece_folders_in(dir)?);
    Ok(folders)
}

/// A run's output folder, locked for as long as this value lives.
#[derive(Debug)]
pub struct RunFolder {
    dir: PathBuf,
    /// Holds the lock.
    _lock: File,
}

impl RunFolder {
    /// Creates `dir` if needed, locks it, and removes the temporary files that killed writers
    /// left in it. Fails, naming the folder, when another process holds its lock.
    pub fn lock(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(io_error(dir))?;
        let path = dir.join(LOCK_FILE);
        let file = File::options()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(io_error(&path))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                // The folder is busy: an I/O condition of the folder, named as the folder.
                return Err(Error::Io {
                    path: dir.to_owned(),
                    error: std::io::Error::new(
                        std::io::ErrorKind::WouldBlock,
                        format!(
                            "another mochi run is writing into this folder (it holds \
                             {LOCK_FILE}); wait for it to end or choose another folder with -o"
                        ),
                    ),
                });
            }
            Err(TryLockError::Error(error)) => return Err(Error::Io { path, error }),
        }
        remove_stale_temp_files(dir);
        Ok(Self {
            dir: dir.to_owned(),
            _lock: file,
        })
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The run files in the folder, in name order (see [`run_files_in`]).
    pub fn run_files(&self) -> Result<Vec<PathBuf>> {
        run_files_in(&self.dir)
    }

    /// Removes the run files of an earlier run, and its frames' and checkpoints' folders of
    /// pieces where they hold nothing else (every other file stays); returns how many files and folders.
    pub fn clear(&self) -> Result<usize> {
        let files = self.run_files()?;
        for file in &files {
            std::fs::remove_file(file).map_err(io_error(file))?;
        }
        let folders = piece_folders_in(&self.dir)?;
        for folder in &folders {
            std::fs::remove_dir_all(folder).map_err(io_error(folder))?;
        }
        Ok(files.len() + folders.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_file_names_are_the_files_a_run_writes() {
        for name in [
            "series.pvd",
            "scene.toml",
            "checkpoint.bin",
            "frame_00000000.vtu",
            "frame_00000100.pvtu",
            "frame_00012345.csv",
            "frame_123456789.png",
            "walls.pvd",
            "walls.csv",
            "flow.csv",
            "wall_00000100_0.vtp",
            "wall_2.vtp",
            "clumps.pvd",
            "clumps_00000300.vtu",
        ] {
            assert!(is_run_file_name(name), "{name}");
        }
        for name in [
            "notes.txt",
            "frame_.vtu",
            "frame_12a.vtu",
            "frame_00000001.npy",
            "run.gif",
            ".mochi.lock",
            "scene.toml.bak",
            "clumps_.vtu",
            "clumps_00000300.csv",
        ] {
            assert!(!is_run_file_name(name), "{name}");
        }
    }

    #[test]
    fn a_second_lock_on_a_folder_fails_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let first = RunFolder::lock(dir.path()).unwrap();
        let e = RunFolder::lock(dir.path()).unwrap_err().to_string();
        assert!(e.contains("another mochi run"), "{e}");
        drop(first);
        RunFolder::lock(dir.path()).unwrap();
    }

    #[test]
    fn clear_removes_the_run_files_only() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let run = [
            "series.pvd",
            "frame_00000010.vtu",
            "frame_00000020.pvtu",
            "walls.pvd",
            "wall_0.vtp",
            "flow.csv",
        ];
        for name in run.iter().chain(&["notes.txt", "start.csv"]) {
            std::fs::write(d.join(name), b"x").unwrap();
        }
        // A frame's or checkpoint's folder of pieces goes; one that holds something else, or
        // is named otherwise, stays.
        for (folder, file) in [
            ("frame_00000020", "frame_00000020_1.vtu"),
            ("checkpoint_00000020", "checkpoint_00000020_0.bin"),
            ("checkpoint_00000020-2", "checkpoint_00000020_3.bin"),
            ("frame_00000030", "notes.txt"),
            ("checkpoint_00000030", "checkpoint_00000020_0.bin"),
            ("pieces", "frame_00000030_0.vtu"),
        ] {
            std::fs::create_dir(d.join(folder)).unwrap();
            std::fs::write(d.join(folder).join(file), b"x").unwrap();
        }
        let folder = RunFolder::lock(d).unwrap();
        assert_eq!(folder.clear().unwrap(), run.len() + 3);
        assert!(run.iter().all(|name| !d.join(name).exists()));
        for gone in [
            "frame_00000020",
            "checkpoint_00000020",
            "checkpoint_00000020-2",
        ] {
            assert!(!d.join(gone).exists(), "{gone}");
        }
        assert!(
            d.join("checkpoint_00000030/checkpoint_00000020_0.bin")
                .exists()
        );
        assert!(d.join("frame_00000030/notes.txt").exists() && d.join("pieces").exists());
        assert!(d.join("notes.txt").exists() && d.join("start.csv").exists());
    }
}
