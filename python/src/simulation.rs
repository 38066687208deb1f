//! `mochi.Simulation`: a DEM run set up by the library's [`RunStart`] (the same function `mochi
//! simulate` uses), stepped from Python.
//!
//! Invariants: `step` counts the steps the stepper has taken (its particles' step); `now` is
//! `None` or the particles at `step` (read back once, dropped on every step).

use crate::to_py_err;
use mochi::dem::Particles;
use mochi::dem::scene::SceneFlags;
use mochi::engines::{BackendChoice, Options};
use mochi::io;
use mochi::run::{FIRST_PROGRESS_STEPS, Run, RunStart, progress_steps};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::{PyTypeError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::ffi::CString;
use std::path::PathBuf;
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

/// A scene value from Python as TOML: bool, int, float, str, path, or a list or tuple of them.
fn toml_value(key: &str, value: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
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
    if let Ok(path) = value.extract::<PathBuf>() {
        let text = path
            .to_str()
            .ok_or_else(|| bad("the path is not valid UTF-8"))?;
        return Ok(toml::Value::String(text.to_owned()));
    }
    Err(bad(&format!(
        "a value of type {} cannot be a scene value (use bool, int, float, str, a path, or a \
         list of them)",
        value.get_type().name()?
    )))
}

/// A scene dict as `key=value` overrides, in the dict's order.
fn overrides(scene: &Bound<'_, PyDict>) -> PyResult<Vec<String>> {
    scene
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
            Ok(format!("{key}={}", toml_value(&key, &value)?))
        })
        .collect()
}

/// The start of a new run from `scene`: a dict of scene keys, a TOML file, or `None`.
fn new_start(py: Python<'_>, scene: Option<&Bound<'_, PyAny>>) -> PyResult<RunStart> {
    let flags = SceneFlags::default();
    let (file, overrides) = match scene {
        None => (None, Vec::new()),
        Some(scene) => match scene.cast::<PyDict>() {
            Ok(dict) => (None, overrides(dict)?),
            Err(_) => {
                let path: PathBuf = scene.extract().map_err(|_| {
                    PyTypeError::new_err(
                        "scene must be a dict of scene keys, a path to a scene TOML, or None",
                    )
                })?;
                (Some(path), Vec::new())
            }
        },
    };
    py.detach(|| RunStart::new(file.as_deref(), &flags, &overrides))
        .map_err(to_py_err)
}

/// `values` (three per sphere) as an `(N, 3)` float32 array.
fn triples<'py>(py: Python<'py>, values: &[[f32; 3]]) -> Bound<'py, PyArray2<f32>> {
    Array2::from_shape_vec((values.len(), 3), values.as_flattened().to_vec())
        .expect("three values per sphere")
        .into_pyarray(py)
}

