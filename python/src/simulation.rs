//! `mochi.Simulation`: a DEM run set up by the library's [`RunStart`] (the same function `mochi
//! simulate` uses), stepped from Python.
//!
//! Invariants: `step` counts the steps the stepper has taken (its particles' step); `now` is
//! `None` or the snapshot at `step` (the particles without their springs, each sphere's
//! contacts counted: read back once, dropped on every step), and `views` holds
//! only arrays made from `now` (dropped with it, and whenever the state is set); the arrays
//! handed out are read-only snapshots.

use crate::{Guarded, MochiError, guard, plain_array, to_py_err};
use mochi::SphereSet;
use mochi::dem::contacts::ContactData;
use mochi::dem::scene::{Overrides, SceneConfig, SceneFlags, SceneKind};
use mochi::dem::walls::spec::NewMotion;
use mochi::dem::{Energies, Motion, Particles, Snapshot};
use mochi::engines::{BackendChoice, Options};
use mochi::io;
use mochi::run::{FIRST_PROGRESS_STEPS, Run, RunStart, progress_steps};
use numpy::ndarray::{Array1, Array2, Dimension, Ix1, Ix2};
use numpy::{
    Element, IntoPyArray, PyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{IntoPyDict, PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple, PyType};
use std::ffi::CString;
use std::path::PathBuf;
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

/// The scene keys whose TOML values are arrays of tables (`[[wall]]`, `[[inflow]]`,
/// `[[outflow]]`, `[[materials]]`, `[[material_pairs]]` and its short form, `[[clump]]`, as
/// `dem::scene` documents them): a lone dict given for one is that array's one table.
const TABLE_ARRAYS: [&str; 7] = [
    "wall",
    "inflow",
    "outflow",
    "materials",
    "material_pairs",
    "material_pair",
    "clump",
];

/// Whether the dict `table` given for `key` is one table of a list: a key of
/// [`TABLE_ARRAYS`], or `material` with a `name` (a named material, `[[material]]`, where the
/// `[material]` table has no name).
fn one_of_a_list(key: &str, table: &toml::Table) -> bool {
    TABLE_ARRAYS.contains(&key) || (key == "material" && table.contains_key("name"))
}

/// A scene value from Python as TOML: bool, int, float, str, a path, a dict (a table, its keys
/// str), or a list or tuple of them (an array); a NumPy scalar or 0-d array as the Python scalar
/// it holds, a NumPy array as the nested lists of its values (a masked array only where no entry
/// is masked). `key` names the value in errors.
fn toml_value(key: &str, value: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    let py = value.py();
    let bad = |why: &str| PyValueError::new_err(format!("scene key {key:?}: {why}"));
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyInt>() {
        let int: i64 = value
            .extract()
            .map_err(|_| bad("the integer is outside the range of a 64-bit integer"))?;
        return Ok(toml::Value::Integer(int));
    }
    if value.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(value.extract()?));
    }
    if value.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(value.extract()?));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let items = value
            .try_iter()?
            .map(|item| toml_value(key, &item?))
            .collect::<PyResult<_>>()?;
        return Ok(toml::Value::Array(items));
    }
    if let Ok(dict) = value.cast::<PyDict>() {
        let mut table = toml::Table::new();
        for (field, item) in dict.iter() {
            let field: String = field
                .extract()
                .map_err(|_| bad("the keys of a dict (a table) must be str"))?;
            let item = toml_value(&format!("{key}.{field}"), &item)?;
            table.insert(field, item);
        }
        return Ok(toml::Value::Table(table));
    }
    static GENERIC: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    let array = value.cast::<PyUntypedArray>().ok();
    if array.is_some() || value.is_instance(GENERIC.import(py, "numpy", "generic")?)? {
        let plain = plain_array(&format!("scene key {key:?}"), value)?;
        let scalar = array.is_none_or(|a| a.ndim() == 0);
        let python = plain.call_method0(if scalar { "item" } else { "tolist" })?;
        return toml_value(key, &python);
    }
    if let Ok(path) = value.extract::<PathBuf>() {
        let text = path
            .to_str()
            .ok_or_else(|| bad("the path is not valid UTF-8"))?;
        return Ok(toml::Value::String(text.to_owned()));
    }
    Err(bad(&format!(
        "a value of type {} cannot be a scene value (use bool, int, float, str, a path, a dict, \
         a list of them, or NumPy scalars and arrays)",
        value.get_type().name()?
    )))
}

/// Whether the scene field `key` takes an integer and not the float `x` (a whole number): the
/// library reads the field from the float as an error and from the integer as a value.
fn wants_integer(key: &str, x: f64) -> bool {
    let read = |value: toml::Value| {
        let field = toml::Table::from_iter([(key.to_owned(), value)]);
        SceneConfig::parse(None, None, &Overrides::from_table(field))
    };
    x.fract() == 0.0
        && x.abs() < 9.2e18
        && read(toml::Value::Float(x)).is_err()
        && read(toml::Value::Integer(x as i64)).is_ok()
}

/// A scene dict as the table of the fields it sets (the scene reads it as it reads a file's);
/// a dict or a list of dicts as a table or an array of them (a lone dict of a list as an array
/// of one, [`one_of_a_list`]). A whole float for a field that takes an integer is
/// refused here, naming both, as a scene file's is (`spheres = 3e8`).
fn overrides(scene: &Bound<'_, PyDict>) -> PyResult<Overrides> {
    let fields = scene
        .iter()
        .map(|(key, value)| {
            let key: String = key
                .extract()
                .map_err(|_| PyTypeError::new_err("scene keys must be str"))?;
            if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Err(PyValueError::new_err(format!(
                    "scene key {key:?} is not a field name"
                )));
            }
            let value = match toml_value(&key, &value)? {
                toml::Value::Table(table) if one_of_a_list(&key, &table) => {
                    toml::Value::Array(vec![toml::Value::Table(table)])
                }
                toml::Value::Float(x) if wants_integer(&key, x) => {
                    return Err(PyValueError::new_err(format!(
                        "scene key {key:?} takes an integer, not the float {x:?} (pass {})",
                        x as i64
                    )));
                }
                value => value,
            };
            Ok((key, value))
        })
        .collect::<PyResult<toml::Table>>()?;
    Ok(Overrides::from_table(fields))
}

/// The overrides of `keys` (a dict of scene keys given as keyword arguments; `None`: none).
fn keyword_overrides(keys: Option<&Bound<'_, PyDict>>) -> PyResult<Overrides> {
    keys.map_or(Ok(Overrides::default()), overrides)
}

