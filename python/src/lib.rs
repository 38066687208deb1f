//! Python bindings of mochi: `mochi.detect`, `mochi.Detector`, `mochi.backends`, and
//! `mochi.Simulation` and `mochi.read_frame` (in [`simulation`]).
//!
//! Invariants: no Rust panic crosses into Python (every library call returns `Result`, mapped
//! by [`to_py_err`]); the GIL is released while the library works, and held only while it reads
//! the caller's arrays (Python may not write them meanwhile); arrays are read through NumPy
//! views (any dtype of f32/f64, any memory order), never element by element in Python.
#![deny(unsafe_code)]

use mochi::engines::{BackendChoice, BackendKind, Options, open};
use mochi::{Backend, Pair, ProxyMode, SphereSet};
use numpy::ndarray::{Array2, ArrayView1, ArrayView2};
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, PoisonError};

mod simulation;

create_exception!(
    _mochi,
    MochiError,
    PyRuntimeError,
    "A device or library failure of mochi (bad input raises ValueError instead)."
);

/// Maps a library error to `ValueError` (the caller's input: spheres, sizes, scenes and their
/// files), `OSError` (a file that cannot be read or written) or `MochiError` (everything
/// else). A resumed checkpoint's error is classed by its cause.
pub(crate) fn to_py_err(error: mochi::Error) -> PyErr {
    let class = match &error {
        mochi::Error::Resuming { error, .. } => error,
        other => other,
    };
    match class {
        mochi::Error::InvalidSphere { .. }
        | mochi::Error::InvalidConfig { .. }
        | mochi::Error::Parse { .. }
        | mochi::Error::TooLarge { .. } => PyValueError::new_err(error.to_string()),
        mochi::Error::Io { .. } => PyOSError::new_err(error.to_string()),
        _ => MochiError::new_err(error.to_string()),
    }
}

/// The centres of an `(N, 3)` float32/float64 array, as `f32` (what the library stores), into
/// `out` (its allocation reused): one copy, on the rayon pool for a C-ordered array (with the
/// GIL held: Python may not write the array meanwhile).
fn read_centres_into(centres: &Bound<'_, PyAny>, out: &mut Vec<[f32; 3]>) -> PyResult<()> {
    fn rows<T: Copy + Into<f64> + Sync>(
        view: ArrayView2<'_, T>,
        out: &mut Vec<[f32; 3]>,
    ) -> PyResult<()> {
        if view.ncols() != 3 {
            return Err(PyValueError::new_err(format!(
                "centres must have shape (N, 3), not {:?}",
                view.shape()
            )));
        }
        let row = |r: &[T]| [r[0].into() as f32, r[1].into() as f32, r[2].into() as f32];
        out.clear();
        match view.as_slice() {
            Some(flat) => out.par_extend(flat.par_chunks_exact(3).map(row)),
            None => out.extend(
                view.rows()
                    .into_iter()
                    .map(|r| [r[0].into() as f32, r[1].into() as f32, r[2].into() as f32]),
            ),
        }
        Ok(())
    }
    if let Ok(a) = centres.extract::<PyReadonlyArray2<'_, f32>>() {
        return rows(a.as_array(), out);
    }
    if let Ok(a) = centres.extract::<PyReadonlyArray2<'_, f64>>() {
        return rows(a.as_array(), out);
    }
    Err(PyValueError::new_err(
        "centres must be a NumPy array of shape (N, 3) and dtype float32 or float64",
    ))
}

/// A library error of moving spheres as a Python exception: a usage error (a count unlike the
/// build's) is the caller's input, `ValueError`.
fn move_err(error: mochi::Error) -> PyErr {
    match error {
        mochi::Error::Usage(msg) => PyValueError::new_err(msg),
        other => to_py_err(other),
    }
}

/// Moves the built spheres to `centres` (refused centres leave the build as it was): the
/// backend takes a C-ordered float32 array's rows straight into its own memory where it can
/// ([`Backend::move_centers`]: one pass that checks and uploads them); else they are copied
/// into `spheres` (anything not C-ordered float32 converted into `scratch` first, its
/// allocation kept between calls) and the backend updated from the set. The rows are read with
/// the GIL held (Python may not write the array meanwhile), the update waited for without it.
fn move_spheres(
    py: Python<'_>,
    backend: &mut Box<dyn Backend>,
    spheres: &mut SphereSet,
    centres: &Bound<'_, PyAny>,
    scratch: &mut Vec<[f32; 3]>,
) -> PyResult<()> {
    let direct = centres.extract::<PyReadonlyArray2<'_, f32>>().ok();
    // ndarray's slice is the C order's alone (NumPy's would take Fortran order too).
    let rows = match direct.as_ref().map(|a| a.as_array()) {
        Some(view) if view.ncols() == 3 && view.as_slice().is_some() => {
            let flat = view.to_slice().expect("C-ordered");
            flat.as_chunks::<3>().0
        }
        _ => {
            read_centres_into(centres, scratch)?;
            scratch.as_slice()
        }
    };
    if backend.move_centers(rows).map_err(move_err)? {
        return Ok(());
    }
    spheres.copy_centers_from(rows).map_err(move_err)?;
    py.detach(|| backend.update(spheres)).map_err(to_py_err)
}

