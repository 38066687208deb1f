//! `mochi.Simulation`: a DEM run set up by the library's [`RunStart`] (the same function `mochi
//! simulate` uses), stepped from Python.
//!
//! Invariants: `step` counts the steps the stepper has taken (its particles' step); `now` is
//! `None` or the particles at `step` (read back once, dropped on every step), and `views` holds
//! only arrays made from `now` (dropped with it); the arrays handed out are read-only snapshots.

use crate::{Guarded, guard, plain_array, to_py_err};
use mochi::dem::Particles;
use mochi::dem::scene::{Overrides, SceneConfig, SceneFlags};
use mochi::engines::{BackendChoice, Options};
use mochi::io;
use mochi::run::{FIRST_PROGRESS_STEPS, Run, RunStart, progress_steps};
use numpy::ndarray::{Array1, Array2, Dimension, Ix1, Ix2};
use numpy::{
    Element, IntoPyArray, PyArray, PyArray1, PyArray2, PyUntypedArray, PyUntypedArrayMethods,
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
/// `[[outflow]]`, `[[materials]]`, `[[material_pairs]]` and its short form, as `dem::scene`
/// documents them): a lone dict given for one is that array's one table.
const TABLE_ARRAYS: [&str; 6] = [
    "wall",
    "inflow",
    "outflow",
    "materials",
    "material_pairs",
    "material_pair",
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

/// The start of a new run from `scene`: a dict of scene keys, a TOML file, or `None`.
fn new_start(py: Python<'_>, scene: Option<&Bound<'_, PyAny>>) -> PyResult<RunStart> {
    let flags = SceneFlags::default();
    let (file, overrides) = match scene {
        None => (None, Overrides::default()),
        Some(scene) => match scene.cast::<PyDict>() {
            Ok(dict) => (None, overrides(dict)?),
            Err(_) => {
                let path: PathBuf = scene.extract().map_err(|_| {
                    PyTypeError::new_err(
                        "scene must be a dict of scene keys, a path to a scene TOML, or None",
                    )
                })?;
                (Some(path), Overrides::default())
            }
        },
    };
    py.detach(|| RunStart::new(file.as_deref(), &flags, &overrides))
        .map_err(|error| match error {
            // The library names the source of overrides the command line; here it is the dict.
            mochi::Error::Parse { path, msg, .. }
                if file.is_none() && path.as_os_str() == "command line" =>
            {
                PyValueError::new_err(format!("scene dict: {msg}"))
            }
            other => to_py_err(other),
        })
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
/// `.csv` or `.npy`) into
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
#[pyclass(module = "mochi")]
pub struct Simulation {
    /// Only ever reached through `&mut self` (`Mutex::get_mut`, no locking): the mutex only
    /// makes the class `Sync`, as pyo3 requires.
    run: Mutex<Run>,
    step: u64,
    contacts: u64,
    now: Option<Particles>,
    views: Views,
    /// What a call that panicked said ([`Guarded`]).
    broken: Option<String>,
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
            run: Mutex::new(run),
            contacts: 0,
            now: None,
            views: Views::default(),
            broken: None,
        })
    }

    fn run_mut(&mut self) -> &mut Run {
        self.run.get_mut().unwrap_or_else(PoisonError::into_inner)
    }

    /// The particles now (read back from the backend once per step).
    fn particles(&mut self, py: Python<'_>) -> PyResult<&Particles> {
        if self.now.is_none() {
            let stepper = &mut self.run_mut().stepper;
            let now = py.detach(|| stepper.particles()).map_err(to_py_err)?;
            self.now = Some(now);
        }
        Ok(self.now.as_ref().expect("read back above"))
    }

    /// The spheres now: the particles' count where they were read back since the last step,
    /// else the start's count with the flows' insertions and removals since (no read-back).
    fn spheres_now(&mut self) -> usize {
        if let Some(now) = &self.now {
            return now.len();
        }
        let run = self.run_mut();
        match run.stepper.flow_counts() {
            Some(flows) => {
                let inserted = run.spheres as u64 + flows.inserted;
                inserted.saturating_sub(flows.removed) as usize
            }
            None => run.spheres,
        }
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
        array.call_method("setflags", (), Some(&[("write", false)].into_py_dict(py)?))?;
        *slot(&mut self.views) = Some(array.clone().unbind());
        Ok(array)
    }

    /// Drops what was read back for the last step.
    fn stepped(&mut self) {
        self.now = None;
        self.views = Views::default();
    }
}

