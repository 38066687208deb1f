//! What a run writes of its mesh walls: each wall's surface as a VTK XML PolyData file (binary,
//! appended raw data), once for a wall that never moves (`wall_{k}.vtp`) and at each frame for
//! one that moves (`wall_{step:08}_{k}.vtp`); a ParaView collection of them (`walls.pvd`, the
//! wall as the part, grown a frame at a time); and the force and torque on each wall per frame
//! (`walls.csv`: `time, wall, fx, fy, fz, tx, ty, tz`; N and N·m, the torque about the wall's
//! rotation centre; appended through [`super::append_log`]). Surfaces are written through
//! [`write_atomically`].

use super::frames::Chunked;
use super::write_atomically;
use crate::error::Result;
use std::path::Path;

/// File name of the walls' collection in a run's folder.
pub const WALLS_INDEX: &str = "walls.pvd";

/// File name of the walls' loads in a run's folder.
pub const WALL_LOADS: &str = "walls.csv";

/// Header of [`WALL_LOADS`].
pub const WALL_LOADS_HEADER: &str = "time,wall,fx,fy,fz,tx,ty,tz";

/// The file of wall `k`'s surface: at step `step` for a wall that moves, or its one file
/// (`None`) for a wall that never does.
pub fn wall_file_name(step: Option<u64>, k: usize) -> String {
    match step {
        Some(step) => format!("wall_{step:08}_{k}.vtp"),
        None => format!("wall_{k}.vtp"),
    }
}

/// Whether `name` is a name of [`wall_file_name`].
pub fn is_wall_file_name(name: &str) -> bool {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    name.strip_prefix("wall_")
        .and_then(|rest| rest.strip_suffix(".vtp"))
        .is_some_and(|rest| match rest.split_once('_') {
            Some((step, k)) => digits(step) && digits(k),
            None => digits(rest),
        })
}

/// Writes a triangle surface, each triangle its own three points, as binary PolyData.
pub fn write_surface_vtp(path: &Path, triangles: &[[[f32; 3]; 3]]) -> Result<()> {
    let n = triangles.len() as u64;
    let blocks = [
        ("Points", 36 * n),
        ("connectivity", 12 * n),
        ("offsets", 4 * n),
    ];
    let mut offsets = [0u64; 3];
    for k in 1..3 {
        offsets[k] = offsets[k - 1] + 8 + blocks[k - 1].1;
    }
    let header = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" \
         byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <PolyData>\n    <Piece \
         NumberOfPoints=\"{points}\" NumberOfPolys=\"{n}\">\n      <Points>\n        <DataArray \
         type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{}\"/>\n      \
         </Points>\n      <Polys>\n        <DataArray type=\"UInt32\" Name=\"connectivity\" \
         format=\"appended\" offset=\"{}\"/>\n        <DataArray type=\"UInt32\" \
         Name=\"offsets\" format=\"appended\" offset=\"{}\"/>\n      </Polys>\n    </Piece>\n  \
         </PolyData>\n  <AppendedData encoding=\"raw\">\n   _",
        offsets[0],
        offsets[1],
        offsets[2],
        points = 3 * n,
    );
    write_atomically(path, |out| {
        out.write_all(header.as_bytes())?;
        let mut chunked = Chunked::new(out);
        chunked.put(blocks[0].1.to_le_bytes())?;
        for x in triangles.iter().flatten().flatten() {
            chunked.put(x.to_le_bytes())?;
        }
        chunked.put(blocks[1].1.to_le_bytes())?;
        for i in 0..3 * n as u32 {
            chunked.put(i.to_le_bytes())?;
        }
        chunked.put(blocks[2].1.to_le_bytes())?;
        for t in 1..=n as u32 {
            chunked.put((3 * t).to_le_bytes())?;
        }
        chunked.flush()?;
        out.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
    })
}

/// One row of [`WALL_LOADS`]: wall `wall`'s force and torque at `time`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallLoadRow {
    /// Simulated time \[s\].
    pub time: f64,
    /// The wall, as the scene orders them.
    pub wall: usize,
    /// Force \[N\].
    pub force: [f64; 3],
    /// Torque about the wall's centre \[N·m\].
    pub torque: [f64; 3],
}

/// The lines of `rows` in [`WALL_LOADS`] (after its header, [`WALL_LOADS_HEADER`]).
pub fn wall_load_lines(rows: &[WallLoadRow]) -> String {
    let mut text = String::new();
    for r in rows {
        let [fx, fy, fz] = r.force;
        let [tx, ty, tz] = r.torque;
        text += &format!(
            "{:e},{},{fx:e},{fy:e},{fz:e},{tx:e},{ty:e},{tz:e}\n",
            r.time, r.wall
        );
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn load_rows_are_one_line_each() {
        let row = |time: f64, wall| WallLoadRow {
            time,
            wall,
            force: [1.0, -2.0, 0.5],
            torque: [0.0; 3],
        };
        let text = wall_load_lines(&[row(0.0, 0), row(0.1, 1)]);
        assert_eq!(
            text,
            "0e0,0,1e0,-2e0,5e-1,0e0,0e0,0e0\n1e-1,1,1e0,-2e0,5e-1,0e0,0e0,0e0\n"
        );
    }

    #[test]
    fn wall_file_names_tell_moving_walls_from_resting_ones() {
        assert_eq!(wall_file_name(Some(10), 2), "wall_00000010_2.vtp");
        assert_eq!(wall_file_name(None, 3), "wall_3.vtp");
        for name in ["wall_00000010_2.vtp", "wall_3.vtp"] {
            assert!(is_wall_file_name(name), "{name}");
        }
        for name in [
            "wall_.vtp",
            "wall_1_.vtp",
            "wall_a.vtp",
            "wall_1.vtu",
            "walls.pvd",
        ] {
            assert!(!is_wall_file_name(name), "{name}");
        }
    }

    #[test]
    fn a_surface_file_holds_its_triangles_in_binary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(wall_file_name(None, 0));
        let triangles = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.5]],
        ];
        write_surface_vtp(&path, &triangles).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let opening = b"<AppendedData encoding=\"raw\">\n   _";
        let at = bytes
            .windows(opening.len())
            .position(|w| w == opening)
            .unwrap()
            + opening.len();
        let text = String::from_utf8_lossy(&bytes);
        assert!(
            text.contains("NumberOfPoints=\"6\" NumberOfPolys=\"2\""),
            "{text}"
        );
        // The data after `_`: each block its byte count (u64), then its values.
        let data = &bytes[at..];
        let u64_at = |o: usize| u64::from_le_bytes(data[o..o + 8].try_into().unwrap());
        let f32_at = |o: usize| f32::from_le_bytes(data[o..o + 4].try_into().unwrap());
        let u32_at = |o: usize| u32::from_le_bytes(data[o..o + 4].try_into().unwrap());
        assert_eq!(u64_at(0), 72);
        assert_eq!(f32_at(8 + 4 * 17), 1.5);
        assert_eq!(u64_at(80), 24);
        assert_eq!((u32_at(88), u32_at(88 + 20)), (0, 5));
        assert_eq!(u64_at(112), 8);
        assert_eq!((u32_at(120), u32_at(124)), (3, 6));
        assert!(text.ends_with("\n  </AppendedData>\n</VTKFile>\n"));
    }
}
