//! Sphere files: CSV with header `x,y,z,r`, or NumPy `.npy` of shape N×4 (float32; float64 is
//! accepted and rounded to float32). Both may carry velocities, header `x,y,z,r,vx,vy,vz` or shape
//! N×7, and angular velocities after them, header `x,y,z,r,vx,vy,vz,wx,wy,wz` or shape N×10. A
//! CSV may end any of the three headers with `material`, and a `.npy` of N×11 has it as its 11th
//! column (the frames of `mochi simulate` are such files): each sphere's material, its index in
//! the order of the scene's `[[materials]]` tables, a whole number from 0 to 255. [`read_spheres`]
//! ignores the motion and the materials; [`read_particles`] returns them, and each centre as the
//! file holds it (a CSV's decimal or a float64, read as `f64`): its `f32` centre and the residual
//! that `f32` drops.

use super::{Format, io_error, parse_error, write_atomically};
use crate::error::{Result, try_push, try_vec};
use crate::particles::Particles;
use crate::spheres::{SphereSet, check_count, check_sphere};
use npyz::WriterBuilder;
use std::io::{BufRead, Read, Seek};
use std::path::Path;

/// Every column a sphere file may have, in order; a file has the first 4, 7 or 10 of them.
const COLUMNS: [&str; 10] = ["x", "y", "z", "r", "vx", "vy", "vz", "wx", "wy", "wz"];
/// The column counts a file may have: the sphere, with velocities, and with angular velocities.
const WIDTHS: [usize; 3] = [4, 7, 10];
/// The column of each sphere's material: the last of a CSV whose header ends with it, the 11th
/// of a `.npy` of N×11.
const MATERIAL: &str = "material";
/// The columns of a `.npy` with materials: every column of [`COLUMNS`], then the material.
const NPY_WITH_MATERIAL: usize = COLUMNS.len() + 1;

/// The headers a sphere CSV may have, as errors list them.
fn accepted_headers() -> String {
    let all: Vec<String> = WIDTHS.iter().map(|&w| COLUMNS[..w].join(",")).collect();
    format!(
        "{}, {} or {}, each optionally followed by ,{MATERIAL}",
        all[0], all[1], all[2]
    )
}

/// A sphere's material as a file gives it: a whole number from 0 to 255 (the index of one of
/// the scene's `[[materials]]` tables, which `SceneConfig::start_from` checks).
fn sphere_material(x: f64) -> std::result::Result<u8, String> {
    match x.fract() == 0.0 && (0.0..=255.0).contains(&x) {
        true => Ok(x as u8),
        false => Err(format!(
            "{MATERIAL} {x} is not a material index (a whole number from 0 to 255, the \
             [[materials]] table's place from 0)"
        )),
    }
}

/// Rows of a sphere file: `x, y, z, r`, the centres as the file holds them where that is more
/// than `f32` holds, and the velocities, angular velocities and materials where the file has
/// them (`None` where it does not).
struct Rows {
    spheres: Vec<[f32; 4]>,
    /// The centres as written (CSV) or as `float64` (`.npy`), one per row; empty where the
    /// file holds `float32` (the centres are then exact in `spheres`).
    centres: Vec<[f64; 3]>,
    velocities: Option<Vec<[f32; 3]>>,
    angular_velocities: Option<Vec<[f32; 3]>>,
    materials: Option<Vec<u8>>,
}

impl Rows {
    /// Room for `n` rows of `columns` (4, 7 or 10) values.
    fn with_capacity(n: usize, columns: usize, what: impl Fn() -> String) -> Result<Self> {
        let motion = |from: usize| -> Result<Option<Vec<[f32; 3]>>> {
            (columns >= from).then(|| try_vec(n, &what)).transpose()
        };
        Ok(Self {
            spheres: try_vec(n, &what)?,
            centres: Vec::new(),
            velocities: motion(7)?,
            angular_velocities: motion(10)?,
            materials: None,
        })
    }