/// Reads a frame (`.vtu` as `write_frame` and `mochi simulate` write it, `.csv` or `.npy`) into
/// a dict of NumPy arrays (`positions`, `radii`, `velocities`, `angular_velocities`) with its
/// `step` and `time` (`None` where the file does not say).
#[pyfunction]
pub fn read_frame(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyDict>> {
    let frame = py.detach(|| io::read_frame(&path)).map_err(to_py_err)?;
    let out = PyDict::new(py);
    out.set_item("positions", triples(py, &frame.positions))?;
    out.set_item("radii", Array1::from_vec(frame.radii).into_pyarray(py))?;
    out.set_item("velocities", triples(py, &frame.velocities))?;
    out.set_item("angular_velocities", triples(py, &frame.angular_velocities))?;
    out.set_item("step", frame.step)?;
    out.set_item("time", frame.time)?;
    Ok(out)
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
}

#[pymethods]
impl Simulation {
    /// Sets a run up from `scene` (a dict of scene keys, as in a scene TOML or `mochi simulate
    /// --set`; a path to a scene TOML; or `None`, the default scene `pour`) on `backend`.
    #[new]
    #[pyo3(signature = (scene = None, backend = "auto"))]
    fn new(py: Python<'_>, scene: Option<&Bound<'_, PyAny>>, backend: &str) -> PyResult<Self> {
        let start = new_start(py, scene)?;
        Simulation::open(py, start, backend)
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
        let start = py
            .detach(|| RunStart::resume(&path, &SceneFlags::default(), &[]))
            .map_err(to_py_err)?;
        Simulation::open(py, start, backend)
    }

    /// Takes `n` steps, in batches of about a quarter second with the interpreter lock
    /// released (the first of 10 steps); between batches Ctrl-C stops it (the steps taken so far count) and `progress`, if given, is
    /// called with the number of steps the batch took (an increment, as `tqdm`'s `update`
    /// takes it).
    #[pyo3(signature = (n, progress = None))]
    fn step(&mut self, py: Python<'_>, n: u64, progress: Option<Bound<'_, PyAny>>) -> PyResult<()> {
        let mut left = n;
        let mut next = FIRST_PROGRESS_STEPS;
        while left > 0 {
            let batch = left.min(next);
            let stepper = &mut self.run_mut().stepper;
            let began = Instant::now();
            let advance = py
                .detach(|| stepper.advance(batch as u32))
                .map_err(to_py_err)?;
            next = progress_steps(batch, began.elapsed());
            self.now = None;
            self.step += batch;
            self.contacts = advance.contacts;
            left -= batch;
            if let Some(progress) = &progress {
                progress.call1((batch,))?;
            }
            py.check_signals()?;
        }
        Ok(())
    }

    /// Centres `(N, 3)` float32 \[m\], in input order.
    #[getter]
    fn positions<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        Ok(triples(py, &self.particles(py)?.positions))
    }

    /// Velocities `(N, 3)` float32 \[m/s\], in input order.
    #[getter]
    fn velocities<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        Ok(triples(py, &self.particles(py)?.velocities))
    }

    /// Angular velocities `(N, 3)` float32 \[rad/s\], in input order.
    #[getter]
    fn angular_velocities<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        Ok(triples(py, &self.particles(py)?.angular_velocities))
    }

    /// Radii `(N,)` float32 \[m\], in input order.
    #[getter]
    fn radii<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let radii = self.particles(py)?.radii.clone();
        Ok(Array1::from_vec(radii).into_pyarray(py))
    }

    /// Simulated time \[s\]: steps taken times the time step.
    #[getter]
    fn time(&mut self) -> f64 {
        self.step as f64 * self.run_mut().params.dt as f64
    }

    /// Steps taken (counting those before a resumed checkpoint).
    #[getter]
    fn step_count(&self) -> u64 {
        self.step
    }

    /// Touching pairs in the last step taken (0 before the first).
    #[getter]
    fn contacts(&self) -> u64 {
        self.contacts
    }

    /// The backend's name (`cpu`, `wgpu-rq`, …).
    #[getter]
    fn backend(&mut self) -> &'static str {
        self.run_mut().backend.name()
    }

    /// The time step \[s\].
    #[getter]
    fn dt(&mut self) -> f64 {
        self.run_mut().params.dt as f64
    }

    /// Number of spheres.
    fn __len__(&mut self) -> usize {
        self.run_mut().spheres
    }

    /// Writes the spheres now as a frame, by extension: `.vtu` (ParaView), `.csv` or `.npy`
    /// (float32 N×10: x, y, z, r, vx, vy, vz, wx, wy, wz); atomically, as `mochi simulate`
    /// writes its frames.
    fn write_frame(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.particles(py)?;
        let run = self.run.get_mut().unwrap_or_else(PoisonError::into_inner);
        let frame = run.frame(self.now.as_ref().expect("read back above"));
        py.detach(|| io::write_frame(&path, &frame))
            .map_err(to_py_err)
    }

    /// Saves the run (particles, contact history and resolved scene) for
    /// `Simulation.resume`; atomically.
    fn checkpoint(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.particles(py)?;
        let run = self.run_mut();
        let (scene, state) = (run.scene_toml(), run.state_toml(None));
        let now = self.now.as_ref().expect("read back above");
        py.detach(|| io::write_checkpoint(&path, now, &scene, &state))
            .map_err(to_py_err)
    }

    fn __repr__(&mut self) -> String {
        let step = self.step;
        let run = self.run_mut();
        format!(
            "Simulation(scene={:?}, spheres={}, backend={:?}, step={})",
            run.config.scene.name(),
            run.spheres,
            run.backend.name(),
            step
        )
    }
}
