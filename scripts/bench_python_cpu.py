"""The Python package against the CLI and SciPy on the cpu backend
(docs/performance-log/2026-11-25-to-26-python-cpu.md).

    python scripts/bench_python_cpu.py ROUNDS FILE.npy...   (MOCHI: the CLI, default
    target/release/mochi; needs numpy, scipy and the mochi package)

Each round runs, one after the other on the same spheres: the CLI's first build and detection
(the time it reports) and its process wall clock; the CLI with --repeat 5 (its median, warm);
mochi.detect (the backend it kept from its last call); a warm Detector's update and pairs;
np.load and mochi.detect together (the Python twin of the CLI's wall clock); SciPy's
cKDTree.query_pairs(2 r_max) with the exact filter. Each of these starts with caches the one
before it filled. Then the Python calls and SciPy again, each called ROUNDS times in a row
(`looped`: what a loop over one of them sees). Prints the minimum and the median of each over
the rounds: on a shared machine the minimum is the least disturbed run.
"""

import os
import re
import subprocess
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

import mochi

CLI = os.environ.get("MOCHI", "target/release/mochi")


def timed(f):
    t = time.perf_counter()
    out = f()
    return (time.perf_counter() - t) * 1e3, out


def cli(path, *extra):
    """The CLI's reported build + detect time and its process wall clock [ms]."""
    wall, run = timed(
        lambda: subprocess.run(
            [CLI, "detect", path, "--backend", "cpu", *extra],
            capture_output=True, text=True, check=True,
        )
    )
    build, detect = re.search(r"build ([\d.]+) ms \| detect ([\d.]+) ms", run.stdout).groups()
    return float(build) + float(detect), wall


def scipy_pairs(centres, radii):
    c = centres.astype(np.float64)
    candidates = cKDTree(c).query_pairs(2 * float(radii.max()), output_type="ndarray")
    d = c[candidates[:, 0]] - c[candidates[:, 1]]
    reach = radii[candidates[:, 0]].astype(np.float64) + radii[candidates[:, 1]]
    return candidates[np.einsum("ij,ij->i", d, d) <= reach * reach]


def load(path):
    spheres = np.load(path)
    return np.ascontiguousarray(spheres[:, :3]), np.ascontiguousarray(spheres[:, 3])


def main(rounds, paths):
    for path in paths:
        centres, radii = load(path)
        times = {k: [] for k in ["cli", "cli_wall", "cli_warm", "detect", "warm", "load_detect", "scipy"]}
        detector = mochi.Detector(backend="cpu")
        detector.build(centres, radii)
        for _ in range(rounds):
            first, wall = cli(path)
            times["cli"].append(first)
            times["cli_wall"].append(wall)
            times["cli_warm"].append(cli(path, "--repeat", "5")[0])
            t, pairs = timed(lambda: mochi.detect(centres, radii, backend="cpu"))
            times["detect"].append(t)
            t, again = timed(lambda: (detector.update(centres), detector.pairs())[1])
            times["warm"].append(t)
            times["load_detect"].append(timed(lambda: mochi.detect(*load(path), backend="cpu"))[0])
            t, reference = timed(lambda: scipy_pairs(centres, radii))
            times["scipy"].append(t)
        assert np.array_equal(pairs, again) and len(reference) == len(pairs)
        print(f"{path}: {len(radii)} spheres, {len(pairs)} pairs; min / median [ms] of {rounds}")
        looped = {
            "detect": lambda: mochi.detect(centres, radii, backend="cpu"),
            "warm": lambda: (detector.update(centres), detector.pairs()),
            "scipy": lambda: scipy_pairs(centres, radii),
        }
        for name, call in looped.items():
            times[f"{name} looped"] = [timed(call)[0] for _ in range(rounds)]
        for name, values in times.items():
            print(f"  {name:14s} {min(values):8.2f} {np.median(values):8.2f}")


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2:])
