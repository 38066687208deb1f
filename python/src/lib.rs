//! Python bindings of mochi: `mochi.detect`, `mochi.Detector`, `mochi.backends`, and
//! `mochi.Simulation` and `mochi.read_frame` (in [`simulation`]).
//!
//! Invariants: no Rust panic crosses into Python as pyo3's `PanicException`: every library call
//! returns `Result`, mapped by [`to_py_err`], and every function and method the module exports
//! runs inside [`guard`] (or an object's [`Guarded::guarded`]), which turns a panic, a bug of
//! mochi, into `MochiError` naming the call; an object one of whose calls panicked refuses every
//! later call. The GIL is released while the library works, and held only while it reads the
//! caller's arrays (Python may not write them meanwhile); arrays are read through NumPy views
//! (float32 or float64 in either byte order, any memory order; a masked array only where no entry
//! is masked), never element by element in Python. Every copy the bindings make whose size
//! comes from the input is allocated fallibly (`MemoryError`).
#![deny(unsafe_code)]

use mochi::engines::{BackendChoice, BackendKind, Options, open};
use mochi::{Backend, Pair, ProxyMode, SphereSet, Spheres};
use numpy::ndarray::{Array2, ArrayView1, ArrayView2};
use numpy::{
    IntoPyArray, PyArray2, PyArrayDescrMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PySlice, PyType};
use rayon::prelude::*;
use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

mod simulation;

create_exception!(
    _mochi,
    MochiError,
    PyRuntimeError,
    "A device or library failure of mochi (bad input raises ValueError instead)."
);

/// Maps a library error to `ValueError` (the caller's input: spheres, sizes, scenes and their
/// files), `MemoryError` (memory for something the input sized that could not be had),
/// `OSError` (a file that cannot be read or written) or `MochiError` (everything else). A
/// resumed checkpoint's error is classed by its cause.
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
        mochi::Error::OutOfMemory { .. } => PyMemoryError::new_err(error.to_string()),
        mochi::Error::Io { .. } => PyOSError::new_err(error.to_string()),
        _ => MochiError::new_err(error.to_string()),
    }
}

/// The message and place of the last panic in this module, as its hook saw it (the place is not
/// in the panic's payload); taken by [`panicked`].
static LAST_PANIC: Mutex<Option<(String, Option<String>)>> = Mutex::new(None);

/// The text of a panic's payload.
fn payload_text(payload: &(dyn Any + Send)) -> String {
    match (
        payload.downcast_ref::<&str>(),
        payload.downcast_ref::<String>(),
    ) {
        (Some(text), _) => (*text).to_owned(),
        (_, Some(text)) => text.clone(),
        _ => "a panic without a message".to_owned(),
    }
}

/// Installs the module's panic hook: it records each panic's message and place for
/// [`panicked`], then reports it as Rust's own hook does (on stderr).
fn install_panic_hook() {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let place = info
            .location()
            .map(|at| format!("{}:{}", at.file(), at.line()));
        *LAST_PANIC.lock().unwrap_or_else(PoisonError::into_inner) =
            Some((payload_text(info.payload()), place));
        previous(info);
    }));
}

/// The message of a `MochiError` for a panic caught in `call`: what the panic said, and where,
/// if the hook saw the same panic.
fn panicked(call: &str, payload: &(dyn Any + Send)) -> String {
    let what = payload_text(payload);
    let seen = LAST_PANIC
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .take();
    let place = match seen {
        Some((message, Some(place))) if message == what => format!(" (at {place})"),
        _ => String::new(),
    };
    format!(
        "{call}: internal error, a bug in mochi (please report it with the call that caused \
         it): {what}{place}"
    )
}

/// Runs `body`, the whole of the exported function `call`: a panic in it (on this thread or in
/// a rayon task it waited for) becomes `MochiError` naming `call`.
pub(crate) fn guard<T>(call: &str, body: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(body))
        .unwrap_or_else(|payload| Err(MochiError::new_err(panicked(call, &*payload))))
}