#[pymethods]
impl Simulation {
    /// Sets a run up from `scene` (a dict of scene keys, as in a scene TOML or `mochi simulate
    /// --set`; a path to a scene TOML; or `None`, the default scene `pour`) on `backend`.
    #[new]
    #[pyo3(signature = (scene = None, backend = "auto"))]
    fn new(py: Python<'_>, scene: Option<&Bound<'_, PyAny>>, backend: &str) -> PyResult<Self> {
        guard("mochi.Simulation()", || {
            let start = new_start(py, scene)?;
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
    fn step(&mut self, py: Python<'_>, n: u64, progress: Option<Bound<'_, PyAny>>) -> PyResult<()> {
        self.guarded("Simulation.step", |sim| {
            let mut left = n;
            let mut next = FIRST_PROGRESS_STEPS;
            while left > 0 {
                let batch = left.min(next);
                let stepper = &mut sim.run_mut().stepper;
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

    /// Positions `(N, 3)` float64 \[m\], in input order: a read-only snapshot of this step.
    /// Each is where the step keeps its sphere (its `f32` centre plus the residual that holds
    /// what `f32` cannot: every step's displacement, however small, far from the origin).
    #[getter]
    fn positions<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.guarded("Simulation.positions", |sim| {
            sim.view::<f64, Ix2>(py, |v| &mut v.positions, positions)
        })
    }

    /// Velocities `(N, 3)` float32 \[m/s\], in input order: a read-only snapshot of this step.
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

    /// Angular velocities `(N, 3)` float32 \[rad/s\], in input order: a read-only snapshot of
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

    /// Radii `(N,)` float32 \[m\], in input order: a read-only snapshot of this step.
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

    /// The scene's material names, in order (`["default"]` for a scene without `material`
    /// tables): `materials` indexes them.
    #[getter]
    fn material_names(&mut self) -> PyResult<Vec<String>> {
        self.guarded("Simulation.material_names", |sim| {
            let materials = sim.run_mut().config.materials().map_err(to_py_err)?;
            Ok(materials.names)
        })
    }

    /// Simulated time \[s\]: steps taken times the time step.
    #[getter]
    fn time(&mut self) -> PyResult<f64> {
        self.guarded("Simulation.time", |sim| {
            Ok(sim.step as f64 * sim.run_mut().params.dt as f64)
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
        self.guarded("Simulation.backend", |sim| Ok(sim.run_mut().backend.name()))
    }

    /// The time step \[s\].
    #[getter]
    fn dt(&mut self) -> PyResult<f64> {
        self.guarded("Simulation.dt", |sim| Ok(sim.run_mut().params.dt as f64))
    }

    /// Number of spheres now (inflows add spheres, outflows remove them).
    fn __len__(&mut self) -> PyResult<usize> {
        self.guarded("Simulation.__len__", |sim| Ok(sim.spheres_now()))
    }

    /// Writes the spheres now as a frame, by extension: `.vtu` (ParaView), `.csv` or `.npy`
    /// (float64 N×11: x, y, z, r, vx, vy, vz, wx, wy, wz, material); atomically, as `mochi
    /// simulate` writes its frames.
    fn write_frame(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.guarded("Simulation.write_frame", |sim| {
            sim.particles(py)?;
            let run = sim.run.get_mut().unwrap_or_else(PoisonError::into_inner);
            let frame = run.frame(sim.now.as_ref().expect("read back above"));
            py.detach(|| io::write_frame(&path, &frame))
                .map_err(to_py_err)
        })
    }

    /// Saves the run (particles, contact history and resolved scene) for
    /// `Simulation.resume`; atomically.
    fn checkpoint(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.guarded("Simulation.checkpoint", |sim| {
            sim.particles(py)?;
            let run = sim.run_mut();
            let (scene, state) = (run.scene_toml(), run.state_toml(None));
            let now = sim.now.as_ref().expect("read back above");
            py.detach(|| io::write_checkpoint(&path, now, &scene, &state))
                .map_err(to_py_err)
        })
    }

    fn __repr__(&mut self) -> PyResult<String> {
        self.guarded("Simulation.__repr__", |sim| {
            let (step, spheres) = (sim.step, sim.spheres_now());
            let run = sim.run_mut();
            Ok(format!(
                "Simulation(scene={:?}, spheres={}, backend={:?}, step={})",
                run.config.scene().name(),
                spheres,
                run.backend.name(),
                step
            ))
        })
    }
}
