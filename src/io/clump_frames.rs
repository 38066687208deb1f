//! What a run of clumps writes of its clumps at each frame, beside the frame of their spheres:
//! `clumps_{step:08}.vtu`, a VTK XML UnstructuredGrid (raw appended binary, written through
//! [`write_atomically`]) of one point a clump at its centre of mass (`Float64`), with its
//! `orientation` (a quaternion w, x, y, z: from its principal frame to the world), `velocity`,
//! `angular_velocity`, `mass`, `spheres` (its components) and `kind` (its kind's index in the
//! run's clumps, `Int32`); and their ParaView collection, `clumps.pvd`, listing them as
//! `series.pvd` lists the frames.

use super::vtu_write::vtu_opening;
use super::write_atomically;
use crate::clump::ClumpSet;
use crate::error::Result;
use std::path::Path;

/// File name of the clumps' collection in a run's folder.
pub const CLUMPS_INDEX: &str = "clumps.pvd";

/// The clumps' file of the frame at step `step`.
pub fn clump_frame_name(step: u64) -> String {
    format!("clumps_{step:08}.vtu")
}

/// Whether `name` is a name of [`clump_frame_name`].
pub fn is_clump_frame_name(name: &str) -> bool {
    name.strip_prefix("clumps_")
        .and_then(|rest| rest.strip_suffix(".vtu"))
        .is_some_and(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
}

/// One appended array: its VTK type, name, components and values.
struct Array {
    vtk_type: &'static str,
    name: &'static str,
    components: usize,
    /// The little-endian bytes of its values.
    bytes: Vec<u8>,
}

impl Array {
    fn f64s(name: &'static str, components: usize, values: impl Iterator<Item = f64>) -> Self {
        let bytes = values.flat_map(f64::to_le_bytes).collect();
        Array {
            vtk_type: "Float64",
            name,
            components,
            bytes,
        }
    }

    fn typed(vtk_type: &'static str, name: &'static str, bytes: impl Iterator<Item = u8>) -> Self {
        Array {
            vtk_type,
            name,
            components: 1,
            bytes: bytes.collect(),
        }
    }
}

/// Writes `set`'s clumps at `time` and `step` to `path`, atomically.
pub fn write_clumps_vtu(path: &Path, set: &ClumpSet, time: f64, step: u64) -> Result<()> {
    let clumps = &set.clumps;
    let n = clumps.len();
    let kind = |k: usize| &set.kinds[clumps[k].kind];
    let vectors = |of: &dyn Fn(usize) -> glam::DVec3| -> Vec<f64> {
        (0..n).flat_map(|k| of(k).to_array()).collect()
    };
    let orientation = (0..n).flat_map(|k| {
        let q = clumps[k].body.orientation;
        [q.w, q.x, q.y, q.z]
    });
    let velocity = vectors(&|k| clumps[k].body.velocity);
    let spin = vectors(&|k| clumps[k].body.angular_velocity(&kind(k).inertia));
    let point_data = [
        Array::f64s("orientation", 4, orientation),
        Array::f64s("velocity", 3, velocity.into_iter()),
        Array::f64s("angular_velocity", 3, spin.into_iter()),
        Array::f64s("mass", 1, (0..n).map(|k| kind(k).inertia.mass)),
        Array::typed(
            "UInt32",
            "spheres",
            (0..n).flat_map(|k| (kind(k).template.components.len() as u32).to_le_bytes()),
        ),
        Array::typed(
            "Int32",
            "kind",
            (0..n).flat_map(|k| (clumps[k].kind as i32).to_le_bytes()),
        ),
    ];
    let points = Array::f64s(
        "Points",
        3,
        vectors(&|k| clumps[k].body.position).into_iter(),
    );
    // One vertex a clump (n fits i64 whatever n is).
    let cells = [
        Array::typed(
            "Int64",
            "connectivity",
            (0..n as i64).flat_map(i64::to_le_bytes),
        ),
        Array::typed(
            "Int64",
            "offsets",
            (1..=n as i64).flat_map(i64::to_le_bytes),
        ),
        Array::typed("UInt8", "types", std::iter::repeat_n(1u8, n)),
    ];
    let sections: [(&str, &str, &[Array]); 3] = [
        ("PointData", r#" Vectors="velocity""#, &point_data),
        ("Points", "", std::slice::from_ref(&points)),
        ("Cells", "", &cells),
    ];
    let mut xml = vtu_opening(time, step, n);
    let mut offset = 0u64;
    for (section, attributes, arrays) in sections {
        xml += &format!("      <{section}{attributes}>\n");
        for a in arrays {
            let components = match a.components {
                1 => String::new(),
                c => format!(r#" NumberOfComponents="{c}""#),
            };
            xml += &format!(
                "        <DataArray type=\"{}\" Name=\"{}\"{components} format=\"appended\" \
                 offset=\"{offset}\"/>\n",
                a.vtk_type, a.name
            );
            offset += 8 + a.bytes.len() as u64;
        }
        xml += &format!("      </{section}>\n");
    }
    xml += "    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _";
    write_atomically(path, |out| {
        out.write_all(xml.as_bytes())?;
        for (_, _, arrays) in &sections {
            for a in arrays.iter() {
                out.write_all(&(a.bytes.len() as u64).to_le_bytes())?;
                out.write_all(&a.bytes)?;
            }
        }
        out.write_all(b"\n  </AppendedData>\n</VTKFile>\n")
    })
}
