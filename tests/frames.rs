//! Simulation frames: `.vtu` files are parsed back (XML by roxmltree, the appended raw binary by
//! hand) and every array compared bit for bit; the `.pvd` index lists frames in step order with
//! their times, resuming drops later frames, and bad input or a failing write gives an error and
//! leaves no temporary file.

use mochi::Error;
use mochi::dem::position::join;
use mochi::dem::{ContactHistory, FIRST_WALL, HistoryEntry};
use mochi::io::{
    Frame, FrameSeries, SERIES_INDEX, SeriesEntry, write_frame, write_frame_csv, write_vtu,
};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use tempfile::TempDir;

// ----------------------------------------------------------------------------------------------
// Helpers
// ----------------------------------------------------------------------------------------------

/// Owned data behind a [`Frame`].
#[derive(Clone)]
struct Spheres {
    positions: Vec<[f32; 3]>,
    /// A residual of 0.3 of the spacing above each coordinate of every other sphere.
    position_residuals: Vec<[f32; 3]>,
    radii: Vec<f32>,
    velocities: Vec<[f32; 3]>,
    angular_velocities: Vec<[f32; 3]>,
    /// Every material from 0 to 255, in a scrambled order.
    materials: Vec<u8>,
    /// The contacts each sphere holds in the history of a frictional run (`None`: a run
    /// without one).
    contacts: Option<Vec<u32>>,
}

impl Spheres {
    /// `n` spheres whose values cover awkward floats (−0, subnormals, huge, tiny) and random bit
    /// patterns, so that any conversion or reordering would show.
    fn new(n: usize, seed: u64) -> Self {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let special = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE / 8.0,
            1e-30,
            -3.5e12,
            f32::MAX,
            std::f32::consts::PI,
        ];
        let mut value = |i: usize| loop {
            if i.is_multiple_of(5) {
                break special[(next() % special.len() as u64) as usize];
            }
            let x = f32::from_bits(next() as u32);
            if x.is_finite() && x.abs() < 1e18 {
                break x;
            }
        };
        let positions: Vec<[f32; 3]> = (0..n)
            .map(|i| [value(i), value(i + 1), value(i + 2)])
            .collect();
        let velocities = (0..n)
            .map(|i| [value(i + 3), value(i), value(i + 4)])
            .collect();
        let angular_velocities = (0..n)
            .map(|i| [value(i + 2), value(i + 4), value(i + 1)])
            .collect();
        let radii = (0..n).map(|i| value(i).abs().max(1e-6)).collect();
        let materials = (0..n).map(|i| (i * 167 % 256) as u8).collect();
        let position_residuals = positions
            .iter()
            .enumerate()
            .map(|(i, c): (usize, &[f32; 3])| {
                c.map(|x| {
                    let spacing = x.abs().next_up() - x.abs();
                    match i % 2 == 1 && spacing.is_finite() {
                        true => 0.3 * spacing,
                        false => 0.0,
                    }
                })
            })
            .collect();
        Self {
            positions,
            position_residuals,
            radii,
            velocities,
            angular_velocities,
            materials,
            contacts: None,
        }
    }

    /// `self` with a contact history: sphere i touches its successor (both keep the pair), and
    /// every third sphere the floor.
    fn with_history(mut self) -> Self {
        let n = self.radii.len() as u32;
        let entry = |partner| HistoryEntry {
            partner,
            ..HistoryEntry::default()
        };
        let mut contacts = Vec::new();
        for i in 0..n {
            if i + 1 < n {
                contacts.push((i, entry(i + 1)));
                contacts.push((i + 1, entry(i)));
            }
            if i % 3 == 0 {
                contacts.push((i, entry(FIRST_WALL + 4)));
            }
        }
        let history = ContactHistory::from_contacts(n as usize, &contacts).unwrap();
        self.contacts = Some(history.counts(n as usize));
        self
    }

    /// Each sphere's position, its centre plus its residual, as the frames write it.
    fn exact_positions(&self) -> Vec<[f64; 3]> {
        self.positions
            .iter()
            .zip(&self.position_residuals)
            .map(|(c, r)| std::array::from_fn(|k| join(c[k], r[k])))
            .collect()
    }

    /// Contacts per sphere in [`Self::with_history`].
    fn contact_counts(&self) -> Vec<i64> {
        let n = self.radii.len();
        (0..n)
            .map(|i| (i > 0) as i64 + (i + 1 < n) as i64 + (i % 3 == 0) as i64)
            .collect()
    }

    fn frame(&self, step: u64, time: f64) -> Frame<'_> {
        Frame {
            time,
            step,
            positions: &self.positions,
            position_residuals: &self.position_residuals,
            radii: &self.radii,
            velocities: &self.velocities,
            angular_velocities: &self.angular_velocities,
            materials: &self.materials,
            contacts: self.contacts.as_deref(),
            clumps: None,
            ids: None,
        }
    }
}

/// The documented `speed`: |v| in f64, rounded once to f32.
fn speed(v: [f32; 3]) -> f32 {
    let [x, y, z] = v.map(f64::from);
    (x * x + y * y + z * z).sqrt() as f32
}

/// One decoded `DataArray`.
#[derive(Debug)]
struct Array {
    vtk_type: String,
    components: usize,
    bytes: Vec<u8>,
}

impl Array {
    fn f32_bits(&self) -> Vec<u32> {
        assert_eq!(self.vtk_type, "Float32");
        self.words::<4>().map(u32::from_le_bytes).collect()
    }

    fn f64_bits(&self) -> Vec<u64> {
        assert_eq!(self.vtk_type, "Float64");
        self.words::<8>().map(u64::from_le_bytes).collect()
    }

