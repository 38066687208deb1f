"""mochi: every pair of touching spheres, fast (proxy-sphere collision detection).

See ``mochi.detect``, ``mochi.Detector`` and ``mochi.backends``.
"""

from ._mochi import Detector, MochiError, backends, detect

__all__ = ["Detector", "MochiError", "backends", "detect"]
