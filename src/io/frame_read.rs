//! Reading simulation frames back: the `.vtu` files [`super::write_vtu`] writes (raw appended
//! binary, `UInt64` block headers) and the frame CSVs (`x,y,z,r,vx,vy,vz,wx,wy,wz,material`, or
//! any sphere file). Frames of mochi before it had several materials have no materials, and read
//! as spheres of the first material.

use super::spheres::read_particles_as_written;
use super::spheres::{check_finite, check_velocity};
use super::{Format, io_error, parse_error};
use crate::error::Result;
use crate::spheres::check_sphere;
use std::path::Path;

/// One frame read from a file, owning its data. The vectors are parallel.
#[derive(Debug, Clone, PartialEq)]
pub struct OwnedFrame {
    /// Step number, from the file (`.vtu`) or its name (`frame_{step}.csv`), when known.
    pub step: Option<u64>,
    /// Simulated time \[s\], when the file has it (`.vtu`).
    pub time: Option<f64>,
    /// Centres \[m\]: the positions rounded to `f32`.
    pub positions: Vec<[f32; 3]>,
    /// The positions \[m\] as the file holds them: `f64` (a CSV's decimals read as `f64`;
    /// `f32` in `.vtu` frames of mochi before it kept residuals and in `float32` files).
    pub exact_positions: Vec<[f64; 3]>,
    /// Radii \[m\].
    pub radii: Vec<f32>,
    /// Velocities \[m/s\] (zero when the file has none).
    pub velocities: Vec<[f32; 3]>,
    /// Angular velocities \[rad/s\] (zero when the file has none, as frames of mochi before
    /// rotation have not).
    pub angular_velocities: Vec<[f32; 3]>,
    /// Materials (as [`crate::particles::Particles::materials`]): one per sphere, or empty
    /// where the file has none (every sphere of the first material, 0).
    pub materials: Vec<u8>,
}

/// Reads a frame: a `.vtu` written by [`super::write_vtu`], or a sphere file (`.csv`, `.npy`)
/// with or without velocities. Every problem is an error naming the file.
pub fn read_frame(path: &Path) -> Result<OwnedFrame> {
    let is_vtu = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("vtu"));
    if is_vtu {
        return read_vtu(path);
    }
    Format::of(path)?;
    let (particles, exact_positions) = read_particles_as_written(path)?;
    let step = path
        .file_stem()
        .and_then(|s| s.to_str())
        .and_then(|s| s.strip_prefix("frame_"))
        .and_then(|digits| digits.parse().ok());
    Ok(OwnedFrame {
        step,
        time: None,
        positions: particles.positions,
        exact_positions,
        radii: particles.radii,
        velocities: particles.velocities,
        angular_velocities: particles.angular_velocities,
        materials: particles.materials,
    })
}

/// Marks the start of the raw data in our `.vtu` files.
const APPENDED: &[u8] = b"<AppendedData encoding=\"raw\">";