/// An exported object whose calls run inside [`Guarded::guarded`]: after a call of it
/// panicked, its state is unknown, so every later call is refused.
pub(crate) trait Guarded: Sized {
    /// What the call that panicked said (`None`: none did).
    fn broken(&mut self) -> &mut Option<String>;

    /// Runs `body`, the whole of the method `call`, as [`guard`] does, unless an earlier call
    /// panicked.
    fn guarded<T>(
        &mut self,
        call: &str,
        body: impl FnOnce(&mut Self) -> PyResult<T>,
    ) -> PyResult<T> {
        if let Some(why) = self.broken() {
            return Err(MochiError::new_err(format!(
                "{call}: refused, since an earlier call on this object failed inside mochi: {why}"
            )));
        }
        match catch_unwind(AssertUnwindSafe(|| body(self))) {
            Ok(result) => result,
            Err(payload) => {
                let message = panicked(call, &*payload);
                *self.broken() = Some(message.clone());
                Err(MochiError::new_err(message))
            }
        }
    }
}

/// Panics on purpose inside [`guard`], for mochi's tests of it: `where_ = "pool"` in a rayon
/// task with the GIL released, anything else here with the GIL held.
#[pyfunction]
#[pyo3(name = "_panic")]
fn panic_for_tests(py: Python<'_>, where_: &str) -> PyResult<()> {
    guard("mochi._mochi._panic", || {
        if where_ == "pool" {
            py.detach(|| {
                (0..64u32).into_par_iter().for_each(|k| {
                    assert!(k != 37, "a deliberate panic in a rayon task");
                })
            });
            return Ok(());
        }
        panic!("a deliberate panic")
    })
}

/// A `MemoryError` for `n` items of `T` of `what` that could not be had.
fn out_of_memory<T>(what: &str, n: usize) -> PyErr {
    let bytes = (n as u64).saturating_mul(std::mem::size_of::<T>() as u64);
    PyMemoryError::new_err(format!(
        "{what} of {n} spheres: out of memory ({bytes} bytes needed)"
    ))
}

/// `out` emptied, with room for `n` items (fallibly).
fn emptied_with_room<T>(out: &mut Vec<T>, n: usize, what: &str) -> PyResult<()> {
    out.clear();
    out.try_reserve_exact(n)
        .map_err(|_| out_of_memory::<T>(what, n))
}

/// `array` (the argument `what`) as an array the readers take: a masked array with no masked
/// entry as its data, one with masked entries refused (mochi has no use for a mask, and
/// ignoring it would read the values under it); a float array in the other byte order than the
/// machine's converted (a copy). Anything else as it is.
pub(crate) fn plain_array<'py>(
    what: &str,
    array: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let py = array.py();
    static MASKED: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    let mut array = array.clone();
    if array.is_instance(MASKED.import(py, "numpy.ma", "MaskedArray")?)? {
        let masked: bool = py
            .import("numpy.ma")?
            .call_method1("is_masked", (&array,))?
            .extract()?;
        if masked {
            return Err(PyValueError::new_err(format!(
                "{what} is a masked array with masked entries, and mochi takes no mask: fill \
                 them (.filled(value)) or leave them out"
            )));
        }
        array = array.getattr("data")?;
    }
    if let Ok(untyped) = array.cast::<PyUntypedArray>() {
        let dtype = untyped.dtype();
        if dtype.kind() == b'f' && dtype.is_native_byteorder() == Some(false) {
            let native = dtype.call_method1("newbyteorder", ("=",))?;
            array = array.call_method1("astype", (native,))?;
        }
    }
    Ok(array)
}

