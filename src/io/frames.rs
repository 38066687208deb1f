//! Simulation frames for ParaView: one VTK XML UnstructuredGrid file (`.vtu`) per frame, an
//! optional CSV twin (`x,y,z,r,vx,vy,vz,wx,wy,wz,material`), and a ParaView collection
//! (`series.pvd`) that lists the frames with their times.
//!
//! A `.vtu` frame holds one `VTK_VERTEX` cell per sphere, the positions as `Float64` points
//! (each centre plus its residual, [`crate::particles::position`]: 1e-14 m at 100 m, where
//! `Float32` would round to 8e-6 m) and the point arrays `radius`, `velocity` (3 components), `speed`, `angular_velocity` (3 components;
//! all `Float32`), `id` (`UInt32`, the sphere's index) and `material` (`UInt8`, the sphere's
//! material: its index in the scene's `[[materials]]` tables), and, when the run keeps contact
//! history (friction or EPSD rolling resistance), `contacts` (`UInt32`: the contacts each sphere
//! holds in that history, walls included), and when it has clumps, `clump` (`Int32`: the clump
//! a sphere is a component of, −1 for a free sphere), plus the field data `TimeValue` (`Float64`) and `step`
//! (`UInt64`). The
//! arrays are stored as raw little-endian binary in one `<AppendedData encoding="raw">` block, each
//! preceded by its length in bytes as a `UInt64` (`header_type="UInt64"`). In ParaView, open
//! `series.pvd` and show the spheres with a Glyph (sphere, scale by `radius`, factor 2) or the
//! Point Gaussian representation.
//!
//! The writer is our own rather than the `vtkio` crate's: vtkio (last stable release 0.6.3; 0.7
//! only as release candidates, 0.7.0-rc2 checked) writes XML binary data only as inline base64
//! (a third larger, and encoded), never as raw appended data; it wants every array copied into
//! its own owned model first, serialises through serde and quick-xml, and by default pulls in
//! three compression libraries. A frame needs only a fixed header and a dozen byte blocks, which
//! this file writes straight from the caller's slices (61 MB for a million spheres), with no
//! copy of the state.
//!
//! Every file is written through [`write_atomically`]: a killed run leaves each frame and the
//! index either whole or as it was, and a frame is always written before the index that names it.

use super::clump_frames::{CLUMPS_INDEX, clump_frame_name, write_clumps_vtu};
use super::frame_layout::{Block, blocks_with, frame_stem};
use super::vtu_write::vtu_opening;
use super::{collection, io_error, parse_error, write_atomically};
use crate::clump::ClumpSet;
use crate::error::{Error, Result};
use crate::particles::{Particles, position};
use npyz::WriterBuilder;
use rayon::prelude::*;
use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The state of every sphere at one step of a simulation. The slices are parallel: sphere `i` is
/// `positions[i]` (plus `position_residuals[i]`), `radii[i]`, `velocities[i]`,
/// `angular_velocities[i]` (and `materials[i]`).
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// Simulated time \[s\]; must be finite.
    pub time: f64,
    /// Step number; names the frame's files (`frame_{step:08}.vtu`).
    pub step: u64,
    /// Centres \[m\] (as `f32`: [`Particles::positions`]).
    pub positions: &'a [[f32; 3]],
    /// The centres' residuals \[m\] ([`Particles::position_residuals`]): empty (none) or one
    /// per sphere. The files hold each centre plus its residual, in `f64`.
    pub position_residuals: &'a [[f32; 3]],
    /// Radii \[m\].
    pub radii: &'a [f32],
    /// Velocities \[m/s\].
    pub velocities: &'a [[f32; 3]],
    /// Angular velocities \[rad/s\].
    pub angular_velocities: &'a [[f32; 3]],
    /// Materials ([`Particles::materials`]): empty (every sphere of the first material, 0) or
    /// one per sphere.
    pub materials: &'a [u8],
    /// The contacts each sphere holds in the history of a run that keeps one (`None`: a run
    /// without friction keeps none, and the `.vtu` leaves the array out).
    pub contacts: Option<&'a [u32]>,
    /// The clumps of a run that has any ([`Particles::clumps`]: the first spheres are their
    /// components): the `.vtu` then holds each sphere's clump (`None`: the array is left out).
    pub clumps: Option<&'a ClumpSet>,
    /// Each sphere's id in the whole run, where the frame is a piece of it (one process's
    /// spheres: [`FrameSeries::add_pieces`]); `None`: each sphere's id is its index.
    pub ids: Option<&'a [u32]>,
}