/// Reads the arrays `Points` (`Float64`, as mochi writes them, or `Float32`, as it did before it
/// kept residuals), `radius`, `velocity` and, where the file has them, `angular_velocity` (all
/// `Float32`) and `material` (`UInt8`) of a `.vtu`.
pub fn read_vtu(path: &Path) -> Result<OwnedFrame> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let bad = |msg: String| parse_error(path, None, msg);
    let at = find(&bytes, APPENDED)
        .ok_or_else(|| bad("not a .vtu with raw appended data (as mochi writes)".into()))?;
    let underscore = bytes[at..]
        .iter()
        .position(|&b| b == b'_')
        .ok_or_else(|| bad("no '_' opening the appended data".into()))?;
    let data = &bytes[at + underscore + 1..];
    let header =
        std::str::from_utf8(&bytes[..at]).map_err(|_| bad("the XML header is not UTF-8".into()))?;
    if !header.contains(r#"header_type="UInt64""#) {
        return Err(bad("only header_type=\"UInt64\" is read".into()));
    }
    let big_endian = match attribute_after(header, "<VTKFile", "byte_order") {
        Some("LittleEndian") | None => false,
        Some("BigEndian") => true,
        Some(other) => return Err(bad(format!("unknown byte_order {other:?}"))),
    };
    let u64_of = |b: [u8; 8]| match big_endian {
        true => u64::from_be_bytes(b),
        false => u64::from_le_bytes(b),
    };
    let f32_of = |b: [u8; 4]| match big_endian {
        true => f32::from_be_bytes(b),
        false => f32::from_le_bytes(b),
    };
    let f64_of = |b: [u8; 8]| match big_endian {
        true => f64::from_be_bytes(b),
        false => f64::from_le_bytes(b),
    };
    let n: usize = attribute_after(header, "<Piece", "NumberOfPoints")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| bad("no NumberOfPoints in <Piece>".into()))?;
    // The bytes of the array `name` (`element`, its attributes) of `size`-byte values.
    let block_of = |name: &str, element: &str, components: usize, size: usize| -> Result<&[u8]> {
        let offset: usize = attribute(element, "offset")
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| bad(format!("{name}: no offset")))?;
        let want = n
            .checked_mul(components * size)
            .ok_or_else(|| bad(format!("{name}: {n} points is too many")))?;
        let block = offset
            .checked_add(8)
            .and_then(|start| data.get(offset..start))
            .ok_or_else(|| bad(format!("{name}: the data ends before its block")))?;
        let len = u64_of(block.try_into().expect("8 bytes"));
        if len != want as u64 {
            return Err(bad(format!("{name}: {len} bytes, expected {want}")));
        }
        data.get(offset + 8..offset + 8 + want)
            .ok_or_else(|| bad(format!("{name}: the file ends inside the block")))
    };
    // The values of an array of `Float32` (or, where `wide`, also `Float64`) as f64.
    let array_of = |name: &str, components: usize, wide: bool| -> Result<Vec<f64>> {
        let element =
            data_array(header, name).ok_or_else(|| bad(format!("no DataArray named {name:?}")))?;
        let size = match attribute(element, "type") {
            Some("Float32") => 4,
            Some("Float64") if wide => 8,
            _ if wide => return Err(bad(format!("{name}: only Float64 or Float32 is read"))),
            _ => return Err(bad(format!("{name}: only Float32 is read"))),
        };
        let values = block_of(name, element, components, size)?;
        Ok(match size {
            4 => values
                .chunks_exact(4)
                .map(|b| f32_of(b.try_into().expect("4 bytes")) as f64)
                .collect(),
            _ => values
                .chunks_exact(8)
                .map(|b| f64_of(b.try_into().expect("8 bytes")))
                .collect(),
        })
    };
    let array = |name: &str, components: usize| -> Result<Vec<f32>> {
        let values = array_of(name, components, false)?;
        Ok(values.into_iter().map(|x| x as f32).collect())
    };
    let exact = array_of("Points", 3, true)?;
    let points: Vec<f32> = exact.iter().map(|&x| x as f32).collect();
    let radii = array("radius", 1)?;
    let velocity = array("velocity", 3)?;
    let angular = match data_array(header, "angular_velocity") {
        Some(_) => array("angular_velocity", 3)?,
        None => vec![0.0; 3 * n],
    };
    // One byte per sphere (a byte has no byte order); none in frames of one material's mochi.
    let materials = match data_array(header, "material") {
        Some(element) if attribute(element, "type") == Some("UInt8") => {
            block_of("material", element, 1, 1)?.to_vec()
        }
        Some(_) => return Err(bad("material: only UInt8 is read".into())),
        None => Vec::new(),
    };
    let triples =
        |v: Vec<f32>| -> Vec<[f32; 3]> { v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect() };
    let (points, velocity, angular) = (triples(points), triples(velocity), triples(angular));
    let exact_positions = exact.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    // The rules of a sphere file, so that every reader of a frame gets valid spheres.
    for (i, (((c, &r), v), w)) in points
        .iter()
        .zip(&radii)
        .zip(&velocity)
        .zip(&angular)
        .enumerate()
    {
        check_sphere(c, r)
            .and_then(|()| check_velocity(v))
            .and_then(|()| check_finite("angular velocity", w))
            .map_err(|m| bad(format!("point {i} (0-based): {m}")))?;
    }
    let field = |name: &str| {
        let start = header.find(&format!(r#"Name="{name}""#))?;
        let open = start + header[start..].find('>')? + 1;
        let close = open + header[open..].find('<')?;
        Some(header[open..close].trim())
    };
    Ok(OwnedFrame {
        step: field("step").and_then(|v| v.parse().ok()),
        time: field("TimeValue").and_then(|v| v.parse().ok()),
        positions: points,
        exact_positions,
        radii,
        velocities: velocity,
        angular_velocities: angular,
        materials,
    })
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The attributes of the `<DataArray .. Name="name" ../>` element.
fn data_array<'h>(header: &'h str, name: &str) -> Option<&'h str> {
    let key = format!(r#"Name="{name}""#);
    let mut rest = 0;
    while let Some(found) = header[rest..].find("<DataArray") {
        let start = rest + found;
        let end = start + header[start..].find('>')?;
        let element = &header[start + "<DataArray".len()..end];
        if element.contains(&key) {
            return Some(element);
        }
        rest = end;
    }
    None
}

/// The value of attribute `name` of the first element opening with `tag`.
fn attribute_after<'h>(header: &'h str, tag: &str, name: &str) -> Option<&'h str> {
    let start = header.find(tag)?;
    let end = start + header[start..].find('>')?;
    attribute(&header[start + tag.len()..end], name)
}

