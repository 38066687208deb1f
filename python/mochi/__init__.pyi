"""Type hints of mochi's Python API."""

import os
from typing import Callable, Literal, TypedDict

import numpy as np
import numpy.typing as npt

Mode = Literal["mochi", "nns"]

class MochiError(RuntimeError):
    """A device or library failure (bad input raises ValueError instead)."""

class BackendEntry(TypedDict):
    name: str
    available: bool
    reason: str

def detect(
    centres: npt.NDArray[np.float32] | npt.NDArray[np.float64],
    radii: npt.NDArray[np.float32] | npt.NDArray[np.float64],
    backend: str = "auto",
    mode: Mode = "mochi",
) -> npt.NDArray[np.int64]:
    """Every colliding pair of spheres as a ``(P, 2)`` int64 array, ``i < j``, rows sorted.

    ``centres`` is ``(N, 3)`` and ``radii`` ``(N,)``, float32 or float64, any memory order.
    Raises ``ValueError`` for bad input (naming the row and the reason) and ``MochiError``
    when the backend fails or cannot run here. The backend it opens (its device and buffers)
    and the memory of its copies of the spheres (32 bytes a sphere on the host) are kept for
    the next call with the same ``backend``, which opens and allocates nothing but the result;
    a call with another ``backend`` lets them go.
    """

def backends() -> list[BackendEntry]:
    """Every backend this build knows: its name, whether it runs here, and the device or why not."""

class Detector:
    """A detection backend kept open between calls (build once, update the centres, ask again)."""

    def __init__(self, backend: str = "auto", mode: Mode = "mochi") -> None: ...
    @property
    def backend(self) -> str:
        """The backend's name (``cpu``, ``wgpu-rq``, ...)."""
    def build(
        self,
        centres: npt.NDArray[np.float32] | npt.NDArray[np.float64],
        radii: npt.NDArray[np.float32] | npt.NDArray[np.float64],
    ) -> None:
        """Builds the structure over these spheres."""
    def update(self, centres: npt.NDArray[np.float32] | npt.NDArray[np.float64]) -> None:
        """Moves the spheres of the last ``build`` (same count, same radii)."""
    def pairs(self) -> npt.NDArray[np.int64]:
        """The colliding pairs of the current spheres, as ``detect`` returns them."""

SceneValue = bool | int | float | str | os.PathLike[str] | list[bool | int | float | str]

class FrameDict(TypedDict):
    positions: npt.NDArray[np.float32]
    radii: npt.NDArray[np.float32]
    velocities: npt.NDArray[np.float32]
    angular_velocities: npt.NDArray[np.float32]
    step: int | None
    time: float | None

def read_frame(path: str | os.PathLike[str]) -> FrameDict:
    """Reads a frame (``.vtu`` as ``write_frame`` and ``mochi simulate`` write it, ``.csv`` or
    ``.npy``): positions, radii, velocities and angular velocities, with its step and time
    (``None`` where the file does not say)."""

class Simulation:
    """A DEM simulation: a scene's spheres under gravity, walls and contact forces.

    ``scene`` is a dict of scene keys (as in a scene TOML, or ``mochi simulate --set``), a path
    to a scene TOML, or ``None`` for the default scene (``pour``). Bad keys or values raise
    ``ValueError`` naming them; the run's warnings (overlaps, coarse coordinates, coincident
    centres) are ``UserWarning``s. Arrays are float32 in input order.
    """

    def __init__(
        self,
        scene: dict[str, SceneValue] | str | os.PathLike[str] | None = None,
        backend: str = "auto",
    ) -> None: ...
    @classmethod
    def resume(cls, path: str | os.PathLike[str], backend: str = "auto") -> Simulation:
        """Resumes the run saved by ``checkpoint`` at ``path``."""
    def step(self, n: int, progress: Callable[[int], object] | None = None) -> None:
        """Takes ``n`` steps, in batches of at most 100 with the interpreter lock released.

        Between batches Ctrl-C stops it (the steps taken so far count) and ``progress`` is
        called with the number of steps the batch took (an increment: ``progress=bar.update``
        of tqdm works).
        """
    @property
    def positions(self) -> npt.NDArray[np.float32]:
        """Centres ``(N, 3)`` [m]."""
    @property
    def velocities(self) -> npt.NDArray[np.float32]:
        """Velocities ``(N, 3)`` [m/s]."""
    @property
    def angular_velocities(self) -> npt.NDArray[np.float32]:
        """Angular velocities ``(N, 3)`` [rad/s]."""
    @property
    def radii(self) -> npt.NDArray[np.float32]:
        """Radii ``(N,)`` [m]."""
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
        """Number of spheres."""
    def write_frame(self, path: str | os.PathLike[str]) -> None:
        """Writes the spheres now by extension: ``.vtu`` (ParaView), ``.csv`` or ``.npy``
        (float32 N×10: x, y, z, r, vx, vy, vz, wx, wy, wz); atomically."""
    def checkpoint(self, path: str | os.PathLike[str]) -> None:
        """Saves the run (particles, contact history, resolved scene) for ``resume``."""
