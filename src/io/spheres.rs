//! Sphere files: CSV with header `x,y,z,r`, or NumPy `.npy` of shape N×4 (float32; float64 is
//! accepted and rounded to float32). Both may carry velocities too: header `x,y,z,r,vx,vy,vz`
//! (the frame CSVs of `mochi simulate`), shape N×7; [`read_spheres`] ignores them and
//! [`read_particles`] returns them.

use super::{Format, io_error, parse_error, write_atomically};
use crate::error::Result;
use crate::spheres::{SphereSet, check_sphere};
use npyz::WriterBuilder;
use std::io::BufRead;
use std::path::Path;

const COLUMNS: [&str; 4] = ["x", "y", "z", "r"];
const WITH_VELOCITY: [&str; 7] = ["x", "y", "z", "r", "vx", "vy", "vz"];

/// Rows of a sphere file: `x, y, z, r` and, if the file has them, velocities.
type Rows = (Vec<[f32; 4]>, Option<Vec<[f32; 3]>>);

/// Reads a sphere file (`.csv` or `.npy`, by extension) and validates every sphere (velocity
/// columns, if any, are ignored).
pub fn read_spheres(path: &Path) -> Result<SphereSet> {
    Ok(read_particles(path)?.0)
}

/// Reads a sphere file with its velocities, if it has them (`None` when it has only x,y,z,r).
pub fn read_particles(path: &Path) -> Result<(SphereSet, Option<Vec<[f32; 3]>>)> {
    let (rows, velocities) = match Format::of(path)? {
        Format::Csv => read_csv(path)?,
        Format::Npy => read_npy(path)?,
    };
    Ok((SphereSet::from_xyzr(&rows)?, velocities))
}

/// Checks a velocity row.
pub(super) fn check_velocity(v: &[f32; 3]) -> std::result::Result<(), String> {
    match v.iter().all(|x| x.is_finite()) {
        true => Ok(()),
        false => Err(format!("velocity {v:?} is not finite")),
    }
}

/// Writes spheres as `.csv` or `.npy` (by extension), atomically.
pub fn write_spheres(path: &Path, spheres: &SphereSet) -> Result<()> {
    match Format::of(path)? {
        Format::Csv => write_atomically(path, |out| {
            writeln!(out, "{}", COLUMNS.join(","))?;
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

fn read_csv(path: &Path) -> Result<Rows> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut lines = std::io::BufReader::with_capacity(1 << 20, file)
        .split(b'\n')
        .enumerate()
        .map(|(k, line)| (k as u64 + 1, line));
    let text = |line_no: u64, bytes: std::io::Result<Vec<u8>>| -> Result<String> {
        let bytes = bytes.map_err(io_error(path))?;
        String::from_utf8(bytes).map_err(|e| {
            parse_error(
                path,
                Some(line_no),
                format!(
                    "not UTF-8 text (byte {} of the line)",
                    e.utf8_error().valid_up_to() + 1
                ),
            )
        })
    };
    // The header is the first non-blank line.
    let header = loop {
        match lines.next() {
            None => {
                return Err(parse_error(
                    path,
                    None,
                    "empty file: expected the header x,y,z,r",
                ));
            }
            Some((no, bytes)) => {
                let line = text(no, bytes)?;
                if !line.trim().is_empty() {
                    break (no, line);
                }
            }
        }
    };
    // A byte-order mark (as spreadsheet programs write) opens the text, not the header.
    let header = (header.0, header.1.trim_start_matches('\u{feff}').to_owned());
    let fields: Vec<String> = header
        .1
        .split(',')
        .map(|f| f.trim().to_ascii_lowercase())
        .collect();
    let names: &[&str] = if fields == COLUMNS {
        &COLUMNS
    } else if fields == WITH_VELOCITY {
        &WITH_VELOCITY
    } else {
        return Err(parse_error(
            path,
            Some(header.0),
            format!(
                "the header must be x,y,z,r or x,y,z,r,vx,vy,vz (found {:?})",
                header.1.trim()
            ),
        ));
    };
    let mut rows = Vec::new();
    let mut velocities = Vec::new();
    for (no, bytes) in lines {
        let line = text(no, bytes)?;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let bad = |msg: String| parse_error(path, Some(no), msg);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(bad(format!(
                "expected {} columns ({}), found {}",
                names.len(),
                names.join(","),
                fields.len()
            )));
        }
        let mut row = [0f32; 7];
        for (k, (field, name)) in fields.iter().zip(names).enumerate() {
            row[k] = field
                .parse()
                .map_err(|_| bad(format!("column {name}: {field:?} is not a number")))?;
        }
        check_sphere(&[row[0], row[1], row[2]], row[3]).map_err(bad)?;
        rows.push([row[0], row[1], row[2], row[3]]);
        if names.len() == 7 {
            let v = [row[4], row[5], row[6]];
            check_velocity(&v).map_err(bad)?;
            velocities.push(v);
        }
    }
    Ok((rows, (names.len() == 7).then_some(velocities)))
}

fn read_npy(path: &Path) -> Result<Rows> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let bad = |msg: String| parse_error(path, None, msg);
    check_npy_size(&bytes).map_err(bad)?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| bad(format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    if shape.len() != 2 || !(shape[1] == 4 || shape[1] == 7) {
        return Err(bad(format!(
            "expected an array of shape N×4 (x, y, z, r) or N×7 (and vx, vy, vz), found shape \
             {shape:?}"
        )));
    }
    let columns = shape[1] as usize;
    let n = shape[0] as usize;
    let fortran = npy.order() == npyz::Order::Fortran;
    let dtype = match npy.dtype() {
        npyz::DType::Plain(t) => t.to_string(),
        other => other.descr(),
    };
    let values: Vec<f32> = match dtype.as_str() {
        "<f4" | ">f4" => npy.into_vec::<f32>(),
        "<f8" | ">f8" => npy
            .into_vec::<f64>()
            .map(|v| v.into_iter().map(|x| x as f32).collect()),
        other => return Err(bad(format!("expected float32 values, found dtype {other}"))),
    }
    .map_err(|e| bad(format!("unreadable data ({e}); is the file truncated?")))?;
    let mut rows = Vec::with_capacity(n);
    let mut velocities = Vec::new();
    for i in 0..n {
        let at = |k: usize| {
            if fortran {
                values[k * n + i]
            } else {
                values[i * columns + k]
            }
        };
        let row = [at(0), at(1), at(2), at(3)];
        check_sphere(&[row[0], row[1], row[2]], row[3])
            .map_err(|m| bad(format!("row {i} (0-based): {m}")))?;
        rows.push(row);
        if columns == 7 {
            let v = [at(4), at(5), at(6)];
            check_velocity(&v).map_err(|m| bad(format!("row {i} (0-based): {m}")))?;
            velocities.push(v);
        }
    }
    Ok((rows, (columns == 7).then_some(velocities)))
}

/// Refuses a `.npy` whose header promises more data than the file holds, before the header's
/// shape is multiplied out (a crafted shape would overflow).
fn check_npy_size(bytes: &[u8]) -> Result<(), String> {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    let Some(start) = head.find("'shape':") else {
        return Ok(()); // not a header npyz will accept either; it reports the problem
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
    if total / 2 > bytes.len() as u64 {
        return Err(format!(
            "truncated: the header's shape ({tuple}) needs more data than the file's {} bytes",
            bytes.len()
        ));
    }
    Ok(())
}
