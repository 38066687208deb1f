//! Frames of a run over several processes written in pieces, one a process, none gathered:
//! process k writes the spheres it owns as `frame_<step>/frame_<step>_<k>.vtu` ([`piece_path`]:
//! a `.vtu` as [`super::write_vtu`] writes one, each sphere's id in the whole run in its `id`
//! array), and once every piece is written process 0 writes the ParaView parallel file
//! `frame_<step>.pvtu` that names them ([`super::FrameSeries::add_pieces`]). ParaView opens the
//! `.pvtu`, or the series that lists it, as one data set; [`read_pvtu`] reads the pieces back
//! as one frame, in the order of the ids.

use super::frame_read::{OwnedFrame, read_vtu};
use super::frames::{blocks_with, frame_stem};
use super::{io_error, parse_error, write_atomically};
use crate::error::Result;
use rayon::prelude::*;
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

/// Reads a `.pvtu` (VTK XML PUnstructuredGrid: mochi's, [`super::FrameSeries::add_pieces`], or
/// another writer's) as one frame: each piece it names (relative to its folder) read as
/// [`read_vtu`] reads a `.vtu`, on a thread each, then joined, in the order of their spheres'
/// ids where every piece has an `id` array (else piece after piece). The pieces must be of
/// one step; an id in two pieces is an error.
pub fn read_pvtu(path: &Path) -> Result<OwnedFrame> {
    let text = std::fs::read_to_string(path).map_err(io_error(path))?;
    let sources = piece_sources(&text).map_err(|(line, msg)| parse_error(path, line, msg))?;
    let folder = path.parent().unwrap_or(Path::new(""));
    let pieces = (sources.par_iter())
        .map(|source| read_vtu(&folder.join(source)))
        .collect::<Result<Vec<_>>>()?;
    joined(pieces).map_err(|msg| parse_error(path, None, msg))
}

/// The `Source` of every `<Piece>` of the `.pvtu` `text`, in order, or the line and the problem.
fn piece_sources(text: &str) -> std::result::Result<Vec<String>, (Option<u64>, String)> {
    let document = roxmltree::Document::parse(text)
        .map_err(|e| (Some(u64::from(e.pos().row)), format!("not XML: {e}")))?;
    let root = document.root_element();
    if !root.has_tag_name("VTKFile") || root.attribute("type") != Some("PUnstructuredGrid") {
        let msg = "not a parallel VTK file (no VTKFile of type=\"PUnstructuredGrid\")";
        return Err((None, msg.into()));
    }
    let pieces = root.descendants().filter(|n| n.has_tag_name("Piece"));
    let sources = pieces
        .map(|node| {
            let line = Some(u64::from(document.text_pos_at(node.range().start).row));
            match node.attribute("Source") {
                Some(source) => Ok(source.to_owned()),
                None => Err((line, "a Piece without a Source".into())),
            }
        })
        .collect::<std::result::Result<Vec<_>, _>>()?;
    if sources.is_empty() {
        return Err((None, "names no pieces (no <Piece Source=\"...\"/>)".into()));
    }
    Ok(sources)
}

/// The frame of `pieces` together (see [`read_pvtu`]), or what is wrong with them.
fn joined(pieces: Vec<OwnedFrame>) -> std::result::Result<OwnedFrame, String> {
    let first = &pieces[0];
    if let Some(other) = pieces.iter().find(|p| p.step != first.step) {
        return Err(format!(
            "its pieces are of different steps ({:?} and {:?})",
            first.step, other.step
        ));
    }
    let (step, time) = (first.step, first.time);
    let n: usize = pieces.iter().map(|p| p.radii.len()).sum();
    // An array some pieces lack (none: every sphere of the first material, no count) is
    // zero for their spheres; ids only where every piece has them.
    let materials = pieces.iter().any(|p| !p.materials.is_empty());
    let contacts = pieces.iter().any(|p| !p.contacts.is_empty());
    let ids = pieces.iter().all(|p| p.ids.len() == p.radii.len());
    let mut frame = OwnedFrame {
        step,
        time,
        positions: Vec::with_capacity(n),
        exact_positions: Vec::with_capacity(n),
        radii: Vec::with_capacity(n),
        velocities: Vec::with_capacity(n),
        angular_velocities: Vec::with_capacity(n),
        materials: Vec::new(),
        contacts: Vec::new(),
        ids: Vec::new(),
    };
    for mut piece in pieces {
        let m = piece.radii.len();
        frame.positions.append(&mut piece.positions);
        frame.exact_positions.append(&mut piece.exact_positions);
        frame.radii.append(&mut piece.radii);
        frame.velocities.append(&mut piece.velocities);
        frame
            .angular_velocities
            .append(&mut piece.angular_velocities);
        piece.materials.resize(m, 0);
        piece.contacts.resize(m, 0);
        if materials {
            frame.materials.append(&mut piece.materials);
        }
        if contacts {
            frame.contacts.append(&mut piece.contacts);
        }
        if ids {
            frame.ids.append(&mut piece.ids);
        }
    }
    if ids {
        in_id_order(&mut frame)?;
    }
    Ok(frame)
}

/// Puts the spheres of `frame` (with ids) in the order of their ids; an id twice is an error.
fn in_id_order(frame: &mut OwnedFrame) -> std::result::Result<(), String> {
    let mut order: Vec<usize> = (0..frame.ids.len()).collect();
    order.par_sort_unstable_by_key(|&k| frame.ids[k]);
    if let Some(w) = order
        .windows(2)
        .find(|w| frame.ids[w[0]] == frame.ids[w[1]])
    {
        return Err(format!(
            "its pieces hold the sphere of id {} twice",
            frame.ids[w[0]]
        ));
    }
    fn permuted<T: Copy + Send + Sync>(values: &mut Vec<T>, order: &[usize]) {
        if !values.is_empty() {
            *values = order.par_iter().map(|&k| values[k]).collect();
        }
    }
    permuted(&mut frame.positions, &order);
    permuted(&mut frame.exact_positions, &order);
    permuted(&mut frame.radii, &order);
    permuted(&mut frame.velocities, &order);
    permuted(&mut frame.angular_velocities, &order);
    permuted(&mut frame.materials, &order);
    permuted(&mut frame.contacts, &order);
    permuted(&mut frame.ids, &order);
    Ok(())
}

/// Whether the folder `folder` holds nothing but pieces of the frame of its name (and the
/// temporary files of killed writers): a folder a run wrote, which clearing the run removes.
pub(super) fn holds_only_pieces(folder: &Path) -> Result<bool> {
    let Some(stem) = folder.file_name().and_then(|n| n.to_str()) else {
        return Ok(false);
    };
    let prefix = format!("{stem}_");
    let listing = std::fs::read_dir(folder).map_err(io_error(folder))?;
    for entry in listing {
        let entry = entry.map_err(io_error(folder))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else {
            return Ok(false);
        };
        let piece = (name.strip_prefix(&prefix))
            .and_then(|k| k.strip_suffix(".vtu"))
            .is_some_and(|k| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()));
        if !(piece || super::atomic::is_temp_file_name(name)) {
            return Ok(false);
        }
    }
    Ok(true)
}