    fn integers(&self) -> Vec<i64> {
        match self.vtk_type.as_str() {
            "Int32" => self
                .words::<4>()
                .map(|w| i32::from_le_bytes(w).into())
                .collect(),
            "UInt32" => self
                .words::<4>()
                .map(|w| u32::from_le_bytes(w).into())
                .collect(),
            "Int64" => self.words::<8>().map(i64::from_le_bytes).collect(),
            "UInt8" => self.bytes.iter().map(|&b| b.into()).collect(),
            other => panic!("not an integer type: {other}"),
        }
    }

    fn words<const W: usize>(&self) -> impl Iterator<Item = [u8; W]> + '_ {
        assert_eq!(self.bytes.len() % W, 0);
        self.bytes.chunks_exact(W).map(|c| c.try_into().unwrap())
    }
}

/// A `.vtu` file, parsed the way VTK reads it: XML up to `<AppendedData>`, then raw blocks, each
/// a little-endian `UInt64` byte count followed by the data.
#[derive(Debug)]
struct Vtu {
    n_points: usize,
    n_cells: usize,
    /// Point data by name; the points as `"Points"`; the cells as `"cells/<name>"`.
    arrays: HashMap<String, Array>,
    /// Field data (ascii) by name.
    fields: HashMap<String, String>,
}

const TAIL: &[u8] = b"\n  </AppendedData>\n</VTKFile>\n";

fn read_vtu(path: &Path) -> Vtu {
    let bytes = std::fs::read(path).unwrap();
    let find = |needle: &[u8]| {
        bytes
            .windows(needle.len())
            .position(|w| w == needle)
            .unwrap_or_else(|| panic!("{} has no {:?}", path.display(), needle))
    };
    let appended_at = find(b"<AppendedData");
    let opening = br#"<AppendedData encoding="raw">"#;
    assert_eq!(&bytes[appended_at..appended_at + opening.len()], opening);
    let underscore = appended_at
        + opening.len()
        + bytes[appended_at + opening.len()..]
            .iter()
            .position(|&b| b == b'_')
            .unwrap();
    assert!(
        bytes[appended_at + opening.len()..underscore]
            .iter()
            .all(u8::is_ascii_whitespace),
        "only whitespace before the '_' of the appended data"
    );
    let raw = &bytes[underscore + 1..];

    let xml = String::from_utf8(bytes[..appended_at].to_vec()).unwrap() + "</VTKFile>";
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "VTKFile");
    assert_eq!(root.attribute("type"), Some("UnstructuredGrid"));
    assert_eq!(root.attribute("byte_order"), Some("LittleEndian"));
    assert_eq!(root.attribute("header_type"), Some("UInt64"));
    let grid = child(root, "UnstructuredGrid");
    let piece = child(grid, "Piece");
    let count = |name| piece.attribute(name).unwrap().parse::<usize>().unwrap();

    let mut fields = HashMap::new();
    for a in child(grid, "FieldData")
        .children()
        .filter(|c| c.is_element())
    {
        assert_eq!(a.attribute("format"), Some("ascii"));
        assert_eq!(a.attribute("NumberOfTuples"), Some("1"));
        let name = a.attribute("Name").unwrap().to_owned();
        fields.insert(name, a.text().unwrap().trim().to_owned());
    }

    let mut arrays = HashMap::new();
    let mut blocks = Vec::new();
    for (section, prefix) in [("PointData", ""), ("Points", ""), ("Cells", "cells/")] {
        for a in child(piece, section).children().filter(|c| c.is_element()) {
            assert_eq!(a.tag_name().name(), "DataArray");
            assert_eq!(a.attribute("format"), Some("appended"));
            let offset: usize = a.attribute("offset").unwrap().parse().unwrap();
            let len = u64::from_le_bytes(raw[offset..offset + 8].try_into().unwrap()) as usize;
            blocks.push((offset, len));
            let name = format!("{prefix}{}", a.attribute("Name").unwrap());
            let array = Array {
                vtk_type: a.attribute("type").unwrap().to_owned(),
                components: a
                    .attribute("NumberOfComponents")
                    .map_or(1, |c| c.parse().unwrap()),
                bytes: raw[offset + 8..offset + 8 + len].to_vec(),
            };
            assert!(arrays.insert(name, array).is_none(), "duplicate array");
        }
    }
    // The blocks tile the appended data exactly, and the file closes right after the last one.
    blocks.sort();
    let mut end = 0;
    for (offset, len) in blocks {
        assert_eq!(offset, end, "blocks must be contiguous");
        end = offset + 8 + len;
    }
    assert_eq!(&raw[end..], TAIL);
    Vtu {
        n_points: count("NumberOfPoints"),
        n_cells: count("NumberOfCells"),
        arrays,
        fields,
    }
}

/// The first child element of `node` named `name`.
fn child<'a, 'i>(node: roxmltree::Node<'a, 'i>, name: &str) -> roxmltree::Node<'a, 'i> {
    node.children()
        .find(|c| c.has_tag_name(name))
        .unwrap_or_else(|| panic!("no <{name}> in <{}>", node.tag_name().name()))
}

