"""Type hints of mochi's Python API."""

import os
from types import TracebackType
from typing import Any, Callable, Literal, TypedDict, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "Detector",
    "MochiError",
    "Simulation",
    "__version__",
    "backends",
    "detect",
    "read_frame",
]

_Mode = Literal["mochi", "nns"]

__version__: str

class MochiError(RuntimeError):
    """A device or library failure (bad input raises ValueError instead, and input too large for
    memory MemoryError). A bug inside mochi (a Rust panic) is a MochiError too, naming the call
    and saying it is a bug; a ``Detector`` or ``Simulation`` one of whose calls hit one refuses
    every later call."""

class _BackendEntry(TypedDict):
    name: str
    available: bool
    reason: str

def detect(
    centres: npt.NDArray[np.float32] | npt.NDArray[np.float64],
    radii: npt.NDArray[np.float32] | npt.NDArray[np.float64] | None = None,
    backend: str = "auto",
    mode: _Mode = "mochi",
) -> npt.NDArray[np.int64]:
    """Every colliding pair of spheres as a ``(P, 2)`` int64 array, ``i < j``, rows sorted.

    ``centres`` is ``(N, 3)`` and ``radii`` ``(N,)``, float32 or float64 in either byte order,
    any memory order; or, without ``radii``, one ``(N, 4)`` array of x, y, z, r (as ``mochi
    generate`` writes a ``.npy``). mochi computes in float32: float64 input is rounded to float32 first, and
    the pairs are exact for the rounded spheres (a pair within float32's rounding of touching,
    about 1e-7 of the distance, may differ from a float64 brute force); a float64 value beyond its range is refused,
    naming it. A masked array is read only where no entry is masked (else ``ValueError``: mochi
    takes no mask). Raises ``ValueError`` for bad input (naming the row and the reason),
    ``MemoryError`` (naming what and how many bytes) where the spheres' copies, the backend's
    structure or the pairs do not fit in memory, and ``MochiError`` when the backend fails or
    cannot run here. The backend it opens (its device and buffers)
    and the memory of its copies of the spheres (32 bytes a sphere on the host) are kept for
    the next call with the same ``backend``, which opens and allocates nothing but the result;
    a call with another ``backend`` lets them go.
    """

def backends() -> list[_BackendEntry]:
    """Every backend this build knows: its name, whether it runs here, and the device or why not."""

@final
class Detector:
    """A detection backend kept open between calls (build once, update the centres, ask again)."""

    def __new__(cls, backend: str = "auto", mode: _Mode = "mochi") -> Detector: ...
    @property
    def backend(self) -> str:
        """The backend's name (``cpu``, ``wgpu-rq``, ...)."""
    def build(
        self,
        centres: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        radii: npt.NDArray[np.float32] | npt.NDArray[np.float64] | None = None,
    ) -> None:
        """Builds the structure over these spheres (``centres`` ``(N, 3)`` and ``radii``
        ``(N,)``, or one ``(N, 4)`` array of x, y, z, r)."""
    def update(self, centres: npt.NDArray[np.float32] | npt.NDArray[np.float64]) -> None:
        """Moves the spheres of the last ``build`` (same count, same radii)."""
    def pairs(self) -> npt.NDArray[np.int64]:
        """The colliding pairs of the current spheres, as ``detect`` returns them."""

_Scalar = bool | int | float | str | os.PathLike[str] | np.generic
_SceneValue = (
    _Scalar
    | npt.NDArray[np.generic]
    | list[_Scalar]
    | tuple[_Scalar, ...]
    | dict[str, object]
    | list[dict[str, object]]
)

class _WallLoad(TypedDict):
    name: str
    force: npt.NDArray[np.float64]
    torque: npt.NDArray[np.float64]

class _FlowCounts(TypedDict):
    inserted: int
    refused: int
    removed: int
    present: int
    inserted_mass: float
    removed_mass: float

class _ContactData(TypedDict):
    pairs: npt.NDArray[np.int64]
    normal_force: npt.NDArray[np.float32]
    tangential_force: npt.NDArray[np.float32]
    overlap: npt.NDArray[np.float32]