    /// Checks one row of values (as many as the file's columns) and appends it; the error is
    /// the problem, for the caller to place.
    fn push(&mut self, row: &[f32], what: impl Fn() -> String) -> Result<(), RowError> {
        check_sphere(&[row[0], row[1], row[2]], row[3]).map_err(RowError::Bad)?;
        let triple = |at: usize| [row[at], row[at + 1], row[at + 2]];
        let pushes = [(&mut self.velocities, 4), (&mut self.angular_velocities, 7)];
        for (name, (column, at)) in ["velocity", "angular velocity"].into_iter().zip(pushes) {
            if let Some(column) = column {
                let v = triple(at);
                check_finite(name, &v).map_err(RowError::Bad)?;
                try_push(column, v, &what).map_err(RowError::Fatal)?;
            }
        }
        try_push(&mut self.spheres, [row[0], row[1], row[2], row[3]], &what)
            .map_err(RowError::Fatal)
    }
}

/// Why a row was not taken: a bad value (placed by the caller) or an error of its own.
enum RowError {
    Bad(String),
    Fatal(crate::error::Error),
}

/// Reads a sphere file (`.csv` or `.npy`, by extension) and validates every sphere (velocity
/// columns, if any, are ignored).
pub fn read_spheres(path: &Path) -> Result<SphereSet> {
    let rows = read_rows(path, false)?;
    SphereSet::from_xyzr(&rows.spheres)
}

/// Reads a sphere file into particles at step 0: its velocities and angular velocities where
/// it has them, zero where it does not; no contact history. Each position is the centre as the
/// file writes it (the CSV's decimal, or the `.npy`'s `float64`, read as `f64`): its `f32`
/// centre and the residual ([`Particles::position_residuals`], [`crate::particles::position`]),
/// so a frame written by `mochi simulate` restarts where its spheres were.
pub fn read_particles(path: &Path) -> Result<Particles> {
    read_particles_as_written(path).map(|(particles, _)| particles)
}

/// [`read_particles`], and the positions as the file holds them (in `f64`, which the
/// particles' centres and residuals hold to within 2⁻⁵³ of each).
pub(super) fn read_particles_as_written(path: &Path) -> Result<(Particles, Vec<[f64; 3]>)> {
    let rows = read_rows(path, true)?;
    let mut particles = Particles::at_rest(&SphereSet::from_xyzr(&rows.spheres)?)?;
    for (i, &centre) in rows.centres.iter().enumerate() {
        particles.set_exact_position(i, centre)?;
    }
    let written = match rows.centres.is_empty() {
        true => rows
            .spheres
            .iter()
            .map(|s| [s[0], s[1], s[2]].map(f64::from))
            .collect(),
        false => rows.centres,
    };
    if let Some(v) = rows.velocities {
        particles.velocities = v;
    }
    if let Some(w) = rows.angular_velocities {
        particles.angular_velocities = w;
    }
    if let Some(m) = rows.materials {
        particles.materials = m;
    }
    Ok((particles, written))
}

/// The rows of a sphere file, with its centres as the file holds them where `centres` (and
/// it holds more than `f32`).
fn read_rows(path: &Path, centres: bool) -> Result<Rows> {
    match Format::of(path)? {
        Format::Csv => read_csv(path, centres),
        Format::Npy => read_npy(path, centres),
    }
}

/// Checks a velocity row.
pub(super) fn check_velocity(v: &[f32; 3]) -> std::result::Result<(), String> {
    check_finite("velocity", v)
}

/// Checks that the vector `name` is finite.
pub(super) fn check_finite(name: &str, v: &[f32; 3]) -> std::result::Result<(), String> {
    match v.iter().all(|x| x.is_finite()) {
        true => Ok(()),
        false => Err(format!("{name} {v:?} is not finite")),
    }
}

/// Writes spheres as `.csv` or `.npy` (by extension), atomically.
pub fn write_spheres(path: &Path, spheres: &SphereSet) -> Result<()> {
    match Format::of(path)? {
        Format::Csv => write_atomically(path, |out| {
            writeln!(out, "{}", COLUMNS[..4].join(","))?;
            for [x, y, z, r] in spheres.xyzr() {
                writeln!(out, "{x},{y},{z},{r}")?;
            }
            Ok(())
        }),
        Format::Npy => write_atomically(path, |out| {
            let mut npy = npyz::WriteOptions::new()
                .default_dtype()
                .shape(&[spheres.len() as u64, 4])
                .writer(out)
                .begin_nd()?;
            npy.extend(spheres.xyzr().flatten())?;
            npy.finish()
        }),
    }
}