/// The dtype of `array` in words, for errors (its Python type where it is not an array).
fn dtype_words(array: &Bound<'_, PyAny>) -> String {
    match array.cast::<PyUntypedArray>() {
        Ok(untyped) => format!("dtype {}", untyped.dtype()),
        Err(_) => match array.get_type().name() {
            Ok(name) => format!("a {name}"),
            Err(_) => "something else".to_owned(),
        },
    }
}

/// The index of the first value that `f32` cannot hold (finite in `f64`, infinite in `f32`;
/// or, with `tiny`, positive in `f64` and zero in `f32`), as the conversions below record it.
struct FirstUnheld(AtomicUsize);

impl FirstUnheld {
    fn new() -> Self {
        FirstUnheld(AtomicUsize::new(usize::MAX))
    }

    /// `x` as `f32`, recording `index` where `f32` cannot hold it.
    #[inline(always)]
    fn convert(&self, index: usize, x: f64, tiny: bool) -> f32 {
        let y = x as f32;
        if (y.is_infinite() && x.is_finite()) || (tiny && y == 0.0 && x > 0.0) {
            self.0.fetch_min(index, Ordering::Relaxed);
        }
        y
    }

    fn first(self) -> Option<usize> {
        Some(self.0.into_inner()).filter(|&k| k != usize::MAX)
    }
}

/// The centres of an `(N, 3)` float32/float64 array, as `f32` (what the library stores), into
/// `out` (its allocation reused, grown fallibly): one copy, on the rayon pool for a C-ordered
/// array (with the GIL held: Python may not write the array meanwhile). `centres` has passed
/// [`plain_array`]. A float64 coordinate beyond `f32`'s range is refused, naming it.
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
        emptied_with_room(out, view.nrows(), "centres")?;
        let unheld = FirstUnheld::new();
        let row = |k: usize, r: [T; 3]| r.map(|x| unheld.convert(k, x.into(), false));
        match view.as_slice() {
            Some(flat) => out.par_extend(
                flat.par_chunks_exact(3)
                    .enumerate()
                    .map(|(k, r)| row(k, [r[0], r[1], r[2]])),
            ),
            None => out.extend(
                view.rows()
                    .into_iter()
                    .enumerate()
                    .map(|(k, r)| row(k, [r[0], r[1], r[2]])),
            ),
        }
        if let Some(k) = unheld.first() {
            let r = view.row(k);
            let (axis, x) = ["x", "y", "z"]
                .into_iter()
                .zip(r.iter().map(|&x| x.into()))
                .find(|(_, x): &(_, f64)| (*x as f32).is_infinite())
                .unwrap_or(("x", r[0].into()));
            return Err(PyValueError::new_err(format!(
                "sphere {k}: {axis} = {} is outside the range of float32 (magnitudes up to \
                 {}), in which mochi computes",
                mochi::numbers::shown(x),
                mochi::numbers::shown(f32::MAX)
            )));
        }
        Ok(())
    }
    if let Ok(a) = centres.extract::<PyReadonlyArray2<'_, f32>>() {
        return rows(a.as_array(), out);
    }
    if let Ok(a) = centres.extract::<PyReadonlyArray2<'_, f64>>() {
        return rows(a.as_array(), out);
    }
    Err(PyValueError::new_err(format!(
        "centres must be a NumPy array of shape (N, 3) and dtype float32 or float64, not {}",
        dtype_words(centres)
    )))
}

/// `centres` and `radii` as given, or, without `radii`, the columns of `centres` as one
/// `(N, 4)` array of x, y, z, r (as `mochi generate` writes a `.npy`): its first three columns
/// and its fourth, as views.
fn columns<'py>(
    centres: &Bound<'py, PyAny>,
    radii: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    if let Some(radii) = radii {
        return Ok((centres.clone(), radii.clone()));
    }
    let array = plain_array("spheres", centres)?;
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    if shape.len() != 2 || shape[1] != 4 {
        return Err(PyValueError::new_err(format!(
            "without radii, the spheres must be one (N, 4) array of x, y, z, r, not shape \
             {shape:?} (or give centres (N, 3) and radii (N,))"
        )));
    }
    let py = centres.py();
    let rows = PySlice::full(py);
    let xyz = array.get_item((rows.clone(), PySlice::new(py, 0, 3, 1)))?;
    let r = array.get_item((rows, 3))?;
    Ok((xyz, r))
}