/// The value of `name="value"` among an element's attributes.
fn attribute<'e>(element: &'e str, name: &str) -> Option<&'e str> {
    let key = format!(" {name}=\"");
    let start = element.find(&key)? + key.len();
    let len = element[start..].find('"')?;
    Some(&element[start..start + len])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{Frame, write_frame, write_vtu};

    /// Angular velocities of the two spheres of [`frame`].
    const SPIN: [[f32; 3]; 2] = [[0.5, -1.0, 2.0], [0.0, 0.0, -3.0e-7]];

    fn frame() -> (Vec<[f32; 3]>, Vec<f32>, Vec<[f32; 3]>) {
        (
            vec![[0.0, 1.0, 2.0], [3.5, -4.0, 5.0]],
            vec![0.25, 0.5],
            vec![[1.0, 0.0, 0.0], [0.0, -2.0, 0.5]],
        )
    }

    /// The frame of step `step` at `time` of spheres like [`frame`]'s (centres, radii and
    /// velocities), spinning as [`SPIN`], of `materials`, without residuals or contacts.
    fn frame_at<'a>(
        (time, step): (f64, u64),
        (positions, radii, velocities): (&'a [[f32; 3]], &'a [f32], &'a [[f32; 3]]),
        materials: &'a [u8],
    ) -> Frame<'a> {
        Frame {
            time,
            step,
            positions,
            position_residuals: &[],
            radii,
            velocities,
            angular_velocities: &SPIN,
            materials,
            contacts: None,
        }
    }

    #[test]
    fn vtu_csv_and_npy_frames_read_back_with_their_materials() {
        let (p, r, v) = frame();
        let f = frame_at((0.125, 42), (&p, &r, &v), &[255, 3]);
        let dir = tempfile::tempdir().unwrap();
        for ext in ["vtu", "csv", "npy"] {
            let path = dir.path().join(format!("frame_00000042.{ext}"));
            write_frame(&path, &f).unwrap();
            let got = read_frame(&path).unwrap();
            let time = (ext == "vtu").then_some(0.125);
            assert_eq!((got.step, got.time), (Some(42), time), "{ext}");
            assert_eq!((&got.positions, &got.radii, &got.velocities), (&p, &r, &v));
            assert_eq!(got.angular_velocities, SPIN);
            assert_eq!(got.materials, [255, 3], "{ext}");
        }
        // A frame of one material: every sphere's material is 0.
        let one = Frame {
            materials: &[],
            ..f
        };
        for ext in ["vtu", "csv", "npy"] {
            let path = dir.path().join(format!("one.{ext}"));
            write_frame(&path, &one).unwrap();
            assert_eq!(read_frame(&path).unwrap().materials, [0, 0], "{ext}");
        }
    }

    #[test]
    fn frames_written_before_materials_read_with_none() {
        let (p, r, v) = frame();
        let f = frame_at((0.5, 7), (&p, &r, &v), &[1, 1]);
        let dir = tempfile::tempdir().unwrap();
        // A `.vtu` whose header lists no `material` array, as mochi wrote before materials (its
        // block left in the data, unnamed, is never read).
        let vtu = dir.path().join("old.vtu");
        write_vtu(&vtu, &f).unwrap();
        let bytes = std::fs::read(&vtu).unwrap();
        let at = find(&bytes, APPENDED).unwrap();
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        let start = header
            .find(r#"<DataArray type="UInt8" Name="material""#)
            .unwrap();
        let end = start + header[start..].find('\n').unwrap() + 1;
        let old = [&bytes[..start], &bytes[end..]].concat();
        std::fs::write(&vtu, old).unwrap();
        // A CSV of ten columns, as frames were written before materials.
        let csv = dir.path().join("old.csv");
        std::fs::write(
            &csv,
            "x,y,z,r,vx,vy,vz,wx,wy,wz\n0,1,2,0.25,1,0,0,0.5,-1,2\n3.5,-4,5,0.5,0,-2,0.5,0,0,-3e-7\n",
        )
        .unwrap();
        for path in [vtu, csv] {
            let got = read_frame(&path).unwrap();
            assert_eq!((&got.positions, &got.radii, &got.velocities), (&p, &r, &v));
            assert_eq!(got.angular_velocities, SPIN);
            assert!(got.materials.is_empty(), "{}", path.display());
        }
    }

    /// `bytes` (a little-endian `.vtu` of [`write_vtu`]) with every appended block and its
    /// length in big-endian order, as `byte_order="BigEndian"` declares.
    fn to_big_endian(bytes: &[u8]) -> Vec<u8> {
        let at = find(bytes, APPENDED).unwrap();
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        let data_start = at + bytes[at..].iter().position(|&b| b == b'_').unwrap() + 1;
        let mut out = bytes.to_vec();
        let mut rest = 0;
        while let Some(found) = header[rest..].find("<DataArray") {
            let start = rest + found;
            let end = start + header[start..].find('>').unwrap();
            let element = &header[start + "<DataArray".len()..end];
            rest = end;
            let Some(offset) = attribute(element, "offset") else {
                continue; // an ascii array
            };
            let size = match attribute(element, "type").unwrap() {
                "Float32" | "Int32" | "UInt32" => 4,
                "Float64" | "Int64" | "UInt64" => 8,
                "UInt8" | "Int8" => 1,
                other => panic!("type {other}"),
            };
            let block = data_start + offset.parse::<usize>().unwrap();
            let len = u64::from_le_bytes(bytes[block..block + 8].try_into().unwrap()) as usize;
            out[block..block + 8].reverse();
            for value in out[block + 8..block + 8 + len].chunks_exact_mut(size) {
                value.reverse();
            }
        }
        with_byte_order(&out, "BigEndian")
    }

    /// `bytes` (a `.vtu` of [`write_vtu`]) declaring `byte_order="{order}"`.
    fn with_byte_order(bytes: &[u8], order: &str) -> Vec<u8> {
        let at = find(bytes, APPENDED).unwrap();
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        let changed = header.replacen(
            r#"byte_order="LittleEndian""#,
            &format!(r#"byte_order="{order}""#),
            1,
        );
        assert_ne!(changed, header);
        [changed.as_bytes(), &bytes[at..]].concat()
    }

    #[test]
    fn a_big_endian_vtu_reads_the_same_values() {
        let (p, r, v) = frame();
        let f = frame_at((0.5, 7), (&p, &r, &v), &[]);
        let dir = tempfile::tempdir().unwrap();
        let vtu = dir.path().join("le.vtu");
        write_vtu(&vtu, &f).unwrap();
        let big = dir.path().join("be.vtu");
        std::fs::write(&big, to_big_endian(&std::fs::read(&vtu).unwrap())).unwrap();
        let got = read_frame(&big).unwrap();
        assert_eq!((&got.positions, &got.radii, &got.velocities), (&p, &r, &v));
        assert_eq!(got.angular_velocities, SPIN);
        let odd = with_byte_order(&std::fs::read(&vtu).unwrap(), "MiddleEndian");
        std::fs::write(&vtu, odd).unwrap();
        let e = read_frame(&vtu).unwrap_err().to_string();
        assert!(e.contains("byte_order"), "{e}");
    }

    #[test]
    fn a_vtu_with_a_bad_sphere_is_an_error_naming_the_file_and_point() {
        let (p, mut r, v) = frame();
        r[1] = f32::NAN;
        let f = frame_at((0.0, 1), (&p, &r, &v), &[]);
        let dir = tempfile::tempdir().unwrap();
        let vtu = dir.path().join("nan.vtu");
        write_vtu(&vtu, &f).unwrap();
        let e = read_frame(&vtu).unwrap_err().to_string();
        assert!(e.contains("nan.vtu") && e.contains("point 1"), "{e}");
    }

    #[test]
    fn broken_vtu_files_are_errors() {
        let (p, r, v) = frame();
        let f = frame_at((0.0, 1), (&p, &r, &v), &[]);
        let dir = tempfile::tempdir().unwrap();
        let vtu = dir.path().join("a.vtu");
        write_vtu(&vtu, &f).unwrap();
        let bytes = std::fs::read(&vtu).unwrap();
        let data = find(&bytes, APPENDED).unwrap() + APPENDED.len() + 5;
        std::fs::write(&vtu, &bytes[..data + 20]).unwrap();
        assert!(read_frame(&vtu).is_err());
        std::fs::write(&vtu, b"<VTKFile>").unwrap();
        assert!(read_frame(&vtu).is_err());
        assert!(read_frame(&dir.path().join("missing.vtu")).is_err());
    }
}