/// Checks that `path` holds exactly `spheres` at `step` and `time`.
fn check_vtu(path: &Path, spheres: &Spheres, step: u64, time: f64) {
    let n = spheres.radii.len();
    let vtu = read_vtu(path);
    assert_eq!((vtu.n_points, vtu.n_cells), (n, n));
    assert_eq!(vtu.fields["TimeValue"].parse::<f64>().unwrap(), time);
    assert_eq!(vtu.fields["step"].parse::<u64>().unwrap(), step);

    let bits3 = |v: &[[f32; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    let a = &vtu.arrays;
    assert_eq!(a["Points"].components, 3);
    let positions: Vec<u64> = spheres
        .exact_positions()
        .iter()
        .flatten()
        .map(|x| x.to_bits())
        .collect();
    assert_eq!(a["Points"].f64_bits(), positions);
    assert_eq!(a["radius"].components, 1);
    let radius_bits: Vec<u32> = spheres.radii.iter().map(|r| r.to_bits()).collect();
    assert_eq!(a["radius"].f32_bits(), radius_bits);
    assert_eq!(a["velocity"].components, 3);
    assert_eq!(a["velocity"].f32_bits(), bits3(&spheres.velocities));
    let speeds: Vec<u32> = spheres
        .velocities
        .iter()
        .map(|&v| speed(v).to_bits())
        .collect();
    assert_eq!(a["speed"].f32_bits(), speeds);
    assert_eq!(a["angular_velocity"].components, 3);
    assert_eq!(
        a["angular_velocity"].f32_bits(),
        bits3(&spheres.angular_velocities)
    );
    match &spheres.contacts {
        Some(_) => {
            assert_eq!(a["contacts"].vtk_type, "UInt32");
            assert_eq!(a["contacts"].integers(), spheres.contact_counts());
        }
        None => assert!(!a.contains_key("contacts"), "contacts without a history"),
    }
    assert_eq!(
        (a["material"].vtk_type.as_str(), a["material"].components),
        ("UInt8", 1)
    );
    let materials: Vec<i64> = spheres.materials.iter().map(|&m| m.into()).collect();
    assert_eq!(a["material"].integers(), materials);
    assert!(["Int32", "UInt32"].contains(&a["id"].vtk_type.as_str()));
    assert_eq!(a["id"].integers(), (0..n as i64).collect::<Vec<_>>());

    assert_eq!(
        a["cells/connectivity"].integers(),
        (0..n as i64).collect::<Vec<_>>()
    );
    assert_eq!(
        a["cells/offsets"].integers(),
        (1..=n as i64).collect::<Vec<_>>()
    );
    assert_eq!(a["cells/types"].vtk_type, "UInt8");
    assert_eq!(a["cells/types"].integers(), vec![1; n], "VTK_VERTEX is 1");
}

/// The `(timestep, file)` of each `<DataSet>` of an index, in file order.
fn read_pvd(path: &Path) -> Vec<(f64, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let root = doc.root_element();
    assert_eq!(root.attribute("type"), Some("Collection"));
    let collection = root
        .children()
        .find(|c| c.has_tag_name("Collection"))
        .unwrap();
    collection
        .children()
        .filter(|c| c.is_element())
        .map(|d| {
            assert!(d.has_tag_name("DataSet"));
            let time = d.attribute("timestep").unwrap().parse().unwrap();
            (time, d.attribute("file").unwrap().to_owned())
        })
        .collect()
}

/// Names of the temporary files `write_atomically` left in `dir`.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with(".mochi-"))
        .collect()
}

fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

// ----------------------------------------------------------------------------------------------
// .vtu and .csv
// ----------------------------------------------------------------------------------------------

#[test]
fn vtu_holds_every_array_bit_exactly() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(53, 7);
    let path = dir.path().join("f.vtu");
    write_vtu(&path, &spheres.frame(1234, 0.012_345_678_901_234_567)).unwrap();
    check_vtu(&path, &spheres, 1234, 0.012_345_678_901_234_567);
    assert_eq!(names(dir.path()), ["f.vtu"]);
}

#[test]
fn vtu_holds_the_contact_count_of_each_sphere() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(17, 9).with_history();
    let path = dir.path().join("f.vtu");
    write_vtu(&path, &spheres.frame(3, 0.5)).unwrap();
    check_vtu(&path, &spheres, 3, 0.5);
    // Read back as the frame's contacts (`mochi render --color-by contacts` colours by them),
    // of spheres a reader takes (the generator's go to f32's limits).
    let mut sane = spheres.clone();
    for (k, c) in sane.positions.iter_mut().enumerate() {
        *c = [k as f32, 0.0, 0.0];
    }
    sane.position_residuals.fill([0.0; 3]);
    sane.radii.fill(0.4);
    sane.velocities.fill([0.0; 3]);
    sane.angular_velocities.fill([0.0; 3]);
    write_vtu(&path, &sane.frame(3, 0.5)).unwrap();
    let read = mochi::io::read_frame(&path).unwrap();
    let counts: Vec<i64> = read.contacts.iter().map(|&c| c as i64).collect();
    assert_eq!(counts, spheres.contact_counts());
    sane.contacts = None;
    write_vtu(&path, &sane.frame(3, 0.5)).unwrap();
    assert!(mochi::io::read_frame(&path).unwrap().contacts.is_empty());
}

#[test]
fn an_empty_frame_is_a_valid_file() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(0, 1);
    let path = dir.path().join("empty.vtu");
    write_vtu(&path, &spheres.frame(0, 0.0)).unwrap();
    check_vtu(&path, &spheres, 0, 0.0);
    let csv = dir.path().join("empty.csv");
    write_frame_csv(&csv, &spheres.frame(0, 0.0)).unwrap();
    assert_eq!(
        std::fs::read_to_string(&csv).unwrap(),
        "x,y,z,r,vx,vy,vz,wx,wy,wz,material\n"
    );
}