/// A library error about the caller's spheres as a Python exception: a usage error (centres
/// and radii of different counts, a count unlike the build's) is the caller's input,
/// `ValueError`.
fn spheres_err(error: mochi::Error) -> PyErr {
    match error {
        mochi::Error::Usage(msg) => PyValueError::new_err(msg),
        other => to_py_err(other),
    }
}

/// A C-ordered `(N, 3)` float32 array (`centres` has passed [`plain_array`]): its rows are what
/// the library stores, read where they lie ([`float32_rows`]); `None` for any other array.
fn float32_rows<'py>(centres: &Bound<'py, PyAny>) -> Option<PyReadonlyArray2<'py, f32>> {
    let array = centres.extract::<PyReadonlyArray2<'py, f32>>().ok()?;
    // ndarray's slice is the C order's alone (NumPy's would take Fortran order too).
    let c_ordered = array.as_array().ncols() == 3 && array.as_array().is_standard_layout();
    c_ordered.then_some(array)
}

/// The rows of an array [`float32_rows`] accepted.
fn rows_of<'a>(array: &'a PyReadonlyArray2<'_, f32>) -> &'a [[f32; 3]] {
    let flat = array.as_array().to_slice().expect("C-ordered");
    flat.as_chunks::<3>().0
}

/// A contiguous `(N,)` float32 array (`radii` has passed [`plain_array`]), read where it lies;
/// `None` for any other array.
fn float32_values<'py>(radii: &Bound<'py, PyAny>) -> Option<PyReadonlyArray1<'py, f32>> {
    let array = radii.extract::<PyReadonlyArray1<'py, f32>>().ok()?;
    array.as_array().is_standard_layout().then_some(array)
}

/// The values of an array [`float32_values`] accepted.
fn values_of<'a>(array: &'a PyReadonlyArray1<'_, f32>) -> &'a [f32] {
    array.as_array().to_slice().expect("contiguous")
}

/// Moves the built spheres to `centres` (refused centres leave the build as it was): a
/// C-ordered float32 array's rows are read where they lie, anything else converted into
/// `scratch` first (its allocation kept between calls). Spheres in the backend (`kept` is
/// `None`, [`Backend::takes_centers`]) take the rows straight into its memory, checked as they
/// are copied, with the GIL held (Python may not write the array meanwhile); a kept set takes
/// them as its centres and the backend is updated from it, waited for without the GIL.
fn move_spheres(
    py: Python<'_>,
    backend: &mut Box<dyn Backend>,
    kept: Option<&mut SphereSet>,
    centres: &Bound<'_, PyAny>,
    scratch: &mut Vec<[f32; 3]>,
) -> PyResult<()> {
    let centres = &plain_array("centres", centres)?;
    let direct = float32_rows(centres);
    let rows = match direct.as_ref() {
        Some(array) => rows_of(array),
        None => {
            read_centres_into(centres, scratch)?;
            scratch.as_slice()
        }
    };
    let Some(spheres) = kept else {
        return match backend.move_centers(rows).map_err(spheres_err)? {
            true => Ok(()),
            false => Err(PyRuntimeError::new_err(
                "the backend took the spheres but not their new centres",
            )),
        };
    };
    spheres.copy_centers_from(rows).map_err(spheres_err)?;
    py.detach(|| backend.update(spheres.view()))
        .map_err(to_py_err)
}