impl<'a> Frame<'a> {
    /// The frame of `particles` at time `step · dt`, with each sphere's `contacts` where the
    /// run keeps a history (the step's contacts carry springs: friction or EPSD rolling
    /// resistance: a stepper's snapshot counts them, as
    /// [`ContactHistory::counts`](crate::particles::ContactHistory::counts) does).
    pub fn of(particles: &'a Particles, dt: f32, contacts: Option<&'a [u32]>) -> Self {
        Self {
            time: particles.step as f64 * dt as f64,
            step: particles.step,
            positions: &particles.positions,
            position_residuals: &particles.position_residuals,
            radii: &particles.radii,
            velocities: &particles.velocities,
            angular_velocities: &particles.angular_velocities,
            materials: &particles.materials,
            contacts,
            clumps: (!particles.clumps.clumps.is_empty()).then_some(&particles.clumps),
            ids: None,
        }
    }
}

impl Frame<'_> {
    /// The number of spheres, once the slices and the history are known to agree and the time
    /// to be finite.
    fn checked_len(&self) -> Result<usize> {
        let n = self.positions.len();
        let residuals = self.position_residuals.len();
        let materials = self.materials.len();
        if self.radii.len() != n
            || self.velocities.len() != n
            || self.angular_velocities.len() != n
            || !(residuals == 0 || residuals == n)
            || !(materials == 0 || materials == n)
        {
            return Err(Error::Usage(format!(
                "frame at step {}: {} positions, {residuals} position residuals and {materials} \
                 materials (none or as many), {} radii, {} velocities and {} angular velocities \
                 (must be equal)",
                self.step,
                n,
                self.radii.len(),
                self.velocities.len(),
                self.angular_velocities.len()
            )));
        }
        if let Some(ids) = self.ids
            && ids.len() != n
        {
            return Err(Error::Usage(format!(
                "frame at step {}: {} ids for {n} spheres",
                self.step,
                ids.len()
            )));
        }
        if let Some(contacts) = self.contacts
            && contacts.len() != n
        {
            return Err(Error::Usage(format!(
                "frame at step {}: {} contact counts for {n} spheres",
                self.step,
                contacts.len()
            )));
        }
        if !self.time.is_finite() {
            return Err(Error::Usage(format!(
                "frame at step {}: the time {} is not finite",
                self.step, self.time
            )));
        }
        if n > u32::MAX as usize {
            return Err(Error::TooLarge {
                what: "spheres in a frame".into(),
                got: n as u64,
                limit: u32::MAX.into(),
            });
        }
        Ok(n)
    }
}

impl Frame<'_> {
    /// Where sphere `i` is: its centre plus its residual, in `f64`.
    fn exact_position(&self, i: usize) -> [f64; 3] {
        let hi = self.positions[i];
        let lo = self.position_residuals.get(i).copied().unwrap_or([0.0; 3]);
        std::array::from_fn(|a| position::join(hi[a], lo[a]))
    }

    /// Every sphere's [`exact_position`](Self::exact_position), in order.
    fn exact_positions(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        (0..self.positions.len()).map(|i| self.exact_position(i))
    }

    /// Every sphere's material, in order (0 where the frame has none).
    fn materials(&self) -> impl Iterator<Item = u8> + '_ {
        (0..self.positions.len()).map(|i| self.materials.get(i).copied().unwrap_or(0))
    }
}

