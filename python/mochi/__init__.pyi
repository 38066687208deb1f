"""Type hints of mochi's Python API."""

from typing import Literal, TypedDict

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
    when the backend fails or cannot run here.
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
