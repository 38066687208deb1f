"""mochi: every pair of touching spheres, fast (proxy-sphere collision detection).

See ``mochi.detect``, ``mochi.Detector``, ``mochi.backends``, ``mochi.Simulation`` and
``mochi.read_frame``.
"""

from ._mochi import Detector, MochiError, Simulation, __version__, backends, detect, read_frame

__all__ = [
    "Detector",
    "MochiError",
    "Simulation",
    "__version__",
    "backends",
    "detect",
    "read_frame",
]