/// Speed |v| of a velocity, computed in `f64` and rounded once to `f32` (the `speed` array).
fn speed(v: [f32; 3]) -> f32 {
    glam::Vec3::from(v).as_dvec3().length() as f32
}

// ---------------------------------------------------------------------------------------------
// .vtu
// ---------------------------------------------------------------------------------------------

/// VTK's cell type code of a single point (`VTK_VERTEX`).
const VTK_VERTEX: u8 = 1;

/// The blocks of `frame`, in the order they are written (`contacts` only with a history).
fn blocks(frame: &Frame) -> Vec<Block> {
    blocks_with(frame.contacts.is_some(), frame.clumps.is_some())
}

/// Writes `frame` as a VTK XML UnstructuredGrid (`.vtu`, raw appended binary), atomically.
///
/// Slices of different lengths or a non-finite time are an [`Error::Usage`], and nothing is
/// written.
pub fn write_vtu(path: &Path, frame: &Frame) -> Result<()> {
    let n = frame.checked_len()?;
    let wide = n > i32::MAX as usize;
    let blocks = blocks(frame);
    let header = vtu_header(frame, &blocks, n, wide);
    // The pieces' bytes, encoded into the same vectors block after block.
    let mut encoded = vec![Vec::new(); ENCODED_AT_ONCE];
    write_atomically(path, |out| {
        out.write_all(header.as_bytes())?;
        for &block in &blocks {
            out.write_all(&block.data_bytes(n, wide).to_le_bytes())?;
            write_block(out, block, frame, wide, &mut encoded)?;
        }
        out.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
    })
}

/// The XML up to and including the `_` that opens the appended data.
fn vtu_header(frame: &Frame, blocks: &[Block], n: usize, wide: bool) -> String {
    let mut offsets = vec![0u64; blocks.len()];
    let mut at = 0;
    for (k, block) in blocks.iter().enumerate() {
        offsets[k] = at;
        at += 8 + block.data_bytes(n, wide);
    }
    let mut xml = vtu_opening(frame.time, frame.step, n);
    let sections = [
        ("PointData", r#" Scalars="radius" Vectors="velocity""#),
        ("Points", ""),
        ("Cells", ""),
    ];
    for (section, attributes) in sections {
        xml += &format!("      <{section}{attributes}>\n");
        for (k, block) in blocks.iter().enumerate() {
            if block.section() != section {
                continue;
            }
            let components = match block.components() {
                1 => String::new(),
                c => format!(r#" NumberOfComponents="{c}""#),
            };
            xml += &format!(
                "        <DataArray type=\"{}\" Name=\"{}\"{components} format=\"appended\" \
                 offset=\"{}\"/>\n",
                block.vtk_type(wide),
                block.name(),
                offsets[k]
            );
        }
        xml += &format!("      </{section}>\n");
    }
    xml += "    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _";
    xml
}

/// Spheres a block encodes as one piece of work, and pieces encoded at once (on every core)
/// before they are written in order: at most `ENCODED_AT_ONCE · SPHERES_A_PIECE · 24` bytes
/// (the points) held at a time.
const SPHERES_A_PIECE: usize = 1 << 16;
const ENCODED_AT_ONCE: usize = 64;

/// Writes the data of one block (its length header is already out): its pieces encoded on
/// every core into `encoded` (at most [`ENCODED_AT_ONCE`] vectors), written in order.
fn write_block(
    out: &mut dyn Write,
    block: Block,
    frame: &Frame,
    wide: bool,
    encoded: &mut [Vec<u8>],
) -> std::io::Result<()> {
    if let Some(bytes) = as_stored(block, frame) {
        return out.write_all(bytes);
    }
    let n = frame.radii.len();
    // Each component's clump, where the block is theirs.
    let owners = match (block, frame.clumps) {
        (Block::Clump, Some(set)) => set.owners(),
        _ => Vec::new(),
    };
    let pieces: Vec<usize> = (0..n).step_by(SPHERES_A_PIECE).collect();
    for group in pieces.chunks(encoded.len()) {
        let encoded = &mut encoded[..group.len()];
        (group.par_iter().zip(encoded.par_iter_mut())).for_each(|(&first, bytes)| {
            let spheres = first..n.min(first + SPHERES_A_PIECE);
            encode(block, (frame, &owners), wide, spheres, bytes);
        });
        for bytes in encoded.iter() {
            out.write_all(bytes)?;
        }
    }
    Ok(())
}

/// The bytes of `block` where the frame holds them as the file does (little-endian values of
/// the file's type): written as they lie.
fn as_stored<'f>(block: Block, frame: &Frame<'f>) -> Option<&'f [u8]> {
    if cfg!(target_endian = "big") {
        return None;
    }
    match block {
        Block::Radius => Some(bytemuck::cast_slice(frame.radii)),
        Block::Velocity => Some(bytemuck::cast_slice(frame.velocities)),
        Block::AngularVelocity => Some(bytemuck::cast_slice(frame.angular_velocities)),
        Block::Contacts => frame.contacts.map(bytemuck::cast_slice),
        Block::Id => frame.ids.map(bytemuck::cast_slice),
        _ => None,
    }
}