/// The radii of an `(N,)` float32/float64 array, as `f32`, into `out` (its allocation reused,
/// grown fallibly). `radii` has passed [`plain_array`]. A float64 radius beyond `f32`'s range
/// (too large, or positive but too small to be anything but zero) is refused, naming it.
fn read_radii_into(radii: &Bound<'_, PyAny>, out: &mut Vec<f32>) -> PyResult<()> {
    fn values<T: Copy + Into<f64> + Sync>(
        view: ArrayView1<'_, T>,
        out: &mut Vec<f32>,
    ) -> PyResult<()> {
        emptied_with_room(out, view.len(), "radii")?;
        let unheld = FirstUnheld::new();
        let value = |(k, &r): (usize, &T)| unheld.convert(k, r.into(), true);
        match view.as_slice() {
            Some(flat) => out.par_extend(flat.par_iter().enumerate().map(value)),
            None => out.extend(view.iter().enumerate().map(value)),
        }
        if let Some(k) = unheld.first() {
            let r: f64 = view[k].into();
            return Err(PyValueError::new_err(format!(
                "sphere {k}: radius {} is outside the range of float32 ({} to {}), in which \
                 mochi computes",
                mochi::numbers::shown(r),
                mochi::numbers::shown(f32::from_bits(1)),
                mochi::numbers::shown(f32::MAX)
            )));
        }
        Ok(())
    }
    if let Ok(a) = radii.extract::<PyReadonlyArray1<'_, f32>>() {
        return values(a.as_array(), out);
    }
    if let Ok(a) = radii.extract::<PyReadonlyArray1<'_, f64>>() {
        return values(a.as_array(), out);
    }
    Err(PyValueError::new_err(format!(
        "radii must be a NumPy array of shape (N,) and dtype float32 or float64, not {}",
        dtype_words(radii)
    )))
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
/// the caller): one pass that writes the rows (into memory not zeroed first, allocated
/// fallibly) and checks their order (every backend sorts its pairs already), and a sort where
/// it is not.
fn sorted_rows(pairs: &[Pair]) -> mochi::Result<Vec<i64>> {
    let unsorted = AtomicBool::new(false);
    let mut rows: Vec<[i64; 2]> = Vec::new();
    rows.try_reserve_exact(pairs.len())
        .map_err(|_| mochi::Error::OutOfMemory {
            what: format!("the array of {} pairs", pairs.len()),
            bytes: (pairs.len() as u64).saturating_mul(16),
        })?;
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
    Ok(rows.into_flattened())
}

