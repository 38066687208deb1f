//! Reading simulation frames back: `.vtu` files, those [`super::write_vtu`] writes (raw appended
//! binary, `UInt64` block headers) and those of other writers (any VTK XML encoding, see
//! [`read_vtu`]), and the frame CSVs (`x,y,z,r,vx,vy,vz,wx,wy,wz,material`, or any sphere file).
//! Frames of mochi before it had several materials have no materials, and read as spheres of
//! the first material.

use super::spheres::read_particles_as_written;
use super::spheres::{check_finite, check_velocity};
use super::vtk_arrays::Values;
use super::vtu_read::{PointArray, Vtu, VtuText};
use super::{Format, io_error, parse_error};
use crate::error::Result;
use crate::spheres::check_sphere;
use rayon::prelude::*;
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
    /// The contacts each sphere holds (the `contacts` array of a run with contact history),
    /// or empty where the file has none.
    pub contacts: Vec<u32>,
    /// Each sphere's id (a `.vtu`'s integer array `id`, 0 to 2³²−1; a `.pvtu`'s spheres are
    /// in its order), or empty where the file has none (or one of other values).
    pub ids: Vec<u32>,
}

/// Reads a frame: a `.vtu` ([`read_vtu`]: mochi's or another writer's), a `.pvtu` of pieces
/// ([`read_pvtu`]), or a sphere file (`.csv`, `.npy`) with or without
/// velocities. Every problem is an error naming the file.
pub fn read_frame(path: &Path) -> Result<OwnedFrame> {
    let extension = path.extension().and_then(|e| e.to_str());
    let is = |ext: &str| extension.is_some_and(|e| e.eq_ignore_ascii_case(ext));
    if is("vtu") {
        return read_vtu(path);
    }
    if is("pvtu") {
        return read_pvtu(path);
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
        contacts: Vec::new(),
        ids: Vec::new(),
    })
}

/// The names a point-data array of radii may have (in any case), in order of preference.
const RADIUS_NAMES: [&str; 3] = ["radius", "radii", "r"];
/// The names of an array of diameters (any case), read where none has a [`RADIUS_NAMES`] name.
const DIAMETER_NAMES: [&str; 2] = ["diameter", "diameters"];
/// The names of an array of velocities (any case; 3 components).
const VELOCITY_NAMES: [&str; 3] = ["velocity", "velocities", "v"];
/// The names of an array of angular velocities (any case; 3 components).
const ANGULAR_VELOCITY_NAMES: [&str; 2] = ["angular_velocity", "omega"];

/// Reads a `.vtu` (VTK XML UnstructuredGrid) of spheres, as mochi writes it or any other
/// writer (ascii, inline base64 or appended data, raw or base64, zlib or uncompressed, either
/// byte order): the points are the centres, the radii the point data named `radius`, `radii` or
/// `r` in any case (else half those named `diameter` or `diameters`), the velocities those named
/// `velocity`, `velocities` or `v` and the angular velocities `angular_velocity` or `omega` (zero
/// where there is none) and the materials an integer array `material` (0 to 255; none: every sphere
/// of the first material). The field data `step` and `TimeValue` give the step and time where
/// the file has them. Any number type is read; positions keep their `Float64` values exactly.
pub fn read_vtu(path: &Path) -> Result<OwnedFrame> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    frame_of_vtu(&bytes).map_err(|msg| parse_error(path, None, msg))
}