/// The bytes of `block` of the spheres `spheres` of `frame` (whose components' clumps are
/// `owners`, where the block is theirs), into `out` (emptied first).
fn encode(
    block: Block,
    (frame, owners): (&Frame, &[u32]),
    wide: bool,
    spheres: Range<usize>,
    out: &mut Vec<u8>,
) {
    out.clear();
    let index = |i: usize, out: &mut Vec<u8>| match wide {
        true => out.extend_from_slice(&(i as i64).to_le_bytes()),
        false => out.extend_from_slice(&(i as i32).to_le_bytes()),
    };
    let triples = |rows: &[[f32; 3]], out: &mut Vec<u8>| {
        for x in rows.iter().flatten() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    };
    let range = spheres.clone();
    match block {
        Block::Radius => (frame.radii[range].iter()).for_each(|r| out.extend(r.to_le_bytes())),
        Block::Velocity => triples(&frame.velocities[range], out),
        Block::Speed => (frame.velocities[range].iter())
            .for_each(|&v| out.extend_from_slice(&speed(v).to_le_bytes())),
        Block::AngularVelocity => triples(&frame.angular_velocities[range], out),
        Block::Id => match frame.ids {
            Some(ids) => (ids[range].iter()).for_each(|i| out.extend_from_slice(&i.to_le_bytes())),
            None => range.for_each(|i| out.extend_from_slice(&(i as u32).to_le_bytes())),
        },
        Block::Material => {
            range.for_each(|i| out.push(frame.materials.get(i).copied().unwrap_or(0)));
        }
        Block::Contacts => {
            let contacts = frame.contacts.expect("the block is written with a history");
            (contacts[range].iter()).for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
        }
        Block::Clump => {
            range.for_each(|i| {
                let clump = owners.get(i).map_or(-1, |&k| k as i32);
                out.extend_from_slice(&clump.to_le_bytes());
            });
        }
        Block::Points => range.for_each(|i| {
            for x in frame.exact_position(i) {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }),
        Block::Connectivity => range.for_each(|i| index(i, out)),
        Block::Offsets => range.for_each(|i| index(i + 1, out)),
        Block::Types => out.resize(spheres.len(), VTK_VERTEX),
    }
}

/// Gathers small values into 64 KiB writes (one dynamic call per chunk, not per value).
pub(super) struct Chunked<'o> {
    out: &'o mut dyn Write,
    buf: Box<[u8; 1 << 16]>,
    used: usize,
}