/// `rows` (of [`sorted_rows`]) as a `(P, 2)` int64 array, without a copy.
fn pairs_array(py: Python<'_>, rows: Vec<i64>) -> Bound<'_, PyArray2<i64>> {
    Array2::from_shape_vec((rows.len() / 2, 2), rows)
        .expect("two values per pair")
        .into_pyarray(py)
}

/// A detection backend kept open between calls (build once, update the centres, ask again).
#[pyclass(module = "mochi")]
struct Detector {
    /// Only ever reached through `&mut self` (`Mutex::get_mut`, no locking): the mutex only
    /// makes the class `Sync`, as pyo3 requires.
    backend: Mutex<Box<dyn Backend>>,
    mode: ProxyMode,
    /// The last `build` (`None` before the first).
    built: Option<Built>,
    /// Centres and radii converted from arrays that are not C-ordered float32, their
    /// allocations kept between calls.
    scratch: (Vec<[f32; 3]>, Vec<f32>),
    /// The allocations of the kept set the last `build` replaced, filled by the next: repeated
    /// builds take no fresh memory (whose first touch costs more than the copy).
    spare: (Vec<[f32; 3]>, Vec<f32>),
    /// What a call that panicked said ([`Guarded`]).
    broken: Option<String>,
}

/// Where the spheres of a [`Detector`]'s last build are.
enum Built {
    /// In the backend's memory alone: it takes moved centres straight
    /// ([`Backend::takes_centers`]).
    InBackend,
    /// Kept here for a backend that is updated from a set: their centres those of the last
    /// `update`.
    Kept(SphereSet),
}

impl Guarded for Detector {
    fn broken(&mut self) -> &mut Option<String> {
        &mut self.broken
    }
}

impl Detector {
    /// A detector around a backend already open.
    fn around(backend: Box<dyn Backend>, mode: ProxyMode) -> Self {
        Detector {
            backend: Mutex::new(backend),
            mode,
            built: None,
            scratch: Default::default(),
            spare: Default::default(),
            broken: None,
        }
    }

    /// A detector on a newly opened `backend` (for [`Detector::new`] and [`detect`]).
    fn open(py: Python<'_>, backend: &str, mode: &str) -> PyResult<Self> {
        let choice = parse_backend(backend)?;
        let mode = parse_mode(mode)?;
        let opened = py
            .detach(|| open(choice, &Options::default()))
            .map_err(to_py_err)?;
        Ok(Detector::around(opened.value, mode))
    }

    fn backend_mut(&mut self) -> &mut Box<dyn Backend> {
        self.backend
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// Builds over `centres` and `radii`, read where they lie where they are C-ordered float32
    /// (else converted into the scratch first) and checked there, with the GIL held (Python may
    /// not write the arrays meanwhile). A backend that takes centres straight copies them once,
    /// into its own memory, the GIL still held; any other builds from a set copied here, waited
    /// for without the GIL.
    fn build_spheres(
        &mut self,
        py: Python<'_>,
        centres: &Bound<'_, PyAny>,
        radii: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (centres, radii) = columns(centres, radii)?;
        let (centres, radii) = (&centres, &radii);
        let centres = plain_array("centres", centres)?;
        let radii = plain_array("radii", radii)?;
        let (direct_centres, direct_radii) = (float32_rows(&centres), float32_values(&radii));
        let Detector {
            backend,
            mode,
            built,
            scratch: (centre_scratch, radius_scratch),
            spare,
            ..
        } = self;
        let rows = match direct_centres.as_ref() {
            Some(array) => rows_of(array),
            None => {
                read_centres_into(&centres, centre_scratch)?;
                centre_scratch.as_slice()
            }
        };
        let values = match direct_radii.as_ref() {
            Some(array) => values_of(array),
            None => {
                read_radii_into(&radii, radius_scratch)?;
                radius_scratch.as_slice()
            }
        };
        let spheres = Spheres::check(rows, values).map_err(spheres_err)?;
        let backend = backend.get_mut().unwrap_or_else(PoisonError::into_inner);
        if backend.takes_centers() {
            backend.build(spheres, *mode).map_err(to_py_err)?;
            *built = Some(Built::InBackend);
            return Ok(());
        }
        let set = spheres
            .to_set_in(std::mem::take(spare))
            .map_err(to_py_err)?;
        py.detach(|| backend.build(set.view(), *mode))
            .map_err(to_py_err)?;
        if let Some(Built::Kept(replaced)) = built.replace(Built::Kept(set)) {
            *spare = replaced.into_parts();
        }
        Ok(())
    }

    fn sorted_pairs<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        if self.built.is_none() {
            return Err(MochiError::new_err("pairs() before build()"));
        }
        let backend = self.backend_mut();
        let rows = py
            .detach(|| {
                let mut rows = Ok(Vec::new());
                backend
                    .take_pairs(&mut |pairs| rows = sorted_rows(pairs))
                    .and(rows)
            })
            .map_err(to_py_err)?;
        Ok(pairs_array(py, rows))
    }
}

#[pymethods]
impl Detector {
    #[new]
    #[pyo3(signature = (backend = "auto", mode = "mochi"))]
    fn new(py: Python<'_>, backend: &str, mode: &str) -> PyResult<Self> {
        guard("mochi.Detector()", || Detector::open(py, backend, mode))
    }

    /// The backend's name (`cpu`, `wgpu-rq`, …).
    #[getter]
    fn backend(&mut self) -> PyResult<&'static str> {
        self.guarded("Detector.backend", |d| Ok(d.backend_mut().info().name))
    }

    /// Builds over `centres` `(N, 3)` and `radii` `(N,)` (float32 or float64), or one `(N, 4)`
    /// array of x, y, z, r given alone.
    #[pyo3(signature = (centres, radii = None))]
    fn build(
        &mut self,
        py: Python<'_>,
        centres: &Bound<'_, PyAny>,
        radii: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.guarded("Detector.build", |d| d.build_spheres(py, centres, radii))
    }

    fn update(&mut self, py: Python<'_>, centres: &Bound<'_, PyAny>) -> PyResult<()> {
        self.guarded("Detector.update", |d| {
            let kept = match d.built.as_mut() {
                None => return Err(MochiError::new_err("update() before build()")),
                Some(Built::InBackend) => None,
                Some(Built::Kept(spheres)) => Some(spheres),
            };
            // The radii stay (checked at build); only the new centres are checked, and refused
            // ones leave the build as it was.
            let backend = d.backend.get_mut().unwrap_or_else(PoisonError::into_inner);
            move_spheres(py, backend, kept, centres, &mut d.scratch.0)
        })
    }

    fn pairs<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        self.guarded("Detector.pairs", |d| d.sorted_pairs(py))
    }
}

