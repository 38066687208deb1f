//! Frames of a run over several processes written in pieces, one a process, none gathered:
//! process k writes the spheres it owns as `frame_<step>/frame_<step>_<k>.vtu` ([`piece_path`]:
//! a `.vtu` as [`super::write_vtu`] writes one, each sphere's id in the whole run in its `id`
//! array), and once every piece is written process 0 writes the ParaView parallel file
//! `frame_<step>.pvtu` that names them ([`super::FrameSeries::add_pieces`]). ParaView opens the
//! `.pvtu`, or the series that lists it, as one data set; [`super::read_pvtu`] reads the
//! pieces back as one frame, in the order of the ids.

use super::frame_layout::{blocks_with, frame_stem};
use super::{io_error, write_atomically};
use crate::error::Result;
use std::path::{Path, PathBuf};

/// The folder of the pieces of the frame of step `step` in the series folder `dir`.
pub fn piece_folder(dir: &Path, step: u64) -> PathBuf {
    dir.join(frame_stem(step))
}

/// The file of piece `piece` (the spheres of process `piece`) of the frame of step `step` in
/// the series folder `dir`.
pub fn piece_path(dir: &Path, step: u64, piece: usize) -> PathBuf {
    piece_folder(dir, step).join(piece_name(step, piece))
}

fn piece_name(step: u64, piece: usize) -> String {
    format!("{}_{piece}.vtu", frame_stem(step))
}

/// Whether `name` is the name of a frame's folder of pieces (`frame_<step>`).
pub(super) fn is_piece_folder_name(name: &str) -> bool {
    name.strip_prefix("frame_")
        .is_some_and(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
}

/// Writes `path`, the `.pvtu` of the frame of step `step` in `pieces` pieces (with a history's
/// `contacts` array where `contacts` says), naming the pieces by [`piece_path`] relative to its
/// folder, atomically.
pub(super) fn write_pvtu(path: &Path, step: u64, pieces: usize, contacts: bool) -> Result<()> {
    let blocks = blocks_with(contacts, false);
    let mut xml = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" \
         byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <PUnstructuredGrid \
         GhostLevel=\"0\">\n",
    );
    let sections = [
        ("PointData", r#" Scalars="radius" Vectors="velocity""#),
        ("Points", ""),
    ];
    for (section, attributes) in sections {
        xml += &format!("    <P{section}{attributes}>\n");
        for block in blocks.iter().filter(|b| b.section() == section) {
            let components = match block.components() {
                1 => String::new(),
                c => format!(r#" NumberOfComponents="{c}""#),
            };
            xml += &format!(
                "      <PDataArray type=\"{}\" Name=\"{}\"{components}/>\n",
                block.vtk_type(false),
                block.name()
            );
        }
        xml += &format!("    </P{section}>\n");
    }
    for piece in 0..pieces {
        let source = format!("{}/{}", frame_stem(step), piece_name(step, piece));
        xml += &format!("    <Piece Source=\"{source}\"/>\n");
    }
    xml += "  </PUnstructuredGrid>\n</VTKFile>\n";
    write_atomically(path, |out| out.write_all(xml.as_bytes()))
}

/// Removes the pieces of the frame of step `step` in `dir` numbered `pieces` and beyond (left
/// by an earlier write of the step over more processes).
pub(super) fn remove_pieces_beyond(dir: &Path, step: u64, pieces: usize) -> Result<()> {
    let folder = piece_folder(dir, step);
    let listing = match std::fs::read_dir(&folder) {
        Ok(listing) => listing,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io_error(&folder)(e)),
    };
    let prefix = format!("{}_", frame_stem(step));
    for entry in listing {
        let entry = entry.map_err(io_error(&folder))?;
        let name = entry.file_name();
        let piece = (name.to_str())
            .and_then(|n| n.strip_prefix(&prefix))
            .and_then(|n| n.strip_suffix(".vtu"))
            .and_then(|k| k.parse::<usize>().ok());
        if piece.is_some_and(|k| k >= pieces) {
            std::fs::remove_file(entry.path()).map_err(io_error(&entry.path()))?;
        }
    }
    Ok(())
}

/// Whether the folder `folder` holds nothing but pieces of the frame of its name (and the
/// temporary files of killed writers): a folder a run wrote, which clearing the run removes.
pub(super) fn holds_only_pieces(folder: &Path) -> Result<bool> {
    let Some(stem) = folder.file_name().and_then(|n| n.to_str()) else {
        return Ok(false);
    };
    holds_only_files(folder, &format!("{stem}_"), ".vtu")
}

/// Whether the folder `folder` holds nothing but files named `<prefix><k><suffix>` (`k` a
/// number) and the temporary files of killed writers.
pub(super) fn holds_only_files(folder: &Path, prefix: &str, suffix: &str) -> Result<bool> {
    let listing = std::fs::read_dir(folder).map_err(io_error(folder))?;
    for entry in listing {
        let entry = entry.map_err(io_error(folder))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else {
            return Ok(false);
        };
        let piece = (name.strip_prefix(prefix))
            .and_then(|k| k.strip_suffix(suffix))
            .is_some_and(|k| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()));
        if !(piece || super::atomic::is_temp_file_name(name)) {
            return Ok(false);
        }
    }
    Ok(true)
}

/// The folders in `dir` whose names `named` accepts and which `holds_only` finds holding nothing
/// but their pieces.
pub(super) fn folders_in(
    dir: &Path,
    named: impl Fn(&str) -> bool,
    holds_only: impl Fn(&Path) -> Result<bool>,
) -> Result<Vec<PathBuf>> {
    let mut folders = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_error(dir))? {
        let entry = entry.map_err(io_error(dir))?;
        let is_named = entry.file_name().to_str().is_some_and(&named);
        if is_named && entry.file_type().is_ok_and(|t| t.is_dir()) && holds_only(&entry.path())? {
            folders.push(entry.path());
        }
    }
    Ok(folders)
}