impl<'o> Chunked<'o> {
    pub(super) fn new(out: &'o mut dyn Write) -> Self {
        Self {
            out,
            buf: Box::new([0; 1 << 16]),
            used: 0,
        }
    }

    pub(super) fn put<const W: usize>(&mut self, bytes: [u8; W]) -> std::io::Result<()> {
        if self.used + W > self.buf.len() {
            self.flush()?;
        }
        self.buf[self.used..self.used + W].copy_from_slice(&bytes);
        self.used += W;
        Ok(())
    }

    pub(super) fn flush(&mut self) -> std::io::Result<()> {
        self.out.write_all(&self.buf[..self.used])?;
        self.used = 0;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// .csv
// ---------------------------------------------------------------------------------------------

/// Writes `frame` as CSV with the header `x,y,z,r,vx,vy,vz,wx,wy,wz,material`, one sphere per
/// row, every number in its shortest round-trip form (as [`super::write_spheres`] writes),
/// atomically: the positions (each centre plus its residual) as `f64` (up to 17 significant
/// digits), the material as an integer, the rest as `f32`.
///
/// The file is a sphere file with velocities, angular velocities and materials:
/// [`super::read_particles`]
/// reads it back (so `mochi simulate --input FRAME.csv` restarts from it) and
/// [`super::read_spheres`] reads its spheres. (The contact history is not in it: a restart
/// from a frame starts every contact's springs from zero; a checkpoint keeps them.)
pub fn write_frame_csv(path: &Path, frame: &Frame) -> Result<()> {
    frame.checked_len()?;
    write_atomically(path, |out| {
        writeln!(out, "x,y,z,r,vx,vy,vz,wx,wy,wz,material")?;
        for (((([x, y, z], r), &[vx, vy, vz]), &[wx, wy, wz]), m) in frame
            .exact_positions()
            .zip(frame.radii)
            .zip(frame.velocities)
            .zip(frame.angular_velocities)
            .zip(frame.materials())
        {
            writeln!(out, "{x},{y},{z},{r},{vx},{vy},{vz},{wx},{wy},{wz},{m}")?;
        }
        Ok(())
    })
}

/// Writes `frame` as NumPy `.npy`, float64 of shape N×11 (the columns of
/// [`write_frame_csv`]: the positions, each centre plus its residual, the other columns' `f32`
/// values exactly, and the material), atomically. [`super::read_particles`] and [`super::read_frame`] read
/// it back, as does `numpy.load`.
pub fn write_frame_npy(path: &Path, frame: &Frame) -> Result<()> {
    let n = frame.checked_len()?;
    write_atomically(path, |out| {
        let mut npy = npyz::WriteOptions::<f64>::new()
            .default_dtype()
            .shape(&[n as u64, 11])
            .writer(out)
            .begin_nd()?;
        for (((([x, y, z], &r), &[vx, vy, vz]), &[wx, wy, wz]), m) in frame
            .exact_positions()
            .zip(frame.radii)
            .zip(frame.velocities)
            .zip(frame.angular_velocities)
            .zip(frame.materials())
        {
            let rest = [r, vx, vy, vz, wx, wy, wz].map(f64::from);
            npy.extend([x, y, z].into_iter().chain(rest).chain([m.into()]))?;
        }
        npy.finish()
    })
}

/// Writes `frame` by the extension of `path`: `.vtu` ([`write_vtu`]), `.csv`
/// ([`write_frame_csv`]) or `.npy` ([`write_frame_npy`]); any other is an error naming the file.
pub fn write_frame(path: &Path, frame: &Frame) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("vtu") => write_vtu(path, frame),
        Some("csv") => write_frame_csv(path, frame),
        Some("npy") => write_frame_npy(path, frame),
        other => Err(Error::Parse {
            path: path.to_owned(),
            line: None,
            msg: format!(
                "unknown frame file type {:?}: use .vtu, .csv or .npy",
                other.unwrap_or("")
            ),
        }),
    }
}