class _FrameDict(TypedDict):
    positions: npt.NDArray[np.float64]
    radii: npt.NDArray[np.float32]
    velocities: npt.NDArray[np.float32]
    angular_velocities: npt.NDArray[np.float32]
    materials: npt.NDArray[np.uint8]
    step: int | None
    time: float | None

def read_frame(path: str | os.PathLike[str]) -> _FrameDict:
    """Reads a frame (``.vtu`` as ``write_frame`` and ``mochi simulate`` write it, or of another
    writer such as meshio or ParaView, a ``.pvtu`` of pieces (a run over processes with
    ``frame_pieces``; its spheres in the order of their ids), ``.csv`` or ``.npy``): positions (float64, as the file holds them), radii, velocities and angular
    velocities (float32), materials (uint8: each sphere's index in the scene's materials, 0 for
    every sphere of a file without them), with its step and time (``None`` where the file does
    not say)."""

@final
class Simulation:
    """A DEM simulation: a scene's spheres under gravity, walls and contact forces.

    ``scene`` is a dict of scene keys (as in a scene TOML, in its tables or by their short
    forms, or ``mochi simulate --set``), a path to a scene TOML, or ``None`` for the default
    scene (``pour``). A dict value is a TOML table, whose keys are set one by one (``{"material":
    {"friction": 0.3}}`` keeps the material's other keys), and a list of dicts an array of
    tables: ``{"inflow": [{"lo": [...], "hi": [...], "rate": 2000, "sphere_radius": 0.004}]}``
    is ``[[inflow]]``, and a lone dict for ``wall``, ``inflow``, ``outflow``, ``materials``,
    ``material_pairs`` or ``clump`` (or ``material`` with a ``name``) is an array of one (grains
    of clumps of spheres: ``{"clump": {"shape": "tetrahedron"}}``). Several materials:
    ``{"materials": [{"name": "glass", "density": 2500}, {"name": "steel", "density": 7800}],
    "box_material": "steel", "inflow": {..., "material": "glass"}}``; an input file's
    ``material`` column gives each sphere's (its index in that list, from 0).
    Scene keys may also be keyword arguments (``Simulation(scene="freefall", spheres=500,
    friction=0.3)``), set over ``scene``. NumPy scalars and 0-d arrays count as the
    Python scalars they hold, NumPy arrays as lists. A whole float for a key that takes an
    integer (``"spheres": 3e8``) is refused, as in a scene file: pass an int. Bad keys or values
    raise ``ValueError`` naming the key; the run's warnings (overlaps, coarse coordinates,
    coincident centres) are ``UserWarning``s. ``close()`` (or the end of a ``with`` block)
    lets the backend and its device memory go.

    ``positions`` (float64), ``velocities``, ``angular_velocities`` and ``radii`` (float32) and
    ``materials`` (uint8) are in input order: read-only snapshots of the step they were read at (the same array object until the
    next ``step``; a later step does not change them). Writing into one raises ``ValueError``;
    set ``positions``, ``velocities`` or ``angular_velocities`` whole (``sim.velocities = v``)
    to change the state before the next step.

    Between steps a script may also set ``gravity``, ``external_forces`` and
    ``external_torques`` (``(N, 3)``, added to each sphere every step until changed; GPU backends
    keep them on the device), the material keys (``change(friction=0.3)``) and a wall's motion
    (``set_wall_motion``). ``contact_data()`` lists the contacts now (pairs, normal and
    tangential forces, overlaps), ``forces`` and ``torques`` their sums on each sphere: what the
    next step applies, evaluated on every backend by the Rust contact law.
    """

    def __new__(
        cls,
        scene: dict[str, _SceneValue] | str | os.PathLike[str] | None = None,
        backend: str = "auto",
        **keys: _SceneValue,
    ) -> Simulation: ...
    @classmethod
    def from_arrays(
        cls,
        positions: npt.NDArray[np.floating],
        radii: npt.NDArray[np.floating],
        *,
        velocities: npt.NDArray[np.floating] | None = None,
        angular_velocities: npt.NDArray[np.floating] | None = None,
        materials: npt.NDArray[np.integer] | None = None,
        backend: str = "auto",
        **keys: _SceneValue,
    ) -> Simulation:
        """A run of these spheres, no file: ``positions`` ``(N, 3)`` [m] (float64 kept to the
        residual, as ``positions`` returns them) and ``radii`` ``(N,)`` [m], ``velocities`` and
        ``angular_velocities`` ``(N, 3)`` (zero where not given), ``materials`` ``(N,)``
        (indices of the scene's ``materials``, 0 where not given); scene keys as keyword
        arguments (``gravity``, ``box_lo``, ``friction``, ``wall``, ...). Checked as a sphere
        file is; the box, where not given, is the spheres' bounds with a margin."""
    @classmethod
    def resume(cls, path: str | os.PathLike[str], backend: str = "auto") -> Simulation:
        """Resumes the run saved by ``checkpoint`` at ``path``."""
    def step(self, n: int, progress: Callable[[int], object] | None = None) -> None:
        """Takes ``n`` steps, in batches of about a quarter second (the first of 10 steps) with
        the interpreter lock released.

        Between batches Ctrl-C stops it (the steps taken so far count) and ``progress`` is
        called with the number of steps the batch took (an increment: ``progress=bar.update``
        of tqdm works).
        """
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Positions ``(N, 3)`` [m]: read-only, this step's. Each is the sphere's float32 centre
        (what the contacts use) plus the residual that keeps every step's displacement, however
        small beside float32's spacing far from the origin."""
    @positions.setter
    def positions(self, positions: npt.NDArray[np.floating]) -> None:
        """Moves the spheres (``(N, 3)``, input order) before the next step; the rest stays."""
    @property
    def velocities(self) -> npt.NDArray[np.float32]:
        """Velocities ``(N, 3)`` [m/s]: read-only, this step's."""
    @velocities.setter
    def velocities(self, velocities: npt.NDArray[np.floating]) -> None:
        """Sets the velocities (``(N, 3)``, input order) before the next step."""
    @property
    def angular_velocities(self) -> npt.NDArray[np.float32]:
        """Angular velocities ``(N, 3)`` [rad/s]: read-only, this step's."""
    @angular_velocities.setter
    def angular_velocities(self, angular_velocities: npt.NDArray[np.floating]) -> None:
        """Sets the angular velocities (``(N, 3)``, input order) before the next step; refused
        where the step does not turn its spheres (the paper's law on a GPU backend)."""
    @property
    def gravity(self) -> list[float]:
        """Gravity now [m/s²] (the scene's, turned by its ``gravity_spin`` since t = 0)."""
    @gravity.setter
    def gravity(self, gravity: list[float] | tuple[float, float, float]) -> None:
        """Sets gravity from the next step on; ``ValueError`` where it would move a sphere
        farther than the smallest radius in one step."""
    def change(self, scene: dict[str, _SceneValue] | None = None, **keys: _SceneValue) -> None:
        """Changes scene keys between steps: the material keys (``materials`` with their names
        in their order), ``gravity``, ``dt``, each ``wall``'s ``friction`` and ``material``. The
        step is opened again from the state now (contact history, gravity and external loads
        kept); a time step the contact law cannot keep stable and any other key raise
        ``ValueError``. A new ``dt`` makes ``step_count`` the time now over it, rounded."""
    def set_wall_motion(
        self,
        index: int,
        *,
        velocity: list[float] | tuple[float, float, float] | None = None,
        omega: float | None = None,
        axis: list[float] | tuple[float, float, float] | None = None,
        center: list[float] | tuple[float, float, float] | None = None,
    ) -> None:
        """Moves mesh wall ``index`` (its place in ``wall_loads``) from now on, from where it
        is: at ``velocity`` [m/s], turning at ``omega`` [rad/s] about ``axis`` through
        ``center`` [m] (each not given: the wall's own)."""
    @property
    def kinetic_energy(self) -> float:
        """Σ ½ m v² [J] now."""
    @property
    def rotational_energy(self) -> float:
        """Σ ½ I ω² [J] now, I = 2/5 m r²."""
    @property
    def external_forces(self) -> npt.NDArray[np.float32]:
        """Forces ``(N, 3)`` [N] added to each sphere every step until changed (zeros until set;
        ``None`` removes them); refused in a run whose flows change its spheres."""
    @external_forces.setter
    def external_forces(self, forces: npt.NDArray[np.floating] | None) -> None: ...
    @property
    def external_torques(self) -> npt.NDArray[np.float32]:
        """Torques ``(N, 3)`` [N·m] about each centre added every step until changed; refused
        where the step does not turn its spheres (the paper's frictionless law)."""
    @external_torques.setter
    def external_torques(self, torques: npt.NDArray[np.floating] | None) -> None: ...
    def contact_data(self) -> _ContactData:
        """The contacts now, as the next step resolves them: ``pairs`` ``(P, 2)`` (spheres i < j,
        or a sphere and a wall's negative id: box walls −1 … −6, mesh walls −7, −8, …),
        ``normal_force`` and ``tangential_force`` ``(P, 3)`` [N] on the first of the pair (the
        second takes the opposite), ``overlap`` ``(P,)`` [m]."""
    @property
    def forces(self) -> npt.NDArray[np.float32]:
        """Each sphere's contact force now ``(N, 3)`` [N]: the sum of its ``contact_data()``
        contacts, as the next step adds it up (before gravity and external forces)."""
    @property
    def torques(self) -> npt.NDArray[np.float32]:
        """Each sphere's contact torque about its centre now ``(N, 3)`` [N·m] (zeros where the
        step does not turn its spheres)."""
    @property
    def wall_loads(self) -> list[_WallLoad]:
        """Each mesh wall's force [N] and torque [N·m] (about its rotation centre) in the last
        step, in the scene's order of walls."""
    @property
    def flow(self) -> _FlowCounts:
        """The flows so far: spheres inserted, refused, removed and present, masses inserted
        and removed [kg]."""
    @property
    def radii(self) -> npt.NDArray[np.float32]:
        """Radii ``(N,)`` [m]: read-only, this step's."""
    @property
    def materials(self) -> npt.NDArray[np.uint8]:
        """Materials ``(N,)``: each sphere's index in ``material_names``; read-only, this
        step's."""
    @property
    def clumps(self) -> dict[str, npt.NDArray[Any]]:
        """The clumps now (empty arrays without ``clump`` tables): ``positions`` ``(M, 3)``
        float64 [m] (centres of mass), ``orientations`` ``(M, 4)`` float64 (unit quaternions w,
        x, y, z: principal frame to world), ``velocities`` and ``angular_velocities`` ``(M, 3)``
        float64, ``spheres`` ``(N,)`` int32 (each sphere's clump, -1 for a free sphere)."""
    @property
    def material_names(self) -> list[str]:
        """The scene's material names in order (``["default"]`` without ``material`` tables)."""
    @property
    def time(self) -> float:
        """Simulated time [s]: steps taken times the time step."""
    @property
    def step_count(self) -> int:
        """Steps taken (counting those before a resumed checkpoint)."""
    @property
    def contacts(self) -> int:
        """Touching pairs in the last step taken (0 before the first)."""
    @property
    def backend(self) -> str:
        """The backend's name (``cpu``, ``wgpu-rq``, ...)."""
    @property
    def dt(self) -> float:
        """The time step [s]."""
    def __len__(self) -> int:
        """Number of spheres now: inflows add spheres and outflows remove them, so it is the
        length of ``positions`` at every step."""
    def write_frame(self, path: str | os.PathLike[str]) -> None:
        """Writes the spheres now by extension: ``.vtu`` (ParaView), ``.csv`` or ``.npy``
        (float64 N×11: x, y, z, r, vx, vy, vz, wx, wy, wz, material); atomically. The positions are
        written in float64, the rest as the float32 they are."""
    def checkpoint(self, path: str | os.PathLike[str]) -> None:
        """Saves the run (particles, contact history, resolved scene) for ``resume``."""
    def close(self) -> None:
        """Ends the run and lets its backend (device and buffers) go; every later call but
        ``close`` raises ``MochiError``."""
    @property
    def closed(self) -> bool:
        """Whether ``close`` was called."""
    def __enter__(self) -> Simulation: ...
    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> bool:
        """Closes the simulation; an exception of the block goes on."""