/// The frame of the `.vtu` file `bytes`, or what is wrong with it.
fn frame_of_vtu(bytes: &[u8]) -> std::result::Result<OwnedFrame, String> {
    let text = VtuText::of(bytes)?;
    let vtu = Vtu::parse(&text)?;
    let n = vtu.points();
    let exact = vtu.positions()?.to_f64();
    let radii: Vec<f32> = match vtu.point_data(&RADIUS_NAMES)? {
        Some(radius) => scalars(radius)?
            .to_f64()
            .iter()
            .map(|&r| r as f32)
            .collect(),
        None => match vtu.point_data(&DIAMETER_NAMES)? {
            Some(diameter) => (scalars(diameter)?.to_f64().iter())
                .map(|&d| (d / 2.0) as f32)
                .collect(),
            None => {
                return Err(format!(
                    "no point data of radii: name its array {} (or one of diameters {}), in \
                     any case",
                    either(&RADIUS_NAMES),
                    either(&DIAMETER_NAMES)
                ));
            }
        },
    };
    let velocities = vectors(vtu.point_data(&VELOCITY_NAMES)?, n)?;
    let angular_velocities = vectors(vtu.point_data(&ANGULAR_VELOCITY_NAMES)?, n)?;
    let materials = match vtu.point_data(&["material"])? {
        Some(material) => {
            let name = material.name.clone();
            let codes = scalars(material)?.to_unsigned(u8::MAX.into());
            let codes = codes.map_err(|e| format!("point data {name:?}: {e}"))?;
            codes.into_iter().map(|m| m as u8).collect()
        }
        None => Vec::new(),
    };
    let contacts = match vtu.point_data(&["contacts"])? {
        Some(counts) => {
            let name = counts.name.clone();
            let counts = scalars(counts)?.to_unsigned(u32::MAX.into());
            let counts = counts.map_err(|e| format!("point data {name:?}: {e}"))?;
            counts.into_iter().map(|c| c as u32).collect()
        }
        None => Vec::new(),
    };
    let ids = match vtu.point_data(&["id"])? {
        Some(ids) if ids.components == 1 => (ids.values.to_unsigned(u32::MAX.into()))
            .map(|ids| ids.into_iter().map(|id| id as u32).collect())
            .unwrap_or_default(),
        _ => Vec::new(),
    };
    let positions: Vec<[f32; 3]> = exact
        .chunks_exact(3)
        .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
        .collect();
    let exact_positions = exact.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    // The rules of a sphere file, so that every reader of a frame gets valid spheres.
    for (i, (((c, &r), v), w)) in positions
        .iter()
        .zip(&radii)
        .zip(&velocities)
        .zip(&angular_velocities)
        .enumerate()
    {
        check_sphere(c, r)
            .and_then(|()| check_velocity(v))
            .and_then(|()| check_finite("angular velocity", w))
            .map_err(|m| format!("point {i} (0-based): {m}"))?;
    }
    let first = |values: Option<Values>| values.and_then(|v| v.to_f64().first().copied());
    let step = match vtu.field_data("step")? {
        Some(step) => step
            .to_unsigned(u64::MAX)
            .map_err(|e| format!("field data \"step\": {e}"))?
            .first()
            .copied(),
        None => None,
    };
    Ok(OwnedFrame {
        step,
        time: first(vtu.field_data("TimeValue")?),
        positions,
        exact_positions,
        radii,
        velocities,
        angular_velocities,
        materials,
        contacts,
        ids,
    })
}