/// A library error of a run set up from Python: the scene's own source, where it is the
/// scene dict or the keyword arguments (which the library calls the command line), named so.
fn scene_err(error: mochi::Error) -> PyErr {
    match error {
        mochi::Error::Parse { path, msg, .. } if path.as_os_str() == "command line" => {
            PyValueError::new_err(format!("scene: {msg}"))
        }
        other => to_py_err(other),
    }
}

/// The start of a new run from `scene` (a dict of scene keys, a TOML file, or `None`) and
/// `keys` (scene keys given as keyword arguments, set over it).
fn new_start(
    py: Python<'_>,
    scene: Option<&Bound<'_, PyAny>>,
    keys: Option<&Bound<'_, PyDict>>,
) -> PyResult<RunStart> {
    let flags = SceneFlags::default();
    let (file, overrides) = match scene {
        None => (None, Overrides::default()),
        Some(scene) => match scene.cast::<PyDict>() {
            Ok(dict) => (None, overrides(dict)?),
            Err(_) => {
                let path: PathBuf = scene.extract().map_err(|_| {
                    PyTypeError::new_err(
                        "scene must be a dict of scene keys, a path to a scene TOML, the name \
                         of a scene (\"pour\", \"hopper\", …) or None",
                    )
                })?;
                // A scene's name where no file has it: `Simulation("hopper", spheres=500)`; a
                // bare word that names neither is refused as an unknown scene.
                let bare = path.extension().is_none() && path.components().count() == 1;
                match path.to_str().map(str::parse::<SceneKind>) {
                    Some(Ok(kind)) if !path.exists() => {
                        let scene = toml::Value::String(kind.name().to_owned());
                        let table = toml::Table::from_iter([("scene".to_owned(), scene)]);
                        (None, Overrides::from_table(table))
                    }
                    Some(Err(unknown)) if bare && !path.exists() => {
                        return Err(PyValueError::new_err(format!(
                            "{unknown}; nor is there a scene file {}",
                            path.display()
                        )));
                    }
                    _ => (Some(path), Overrides::default()),
                }
            }
        },
    };
    let overrides = overrides.then(keyword_overrides(keys)?);
    py.detach(|| RunStart::new(file.as_deref(), &flags, &overrides))
        .map_err(scene_err)
}

/// The arrays of [`Simulation::from_arrays`].
struct SphereArrays<'a, 'py> {
    positions: &'a Bound<'py, PyAny>,
    radii: &'a Bound<'py, PyAny>,
    velocities: Option<&'a Bound<'py, PyAny>>,
    angular_velocities: Option<&'a Bound<'py, PyAny>>,
    materials: Option<&'a Bound<'py, PyAny>>,
}

/// `array` as a C-ordered NumPy array of `dtype` (a copy only where it is not one), refused
/// with `what` named where it is not an array of numbers of `shape` (`None`: any length).
fn numbers<'py>(
    array: &Bound<'py, PyAny>,
    what: &str,
    dtype: &str,
    shape: &[Option<usize>],
) -> PyResult<Bound<'py, PyAny>> {
    let py = array.py();
    let plain = plain_array(what, array)?;
    let numpy = py.import("numpy")?;
    let converted = numpy
        .call_method(
            "ascontiguousarray",
            (&plain,),
            Some(&[("dtype", dtype)].into_py_dict(py)?),
        )
        .map_err(|e| PyTypeError::new_err(format!("{what}: not an array of numbers ({e})")))?;
    let got: Vec<usize> = converted.getattr("shape")?.extract()?;
    let fits = got.len() == shape.len()
        && got
            .iter()
            .zip(shape)
            .all(|(g, s)| s.is_none_or(|s| s == *g));
    if !fits {
        let want: Vec<String> = shape
            .iter()
            .map(|s| s.map_or("N".to_owned(), |s| s.to_string()))
            .collect();
        return Err(PyValueError::new_err(format!(
            "{what} must have shape ({}), not {got:?}",
            want.join(", ")
        )));
    }
    Ok(converted)
}

/// `array` as rows of three numbers of `dtype` (`T`), `n` of them where given (`what` names it
/// in errors).
fn rows_of<T: Element + Copy>(
    array: &Bound<'_, PyAny>,
    what: &str,
    dtype: &str,
    n: Option<usize>,
) -> PyResult<Vec<[T; 3]>> {
    let array = numbers(array, what, dtype, &[n, Some(3)])?;
    let rows: PyReadonlyArray2<'_, T> = array.extract()?;
    Ok(rows
        .as_array()
        .rows()
        .into_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

impl SphereArrays<'_, '_> {
    /// The particles the arrays describe, at rest where no velocities are given.
    fn particles(&self) -> PyResult<Particles> {
        let positions: Vec<[f64; 3]> = rows_of(self.positions, "positions", "float64", None)?;
        let n = positions.len();
        let radii = numbers(self.radii, "radii", "float32", &[Some(n)])?;
        let radii: PyReadonlyArray1<'_, f32> = radii.extract()?;
        let centres: Vec<[f32; 3]> = positions
            .iter()
            .enumerate()
            .map(
                |(i, &c)| match c.iter().any(|x| x.is_finite() && (*x as f32).is_infinite()) {
                    true => Err(PyValueError::new_err(format!(
                        "sphere {i}: position {c:?} is outside the range of float32 (magnitudes \
                         up to {:e}), in which mochi computes",
                        f32::MAX
                    ))),
                    false => Ok(c.map(|x| x as f32)),
                },
            )
            .collect::<PyResult<_>>()?;
        let spheres = SphereSet::new(centres, radii.as_array().to_vec()).map_err(to_py_err)?;
        let mut particles = Particles::at_rest(&spheres).map_err(to_py_err)?;
        for (i, &c) in positions.iter().enumerate() {
            particles.set_exact_position(i, c).map_err(to_py_err)?;
        }
        let triples = |array: Option<&Bound<'_, PyAny>>, what: &str| {
            array
                .map(|a| rows_of::<f32>(a, what, "float32", Some(n)))
                .transpose()
        };
        if let Some(v) = triples(self.velocities, "velocities")? {
            particles.velocities = v;
        }
        if let Some(w) = triples(self.angular_velocities, "angular_velocities")? {
            particles.angular_velocities = w;
        }
        if let Some(m) = self.materials {
            let m = numbers(m, "materials", "int64", &[Some(n)])?;
            let m: PyReadonlyArray1<'_, i64> = m.extract()?;
            particles.materials = m
                .as_array()
                .iter()
                .enumerate()
                .map(|(i, &k)| {
                    u8::try_from(k).map_err(|_| {
                        PyValueError::new_err(format!(
                            "sphere {i}: material {k} is not an index of a material (0 to 255)"
                        ))
                    })
                })
                .collect::<PyResult<_>>()?;
        }
        Ok(particles)
    }
}

/// A library error of a call with a bad argument: a usage error is a `ValueError` too.
fn usage_err(error: mochi::Error) -> PyErr {
    match error {
        mochi::Error::Usage(msg) => PyValueError::new_err(msg),
        other => to_py_err(other),
    }
}

/// Makes `array` read-only (a snapshot whose writes would be lost).
fn read_only<T>(array: &Bound<'_, T>) -> PyResult<()> {
    let py = array.py();
    array
        .as_any()
        .call_method("setflags", (), Some(&[("write", false)].into_py_dict(py)?))?;
    Ok(())
}

/// A copy of `values`, allocated fallibly (`MemoryError` naming `what`).
fn copied<T: Copy>(values: &[T], what: &str) -> PyResult<Vec<T>> {
    let mut copy = Vec::new();
    copy.try_reserve_exact(values.len()).map_err(|_| {
        PyMemoryError::new_err(format!(
            "{what}: out of memory ({} bytes needed)",
            std::mem::size_of_val(values)
        ))
    })?;
    copy.extend_from_slice(values);
    Ok(copy)
}

/// `values` (three per sphere) as an `(N, 3)` array (float32, or float64 for positions).
fn triples<'py, T: Element + Copy>(
    py: Python<'py>,
    values: &[[T; 3]],
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let flat = copied(values.as_flattened(), "an array of the spheres")?;
    Array2::from_shape_vec((values.len(), 3), flat)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// `values` (one per sphere) as an `(N,)` array.
fn singles<'py, T: Element + Copy>(
    py: Python<'py>,
    values: &[T],
) -> PyResult<Bound<'py, PyArray1<T>>> {
    Ok(Array1::from_vec(copied(values, "an array of the spheres")?).into_pyarray(py))
}