/// The radii of an `(N,)` float32/float64 array, as `f32`, into `out` (its allocation reused).
fn read_radii_into(radii: &Bound<'_, PyAny>, out: &mut Vec<f32>) -> PyResult<()> {
    fn values<T: Copy + Into<f64> + Sync>(view: ArrayView1<'_, T>, out: &mut Vec<f32>) {
        let value = |&r: &T| r.into() as f32;
        out.clear();
        match view.as_slice() {
            Some(flat) => out.par_extend(flat.par_iter().map(value)),
            None => out.extend(view.iter().map(value)),
        }
    }
    if let Ok(a) = radii.extract::<PyReadonlyArray1<'_, f32>>() {
        values(a.as_array(), out);
        return Ok(());
    }
    if let Ok(a) = radii.extract::<PyReadonlyArray1<'_, f64>>() {
        values(a.as_array(), out);
        return Ok(());
    }
    Err(PyValueError::new_err(
        "radii must be a NumPy array of shape (N,) and dtype float32 or float64",
    ))
}

/// A validated sphere set; every complaint about the arrays (row and reason) is a `ValueError`.
fn sphere_set(py: Python<'_>, centres: Vec<[f32; 3]>, radii: Vec<f32>) -> PyResult<SphereSet> {
    py.detach(|| SphereSet::new(centres, radii))
        .map_err(|error| match error {
            mochi::Error::Usage(msg) => PyValueError::new_err(msg),
            other => to_py_err(other),
        })
}

fn parse_backend(name: &str) -> PyResult<BackendChoice> {
    name.parse().map_err(PyValueError::new_err)
}

fn parse_mode(name: &str) -> PyResult<ProxyMode> {
    match name.to_ascii_lowercase().as_str() {
        "mochi" => Ok(ProxyMode::Mochi),
        "nns" => Ok(ProxyMode::Nns),
        _ => Err(PyValueError::new_err(format!(
            "mode must be \"mochi\" or \"nns\", not {name:?}"
        ))),
    }
}

/// Pairs as the rows `i, j` of a `(P, 2)` array, sorted; on the rayon pool (the GIL released by
/// the caller): one pass that writes the rows (into memory not zeroed first) and checks their
/// order (every backend sorts its pairs already), and a sort where it is not.
fn sorted_rows(pairs: &[Pair]) -> Vec<i64> {
    let unsorted = AtomicBool::new(false);
    let mut rows: Vec<[i64; 2]> = Vec::new();
    (0..pairs.len())
        .into_par_iter()
        .map(|k| {
            if k > 0 && pairs[k - 1] >= pairs[k] {
                unsorted.store(true, Ordering::Relaxed);
            }
            [i64::from(pairs[k].i), i64::from(pairs[k].j)]
        })
        .collect_into_vec(&mut rows);
    if unsorted.into_inner() {
        rows.par_sort_unstable();
    }
    rows.into_flattened()
}