#[test]
fn csv_rows_parse_back_to_the_same_floats() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(41, 3);
    let path = dir.path().join("f.csv");
    write_frame_csv(&path, &spheres.frame(5, 1.5)).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,r,vx,vy,vz,wx,wy,wz,material"));
    // The positions in f64, the material an integer, the rest in f32.
    let rows: Vec<Vec<u64>> = lines
        .map(|l| {
            l.split(',')
                .enumerate()
                .map(|(k, f)| match k {
                    0..3 => f.parse::<f64>().unwrap().to_bits(),
                    10 => f.parse::<u8>().unwrap().into(),
                    _ => f.parse::<f32>().unwrap().to_bits().into(),
                })
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 41);
    let positions = spheres.exact_positions();
    for (i, row) in rows.iter().enumerate() {
        let [vx, vy, vz] = spheres.velocities[i];
        let [wx, wy, wz] = spheres.angular_velocities[i];
        let rest = [spheres.radii[i], vx, vy, vz, wx, wy, wz].map(|v| v.to_bits().into());
        let want: Vec<u64> = positions[i]
            .map(f64::to_bits)
            .into_iter()
            .chain(rest)
            .chain([spheres.materials[i].into()])
            .collect();
        assert_eq!(row, &want, "row {i}");
    }
}

#[test]
fn npy_frames_hold_the_csv_columns_bit_exactly() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(37, 4);
    let path = dir.path().join("f.npy");
    write_frame(&path, &spheres.frame(5, 1.5)).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape(), &[37, 11]);
    // float64: the positions, the rest's f32 values exactly, and the material.
    let values: Vec<f64> = npy.into_vec().unwrap();
    let positions = spheres.exact_positions();
    for (i, row) in values.chunks_exact(11).enumerate() {
        let [x, y, z] = positions[i];
        let [vx, vy, vz] = spheres.velocities[i];
        let [wx, wy, wz] = spheres.angular_velocities[i];
        let rest = [spheres.radii[i], vx, vy, vz, wx, wy, wz].map(f64::from);
        let want: Vec<u64> = [x, y, z]
            .into_iter()
            .chain(rest)
            .chain([spheres.materials[i].into()])
            .map(f64::to_bits)
            .collect();
        assert_eq!(
            row.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            want,
            "row {i}"
        );
    }
    assert_eq!(leftovers(dir.path()), Vec::<String>::new());
}

#[test]
fn write_frame_picks_the_writer_by_extension_and_refuses_others() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(9, 5);
    let frame = spheres.frame(2, 0.5);
    for ext in ["vtu", "CSV", "npy"] {
        write_frame(&dir.path().join(format!("f.{ext}")), &frame).unwrap();
    }
    check_vtu(&dir.path().join("f.vtu"), &spheres, 2, 0.5);
    let csv = dir.path().join("f.csv");
    write_frame_csv(&csv, &frame).unwrap();
    assert_eq!(
        std::fs::read(&csv).unwrap(),
        std::fs::read(dir.path().join("f.CSV")).unwrap()
    );
    let error = write_frame(&dir.path().join("f.txt"), &frame).unwrap_err();
    assert!(
        matches!(&error, Error::Parse { msg, .. } if msg.contains("frame file type")),
        "{error}"
    );
    assert!(!dir.path().join("f.txt").exists());
}

#[test]
fn mismatched_lengths_and_bad_times_are_usage_errors_and_write_nothing() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(4, 2);
    let short = &spheres.radii[..3];
    let other = Spheres::new(5, 2).with_history();
    let frames = [
        Frame {
            angular_velocities: &spheres.angular_velocities[1..],
            ..spheres.frame(1, 0.1)
        },
        Frame {
            contacts: other.contacts.as_deref(),
            ..spheres.frame(1, 0.1)
        },
        Frame {
            radii: short,
            ..spheres.frame(1, 0.1)
        },
        Frame {
            velocities: &spheres.velocities[1..],
            ..spheres.frame(1, 0.1)
        },
        Frame {
            materials: &spheres.materials[1..],
            ..spheres.frame(1, 0.1)
        },
        Frame {
            ids: Some(&[0, 1, 2]),
            ..spheres.frame(1, 0.1)
        },
        Frame {
            positions: &spheres.positions[..0],
            position_residuals: &[],
            ..spheres.frame(1, 0.1)
        },
        spheres.frame(1, f64::NAN),
        spheres.frame(1, f64::INFINITY),
    ];
    let mut series = FrameSeries::create(&dir.path().join("out")).unwrap();
    for frame in &frames {
        let vtu = write_vtu(&dir.path().join("f.vtu"), frame);
        assert!(matches!(vtu, Err(Error::Usage(_))), "{vtu:?}");
        let csv = write_frame_csv(&dir.path().join("f.csv"), frame);
        assert!(matches!(csv, Err(Error::Usage(_))), "{csv:?}");
        let written = series.write(frame, true);
        assert!(matches!(written, Err(Error::Usage(_))), "{written:?}");
    }
    assert_eq!(names(dir.path()), ["out"]);
    assert_eq!(names(series.dir()), [SERIES_INDEX]);
    assert!(read_pvd(&series.index_path()).is_empty());
}

// ----------------------------------------------------------------------------------------------
// series.pvd
// ----------------------------------------------------------------------------------------------

