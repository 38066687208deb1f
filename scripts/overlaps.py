#!/usr/bin/env python3
"""Overlaps of the touching pairs of a frame, relative to the smaller sphere's radius.

Usage: python3 scripts/overlaps.py FRAME.csv PAIRS.csv
FRAME.csv: a frame of `mochi simulate --csv` (x,y,z,r,...); PAIRS.csv: `mochi detect FRAME.csv -o`.
"""
import sys

import numpy as np

frame, pairs = sys.argv[1], sys.argv[2]
spheres = np.loadtxt(frame, delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
ij = np.loadtxt(pairs, delimiter=",", skiprows=1, dtype=np.int64).reshape(-1, 2)
centres, radii = spheres[:, :3], spheres[:, 3]
d = np.linalg.norm(centres[ij[:, 0]] - centres[ij[:, 1]], axis=1)
smaller = np.minimum(radii[ij[:, 0]], radii[ij[:, 1]])
relative = (radii[ij[:, 0]] + radii[ij[:, 1]] - d) / smaller
if len(relative) == 0:
    print("no contacts")
    sys.exit(0)
q = np.quantile(relative, [0.5, 0.9, 0.99, 0.999])
print(
    f"contacts {len(ij)}; overlap / smaller radius: median {q[0]:.4f}, p90 {q[1]:.4f}, "
    f"p99 {q[2]:.4f}, p99.9 {q[3]:.4f}, max {relative.max():.4f}"
)
large = smaller > np.quantile(radii, 0.9)
if large.any():
    print(
        f"  pairs whose smaller sphere is among the largest 10%: max {relative[large].max():.4f}, "
        f"p99 {np.quantile(relative[large], 0.99):.4f}"
    )
