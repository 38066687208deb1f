"""mochi.detect from NumPy on a GPU backend, wall clock as Python sees it.

    python benches/python_detect.py ROUNDS BACKEND FILE.npy...   (needs numpy and the mochi package)

FILE is an N×4 (x, y, z, r) float32 sphere file (`mochi generate … -o FILE.npy`). For each file,
ROUNDS times in a row: `mochi.detect(centres, radii, backend=BACKEND)` (the first call opens the
backend, every later one reuses it: the loop a user writes), then the same through a `Detector`
split into its parts: `build` (the spheres converted, checked, uploaded and binned) and `pairs`
(detection, the pairs read back, sorted and handed over as an int64 array), and a warm
`update` + `pairs`. Prints the first call and the minimum and median of the later ones [ms].
"""

import sys
import time

import numpy as np

import mochi


def timed(f):
    t = time.perf_counter()
    out = f()
    return (time.perf_counter() - t) * 1e3, out


def summary(values):
    later = values[1:] or values
    return f"first {values[0]:8.2f}  min {min(later):8.2f}  median {np.median(later):8.2f}"


def main(rounds, backend, paths):
    for path in paths:
        spheres = np.load(path)
        centres = np.ascontiguousarray(spheres[:, :3])
        radii = np.ascontiguousarray(spheres[:, 3])
        times = {k: [] for k in ["detect", "build", "pairs", "update+pairs"]}
        for _ in range(rounds):
            t, pairs = timed(lambda: mochi.detect(centres, radii, backend=backend))
            times["detect"].append(t)
        detector = mochi.Detector(backend=backend)
        for _ in range(rounds):
            times["build"].append(timed(lambda: detector.build(centres, radii))[0])
            t, again = timed(detector.pairs)
            times["pairs"].append(t)
        for _ in range(rounds):
            times["update+pairs"].append(
                timed(lambda: (detector.update(centres), detector.pairs()))[0]
            )
        assert np.array_equal(pairs, again)
        print(f"{path}: {len(radii)} spheres ({centres.dtype}), {len(pairs)} pairs, "
              f"backend {detector.backend}, {rounds} calls each [ms]")
        for name, values in times.items():
            print(f"  {name:13s} {summary(values)}")


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2], sys.argv[3:])