// ---------------------------------------------------------------------------------------------
// series.pvd
// ---------------------------------------------------------------------------------------------

/// File name of a series' index, a ParaView collection, inside its directory.
pub const SERIES_INDEX: &str = "series.pvd";

/// One frame listed in a series' index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesEntry {
    /// Step number.
    pub step: u64,
    /// Simulated time \[s\].
    pub time: f64,
    /// Whether the frame is a `.pvtu` of pieces, one a process of a run over several
    /// ([`FrameSeries::add_pieces`]); else a `.vtu`.
    pub pieces: bool,
}

impl SeriesEntry {
    /// The frame's file name (`.vtu`, or `.pvtu` where it is of pieces), relative to the series
    /// directory.
    pub fn file_name(&self) -> String {
        let extension = if self.pieces { "pvtu" } else { "vtu" };
        format!("{}.{extension}", frame_stem(self.step))
    }

    /// The frame's line in the index.
    fn line(&self) -> String {
        collection::entry_line(self.time, 0, &self.file_name())
    }

    /// The frame's clumps' line in their index ([`CLUMPS_INDEX`]).
    fn clumps_line(&self) -> String {
        collection::entry_line(self.time, 0, &clump_frame_name(self.step))
    }
}

/// A directory of frames (`frame_{step:08}.vtu`, optionally `.csv`) and their index
/// [`SERIES_INDEX`], which lists them in step order. Each [`FrameSeries::write`] writes the frame
/// first and then adds it to the index, so the index never names a missing or partial file.
#[derive(Debug)]
pub struct FrameSeries {
    dir: PathBuf,
    entries: Vec<SeriesEntry>,
}