/// Every colliding pair `(i, j)`, `i < j`, of the spheres (`centres` `(N, 3)` and `radii`
/// `(N,)`, float32 or float64; or one `(N, 4)` array of x, y, z, r given alone), as a sorted
/// `(P, 2)` int64 array. mochi computes in float32: float64 input is rounded first, and the
/// pairs are exact for the rounded spheres. The backend it opens (its device and buffers) and the memory of the spheres' copies are
/// kept for the next call with the same `backend`, which opens and allocates nothing; a call
/// with another `backend` lets them go.
#[pyfunction]
#[pyo3(signature = (centres, radii = None, backend = "auto", mode = "mochi"))]
fn detect<'py>(
    py: Python<'py>,
    centres: &Bound<'py, PyAny>,
    radii: Option<&Bound<'py, PyAny>>,
    backend: &str,
    mode: &str,
) -> PyResult<Bound<'py, PyArray2<i64>>> {
    guard("mochi.detect", || {
        let mode = parse_mode(mode)?;
        let kept = KEPT.lock().unwrap_or_else(PoisonError::into_inner).take();
        let mut detector = match kept {
            Some((name, mut kept)) if name == backend => {
                kept.mode = mode;
                kept
            }
            _ => Detector::open(py, backend, mode.name())?,
        };
        detector.build_spheres(py, centres, radii)?;
        let pairs = detector.sorted_pairs(py)?;
        *KEPT.lock().unwrap_or_else(PoisonError::into_inner) = Some((backend.to_owned(), detector));
        Ok(pairs)
    })
}

/// The detector [`detect`] used last and the `backend` argument it was opened for, kept for
/// the next call with the same argument (its device, pipelines and buffers, and the memory of
/// its spheres, reused); empty before the first call, while a call holds it, and after a call
/// that failed or panicked.
static KEPT: Mutex<Option<(String, Detector)>> = Mutex::new(None);

/// Every backend this build knows: name, whether it can run here, and the device or the reason.
#[pyfunction]
fn backends(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    guard("mochi.backends", || {
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
    })
}

#[pymodule]
fn _mochi(m: &Bound<'_, PyModule>) -> PyResult<()> {
    install_panic_hook();
    m.add("MochiError", m.py().get_type::<MochiError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(detect, m)?)?;
    m.add_function(wrap_pyfunction!(backends, m)?)?;
    m.add_function(wrap_pyfunction!(panic_for_tests, m)?)?;
    m.add_class::<Detector>()?;
    m.add_class::<simulation::Simulation>()?;
    m.add_function(wrap_pyfunction!(simulation::read_frame, m)?)?;
    Ok(())
}