/// Each sphere's material (`(N,)` uint8): its index in the scene's materials, 0 for every
/// sphere where the particles keep none (one material).
fn materials<'py>(py: Python<'py>, p: &Particles) -> PyResult<Bound<'py, PyArray1<u8>>> {
    match p.materials.is_empty() {
        true => {
            let mut zeros = Vec::new();
            zeros.try_reserve_exact(p.len()).map_err(|_| {
                PyMemoryError::new_err(format!(
                    "the materials of {} spheres: out of memory ({} bytes needed)",
                    p.len(),
                    p.len()
                ))
            })?;
            zeros.resize(p.len(), 0);
            Ok(Array1::from_vec(zeros).into_pyarray(py))
        }
        false => singles(py, &p.materials),
    }
}

/// Where [`Views`] keeps one array.
type Slot<T, D> = fn(&mut Views) -> &mut Option<Py<PyArray<T, D>>>;

/// How one array of [`Views`] is made from the particles.
type Make<'py, T, D> = fn(Python<'py>, &Particles) -> PyResult<Bound<'py, PyArray<T, D>>>;

/// Where the spheres are (`(N, 3)` float64): each centre plus its residual.
fn positions<'py>(py: Python<'py>, p: &Particles) -> PyResult<Bound<'py, PyArray2<f64>>> {
    triples(py, &p.exact_positions().map_err(to_py_err)?)
}

/// The arrays of the particles now that a `Simulation` has handed out, each made once: the same
/// read-only array for every read until the next step.
#[derive(Default)]
struct Views {
    positions: Option<Py<PyArray2<f64>>>,
    velocities: Option<Py<PyArray2<f32>>>,
    angular_velocities: Option<Py<PyArray2<f32>>>,
    radii: Option<Py<PyArray1<f32>>>,
    materials: Option<Py<PyArray1<u8>>>,
}