#[test]
fn the_index_lists_frames_in_step_order_with_their_times() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("run/frames");
    let mut series = FrameSeries::create(&out).unwrap();
    assert!(read_pvd(&series.index_path()).is_empty());
    let spheres = Spheres::new(9, 11);
    let times = [(0, 0.0), (100, 0.25), (200, 0.5), (50, 0.125), (100, 0.3)];
    for (k, &(step, time)) in times.iter().enumerate() {
        let path = series.write(&spheres.frame(step, time), k == 1).unwrap();
        assert_eq!(path, out.join(format!("frame_{step:08}.vtu")));
        check_vtu(&path, &spheres, step, time);
    }
    // Sorted by step; the second frame of step 100 replaced the first.
    let want = [(0.0, 0), (0.125, 50), (0.3, 100), (0.5, 200)];
    let listed = read_pvd(&series.index_path());
    let want_listed: Vec<(f64, String)> = want
        .iter()
        .map(|&(t, s)| (t, format!("frame_{s:08}.vtu")))
        .collect();
    assert_eq!(listed, want_listed);
    let entries: Vec<SeriesEntry> = want
        .iter()
        .map(|&(time, step)| SeriesEntry {
            step,
            time,
            pieces: false,
        })
        .collect();
    assert_eq!(series.entries(), entries);
    for (_, file) in &listed {
        assert!(out.join(file).is_file());
    }
    assert_eq!(
        names(&out),
        [
            "frame_00000000.vtu",
            "frame_00000050.vtu",
            "frame_00000100.csv",
            "frame_00000100.vtu",
            "frame_00000200.vtu",
            SERIES_INDEX
        ]
    );
}

#[test]
fn resuming_drops_later_frames_from_the_index() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("frames");
    let spheres = Spheres::new(3, 5);
    let mut series = FrameSeries::create(&out).unwrap();
    for step in [0, 100, 200, 300] {
        series
            .write(&spheres.frame(step, step as f64 * 1e-3), false)
            .unwrap();
    }
    drop(series);

    let mut resumed = FrameSeries::open_for_resume(&out, 250).unwrap();
    let steps = |s: &FrameSeries| s.entries().iter().map(|e| e.step).collect::<Vec<_>>();
    assert_eq!(steps(&resumed), [0, 100, 200]);
    assert_eq!(resumed.entries()[2].time, 0.2);
    // The index on disk already says so.
    let listed: Vec<String> = read_pvd(&out.join(SERIES_INDEX))
        .into_iter()
        .map(|(_, f)| f)
        .collect();
    assert_eq!(
        listed,
        [
            "frame_00000000.vtu",
            "frame_00000100.vtu",
            "frame_00000200.vtu"
        ]
    );
    resumed.write(&spheres.frame(300, 0.31), false).unwrap();
    assert_eq!(steps(&resumed), [0, 100, 200, 300]);
    assert_eq!(read_pvd(&out.join(SERIES_INDEX))[3].0, 0.31);

    // A resume step on a frame keeps that frame.
    assert_eq!(
        steps(&FrameSeries::open_for_resume(&out, 100).unwrap()),
        [0, 100]
    );
    assert_eq!(steps(&FrameSeries::open_for_resume(&out, 0).unwrap()), [0]);
    // No index (a run that wrote no frames): a new, empty series.
    let fresh = dir.path().join("no_frames_yet");
    let started = FrameSeries::open_for_resume(&fresh, 10).unwrap();
    assert!(started.entries().is_empty());
    assert!(read_pvd(&fresh.join(SERIES_INDEX)).is_empty());
}

#[test]
fn a_foreign_index_is_a_parse_error() {
    let dir = TempDir::new().unwrap();
    let index = dir.path().join(SERIES_INDEX);
    for text in [
        "<VTKFile type=\"UnstructuredGrid\"/>",
        "<VTKFile type=\"Collection\"><Collection>\n<DataSet timestep=\"x\" file=\"frame_1.vtu\"/>",
        "<VTKFile type=\"Collection\"><Collection>\n<DataSet timestep=\"1\" file=\"other.vtu\"/>",
        "<VTKFile type=\"Collection\"><Collection>\n<DataSet file=\"frame_1.vtu\"/>",
    ] {
        std::fs::write(&index, text).unwrap();
        let err = FrameSeries::open_for_resume(dir.path(), 5).unwrap_err();
        assert!(matches!(err, Error::Parse { .. }), "{text}: {err:?}");
        assert_eq!(
            std::fs::read_to_string(&index).unwrap(),
            text,
            "left as it was"
        );
    }
}

// ----------------------------------------------------------------------------------------------
// Failing writes
// ----------------------------------------------------------------------------------------------

#[test]
fn writing_under_a_file_fails_cleanly() {
    let dir = TempDir::new().unwrap();
    let file = dir.path().join("plain");
    std::fs::write(&file, "x").unwrap();
    let spheres = Spheres::new(5, 9);
    let frame = spheres.frame(1, 0.0);
    let err = write_vtu(&file.join("f.vtu"), &frame).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert!(write_frame_csv(&file.join("f.csv"), &frame).is_err());
    let err = FrameSeries::create(&file).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert!(FrameSeries::create(&file.join("sub")).is_err());
    assert_eq!(names(dir.path()), ["plain"]);
}

#[test]
fn a_frame_that_cannot_be_written_stays_out_of_the_index() {
    let dir = TempDir::new().unwrap();
    let mut series = FrameSeries::create(dir.path()).unwrap();
    let spheres = Spheres::new(5, 4);
    series.write(&spheres.frame(0, 0.0), false).unwrap();
    let before = std::fs::read(series.index_path()).unwrap();

    // A directory where the frame should go: the frame fails, the index is untouched.
    std::fs::create_dir(dir.path().join("frame_00000010.vtu")).unwrap();
    assert!(series.write(&spheres.frame(10, 1.0), false).is_err());
    // The same for the CSV twin: the .vtu is whole, but the index does not name it.
    std::fs::create_dir(dir.path().join("frame_00000020.csv")).unwrap();
    assert!(series.write(&spheres.frame(20, 2.0), true).is_err());
    assert_eq!(std::fs::read(series.index_path()).unwrap(), before);
    assert_eq!(series.entries().len(), 1);
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );

    // An index that cannot be replaced: an error, and the entries stay as they were.
    std::fs::remove_file(series.index_path()).unwrap();
    std::fs::create_dir(series.index_path()).unwrap();
    let err = series.write(&spheres.frame(30, 3.0), false).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert_eq!(series.entries().len(), 1);
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
}