/// `rows` (of [`sorted_rows`]) as a `(P, 2)` int64 array, without a copy.
fn pairs_array(py: Python<'_>, rows: Vec<i64>) -> Bound<'_, PyArray2<i64>> {
    Array2::from_shape_vec((rows.len() / 2, 2), rows)
        .expect("two values per pair")
        .into_pyarray(py)
}

/// A detection backend kept open between calls.
#[pyclass(module = "mochi")]
struct Detector {
    /// Only ever reached through `&mut self` (`Mutex::get_mut`, no locking): the mutex only
    /// makes the class `Sync`, as pyo3 requires.
    backend: Mutex<Box<dyn Backend>>,
    mode: ProxyMode,
    /// The spheres of the last `build` (`None` before the first); their centres those of the
    /// last `update` that the backend did not take straight ([`move_spheres`]).
    spheres: Option<SphereSet>,
    /// Centres converted from arrays that are not C-ordered float32, kept between updates.
    scratch: Vec<[f32; 3]>,
    /// The allocations of the spheres the last `build` replaced, filled by the next: repeated
    /// builds take no fresh memory (whose first touch costs more than the copy).
    spare: (Vec<[f32; 3]>, Vec<f32>),
}

impl Detector {
    /// A detector around a backend already open.
    fn around(backend: Box<dyn Backend>, mode: ProxyMode) -> Self {
        Detector {
            backend: Mutex::new(backend),
            mode,
            spheres: None,
            scratch: Vec::new(),
            spare: Default::default(),
        }
    }

    fn backend_mut(&mut self) -> &mut Box<dyn Backend> {
        self.backend
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
    }
}

#[pymethods]
impl Detector {
    #[new]
    #[pyo3(signature = (backend = "auto", mode = "mochi"))]
    fn new(py: Python<'_>, backend: &str, mode: &str) -> PyResult<Self> {
        let choice = parse_backend(backend)?;
        let mode = parse_mode(mode)?;
        let opened = py
            .detach(|| open(choice, &Options::default()))
            .map_err(to_py_err)?;
        Ok(Detector::around(opened.backend, mode))
    }

    /// The backend's name (`cpu`, `wgpu-rq`, …).
    #[getter]
    fn backend(&mut self) -> &'static str {
        self.backend_mut().info().name
    }

    fn build(
        &mut self,
        py: Python<'_>,
        centres: &Bound<'_, PyAny>,
        radii: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (mut centres_f32, mut radii_f32) = std::mem::take(&mut self.spare);
        read_centres_into(centres, &mut centres_f32)?;
        read_radii_into(radii, &mut radii_f32)?;
        let spheres = sphere_set(py, centres_f32, radii_f32)?;
        let mode = self.mode;
        let backend = self.backend_mut();
        py.detach(|| backend.build(&spheres, mode))
            .map_err(to_py_err)?;
        if let Some(replaced) = self.spheres.replace(spheres) {
            self.spare = replaced.into_parts();
        }
        Ok(())
    }

    fn update(&mut self, py: Python<'_>, centres: &Bound<'_, PyAny>) -> PyResult<()> {
        let Some(spheres) = self.spheres.as_mut() else {
            return Err(MochiError::new_err("update() before build()"));
        };
        // The radii stay (checked at build); only the new centres are checked, and refused ones
        // leave the build as it was.
        let backend = self
            .backend
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner);
        move_spheres(py, backend, spheres, centres, &mut self.scratch)
    }

    fn pairs<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        if self.spheres.is_none() {
            return Err(MochiError::new_err("pairs() before build()"));
        }
        let backend = self.backend_mut();
        let rows = py
            .detach(|| {
                let mut rows = Vec::new();
                backend
                    .take_pairs(&mut |pairs| rows = sorted_rows(pairs))
                    .map(|_| rows)
            })
            .map_err(to_py_err)?;
        Ok(pairs_array(py, rows))
    }
}

/// Every colliding pair `(i, j)`, `i < j`, of the spheres, as a sorted `(P, 2)` int64 array.
/// The backend it opens (its device and buffers) and the memory of the spheres' copies are
/// kept for the next call with the same `backend`, which opens and allocates nothing; a call
/// with another `backend` lets them go.
#[pyfunction]
#[pyo3(signature = (centres, radii, backend = "auto", mode = "mochi"))]
fn detect<'py>(
    py: Python<'py>,
    centres: &Bound<'py, PyAny>,
    radii: &Bound<'py, PyAny>,
    backend: &str,
    mode: &str,
) -> PyResult<Bound<'py, PyArray2<i64>>> {
    let mode = parse_mode(mode)?;
    let kept = KEPT.lock().unwrap_or_else(PoisonError::into_inner).take();
    let mut detector = match kept {
        Some((name, mut kept)) if name == backend => {
            kept.mode = mode;
            kept
        }
        _ => Detector::new(py, backend, mode.name())?,
    };
    detector.build(py, centres, radii)?;
    let pairs = detector.pairs(py)?;
    *KEPT.lock().unwrap_or_else(PoisonError::into_inner) = Some((backend.to_owned(), detector));
    Ok(pairs)
}

/// The detector [`detect`] used last and the `backend` argument it was opened for, kept for
/// the next call with the same argument (its device, pipelines and buffers, and the memory of
/// its spheres, reused); empty before the first call, while a call holds it, and after a call
/// that failed.
static KEPT: Mutex<Option<(String, Detector)>> = Mutex::new(None);

/// Every backend this build knows: name, whether it can run here, and the device or the reason.
#[pyfunction]
fn backends(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    let probes: Vec<_> = py.detach(|| {
        BackendKind::ALL
            .iter()
            .map(|&kind| (kind.name(), kind.probe()))
            .collect()
    });
    probes
        .into_iter()
        .map(|(name, probe)| {
            let entry = PyDict::new(py);
            entry.set_item("name", name)?;
            entry.set_item("available", probe.is_ok())?;
            entry.set_item("reason", probe.unwrap_or_else(|why| why))?;
            Ok(entry)
        })
        .collect()
}

#[pymodule]
fn _mochi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("MochiError", m.py().get_type::<MochiError>())?;
    m.add_function(wrap_pyfunction!(detect, m)?)?;
    m.add_function(wrap_pyfunction!(backends, m)?)?;
    m.add_class::<Detector>()?;
    m.add_class::<simulation::Simulation>()?;
    m.add_function(wrap_pyfunction!(simulation::read_frame, m)?)?;
    Ok(())
}
