//! Clump files: CSV with the header `x,y,z,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz,template`, one clump a
//! row: where its template's origin is \[m\], the rotation from its template's frame to the
//! world (a quaternion w, x, y, z; normalised as read), the velocity of its template's origin
//! \[m/s\], its angular velocity \[rad/s\] and its template (a scene's `[[clump]]` table's name,
//! or a built-in shape's). Blank lines are skipped; a row of other columns, a field that is not
//! a finite number or a quaternion of length 0 is an error naming its line.

use super::{io_error, parse_error};
use crate::error::Result;
use glam::{DQuat, DVec3};
use std::path::Path;

/// The header of a clump file.
pub const CLUMP_HEADER: &str = "x,y,z,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz,template";

/// One row of a clump file.
#[derive(Debug, Clone, PartialEq)]
pub struct ClumpRow {
    /// Where the template's origin is \[m\].
    pub position: DVec3,
    /// The rotation from the template's frame to the world (unit).
    pub orientation: DQuat,
    /// The velocity of the template's origin \[m/s\].
    pub velocity: DVec3,
    /// Angular velocity \[rad/s\].
    pub angular_velocity: DVec3,
    /// The template's name.
    pub template: String,
}

/// Whether the file at `path` is a clump file: its first non-blank line is [`CLUMP_HEADER`]
/// (false where it cannot be read: the sphere reader then says why).
pub fn is_clump_file(path: &Path) -> bool {
    std::fs::read_to_string(path).is_ok_and(|text| {
        text.trim_start_matches('\u{feff}')
            .lines()
            .find(|l| !l.trim().is_empty())
            .is_some_and(|l| header_of(l) == CLUMP_HEADER)
    })
}

/// A header line as compared: its fields trimmed and in lower case.
fn header_of(line: &str) -> String {
    line.split(',')
        .map(|f| f.trim().to_ascii_lowercase())
        .collect::<Vec<_>>()
        .join(",")
}

/// Reads a clump file.
pub fn read_clumps(path: &Path) -> Result<Vec<ClumpRow>> {
    let text = std::fs::read_to_string(path).map_err(io_error(path))?;
    let mut lines = text
        .trim_start_matches('\u{feff}')
        .lines()
        .enumerate()
        .map(|(k, l)| (k as u64 + 1, l))
        .filter(|(_, l)| !l.trim().is_empty());
    match lines.next() {
        Some((_, header)) if header_of(header) == CLUMP_HEADER => {}
        Some((no, header)) => {
            return Err(parse_error(
                path,
                Some(no),
                format!(
                    "the header must be {CLUMP_HEADER} (found {:?})",
                    header.trim()
                ),
            ));
        }
        None => {
            return Err(parse_error(
                path,
                None,
                format!("empty file: expected the header {CLUMP_HEADER}"),
            ));
        }
    }
    let mut rows = Vec::new();
    for (no, line) in lines {
        let bad = |msg: String| parse_error(path, Some(no), msg);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 14 {
            return Err(bad(format!(
                "expected 14 columns ({CLUMP_HEADER}), found {}",
                fields.len()
            )));
        }
        let names: Vec<&str> = CLUMP_HEADER.split(',').collect();
        let mut x = [0.0f64; 13];
        for (k, value) in x.iter_mut().enumerate() {
            *value = fields[k]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(format!(
                        "column {}: {:?} is not a finite number",
                        names[k], fields[k]
                    ))
                })?;
        }
        let q = DQuat::from_xyzw(x[4], x[5], x[6], x[3]);
        if q.length() == 0.0 {
            return Err(bad("the quaternion (qw, qx, qy, qz) has length 0".into()));
        }
        if fields[13].is_empty() {
            return Err(bad("column template is empty".into()));
        }
        rows.push(ClumpRow {
            position: DVec3::new(x[0], x[1], x[2]),
            orientation: q.normalize(),
            velocity: DVec3::new(x[7], x[8], x[9]),
            angular_velocity: DVec3::new(x[10], x[11], x[12]),
            template: fields[13].to_owned(),
        });
    }
    Ok(rows)
}