#[cfg(unix)]
#[test]
fn a_read_only_directory_fails_cleanly() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new().unwrap();
    let out: PathBuf = dir.path().join("ro");
    let mut series = FrameSeries::create(&out).unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o555)).unwrap();
    let probe = out.join("probe");
    if std::fs::write(&probe, "").is_ok() {
        // Root (as in CI containers) writes anyway; the other failure tests still run.
        std::fs::remove_file(&probe).unwrap();
        eprintln!("note: read-only directories are writable here (root?); not tested");
        return;
    }
    let spheres = Spheres::new(2, 8);
    let err = series.write(&spheres.frame(0, 0.0), true).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("frame_00000000.vtu"), "{err}");
    assert_eq!(names(&out), [SERIES_INDEX]);
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o755)).unwrap();
}

// ----------------------------------------------------------------------------------------------
// Speed (opt-in): cargo test --release --test frames -- --ignored --nocapture
// ----------------------------------------------------------------------------------------------

#[test]
#[ignore = "timing; run in release"]
fn a_million_sphere_frame_writes_fast() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(1_000_000, 12);
    let frame = spheres.frame(1, 0.5);
    let path = dir.path().join("big.vtu");
    let mut times = Vec::new();
    for _ in 0..5 {
        let start = std::time::Instant::now();
        write_vtu(&path, &frame).unwrap();
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let size = std::fs::metadata(&path).unwrap().len();
    eprintln!(
        "1M spheres: {:.1} ms median (min {:.1} ms), {:.1} MB",
        times[2] * 1e3,
        times[0] * 1e3,
        size as f64 / 1e6
    );
    check_vtu(&path, &spheres, 1, 0.5);
    let start = std::time::Instant::now();
    write_frame_csv(&dir.path().join("big.csv"), &frame).unwrap();
    eprintln!(
        "1M spheres CSV: {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
}

// ----------------------------------------------------------------------------------------------
// Sphere files with motion
// ----------------------------------------------------------------------------------------------

/// A `.npy` of `rows` (float32, C order), as NumPy writes it.
fn write_npy(path: &Path, rows: &[Vec<f32>]) {
    use npyz::WriterBuilder;
    let columns = rows.first().map_or(4, Vec::len) as u64;
    let file = std::fs::File::create(path).unwrap();
    let mut npy = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[rows.len() as u64, columns])
        .writer(std::io::BufWriter::new(file))
        .begin_nd()
        .unwrap();
    npy.extend(rows.iter().flatten().copied()).unwrap();
    npy.finish().unwrap();
}

#[test]
fn sphere_files_of_4_7_and_10_columns_read_back_their_motion_and_materials() {
    let dir = TempDir::new().unwrap();
    let spheres = Spheres::new(23, 5);
    let finite = |v: [f32; 3]| v.map(|x| if x.abs() < 1e30 { x } else { 1.0 });
    let rows: Vec<Vec<f32>> = (0..23)
        .map(|i| {
            let [x, y, z] = finite(spheres.positions[i]);
            let r = spheres.radii[i].clamp(1e-6, 1e6);
            let [vx, vy, vz] = spheres.velocities[i];
            let [wx, wy, wz] = spheres.angular_velocities[i];
            vec![x, y, z, r, vx, vy, vz, wx, wy, wz]
        })
        .collect();
    // Each sphere's material, as the `material` column and the 11th of a `.npy` give it.
    let materials: Vec<u8> = (0..23).map(|i| [0, 3, 255][i % 3]).collect();
    for (columns, with_material) in [4, 7, 10].into_iter().flat_map(|c| [(c, false), (c, true)]) {
        let cut: Vec<Vec<f32>> = rows.iter().map(|r| r[..columns].to_vec()).collect();
        let mut header =
            ["x", "y", "z", "r", "vx", "vy", "vz", "wx", "wy", "wz"][..columns].join(",");
        let name = format!("s{columns}{}", if with_material { "m" } else { "" });
        let csv = dir.path().join(format!("{name}.csv"));
        let mut text: Vec<String> = cut
            .iter()
            .map(|r| r.iter().map(f32::to_string).collect::<Vec<_>>().join(","))
            .collect();
        if with_material {
            header += ",material";
            for (line, m) in text.iter_mut().zip(&materials) {
                *line += &format!(",{m}");
            }
        }
        std::fs::write(&csv, format!("{header}\n{}\n", text.join("\n"))).unwrap();
        let mut files = vec![csv];
        // A `.npy` has the material as its 11th column only.
        if !with_material || columns == 10 {
            let npy = dir.path().join(format!("{name}.npy"));
            let wide: Vec<Vec<f32>> = match with_material {
                true => (cut.iter().zip(&materials))
                    .map(|(r, &m)| r.iter().copied().chain([m.into()]).collect())
                    .collect(),
                false => cut.clone(),
            };
            write_npy(&npy, &wide);
            files.push(npy);
        }
        for path in &files {
            let p = mochi::io::read_particles(path).unwrap();
            for (i, row) in rows.iter().enumerate() {
                let at = |k: usize| [row[k], row[k + 1], row[k + 2]];
                assert_eq!(p.positions[i], at(0), "{path:?} row {i}");
                assert_eq!(p.radii[i], row[3]);
                let v = if columns >= 7 { at(4) } else { [0.0; 3] };
                let w = if columns == 10 { at(7) } else { [0.0; 3] };
                assert_eq!((p.velocities[i], p.angular_velocities[i]), (v, w));
            }
            match with_material {
                true => assert_eq!(p.materials, materials, "{path:?}"),
                false => assert!(p.materials.is_empty(), "{path:?}"),
            }
            assert!(p.history.is_empty() && p.step == 0);
        }
    }
    // A frame CSV is such a file: its angular velocities come back bit for bit.
    let frame = dir.path().join("frame.csv");
    let rowed = Spheres {
        positions: rows.iter().map(|r| [r[0], r[1], r[2]]).collect(),
        radii: rows.iter().map(|r| r[3]).collect(),
        ..Spheres::new(23, 5)
    };
    write_frame_csv(&frame, &rowed.frame(1, 0.1)).unwrap();
    let p = mochi::io::read_particles(&frame).unwrap();
    assert_eq!(p.angular_velocities, rowed.angular_velocities);
    assert_eq!(p.velocities, rowed.velocities);
    assert_eq!(p.materials, rowed.materials);
    // So is a frame `.npy`, float64 N×11.
    let frame = dir.path().join("frame.npy");
    write_frame(&frame, &rowed.frame(1, 0.1)).unwrap();
    let p = mochi::io::read_particles(&frame).unwrap();
    assert_eq!(p.angular_velocities, rowed.angular_velocities);
    assert_eq!(p.materials, rowed.materials);
}