/// `names` as words: "a, b or c".
fn either(names: &[&str]) -> String {
    match names.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// The values of `array`, one a point.
fn scalars(array: PointArray) -> std::result::Result<Values, String> {
    match array.components {
        1 => Ok(array.values),
        c => Err(format!(
            "point data {:?} has {c} components, not 1",
            array.name
        )),
    }
}

/// The vectors of `array`, one a point, 3 components each; zero where there is no array (of
/// `n` points).
fn vectors(array: Option<PointArray>, n: usize) -> std::result::Result<Vec<[f32; 3]>, String> {
    let Some(array) = array else {
        return Ok(vec![[0.0; 3]; n]);
    };
    if array.components != 3 {
        return Err(format!(
            "point data {:?} has {} components, not 3",
            array.name, array.components
        ));
    }
    let values = array.values.to_f64();
    Ok(values
        .chunks_exact(3)
        .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
        .collect())
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
            clumps: None,
            ids: None,
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

    /// The index of `needle` in `haystack`.
    fn position(haystack: &[u8], needle: &[u8]) -> usize {
        haystack
            .windows(needle.len())
            .position(|w| w == needle)
            .unwrap_or_else(|| panic!("no {:?}", String::from_utf8_lossy(needle)))
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
        let start = position(&bytes, br#"<DataArray type="UInt8" Name="material""#);
        let end = start + position(&bytes[start..], b"\n") + 1;
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

    /// A fixture of `tests/data` (written by `make_vtu_fixtures.py`).
    fn fixture(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name)
    }

    /// The spheres of every fixture.
    const CENTRES: [[f32; 3]; 3] = [[0.0, 1.0, 2.0], [3.5, -4.0, 5.0], [0.25, 0.5, -0.125]];
    const RADII: [f32; 3] = [0.25, 0.5, 0.125];
    const VELOCITIES: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, -2.0, 0.5], [0.0; 3]];

    #[test]
    fn vtu_files_of_other_writers_read_as_their_spheres() {
        // (file, with velocities, step and time)
        let fixtures = [
            ("vtu_meshio_ascii.vtu", true, None),
            ("vtu_meshio_binary.vtu", true, None),
            ("vtu_meshio_zlib.vtu", false, None),
            ("vtu_vtk_appended_zlib.vtu", true, None),
            ("vtu_vtk_big_endian.vtu", true, Some((12, 0.375))),
        ];
        for (name, moving, when) in fixtures {
            let got = read_frame(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(got.positions, CENTRES, "{name}");
            let exact = CENTRES.map(|c| c.map(f64::from));
            assert_eq!(got.exact_positions, exact, "{name}");
            assert_eq!(got.radii, RADII, "{name}");
            let velocities = if moving { VELOCITIES } else { [[0.0; 3]; 3] };
            assert_eq!(got.velocities, velocities, "{name}");
            assert_eq!(got.angular_velocities, [[0.0; 3]; 3], "{name}");
            assert!(got.materials.is_empty(), "{name}");
            assert_eq!((got.step, got.time), when.unzip(), "{name}");
        }
    }

    #[test]
    fn angular_velocities_and_materials_of_other_writers_are_read() {
        // LIGGGHTS names them omega; a material of any integer type.
        let text = std::fs::read_to_string(fixture("vtu_meshio_ascii.vtu")).unwrap();
        let extra = "<DataArray type=\"Float32\" Name=\"omega\" NumberOfComponents=\"3\" \
                     format=\"ascii\">0 0 1  0 2 0  3 0 0</DataArray>\n\
                     <DataArray type=\"Int32\" Name=\"material\" format=\"ascii\">2 0 255\
                     </DataArray>\n</PointData>";
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("spin.vtu");
        std::fs::write(&path, text.replace("</PointData>", extra)).unwrap();
        let got = read_frame(&path).unwrap();
        let spin = [[0.0, 0.0, 1.0], [0.0, 2.0, 0.0], [3.0, 0.0, 0.0]];
        assert_eq!(
            (got.angular_velocities, got.materials),
            (spin.to_vec(), vec![2, 0, 255])
        );
        // A material beyond 255 or of a float type is refused.
        for (from, to, error) in [
            ("2 0 255", "2 0 256", "256, is not in 0..=255"),
            (
                "\"Int32\" Name=\"material\"",
                "\"Float32\" Name=\"material\"",
                "not an integer",
            ),
        ] {
            let bad = text.replace("</PointData>", &extra.replace(from, to));
            std::fs::write(&path, bad).unwrap();
            let e = read_frame(&path).unwrap_err().to_string();
            assert!(
                e.contains("spin.vtu") && e.contains("material") && e.contains(error),
                "{e}"
            );
        }
    }

    #[test]
    fn malformed_vtu_files_get_one_error_naming_the_file_and_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        // (fixture, text replaced, by, in the error)
        let cases = [
            ("vtu_meshio_ascii.vtu", "<?xml", "<<?xml", "bad XML"),
            ("vtu_meshio_ascii.vtu", "</Piece>", "</Peace>", "bad XML"),
            (
                "vtu_meshio_ascii.vtu",
                "\"UnstructuredGrid\"",
                "\"PolyData\"",
                "PolyData",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "LittleEndian",
                "MiddleEndian",
                "byte_order",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "version=\"0.1\"",
                "header_type=\"UInt16\"",
                "UInt16",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "\"Radius\"",
                "\"size\"",
                "no point data of radii",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "Points=\"3\"",
                "Points=\"4\"",
                "expected 4 × 3",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "Points=\"3\"",
                "Points=\"-3\"",
                "NumberOfPoints",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "5.00000000000e-01\n-1.25",
                "0.5x\n-1.25",
                "\"0.5x\"",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "\"Float64\" Name=\"Radius\"",
                "\"Float16\" Name=\"Radius\"",
                "Float16",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "\"Radius\" format=\"ascii\"",
                "\"Radius\" format=\"hex\"",
                "hex",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "\"v\" NumberOfComponents=\"3\"",
                "\"v\" NumberOfComponents=\"2\"",
                "expected 3 × 2",
            ),
            (
                "vtu_meshio_ascii.vtu",
                "</UnstructuredGrid>",
                "<Piece/></UnstructuredGrid>",
                "2 <Piece>s",
            ),
            (
                "vtu_meshio_binary.vtu",
                "AAAAAAAAAAAAAAAAAAAA",
                "AAAAAAAAAAAAAAAA",
                "ends inside",
            ),
            (
                "vtu_meshio_binary.vtu",
                "GAAAAAAAAAAAANA",
                "G*AAAAAAAAAAANA",
                "base64",
            ),
            (
                "vtu_meshio_zlib.vtu",
                "vtkZLibDataCompressor",
                "vtkLZ4DataCompressor",
                "vtkLZ4DataCompressor",
            ),
            ("vtu_meshio_zlib.vtu", "eJxjYACBB", "eJxjYACBC", "zlib"),
            (
                "vtu_vtk_big_endian.vtu",
                "offset=\"104\"",
                "offset=\"9999\"",
                "offset 9999",
            ),
            (
                "vtu_vtk_big_endian.vtu",
                "encoding=\"base64\"",
                "encoding=\"hex\"",
                "hex",
            ),
            ("vtu_vtk_big_endian.vtu", "   _", "   ", "'_'"),
        ];
        for (name, from, to, error) in cases {
            let text = std::fs::read_to_string(fixture(name)).unwrap();
            assert!(text.contains(from), "{name} has no {from:?}");
            let path = dir.path().join(format!("broken_{name}"));
            std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
            let e = read_frame(&path).unwrap_err().to_string();
            assert!(
                e.contains(&format!("broken_{name}")) && e.contains(error),
                "{from:?} → {to:?}: {e}"
            );
        }
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
        // Cut before the points' block, then inside it.
        let data = position(&bytes, b"\n   _") + 5;
        let points = position(&bytes, br#"Name="Points""#);
        let offset = position(&bytes[points..], b"offset=\"") + points + 8;
        let len = position(&bytes[offset..], b"\"");
        let offset: usize = std::str::from_utf8(&bytes[offset..offset + len])
            .unwrap()
            .parse()
            .unwrap();
        for (cut, error) in [(20, "past the end"), (offset + 12, "ends inside a block")] {
            std::fs::write(&vtu, &bytes[..data + cut]).unwrap();
            let e = read_frame(&vtu).unwrap_err().to_string();
            assert!(
                e.contains("a.vtu") && e.contains("the points") && e.contains(error),
                "{e}"
            );
        }
        std::fs::write(&vtu, b"<VTKFile>").unwrap();
        assert!(read_frame(&vtu).is_err());
        std::fs::write(&vtu, [&bytes[..10], &[0xff], &bytes[11..]].concat()).unwrap();
        let e = read_frame(&vtu).unwrap_err().to_string();
        assert!(e.contains("UTF-8"), "{e}");
        assert!(read_frame(&dir.path().join("missing.vtu")).is_err());
    }
}