/// Reads a frame (`.vtu` as `write_frame` and `mochi simulate` write it or of another writer,
/// a `.pvtu` of pieces, its spheres in the order of their ids, `.csv` or `.npy`) into
/// a dict of NumPy arrays (`positions`, float64, `radii`, `velocities`, `angular_velocities`,
/// float32, `materials`, uint8: 0 for every sphere of a file without them) with its `step` and
/// `time` (`None` where the file does not say).
#[pyfunction]
pub fn read_frame(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyDict>> {
    guard("mochi.read_frame", || {
        let mut frame = py.detach(|| io::read_frame(&path)).map_err(to_py_err)?;
        // A file without materials: every sphere of the first.
        frame.materials.resize(frame.radii.len(), 0);
        let out = PyDict::new(py);
        out.set_item("positions", triples(py, &frame.exact_positions)?)?;
        out.set_item("radii", Array1::from_vec(frame.radii).into_pyarray(py))?;
        out.set_item("velocities", triples(py, &frame.velocities)?)?;
        out.set_item(
            "angular_velocities",
            triples(py, &frame.angular_velocities)?,
        )?;
        out.set_item(
            "materials",
            Array1::from_vec(frame.materials).into_pyarray(py),
        )?;
        out.set_item("step", frame.step)?;
        out.set_item("time", frame.time)?;
        Ok(out)
    })
}

/// A DEM simulation: a scene's spheres under gravity, walls and contact forces.
///
/// `scene` is a dict of scene keys (as in a scene TOML, in its tables or by their short
/// forms, or `mochi simulate --set`), a path to a scene TOML, or `None` for the default
/// scene (`pour`). A dict value is a TOML table, whose keys are set one by one (`{"material":
/// {"friction": 0.3}}` keeps the material's other keys), and a list of dicts an array of
/// tables: `{"inflow": [{"lo": [...], "hi": [...], "rate": 2000, "sphere_radius": 0.004}]}`
/// is `[[inflow]]`, and a lone dict for `wall`, `inflow`, `outflow`, `materials`,
/// `material_pairs` or `clump` (or `material` with a `name`) is an array of one (grains of
/// clumps of spheres: `{"clump": {"shape": "tetrahedron"}}`). Several materials:
/// `{"materials": [{"name": "glass", "density": 2500}, {"name": "steel", "density": 7800}],
/// "box_material": "steel", "inflow": {..., "material": "glass"}}`; an input file's
/// `material` column gives each sphere's (its index in that list, from 0).
/// Scene keys may also be keyword arguments (`Simulation(scene="freefall", spheres=500,
/// friction=0.3)`), set over `scene`. NumPy scalars and 0-d arrays count as the
/// Python scalars they hold, NumPy arrays as lists. A whole float for a key that takes an
/// integer (`"spheres": 3e8`) is refused, as in a scene file: pass an int. Bad keys or values
/// raise `ValueError` naming the key; the run's warnings (overlaps, coarse coordinates,
/// coincident centres) are `UserWarning`s. `close()` (or the end of a `with` block)
/// lets the backend and its device memory go.
///
/// `positions` (float64), `velocities`, `angular_velocities` and `radii` (float32) and
/// `materials` (uint8) are in input order: read-only snapshots of the step they were read at (the same array object until the
/// next `step`; a later step does not change them). Writing into one raises `ValueError`;
/// set `positions`, `velocities` or `angular_velocities` whole (`sim.velocities = v`)
/// to change the state before the next step.
///
/// Between steps a script may also set `gravity`, `external_forces` and
/// `external_torques` (`(N, 3)`, added to each sphere every step until changed; GPU backends
/// keep them on the device), the material keys (`change(friction=0.3)`) and a wall's motion
/// (`set_wall_motion`). `contact_data()` lists the contacts now (pairs, normal and
/// tangential forces, overlaps), `forces` and `torques` their sums on each sphere: what the
/// next step applies, evaluated on every backend by the Rust contact law.
///
#[pyclass(module = "mochi")]
pub struct Simulation {
    /// Only ever reached through `&mut self` (`Mutex::get_mut`, no locking): the mutex only
    /// makes the class `Sync`, as pyo3 requires. `None` once closed.
    run: Mutex<Option<Run>>,
    step: u64,
    contacts: u64,
    now: Option<Snapshot>,
    views: Views,
    /// The contacts of `now`, where asked for since the last step.
    touching: Option<ContactData>,
    /// What a call that panicked said ([`Guarded`]).
    broken: Option<String>,
}

/// The run in `run`, or `MochiError` once the simulation is closed.
fn open_run(run: &mut Mutex<Option<Run>>) -> PyResult<&mut Run> {
    let run = run.get_mut().unwrap_or_else(PoisonError::into_inner);
    run.as_mut()
        .ok_or_else(|| MochiError::new_err("the simulation is closed (close() was called)"))
}

impl Guarded for Simulation {
    fn broken(&mut self) -> &mut Option<String> {
        &mut self.broken
    }
}

impl Simulation {
    /// Opens `start` on `backend` and issues the run's warnings as Python warnings.
    fn open(py: Python<'_>, start: RunStart, backend: &str) -> PyResult<Self> {
        let choice: BackendChoice = backend.parse().map_err(PyValueError::new_err)?;
        let processes = mochi::distributed::launched_processes();
        if processes > 1 {
            return Err(MochiError::new_err(format!(
                "this Python process is one of {processes} that an MPI launcher started, and \
                 mochi's Python package runs a simulation in one process (each of them would \
                 run the whole scene): run Python without mpirun, or run the scene with \
                 `mpirun -np {processes} mochi simulate` (mochi built with the mpi feature)"
            )));
        }
        let run = py
            .detach(|| start.open(choice, &Options::default()))
            .map_err(to_py_err)?;
        let warnings = [
            run.overlap_warning(),
            run.coarse_warning.clone(),
            run.coincident_warning(),
            run.flow_warning.clone(),
        ];
        for warning in warnings.into_iter().flatten() {
            let message = CString::new(warning).unwrap_or_default();
            PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 2)?;
        }
        Ok(Simulation {
            step: run.first_step,
            run: Mutex::new(Some(run)),
            contacts: 0,
            now: None,
            views: Views::default(),
            touching: None,
            broken: None,
        })
    }

    /// The run, or `MochiError` once the simulation is closed.
    fn run_mut(&mut self) -> PyResult<&mut Run> {
        open_run(&mut self.run)
    }

    /// The particles now (read back from the backend once per step).
    fn particles(&mut self, py: Python<'_>) -> PyResult<&Particles> {
        if self.now.is_none() {
            let stepper = &mut self.run_mut()?.stepper;
            let now = py.detach(|| stepper.snapshot()).map_err(to_py_err)?;
            self.now = Some(now);
        }
        Ok(&self.now.as_ref().expect("read back above").particles)
    }

    /// The spheres now: the particles' count where they were read back since the last step,
    /// else the start's count with the flows' insertions and removals since (no read-back).
    fn spheres_now(&mut self) -> PyResult<usize> {
        if let Some(now) = &self.now {
            return Ok(now.particles.len());
        }
        let run = self.run_mut()?;
        Ok(match run.stepper.flow_counts() {
            Some(flows) => {
                let inserted = run.spheres as u64 + flows.inserted;
                inserted.saturating_sub(flows.removed) as usize
            }
            None => run.spheres,
        })
    }

    /// The array in `slot` of [`Self::views`], made by `make` from the particles now and set
    /// read-only where none is yet.
    fn view<'py, T: Element, D: Dimension>(
        &mut self,
        py: Python<'py>,
        slot: Slot<T, D>,
        make: Make<'py, T, D>,
    ) -> PyResult<Bound<'py, PyArray<T, D>>> {
        if let Some(array) = slot(&mut self.views) {
            return Ok(array.bind(py).clone());
        }
        let array = make(py, self.particles(py)?)?;
        read_only(&array)?;
        *slot(&mut self.views) = Some(array.clone().unbind());
        Ok(array)
    }

    /// The spheres' kinetic energy now (read back once per step).
    fn energies(&mut self, py: Python<'_>) -> PyResult<Energies> {
        self.particles(py)?;
        let densities = &self.run_mut()?.params.materials.densities;
        let densities = densities.clone();
        Ok(self
            .now
            .as_ref()
            .expect("read back above")
            .particles
            .energies(&densities))
    }

    /// `array` as three float32 values per sphere now (`what` names it in errors).
    fn triples_of(&mut self, array: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f32; 3]>> {
        rows_of(array, what, "float32", Some(self.spheres_now()?))
    }

    /// Writes `motion` into the run's step (the interpreter lock released); what was read back
    /// is dropped.
    fn set_motion(&mut self, py: Python<'_>, motion: &Motion<'_>) -> PyResult<()> {
        let run = self.run_mut()?;
        let set = py.detach(|| run.set_motion(motion));
        self.stepped();
        set.map_err(usage_err)
    }

    /// Drops what was read back for the last step.
    fn stepped(&mut self) {
        self.now = None;
        self.views = Views::default();
        self.touching = None;
    }

    /// The contacts now (evaluated once per step, the interpreter lock released).
    fn touching(&mut self, py: Python<'_>) -> PyResult<&ContactData> {
        if self.touching.is_none() {
            let run = self.run_mut()?;
            let data = py.detach(|| run.contact_data()).map_err(to_py_err)?;
            self.touching = Some(data);
        }
        Ok(self.touching.as_ref().expect("evaluated above"))
    }

    /// Replaces the run's external forces (`forces`) or torques with `rows` (`None`: none).
    fn set_loads(
        &mut self,
        py: Python<'_>,
        rows: Option<&Bound<'_, PyAny>>,
        forces: bool,
    ) -> PyResult<()> {
        let what = if forces {
            "external_forces"
        } else {
            "external_torques"
        };
        let rows = match rows {
            Some(array) if !array.is_none() => self.triples_of(array, what)?,
            _ => Vec::new(),
        };
        let run = self.run_mut()?;
        let mut loads = run.external_loads().clone();
        match forces {
            true => loads.forces = rows,
            false => loads.torques = rows,
        }
        py.detach(|| run.set_external_loads(loads))
            .map_err(usage_err)
    }

    /// The run's external forces or torques as an `(N, 3)` float32 array (zeros where none).
    fn loads<'py>(&mut self, py: Python<'py>, forces: bool) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let n = self.spheres_now()?;
        let loads = self.run_mut()?.external_loads();
        let rows = if forces {
            &loads.forces
        } else {
            &loads.torques
        };
        let array = match rows.is_empty() {
            true => triples(py, &vec![[0.0f32; 3]; n])?,
            false => triples(py, rows)?,
        };
        read_only(&array)?;
        Ok(array)
    }
}