#[test]
fn sphere_files_with_bad_motion_columns_are_one_clear_error() {
    let dir = TempDir::new().unwrap();
    let error = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        mochi::io::read_particles(&path).unwrap_err().to_string()
    };
    // A header of another width: the error lists the three accepted ones.
    let e = error("a.csv", "x,y,z,r,vx,vy,vz,wx\n0,0,0,1,0,0,0,0\n");
    assert!(
        e.contains("a.csv") && e.contains("x,y,z,r, x,y,z,r,vx,vy,vz or x,y,z,r,vx,vy,vz,wx,wy,wz"),
        "{e}"
    );
    // A row short of the header's columns, and a non-finite angular velocity: file and line.
    let e = error("b.csv", "x,y,z,r,vx,vy,vz,wx,wy,wz\n0,0,0,1,0,0,0,0,0\n");
    assert!(e.contains("b.csv:2:") && e.contains("expected 10"), "{e}");
    let e = error(
        "c.csv",
        "x,y,z,r,vx,vy,vz,wx,wy,wz\n0,0,0,1,0,0,0,0,inf,0\n",
    );
    assert!(
        e.contains("c.csv:2:") && e.contains("angular velocity"),
        "{e}"
    );
    // A .npy of another width: the error names the three shapes.
    let npy = dir.path().join("d.npy");
    write_npy(&npy, &[vec![0.0, 0.0, 0.0, 1.0, 0.0]]);
    let e = mochi::io::read_particles(&npy).unwrap_err().to_string();
    assert!(
        e.contains("N×4") && e.contains("N×7") && e.contains("N×10"),
        "{e}"
    );
    write_npy(
        &npy,
        &[vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, f32::NAN, 0.0]],
    );
    let e = mochi::io::read_particles(&npy).unwrap_err().to_string();
    assert!(e.contains("row 0") && e.contains("angular velocity"), "{e}");
}

#[test]
fn a_material_that_is_not_a_whole_number_from_0_to_255_is_one_clear_error() {
    let dir = TempDir::new().unwrap();
    let error = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        mochi::io::read_particles(&path).unwrap_err().to_string()
    };
    // CSV: the file, the line and the value.
    for (k, bad) in ["1.5", "256", "-1", "nan", "inf"].into_iter().enumerate() {
        let name = format!("m{k}.csv");
        let e = error(
            &name,
            &format!("x,y,z,r,material\n0,0,0,1,0\n\n3,0,0,1,{bad}\n"),
        );
        assert!(
            e.contains(&format!("{name}:4:")) && e.contains("a whole number from 0 to 255"),
            "{e}"
        );
    }
    let e = error(
        "glass.csv",
        "x,y,z,r,vx,vy,vz,material\n0,0,0,1,0,0,0,glass\n",
    );
    assert!(
        e.contains("glass.csv:2:") && e.contains("column material: \"glass\" is not a number"),
        "{e}"
    );
    // A row without its material.
    let e = error("short.csv", "x,y,z,r,material\n0,0,0,1\n");
    assert!(
        e.contains("short.csv:2:") && e.contains("expected 5 columns (x,y,z,r,material)"),
        "{e}"
    );
    // The material elsewhere than last is no accepted header.
    let e = error("first.csv", "material,x,y,z,r\n0,0,0,0,1\n");
    assert!(
        e.contains("first.csv:1:") && e.contains("followed by ,material"),
        "{e}"
    );
    // .npy: the row of the bad value (0-based), and the accepted shapes.
    let npy = dir.path().join("m.npy");
    let row = |m: f32| vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, m];
    for bad in [0.5, 256.0, -1.0, f32::NAN] {
        write_npy(&npy, &[row(0.0), row(1.0), row(bad)]);
        let e = mochi::io::read_particles(&npy).unwrap_err().to_string();
        assert!(
            e.contains("m.npy") && e.contains("row 2 (0-based)") && e.contains("material"),
            "{e}"
        );
    }
    write_npy(&npy, &[vec![0.0, 0.0, 0.0, 1.0, 0.0]]);
    let e = mochi::io::read_particles(&npy).unwrap_err().to_string();
    assert!(e.contains("N×11 (and the material)"), "{e}");
}