/// Longest line a sphere CSV may have, in bytes (a row of ten numbers needs a few hundred).
const MAX_LINE: usize = 4096;

/// The lines of a sphere CSV as text, numbered from 1, each at most [`MAX_LINE`] bytes.
struct Lines<'a> {
    reader: std::io::BufReader<std::fs::File>,
    path: &'a Path,
    buf: Vec<u8>,
    no: u64,
}

impl Lines<'_> {
    /// The next line (without its end), or `None` at the end of the file.
    fn next(&mut self) -> Result<Option<(u64, &str)>> {
        self.buf.clear();
        self.no += 1;
        let limit = MAX_LINE as u64 + 1;
        let read = (&mut self.reader)
            .take(limit)
            .read_until(b'\n', &mut self.buf)
            .map_err(io_error(self.path))?;
        if read == 0 {
            return Ok(None);
        }
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
        } else if read as u64 == limit {
            return Err(parse_error(
                self.path,
                Some(self.no),
                format!("line longer than the limit of {MAX_LINE} bytes"),
            ));
        }
        let text = std::str::from_utf8(&self.buf).map_err(|e| {
            parse_error(
                self.path,
                Some(self.no),
                format!("not UTF-8 text (byte {} of the line)", e.valid_up_to() + 1),
            )
        })?;
        Ok(Some((self.no, text)))
    }
}

fn read_csv(path: &Path, centres: bool) -> Result<Rows> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut lines = Lines {
        reader: std::io::BufReader::with_capacity(1 << 20, file),
        path,
        buf: Vec::new(),
        no: 0,
    };
    // The header is the first non-blank line.
    let (header_no, fields, header_text) = loop {
        match lines.next()? {
            None => {
                return Err(parse_error(
                    path,
                    None,
                    format!("empty file: expected the header {}", accepted_headers()),
                ));
            }
            Some((no, line)) if !line.trim().is_empty() => {
                // A byte-order mark (as spreadsheet programs write) opens the text, not the header.
                let line = match no {
                    1 => line.trim_start_matches('\u{feff}'),
                    _ => line,
                };
                let fields: Vec<String> = line
                    .split(',')
                    .map(|f| f.trim().to_ascii_lowercase())
                    .collect();
                break (no, fields, line.trim().to_owned());
            }
            Some(_) => {}
        }
    };
    // The material column, where the header ends with it, is read apart from the others.
    let with_material = fields.last().is_some_and(|f| f == MATERIAL);
    let motion = &fields[..fields.len() - with_material as usize];
    let Some(names) = WIDTHS
        .iter()
        .map(|&w| &COLUMNS[..w])
        .find(|names| motion == *names)
    else {
        return Err(parse_error(
            path,
            Some(header_no),
            format!(
                "the header must be {} (found {header_text:?})",
                accepted_headers()
            ),
        ));
    };
    // The columns every row has: `names`, then the material where the header ends with it.
    let header = &fields;
    let mut rows = Rows::with_capacity(0, names.len(), String::new)?;
    if with_material {
        rows.materials = Some(Vec::new());
    }
    while let Some((no, line)) = lines.next()? {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let bad = |msg: String| parse_error(path, Some(no), msg);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != header.len() {
            return Err(bad(format!(
                "expected {} columns ({}), found {}",
                header.len(),
                header.join(","),
                fields.len()
            )));
        }
        // The material's field, where the header has it, is the one after `names`.
        let (fields, material) = fields.split_at(names.len());
        let material = material
            .first()
            .map(|field| {
                let value = field
                    .parse::<f64>()
                    .map_err(|_| bad(format!("column {MATERIAL}: {field:?} is not a number")))?;
                sphere_material(value).map_err(&bad)
            })
            .transpose()?;
        let mut row = [0f32; COLUMNS.len()];
        let mut centre = [0f64; 3];
        for (k, (field, name)) in fields.iter().zip(names).enumerate() {
            let not_a_number = || bad(format!("column {name}: {field:?} is not a number"));
            row[k] = field.parse().map_err(|_| not_a_number())?;
            if k < 3 && centres {
                centre[k] = field.parse().map_err(|_| not_a_number())?;
            }
        }
        let count = rows.spheres.len() + 1;
        check_count(count)?;
        let what = || format!("{count} rows of {}", path.display());
        if centres {
            try_push(&mut rows.centres, centre, what)?;
        }
        if let (Some(materials), Some(m)) = (&mut rows.materials, material) {
            try_push(materials, m, what)?;
        }
        rows.push(&row[..names.len()], what).map_err(|e| match e {
            RowError::Bad(msg) => bad(msg),
            RowError::Fatal(e) => e,
        })?;
    }
    Ok(rows)
}

