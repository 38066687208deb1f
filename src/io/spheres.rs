//! Sphere files: CSV with header `x,y,z,r`, or NumPy `.npy` of shape N×4 (float32; float64 is
//! accepted and rounded to float32).

use super::{Format, io_error, parse_error, write_atomically};
use crate::error::{Error, Result};
use crate::spheres::{SphereSet, check_sphere};
use npyz::WriterBuilder;
use std::path::Path;

const COLUMNS: [&str; 4] = ["x", "y", "z", "r"];

/// Reads a sphere file (`.csv` or `.npy`, by extension) and validates every sphere.
pub fn read_spheres(path: &Path) -> Result<SphereSet> {
    let rows = match Format::of(path)? {
        Format::Csv => read_csv(path)?,
        Format::Npy => read_npy(path)?,
    };
    SphereSet::from_xyzr(&rows)
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

fn read_csv(path: &Path) -> Result<Vec<[f32; 4]>> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(std::io::BufReader::with_capacity(1 << 20, file));
    let mut records = reader.records();
    let csv_error = |e: csv::Error| {
        let line = e.position().map(|p| p.line());
        match e.into_kind() {
            csv::ErrorKind::Io(source) => Error::Io {
                path: path.to_owned(),
                source,
            },
            kind => parse_error(path, line, format!("{kind:?}")),
        }
    };
    let header = match records.next() {
        None => {
            return Err(parse_error(
                path,
                None,
                "empty file: expected the header x,y,z,r",
            ));
        }
        Some(h) => h.map_err(csv_error)?,
    };
    if !header.iter().map(str::to_ascii_lowercase).eq(COLUMNS) {
        return Err(parse_error(
            path,
            Some(1),
            format!(
                "the header must be x,y,z,r (found {:?})",
                header.iter().collect::<Vec<_>>().join(",")
            ),
        ));
    }
    let mut rows = Vec::new();
    for record in records {
        let record = record.map_err(csv_error)?;
        let line = record.position().map(|p| p.line());
        if record.len() != 4 {
            return Err(parse_error(
                path,
                line,
                format!("expected 4 columns (x,y,z,r), found {}", record.len()),
            ));
        }
        let mut row = [0f32; 4];
        for (k, (field, name)) in record.iter().zip(COLUMNS).enumerate() {
            row[k] = field.parse().map_err(|_| {
                parse_error(
                    path,
                    line,
                    format!("column {name}: {field:?} is not a number"),
                )
            })?;
        }
        check_sphere(&[row[0], row[1], row[2]], row[3]).map_err(|m| parse_error(path, line, m))?;
        rows.push(row);
    }
    Ok(rows)
}

fn read_npy(path: &Path) -> Result<Vec<[f32; 4]>> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let bad = |msg: String| parse_error(path, None, msg);
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| bad(format!("not a .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    if shape.len() != 2 || shape[1] != 4 {
        return Err(bad(format!(
            "expected an array of shape N×4 (x, y, z, r), found shape {shape:?}"
        )));
    }
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
    for i in 0..n {
        let at = |k: usize| {
            if fortran {
                values[k * n + i]
            } else {
                values[i * 4 + k]
            }
        };
        let row = [at(0), at(1), at(2), at(3)];
        check_sphere(&[row[0], row[1], row[2]], row[3])
            .map_err(|m| bad(format!("row {i} (0-based): {m}")))?;
        rows.push(row);
    }
    Ok(rows)
}