#[test]
fn a_frame_in_pieces_reads_back_as_the_whole_frame_in_the_order_of_its_ids() {
    use mochi::io::{piece_folder, piece_path, read_frame, read_series_index};
    let dir = TempDir::new().unwrap();
    let n = 11;
    let positions: Vec<[f32; 3]> = (0..n)
        .map(|i| [i as f32 * 0.1, 0.5 - i as f32 * 0.01, 0.25])
        .collect();
    let residuals: Vec<[f32; 3]> = (0..n).map(|i| [1e-9 * i as f32, 0.0, -2e-9]).collect();
    let radii: Vec<f32> = (0..n).map(|i| 0.01 + 0.001 * i as f32).collect();
    let velocities: Vec<[f32; 3]> = (0..n).map(|i| [i as f32, -1.5, 0.0]).collect();
    let spins: Vec<[f32; 3]> = (0..n).map(|i| [0.0, 2.0, -(i as f32)]).collect();
    let materials: Vec<u8> = (0..n).map(|i| (i % 3) as u8).collect();
    let contacts: Vec<u32> = (0..n).map(|i| (i % 4) as u32).collect();
    let whole = Frame {
        time: 0.5,
        step: 40,
        positions: &positions,
        position_residuals: &residuals,
        radii: &radii,
        velocities: &velocities,
        angular_velocities: &spins,
        materials: &materials,
        contacts: Some(&contacts),
        clumps: None,
        ids: None,
    };
    let one = dir.path().join("whole.vtu");
    write_vtu(&one, &whole).unwrap();
    // Three processes' pieces, the spheres dealt out (the third holds none); an earlier write
    // of the step over four left a fourth.
    let out = dir.path().join("run");
    let mut series = FrameSeries::create(&out).unwrap();
    let owned: [Vec<u32>; 3] = [
        (0..n as u32).filter(|i| i % 3 != 1).rev().collect(),
        (0..n as u32).filter(|i| i % 3 == 1).collect(),
        Vec::new(),
    ];
    std::fs::create_dir_all(piece_folder(&out, 40)).unwrap();
    for (k, ids) in owned.iter().enumerate() {
        fn pick<T: Copy>(all: &[T], ids: &[u32]) -> Vec<T> {
            ids.iter().map(|&i| all[i as usize]).collect()
        }
        let (p, r, v) = (
            pick(&positions, ids),
            pick(&radii, ids),
            pick(&velocities, ids),
        );
        let (w, m, c) = (
            pick(&spins, ids),
            pick(&materials, ids),
            pick(&contacts, ids),
        );
        let lo = pick(&residuals, ids);
        let piece = Frame {
            positions: &p,
            position_residuals: &lo,
            radii: &r,
            velocities: &v,
            angular_velocities: &w,
            materials: &m,
            contacts: Some(&c),
            ids: Some(ids),
            ..whole
        };
        write_vtu(&piece_path(&out, 40, k), &piece).unwrap();
    }
    std::fs::write(piece_path(&out, 40, 3), b"stale").unwrap();
    let pvtu = series.add_pieces(40, 0.5, 3, true).unwrap();
    assert_eq!(pvtu, out.join("frame_00000040.pvtu"));
    assert!(
        !piece_path(&out, 40, 3).exists(),
        "the stale piece is removed"
    );
    let entry = SeriesEntry {
        step: 40,
        time: 0.5,
        pieces: true,
    };
    assert_eq!(read_series_index(&out.join(SERIES_INDEX)).unwrap(), [entry]);
    assert_eq!(entry.file_name(), "frame_00000040.pvtu");
    // The parallel file declares the pieces' arrays and names the pieces.
    let text = std::fs::read_to_string(&pvtu).unwrap();
    let document = roxmltree::Document::parse(&text).unwrap();
    let declared: Vec<&str> = (document.descendants())
        .filter(|n| n.has_tag_name("PDataArray"))
        .filter_map(|n| n.attribute("Name"))
        .collect();
    let want = [
        "radius",
        "velocity",
        "speed",
        "angular_velocity",
        "id",
        "material",
        "contacts",
        "Points",
    ];
    assert_eq!(declared, want);
    let sources: Vec<&str> = (document.descendants())
        .filter_map(|n| n.attribute("Source"))
        .collect();
    let names = (0..3).map(|k| format!("frame_00000040/frame_00000040_{k}.vtu"));
    assert_eq!(sources, names.collect::<Vec<_>>());
    // Read back: the whole frame, every array, in the order of the ids.
    let got = read_frame(&pvtu).unwrap();
    let expected = read_frame(&one).unwrap();
    assert_eq!(got.ids, (0..n as u32).collect::<Vec<_>>());
    assert_eq!(got, expected);
    assert_eq!(got.contacts, contacts);
    let exact =
        (positions.iter().zip(&residuals)).map(|(c, r)| std::array::from_fn(|k| join(c[k], r[k])));
    assert_eq!(got.exact_positions, exact.collect::<Vec<[f64; 3]>>());
    // A sphere in two pieces, and a piece missing, are errors naming the file.
    let first = std::fs::read(piece_path(&out, 40, 0)).unwrap();
    std::fs::write(piece_path(&out, 40, 2), &first).unwrap();
    let e = read_frame(&pvtu).unwrap_err().to_string();
    assert!(
        e.contains("frame_00000040.pvtu") && e.contains("twice"),
        "{e}"
    );
    std::fs::remove_file(piece_path(&out, 40, 1)).unwrap();
    let e = read_frame(&pvtu).unwrap_err().to_string();
    assert!(e.contains("frame_00000040_1.vtu"), "{e}");
    std::fs::write(
        &pvtu,
        "<VTKFile type=\"PUnstructuredGrid\"><PUnstructuredGrid/></VTKFile>",
    )
    .unwrap();
    let e = read_frame(&pvtu).unwrap_err().to_string();
    assert!(e.contains("no pieces"), "{e}");
}