impl FrameSeries {
    /// Starts a new series in `dir` (created if needed) with an empty index, replacing any index
    /// already there. Frame files already in `dir` are left alone, and replaced as frames of the
    /// same step are written.
    pub fn create(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir).map_err(io_error(dir))?;
        let series = Self {
            dir: dir.to_owned(),
            entries: Vec::new(),
        };
        write_index(&series.index_path(), &series.entries)?;
        Ok(series)
    }

    /// Goes on with the series in `dir` after a restart from step `resume_step`: reads its index,
    /// keeps the frames with `step <= resume_step`, and rewrites the index with only those. The
    /// files of the dropped frames stay on disk until frames of the same steps replace them.
    /// A run that wrote no frames has no index: a new series starts then.
    pub fn open_for_resume(dir: &Path, resume_step: u64) -> Result<Self> {
        let series = Self {
            dir: dir.to_owned(),
            entries: Vec::new(),
        };
        let index = series.index_path();
        if !index.exists() {
            return Self::create(dir);
        }
        let text = std::fs::read_to_string(&index).map_err(io_error(&index))?;
        let mut entries = parse_index(&index, &text)?;
        entries.retain(|e| e.step <= resume_step);
        entries.sort_by_key(|e| e.step);
        entries.dedup_by_key(|e| e.step);
        write_index(&index, &entries)?;
        let clumps = dir.join(CLUMPS_INDEX);
        if clumps.exists() {
            let lines: String = entries.iter().map(SeriesEntry::clumps_line).collect();
            collection::write_collection(&clumps, &lines)?;
        }
        Ok(Self { entries, ..series })
    }

    /// Writes `frame` as `frame_{step:08}.vtu` (and `.csv` when `csv`, and its clumps as
    /// `clumps_{step:08}.vtu` where it has any), then adds it to the index: its entry appended
    /// after the last (a frame of the last step or before rewrites the index with the frame in
    /// its place), and to the clumps' index ([`CLUMPS_INDEX`]). Returns the `.vtu` path. On an
    /// error the index and [`FrameSeries::entries`] are as before.
    pub fn write(&mut self, frame: &Frame, csv: bool) -> Result<PathBuf> {
        let stem = frame_stem(frame.step);
        let vtu = self.dir.join(format!("{stem}.vtu"));
        write_vtu(&vtu, frame)?;
        if csv {
            write_frame_csv(&self.dir.join(format!("{stem}.csv")), frame)?;
        }
        if let Some(set) = frame.clumps {
            let clumps = self.dir.join(clump_frame_name(frame.step));
            write_clumps_vtu(&clumps, set, frame.time, frame.step)?;
        }
        self.index(SeriesEntry {
            step: frame.step,
            time: frame.time,
            pieces: false,
        })?;
        if frame.clumps.is_some() {
            // A run's frames either all have clumps or none do: its clumps' index lists them all.
            let lines: String = self.entries.iter().map(SeriesEntry::clumps_line).collect();
            collection::write_collection(&self.dir.join(CLUMPS_INDEX), &lines)?;
        }
        Ok(vtu)
    }

    /// Adds the frame of step `step` at `time` whose `pieces` processes each wrote the piece
    /// of its own spheres ([`super::piece_path`]; the pieces hold a history's `contacts` array
    /// where `contacts` says) as `frame_{step:08}.pvtu`, which names them, then to the index as
    /// [`write`](Self::write) adds a frame; the pieces an earlier write of the step left beyond
    /// these are removed. Returns the `.pvtu` path. On an error the index and
    /// [`FrameSeries::entries`] are as before.
    pub fn add_pieces(
        &mut self,
        step: u64,
        time: f64,
        pieces: usize,
        contacts: bool,
    ) -> Result<PathBuf> {
        let pvtu = self.dir.join(format!("{}.pvtu", frame_stem(step)));
        super::pieces::write_pvtu(&pvtu, step, pieces, contacts)?;
        super::pieces::remove_pieces_beyond(&self.dir, step, pieces)?;
        let pieces = true;
        self.index(SeriesEntry { step, time, pieces })?;
        Ok(pvtu)
    }

    /// Adds the frame of `entry` (written) to the index.
    fn index(&mut self, entry: SeriesEntry) -> Result<()> {
        let step = entry.step;
        if self.entries.last().is_none_or(|last| last.step < step) {
            // The usual case, a frame after the last: only its entry is written.
            collection::append_entries(&self.index_path(), &entry.line())?;
            self.entries.push(entry);
            return Ok(());
        }
        let mut entries = self.entries.clone();
        entries.retain(|e| e.step != step);
        let at = entries.partition_point(|e| e.step < step);
        entries.insert(at, entry);
        write_index(&self.index_path(), &entries)?;
        self.entries = entries;
        Ok(())
    }

    /// The series directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The index file, `dir/series.pvd`.
    pub fn index_path(&self) -> PathBuf {
        self.dir.join(SERIES_INDEX)
    }

    /// The frames in the index, in step order.
    pub fn entries(&self) -> &[SeriesEntry] {
        &self.entries
    }
}

fn write_index(path: &Path, entries: &[SeriesEntry]) -> Result<()> {
    let lines: String = entries.iter().map(SeriesEntry::line).collect();
    collection::write_collection(path, &lines)
}

/// Reads the frames listed in a series index ([`SERIES_INDEX`]) this module wrote, in its order.
pub fn read_series_index(path: &Path) -> Result<Vec<SeriesEntry>> {
    let text = std::fs::read_to_string(path).map_err(io_error(path))?;
    parse_index(path, &text)
}