#[pymethods]
impl Simulation {
    /// Sets a run up from `scene` (a dict of scene keys, as in a scene TOML or `mochi simulate
    /// --set`; a path to a scene TOML; the name of a scene, `"hopper"`; or `None`, the default
    /// scene `pour`) and `keys` (scene keys as keyword arguments, set over it) on `backend`.
    #[new]
    #[pyo3(signature = (scene = None, backend = "auto", **keys))]
    fn new(
        py: Python<'_>,
        scene: Option<&Bound<'_, PyAny>>,
        backend: &str,
        keys: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        guard("mochi.Simulation()", || {
            let start = new_start(py, scene, keys)?;
            Simulation::open(py, start, backend)
        })
    }

    /// Sets a run up from arrays, no file: `positions` `(N, 3)` [m] and `radii` `(N,)` [m]
    /// (float32 or float64), with `velocities` and `angular_velocities` `(N, 3)` (zero where
    /// not given) and `materials` `(N,)` (indices of the scene's `materials`; 0 where not
    /// given), and any other scene keys as keyword arguments (the box, gravity, the material,
    /// walls, flows, …) on `backend`.
    #[classmethod]
    #[pyo3(signature = (
        positions,
        radii,
        *,
        velocities = None,
        angular_velocities = None,
        materials = None,
        backend = "auto",
        **keys
    ))]
    #[allow(clippy::too_many_arguments)]
    fn from_arrays(
        _cls: &Bound<'_, pyo3::types::PyType>,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        radii: &Bound<'_, PyAny>,
        velocities: Option<&Bound<'_, PyAny>>,
        angular_velocities: Option<&Bound<'_, PyAny>>,
        materials: Option<&Bound<'_, PyAny>>,
        backend: &str,
        keys: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        guard("mochi.Simulation.from_arrays", || {
            let arrays = SphereArrays {
                positions,
                radii,
                velocities,
                angular_velocities,
                materials,
            };
            let particles = arrays.particles()?;
            let overrides = keyword_overrides(keys)?;
            let start = py
                .detach(|| RunStart::of_particles(particles, &overrides))
                .map_err(scene_err)?;
            Simulation::open(py, start, backend)
        })
    }

    /// Resumes the run saved in the checkpoint at `path` on `backend`.
    #[classmethod]
    #[pyo3(signature = (path, backend = "auto"))]
    fn resume(
        _cls: &Bound<'_, pyo3::types::PyType>,
        py: Python<'_>,
        path: PathBuf,
        backend: &str,
    ) -> PyResult<Self> {
        guard("mochi.Simulation.resume", || {
            let start = py
                .detach(|| RunStart::resume(&path, &SceneFlags::default(), &Overrides::default()))
                .map_err(to_py_err)?;
            Simulation::open(py, start, backend)
        })
    }

    /// Takes `n` steps, in batches of about a quarter second with the interpreter lock
    /// released (the first of 10 steps); between batches Ctrl-C stops it (the steps taken so far count) and `progress`, if given, is
    /// called with the number of steps the batch took (an increment, as `tqdm`'s `update`
    /// takes it).
    #[pyo3(signature = (n, progress = None))]
    fn step(&mut self, py: Python<'_>, n: i64, progress: Option<Bound<'_, PyAny>>) -> PyResult<()> {
        let n = u64::try_from(n).map_err(|_| {
            PyValueError::new_err(format!("step takes a number of steps from 0, got {n}"))
        })?;
        self.guarded("Simulation.step", |sim| {
            let mut left = n;
            let mut next = FIRST_PROGRESS_STEPS;
            while left > 0 {
                let batch = left.min(next);
                let stepper = &mut sim.run_mut()?.stepper;
                let began = Instant::now();
                let advance = py.detach(|| stepper.advance(batch as u32));
                // Even a failed batch may have moved the state.
                sim.stepped();
                let advance = advance.map_err(to_py_err)?;
                next = progress_steps(batch, began.elapsed());
                sim.step += batch;
                sim.contacts = advance.contacts;
                left -= batch;
                if let Some(progress) = &progress {
                    progress.call1((batch,))?;
                }
                py.check_signals()?;
            }
            Ok(())
        })
    }

    /// Positions `(N, 3)` float64 [m], in input order: a read-only snapshot of this step.
    /// Each is where the step keeps its sphere (its `f32` centre plus the residual that holds
    /// what `f32` cannot: every step's displacement, however small, far from the origin).
    #[getter]
    fn positions<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.guarded("Simulation.positions", |sim| {
            sim.view::<f64, Ix2>(py, |v| &mut v.positions, positions)
        })
    }

    /// Velocities `(N, 3)` float32 [m/s], in input order: a read-only snapshot of this step.
    #[getter]
    fn velocities<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.guarded("Simulation.velocities", |sim| {
            sim.view::<f32, Ix2>(
                py,
                |v| &mut v.velocities,
                |py, p| triples(py, &p.velocities),
            )
        })
    }

    /// Moves the spheres to `positions` `(N, 3)` [m] (in input order, N the spheres now)
    /// before the next step; velocities, spins and contact history stay. A position outside
    /// the box by more than its own size is refused (with the box's walls).
    #[setter]
    fn set_positions(&mut self, py: Python<'_>, positions: &Bound<'_, PyAny>) -> PyResult<()> {
        self.guarded("Simulation.positions", |sim| {
            let n = sim.spheres_now()?;
            let rows: Vec<[f64; 3]> = rows_of(positions, "positions", "float64", Some(n))?;
            sim.set_motion(
                py,
                &Motion {
                    positions: Some(&rows),
                    ..Motion::default()
                },
            )
        })
    }

    /// Sets the spheres' velocities `(N, 3)` [m/s] (in input order) before the next step.
    #[setter]
    fn set_velocities(&mut self, py: Python<'_>, velocities: &Bound<'_, PyAny>) -> PyResult<()> {
        self.guarded("Simulation.velocities", |sim| {
            let rows = sim.triples_of(velocities, "velocities")?;
            sim.set_motion(
                py,
                &Motion {
                    velocities: Some(&rows),
                    ..Motion::default()
                },
            )
        })
    }

    /// Sets the spheres' angular velocities `(N, 3)` [rad/s] (in input order) before the
    /// next step; refused where the run's step does not turn its spheres (the paper's
    /// frictionless law on a GPU backend).
    #[setter]
    fn set_angular_velocities(
        &mut self,
        py: Python<'_>,
        angular_velocities: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.guarded("Simulation.angular_velocities", |sim| {
            let rows = sim.triples_of(angular_velocities, "angular_velocities")?;
            sim.set_motion(
                py,
                &Motion {
                    angular_velocities: Some(&rows),
                    ..Motion::default()
                },
            )
        })
    }

    /// Angular velocities `(N, 3)` float32 [rad/s], in input order: a read-only snapshot of
    /// this step.
    #[getter]
    fn angular_velocities<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.guarded("Simulation.angular_velocities", |sim| {
            sim.view::<f32, Ix2>(
                py,
                |v| &mut v.angular_velocities,
                |py, p| triples(py, &p.angular_velocities),
            )
        })
    }

    /// Radii `(N,)` float32 [m], in input order: a read-only snapshot of this step.
    #[getter]
    fn radii<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        self.guarded("Simulation.radii", |sim| {
            sim.view::<f32, Ix1>(py, |v| &mut v.radii, |py, p| singles(py, &p.radii))
        })
    }

    /// Materials `(N,)` uint8, in input order: each sphere's index in `material_names` (the
    /// scene's `material` tables, in order); a read-only snapshot of this step.
    #[getter]
    fn materials<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<u8>>> {
        self.guarded("Simulation.materials", |sim| {
            sim.view::<u8, Ix1>(py, |v| &mut v.materials, materials)
        })
    }

    /// The clumps now, a dict of NumPy arrays (empty without `clump` tables): `positions`
    /// `(M, 3)` float64 [m] (their centres of mass), `orientations` `(M, 4)` float64 (unit
    /// quaternions w, x, y, z: each clump's principal frame to the world), `velocities` `(M, 3)`
    /// and `angular_velocities` `(M, 3)` float64 [m/s, rad/s], and `spheres` `(N,)` int32 (each
    /// sphere's clump, -1 for a free sphere).
    #[getter]
    fn clumps<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.guarded("Simulation.clumps", |sim| {
            let p = sim.particles(py)?;
            let set = &p.clumps;
            let rows = |f: &dyn Fn(&mochi::clump::Clump) -> Vec<f64>, width: usize| {
                let flat: Vec<f64> = set.clumps.iter().flat_map(f).collect();
                Array2::from_shape_vec((set.clumps.len(), width), flat)
                    .map(|a| a.into_pyarray(py))
                    .map_err(|e| PyValueError::new_err(e.to_string()))
            };
            let owners = set.owners();
            let spheres: Vec<i32> = (0..p.len())
                .map(|i| owners.get(i).map_or(-1, |&k| k as i32))
                .collect();
            let out = PyDict::new(py);
            out.set_item(
                "positions",
                rows(&|c| c.body.position.to_array().to_vec(), 3)?,
            )?;
            out.set_item(
                "orientations",
                rows(
                    &|c| {
                        let q = c.body.orientation;
                        vec![q.w, q.x, q.y, q.z]
                    },
                    4,
                )?,
            )?;
            out.set_item(
                "velocities",
                rows(&|c| c.body.velocity.to_array().to_vec(), 3)?,
            )?;
            out.set_item(
                "angular_velocities",
                rows(
                    &|c| {
                        let inertia = &set.kinds[c.kind].inertia;
                        c.body.angular_velocity(inertia).to_array().to_vec()
                    },
                    3,
                )?,
            )?;
            out.set_item("spheres", Array1::from_vec(spheres).into_pyarray(py))?;
            Ok(out)
        })
    }

    /// The scene's material names, in order (`["default"]` for a scene without `material`
    /// tables): `materials` indexes them.
    #[getter]
    fn material_names(&mut self) -> PyResult<Vec<String>> {
        self.guarded("Simulation.material_names", |sim| {
            let materials = sim.run_mut()?.config.materials().map_err(to_py_err)?;
            Ok(materials.names)
        })
    }

    /// Simulated time [s]: steps taken times the time step.
    #[getter]
    fn time(&mut self) -> PyResult<f64> {
        self.guarded("Simulation.time", |sim| {
            Ok(sim.step as f64 * sim.run_mut()?.params.dt as f64)
        })
    }

    /// Steps taken (counting those before a resumed checkpoint).
    #[getter]
    fn step_count(&mut self) -> PyResult<u64> {
        self.guarded("Simulation.step_count", |sim| Ok(sim.step))
    }

    /// Touching pairs in the last step taken (0 before the first).
    #[getter]
    fn contacts(&mut self) -> PyResult<u64> {
        self.guarded("Simulation.contacts", |sim| Ok(sim.contacts))
    }

    /// The backend's name (`cpu`, `wgpu-rq`, …).
    #[getter]
    fn backend(&mut self) -> PyResult<&'static str> {
        self.guarded("Simulation.backend", |sim| {
            Ok(sim.run_mut()?.backend.name())
        })
    }

    /// The time step [s].
    #[getter]
    fn dt(&mut self) -> PyResult<f64> {
        self.guarded("Simulation.dt", |sim| Ok(sim.run_mut()?.params.dt as f64))
    }

    /// Gravity now [m/s²] (the scene's, turned by its `gravity_spin` since t = 0).
    #[getter]
    fn gravity(&mut self) -> PyResult<[f32; 3]> {
        self.guarded("Simulation.gravity", |sim| {
            let step = sim.step;
            Ok(sim.run_mut()?.params.gravity_at(step))
        })
    }

    /// Sets gravity [m/s²] from the next step on (with a `gravity_spin`, this is gravity
    /// now, turning on from it); refused where it would move a sphere farther than the
    /// smallest radius in one step.
    #[setter]
    fn set_gravity(&mut self, py: Python<'_>, gravity: [f64; 3]) -> PyResult<()> {
        self.guarded("Simulation.gravity", |sim| {
            let run = sim.run_mut()?;
            py.detach(|| run.set_gravity(gravity)).map_err(usage_err)
        })
    }

    /// Changes scene keys between steps, given as a dict or keyword arguments (as
    /// `Simulation` takes them): the material keys (`friction`, `young_modulus`,
    /// `restitution`, …; `materials` with their names in their order; `material_pairs`),
    /// `gravity`, `dt`, and each `wall`'s `friction` and `material`. The step is opened again
    /// on its backend from the state now (contact history, gravity and external loads kept),
    /// which costs what opening the run costs. A time step the contact law cannot keep stable,
    /// and any other key (the spheres, box, walls' geometry, flows), raise `ValueError` and
    /// change nothing. The time is `step_count · dt`: a new `dt` makes `step_count` the time
    /// now over it, rounded (the clock moves by less than half a step).
    #[pyo3(signature = (scene = None, **keys))]
    fn change(
        &mut self,
        py: Python<'_>,
        scene: Option<&Bound<'_, PyDict>>,
        keys: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        self.guarded("Simulation.change", |sim| {
            let given = match scene {
                Some(dict) => overrides(dict)?,
                None => Overrides::default(),
            };
            let given = given.then(keyword_overrides(keys)?);
            let run = sim.run_mut()?;
            let changed = py.detach(|| run.change(&given));
            // A new time step counts the time now in its steps.
            sim.step = run.stepper.step();
            sim.stepped();
            changed.map_err(scene_err)
        })
    }

    /// Moves mesh wall `index` (its place in `wall_loads`) from now on at `velocity` [m/s],
    /// turning at `omega` [rad/s] about `axis` through `center` [m] (each not given: the
    /// wall's own, the centre where the wall has carried it), starting from where it is now.
    /// The step is opened again as by `change`. The walls a built-in scene makes (a hopper's,
    /// a drum's) move as their scene says: `ValueError`.
    #[pyo3(signature = (index, *, velocity = None, omega = None, axis = None, center = None))]
    fn set_wall_motion(
        &mut self,
        py: Python<'_>,
        index: i64,
        velocity: Option<[f64; 3]>,
        omega: Option<f64>,
        axis: Option<[f64; 3]>,
        center: Option<[f64; 3]>,
    ) -> PyResult<()> {
        let index = usize::try_from(index).map_err(|_| {
            PyValueError::new_err(format!(
                "cannot set the motion of wall {index}: walls are numbered from 0, as wall_loads \
                 lists them"
            ))
        })?;
        self.guarded("Simulation.set_wall_motion", |sim| {
            let motion = NewMotion {
                velocity,
                omega,
                axis,
                center,
            };
            let run = sim.run_mut()?;
            let set = py.detach(|| run.set_wall_motion(index, &motion));
            sim.stepped();
            set.map_err(usage_err)
        })
    }

    /// The spheres' translational kinetic energy now, Σ ½ m v² [J] (each mass from the
    /// sphere's radius and its material's density).
    #[getter]
    fn kinetic_energy(&mut self, py: Python<'_>) -> PyResult<f64> {
        self.guarded("Simulation.kinetic_energy", |sim| {
            Ok(sim.energies(py)?.translational)
        })
    }

    /// The spheres' rotational kinetic energy now, Σ ½ I ω², I = 2/5 m r² [J].
    #[getter]
    fn rotational_energy(&mut self, py: Python<'_>) -> PyResult<f64> {
        self.guarded("Simulation.rotational_energy", |sim| {
            Ok(sim.energies(py)?.rotational)
        })
    }

    /// The force [N] and torque [N·m] (about its rotation centre) the spheres exerted on
    /// each mesh wall in the last step taken, in the scene's order of walls: a list of dicts
    /// `name`, `force`, `torque` (float64 `(3,)` arrays; zero before the first step).
    #[getter]
    fn wall_loads<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.guarded("Simulation.wall_loads", |sim| {
            let run = sim.run_mut()?;
            let loads = run.stepper.wall_loads();
            run.walls
                .meshes
                .iter()
                .enumerate()
                .map(|(k, wall)| {
                    let load = loads.get(k).copied().unwrap_or_default();
                    let entry = PyDict::new(py);
                    entry.set_item("name", &wall.name)?;
                    entry.set_item(
                        "force",
                        Array1::from_vec(load.force.to_vec()).into_pyarray(py),
                    )?;
                    entry.set_item(
                        "torque",
                        Array1::from_vec(load.torque.to_vec()).into_pyarray(py),
                    )?;
                    Ok(entry)
                })
                .collect()
        })
    }

    /// The flows so far: spheres `inserted`, `refused` (no room at their inflow), `removed`,
    /// `present` now, and the masses inserted and removed [kg] (`inserted_mass`,
    /// `removed_mass`); all 0 in a scene without flows.
    #[getter]
    fn flow<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.guarded("Simulation.flow", |sim| {
            let present = sim.spheres_now()?;
            let counts = sim.run_mut()?.stepper.flow_counts().unwrap_or_default();
            let flow = PyDict::new(py);
            flow.set_item("inserted", counts.inserted)?;
            flow.set_item("refused", counts.refused)?;
            flow.set_item("removed", counts.removed)?;
            flow.set_item("present", present)?;
            flow.set_item("inserted_mass", counts.inserted_mass)?;
            flow.set_item("removed_mass", counts.removed_mass)?;
            Ok(flow)
        })
    }

    /// Forces `(N, 3)` float32 [N] added to each sphere's contacts and gravity every step
    /// until changed (zeros until set): set an `(N, 3)` array before a step, or `None` to
    /// remove them. Per sphere, so refused in a run whose inflows or outflows change its
    /// spheres.
    #[getter]
    fn external_forces<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.guarded("Simulation.external_forces", |sim| sim.loads(py, true))
    }

    #[setter]
    fn set_external_forces(
        &mut self,
        py: Python<'_>,
        forces: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.guarded("Simulation.external_forces", |sim| {
            sim.set_loads(py, forces.as_ref(), true)
        })
    }

    /// Torques `(N, 3)` float32 [N·m] about each sphere's centre added every step until
    /// changed (zeros until set; `None` removes them). Refused where the run's step does not
    /// turn its spheres (the paper's frictionless law).
    #[getter]
    fn external_torques<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.guarded("Simulation.external_torques", |sim| sim.loads(py, false))
    }

    #[setter]
    fn set_external_torques(
        &mut self,
        py: Python<'_>,
        torques: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.guarded("Simulation.external_torques", |sim| {
            sim.set_loads(py, torques.as_ref(), false)
        })
    }

    /// The contacts now, as the next step resolves them: a dict of arrays `pairs` `(P, 2)`
    /// int64 (spheres i < j by input index, or a sphere and a wall's negative id: the box's
    /// walls −1 … −6 for the low and high wall of x, y, z; the scene's mesh walls −7, −8, …,
    /// one contact per triangle touched), `normal_force` and `tangential_force` `(P, 3)`
    /// float32 [N] on the first of the pair (the second takes the opposite) and `overlap`
    /// `(P,)` float32 [m]. Evaluated on every backend by the Rust law that each backend's law
    /// is checked against, from the state read back (once per step).
    fn contact_data<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.guarded("Simulation.contact_data", |sim| {
            let data = sim.touching(py)?;
            let pairs = copied(data.pairs.as_flattened(), "the contacts")?;
            let pairs = Array2::from_shape_vec((data.pairs.len(), 2), pairs)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            let out = PyDict::new(py);
            out.set_item("pairs", pairs.into_pyarray(py))?;
            out.set_item("normal_force", triples(py, &data.normal_force)?)?;
            out.set_item("tangential_force", triples(py, &data.tangential_force)?)?;
            out.set_item("overlap", singles(py, &data.overlap)?)?;
            Ok(out)
        })
    }

    /// Each sphere's contact force now `(N, 3)` float32 [N]: the sum of its contacts in
    /// `contact_data()` (with spheres and walls) as the next step adds it up, before gravity
    /// and external forces. A read-only snapshot.
    #[getter]
    fn forces<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.guarded("Simulation.forces", |sim| {
            let array = triples(py, &sim.touching(py)?.forces)?;
            read_only(&array)?;
            Ok(array)
        })
    }

    /// Each sphere's contact torque about its centre now `(N, 3)` float32 [N·m], as
    /// `forces` (zeros where the run's step does not turn its spheres).
    #[getter]
    fn torques<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.guarded("Simulation.torques", |sim| {
            let array = triples(py, &sim.touching(py)?.torques)?;
            read_only(&array)?;
            Ok(array)
        })
    }

    /// Number of spheres now (inflows add spheres, outflows remove them).
    fn __len__(&mut self) -> PyResult<usize> {
        self.guarded("Simulation.__len__", |sim| sim.spheres_now())
    }

    /// Writes the spheres now as a frame, by extension: `.vtu` (ParaView), `.csv` or `.npy`
    /// (float64 N×11: x, y, z, r, vx, vy, vz, wx, wy, wz, material); atomically, as `mochi
    /// simulate` writes its frames.
    fn write_frame(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.guarded("Simulation.write_frame", |sim| {
            sim.particles(py)?;
            let run = open_run(&mut sim.run)?;
            let now = sim.now.as_ref().expect("read back above");
            let frame = run.frame(&now.particles, &now.contacts);
            py.detach(|| io::write_frame(&path, &frame))
                .map_err(to_py_err)
        })
    }

    /// Saves the run (particles, contact history and resolved scene) for
    /// `Simulation.resume`; atomically. Reads the springs back too, which the arrays of the
    /// spheres now do not.
    fn checkpoint(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.guarded("Simulation.checkpoint", |sim| {
            let run = sim.run_mut()?;
            let (scene, state) = (run.scene_toml(), run.state_toml(None));
            let stepper = &mut run.stepper;
            py.detach(|| {
                let now = stepper.particles()?;
                io::write_checkpoint(&path, &now, &scene, &state)
            })
            .map_err(to_py_err)
        })
    }

    fn __repr__(&mut self) -> PyResult<String> {
        self.guarded("Simulation.__repr__", |sim| {
            if sim
                .run
                .get_mut()
                .unwrap_or_else(PoisonError::into_inner)
                .is_none()
            {
                return Ok(format!("Simulation(closed, step={})", sim.step));
            }
            let (step, spheres) = (sim.step, sim.spheres_now()?);
            let run = sim.run_mut()?;
            Ok(format!(
                "Simulation(scene={:?}, spheres={}, backend={:?}, step={})",
                run.config.scene().name(),
                spheres,
                run.backend.name(),
                step
            ))
        })
    }

    /// Ends the run and lets its backend go (its device and buffers); every later call but
    /// `close` raises `MochiError`. A `with` block closes the simulation at its end.
    fn close(&mut self) {
        self.stepped();
        *self.run.get_mut().unwrap_or_else(PoisonError::into_inner) = None;
    }

    /// Whether `close` was called.
    #[getter]
    fn closed(&mut self) -> bool {
        self.run
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
            .is_none()
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// Closes the simulation (exceptions of the block go on).
    fn __exit__(
        &mut self,
        _kind: Option<&Bound<'_, PyAny>>,
        _value: Option<&Bound<'_, PyAny>>,
        _traceback: Option<&Bound<'_, PyAny>>,
    ) -> bool {
        self.close();
        false
    }
}