fn read_npy(path: &Path, centres: bool) -> Result<Rows> {
    let bad = |msg: String| parse_error(path, None, msg);
    // The header is checked against the file's length before npyz parses it; the data is then
    // read in blocks into a fallibly allocated array.
    let mut file = std::fs::File::open(path).map_err(io_error(path))?;
    let size = file.metadata().map_err(io_error(path))?.len();
    let mut head = Vec::new();
    (&mut file)
        .take(4096)
        .read_to_end(&mut head)
        .map_err(io_error(path))?;
    let data_at = check_npy_size(&head, size).map_err(bad)?;
    file.seek(std::io::SeekFrom::Start(0))
        .map_err(io_error(path))?;
    let npy = npyz::NpyFile::new(std::io::BufReader::new(&mut file))
        .map_err(|e| bad(format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    let mut widths = WIDTHS.iter().chain([&NPY_WITH_MATERIAL]);
    if shape.len() != 2 || !widths.any(|&w| shape[1] == w as u64) {
        return Err(bad(format!(
            "expected an array of shape N×4 (x, y, z, r), N×7 (and vx, vy, vz), N×10 (and wx, \
             wy, wz) or N×11 (and the {MATERIAL}), found shape {shape:?}"
        )));
    }
    let columns = shape[1] as usize;
    // The columns of the sphere and its motion; the material's, where there is one, is read
    // apart from them (exactly, from the file's value).
    let motion = columns.min(COLUMNS.len());
    let n = shape[0] as usize;
    check_count(n)?;
    let fortran = npy.order() == npyz::Order::Fortran;
    let dtype = match npy.dtype() {
        npyz::DType::Plain(t) => t.to_string(),
        other => other.descr(),
    };
    let decode: fn(&[u8]) -> f64 = match dtype.as_str() {
        "<f4" => |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        ">f4" => |b| f32::from_be_bytes([b[0], b[1], b[2], b[3]]) as f64,
        "<f8" => |b| f64::from_le_bytes(std::array::from_fn(|k| b[k])),
        ">f8" => |b| f64::from_be_bytes(std::array::from_fn(|k| b[k])),
        other => return Err(bad(format!("expected float32 values, found dtype {other}"))),
    };
    let item = if dtype.ends_with('4') { 4 } else { 8 };
    let what = || format!("{n} rows of {}", path.display());
    let total = n * columns;
    let mut values: Vec<f32> = try_vec(total, what)?;
    let mut rows = Rows::with_capacity(n, motion, what)?;
    if columns == NPY_WITH_MATERIAL {
        let mut materials = Vec::new();
        crate::error::try_resize(&mut materials, n, 0, what)?;
        rows.materials = Some(materials);
    }
    // The centres of a float64 file, as the file holds them (each value's row and column by
    // the file's order).
    let wide = item == 8 && centres;
    if wide {
        crate::error::try_resize(&mut rows.centres, n, [0.0; 3], what)?;
    }
    let mut data = std::io::BufReader::new(file);
    data.seek(std::io::SeekFrom::Start(data_at))
        .map_err(io_error(path))?;
    let mut block = vec![0u8; item << 14];
    while values.len() < total {
        let bytes = &mut block[..item * (total - values.len()).min(1 << 14)];
        data.read_exact(bytes).map_err(|e| {
            bad(format!(
                "unreadable data ({e} after {} of {total} values); is the file truncated?",
                values.len()
            ))
        })?;
        for value in bytes.chunks_exact(item).map(decode) {
            let k = values.len();
            let (i, column) = match fortran {
                true => (k % n, k / n),
                false => (k / columns, k % columns),
            };
            if column < 3 && wide {
                rows.centres[i][column] = value;
            }
            if let Some(materials) = rows.materials.as_mut().filter(|_| column == motion) {
                materials[i] =
                    sphere_material(value).map_err(|m| bad(format!("row {i} (0-based): {m}")))?;
            }
            values.push(value as f32);
        }
    }
    let mut row = [0f32; COLUMNS.len()];
    for i in 0..n {
        for (k, value) in row[..motion].iter_mut().enumerate() {
            *value = match fortran {
                true => values[k * n + i],
                false => values[i * columns + k],
            };
        }
        rows.push(&row[..motion], what).map_err(|e| match e {
            RowError::Bad(m) => bad(format!("row {i} (0-based): {m}")),
            RowError::Fatal(e) => e,
        })?;
    }
    Ok(rows)
}

/// Refuses a `.npy` whose header, or the data its shape promises, is longer than the file,
/// before either is allocated (a crafted length or shape would ask for any amount of memory).
/// `bytes` are the file's first bytes; returns where the data starts.
fn check_npy_size(bytes: &[u8], file_len: u64) -> Result<u64, String> {
    // Magic (6 bytes), version (2), then the header length: 2 bytes in version 1, 4 after; the
    // data follows the header. Without the magic, npyz refuses the file.
    let mut data_at = 0;
    if bytes.len() >= 12 && bytes.starts_with(b"\x93NUMPY") {
        let (len, at) = match bytes[6] {
            1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as u64, 10),
            _ => (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as u64,
                12,
            ),
        };
        if at + len > file_len {
            return Err(format!(
                "not a .npy file: its header declares {len} bytes, more than the file's {file_len}"
            ));
        }
        data_at = at + len;
    }
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    let Some(start) = head.find("'shape':") else {
        return Ok(data_at); // not a header npyz will accept either; it reports the problem
    };
    let tuple = head[start + 8..]
        .trim_start()
        .trim_start_matches('(')
        .split(')')
        .next()
        .unwrap_or("");
    let mut total: u64 = 8; // bytes per value, at most (float64)
    for dim in tuple.split(',').map(str::trim).filter(|d| !d.is_empty()) {
        let dim: u64 = dim
            .parse()
            .map_err(|_| format!("bad shape entry {dim:?}"))?;
        total = total.saturating_mul(dim);
    }
    if total / 2 > file_len {
        return Err(format!(
            "truncated: the header's shape ({tuple}) needs more data than the file's {file_len} \
             bytes"
        ));
    }
    Ok(data_at)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version-1 `.npy` of `descr` and `shape`, header padded to 64 bytes, then `data`.
    fn npy(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
        let mut dict =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while !(10 + dict.len() + 1).is_multiple_of(64) {
            dict.push(' ');
        }
        dict.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend((dict.len() as u16).to_le_bytes());
        out.extend(dict.as_bytes());
        out.extend(data);
        out
    }

    #[test]
    fn npy_of_either_byte_order_and_width_reads_the_same() {
        let rows = [[1.5f32, -2.0, 3.25, 0.5], [0.0, 1e-3, -7.0, 2.0]];
        let values: Vec<f32> = rows.iter().flatten().copied().collect();
        let dir = tempfile::tempdir().unwrap();
        let cases: [(&str, Vec<u8>); 4] = [
            ("<f4", values.iter().flat_map(|x| x.to_le_bytes()).collect()),
            (">f4", values.iter().flat_map(|x| x.to_be_bytes()).collect()),
            (
                "<f8",
                values
                    .iter()
                    .flat_map(|&x| f64::from(x).to_le_bytes())
                    .collect(),
            ),
            (
                ">f8",
                values
                    .iter()
                    .flat_map(|&x| f64::from(x).to_be_bytes())
                    .collect(),
            ),
        ];
        for (descr, data) in cases {
            let path = dir.path().join("s.npy");
            std::fs::write(&path, npy(descr, "(2, 4)", &data)).unwrap();
            let spheres = read_spheres(&path).unwrap();
            assert_eq!(spheres.xyzr().collect::<Vec<_>>(), rows, "{descr}");
            // One byte short: refused.
            std::fs::write(&path, npy(descr, "(2, 4)", &data[..data.len() - 1])).unwrap();
            let err = read_spheres(&path).unwrap_err().to_string();
            assert!(
                err.contains("of 8 values); is the file truncated?"),
                "{descr}: {err}"
            );
        }
    }
}