/// Reads the `<DataSet timestep=".." file="frame_N.vtu"/>` entries (`.pvtu` for a frame of
/// pieces) of an index this module wrote (the step comes from the file name), with an XML
/// parser: an error names the line.
fn parse_index(path: &Path, text: &str) -> Result<Vec<SeriesEntry>> {
    let document = roxmltree::Document::parse(text).map_err(|e| {
        let line = Some(u64::from(e.pos().row));
        parse_error(path, line, format!("not XML: {e}"))
    })?;
    let root = document.root_element();
    if !root.has_tag_name("VTKFile") || root.attribute("type") != Some("Collection") {
        return Err(parse_error(
            path,
            None,
            "not a ParaView collection (no VTKFile of type=\"Collection\")",
        ));
    }
    let data_sets = root
        .descendants()
        .filter(|node| node.has_tag_name("DataSet"));
    data_sets
        .map(|node| {
            let line = Some(u64::from(document.text_pos_at(node.range().start).row));
            let bad = |msg: String| parse_error(path, line, msg);
            let timestep = node
                .attribute("timestep")
                .ok_or_else(|| bad("a DataSet without a timestep".into()))?;
            let file = node
                .attribute("file")
                .ok_or_else(|| bad("a DataSet without a file".into()))?;
            let time: f64 = timestep
                .parse()
                .ok()
                .filter(|t: &f64| t.is_finite())
                .ok_or_else(|| bad(format!("timestep {timestep:?} is not a finite number")))?;
            let stem = file.strip_prefix("frame_");
            let (digits, pieces) = match stem.and_then(|f| f.strip_suffix(".pvtu")) {
                Some(digits) => (Some(digits), true),
                None => (stem.and_then(|f| f.strip_suffix(".vtu")), false),
            };
            let step = digits
                .filter(|digits| digits.bytes().all(|b| b.is_ascii_digit()))
                .and_then(|digits| digits.parse().ok())
                .ok_or_else(|| {
                    bad(format!(
                        "file {file:?} is not a frame_<step>.vtu (or .pvtu) name"
                    ))
                })?;
            Ok(SeriesEntry { step, time, pieces })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(text: &str) -> std::result::Result<Vec<SeriesEntry>, String> {
        parse_index(Path::new("series.pvd"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn an_index_is_read_as_xml_whatever_its_layout() {
        let text = "<?xml version='1.0'?>\n<VTKFile type='Collection' version='0.1'>\n\
                    <Collection><DataSet part='0' file='frame_00000010.vtu' group=''\n \
                    timestep='0.5'/>\n<!-- <DataSet timestep=\"9\" file=\"frame_9.vtu\"/> -->\n\
                    <DataSet timestep=\"1e0\" file=\"frame_00000020.vtu\"></DataSet>\
                    <DataSet timestep='2' file='frame_00000030.pvtu'/>\
                    </Collection></VTKFile>";
        let entry = |step, time, pieces| SeriesEntry { step, time, pieces };
        let want = vec![
            entry(10, 0.5, false),
            entry(20, 1.0, false),
            entry(30, 2.0, true),
        ];
        assert_eq!(parsed(text), Ok(want));
    }

    #[test]
    fn a_broken_index_is_refused_naming_its_line() {
        let collection = |body: &str| {
            format!("<VTKFile type=\"Collection\">\n<Collection>\n{body}\n</Collection></VTKFile>")
        };
        let cases = [
            ("<VTKFile>not an index", "series.pvd:1: not XML"),
            (
                "<VTKFile type=\"UnstructuredGrid\"></VTKFile>",
                "not a ParaView collection",
            ),
            (
                &collection("<DataSet timestep=\"0\"/>") as &str,
                "series.pvd:3: a DataSet without a file",
            ),
            (
                &collection("<DataSet file=\"frame_1.vtu\"/>"),
                "without a timestep",
            ),
            (
                &collection("<DataSet timestep=\"x\" file=\"frame_1.vtu\"/>"),
                "finite",
            ),
            (
                &collection("<DataSet timestep=\"0\" file=\"a.vtu\"/>"),
                "frame_<step>.vtu",
            ),
        ];
        for (text, said) in cases {
            let e = parsed(text).unwrap_err();
            assert!(e.contains("series.pvd") && e.contains(said), "{text}: {e}");
        }
    }
}
