//! What a run writes of its mesh walls: each wall's surface at each frame as a VTK XML PolyData
//! file (`wall_{step:08}_{k}.vtp`, ASCII), a ParaView collection of them (`walls.pvd`, the wall
//! as the part), and the force and torque on each wall per frame (`walls.csv`: `time, wall, fx,
//! fy, fz, tx, ty, tz`; N and N·m, the torque about the wall's rotation centre; appended
//! through [`super::append_log`]). Every file is written through [`write_atomically`].

use super::frames::SeriesEntry;
use super::write_atomically;
use crate::error::Result;
use std::path::Path;

/// File name of the walls' collection in a run's folder.
pub const WALLS_INDEX: &str = "walls.pvd";

/// File name of the walls' loads in a run's folder.
pub const WALL_LOADS: &str = "walls.csv";

/// Header of [`WALL_LOADS`].
pub const WALL_LOADS_HEADER: &str = "time,wall,fx,fy,fz,tx,ty,tz";

/// The file of wall `k`'s surface at step `step`.
pub fn wall_file_name(step: u64, k: usize) -> String {
    format!("wall_{step:08}_{k}.vtp")
}

/// Writes a triangle surface: `triangles` index `points`.
pub fn write_surface_vtp(path: &Path, points: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<()> {
    write_atomically(path, |out| {
        writeln!(
            out,
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" \
             byte_order=\"LittleEndian\">\n  <PolyData>\n    <Piece NumberOfPoints=\"{}\" \
             NumberOfPolys=\"{}\">\n      <Points>\n        <DataArray type=\"Float32\" \
             NumberOfComponents=\"3\" format=\"ascii\">",
            points.len(),
            triangles.len()
        )?;
        for p in points {
            writeln!(out, "{} {} {}", p[0], p[1], p[2])?;
        }
        writeln!(
            out,
            "        </DataArray>\n      </Points>\n      <Polys>\n        <DataArray \
             type=\"UInt32\" Name=\"connectivity\" format=\"ascii\">"
        )?;
        for t in triangles {
            writeln!(out, "{} {} {}", t[0], t[1], t[2])?;
        }
        writeln!(
            out,
            "        </DataArray>\n        <DataArray type=\"UInt32\" Name=\"offsets\" \
             format=\"ascii\">"
        )?;
        for k in 1..=triangles.len() {
            writeln!(out, "{}", 3 * k)?;
        }
        writeln!(
            out,
            "        </DataArray>\n      </Polys>\n    </Piece>\n  </PolyData>\n</VTKFile>"
        )
    })
}

/// Writes the collection of `walls` walls at the frames `entries` (their files
/// [`wall_file_name`]) to `path`.
pub fn write_walls_index(path: &Path, entries: &[SeriesEntry], walls: usize) -> Result<()> {
    write_atomically(path, |out| {
        out.write_all(
            b"<?xml version=\"1.0\"?>\n\
              <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  \
              <Collection>\n",
        )?;
        for e in entries {
            for k in 0..walls {
                writeln!(
                    out,
                    r#"    <DataSet timestep="{}" group="" part="{k}" file="{}"/>"#,
                    e.time,
                    wall_file_name(e.step, k)
                )?;
            }
        }
        out.write_all(b"  </Collection>\n</VTKFile>\n")
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
    fn a_surface_file_lists_its_points_and_triangles() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(wall_file_name(10, 2));
        assert!(path.ends_with("wall_00000010_2.vtp"));
        let points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        write_surface_vtp(&path, &points, &[[0, 1, 2]]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("NumberOfPoints=\"3\" NumberOfPolys=\"1\""),
            "{text}"
        );
        assert!(
            text.contains("0 1 2\n") && text.contains("1 0 0\n"),
            "{text}"
        );
        let index = dir.path().join(WALLS_INDEX);
        let entries = [SeriesEntry {
            step: 10,
            time: 0.5,
        }];
        write_walls_index(&index, &entries, 2).unwrap();
        let text = std::fs::read_to_string(&index).unwrap();
        assert!(text.contains(r#"timestep="0.5" group="" part="1" file="wall_00000010_1.vtp""#));
    }
}
