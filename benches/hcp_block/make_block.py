#!/usr/bin/env python3
"""The HCP block of the comparison with Chrono DEM-Engine, as a sphere file mochi reads (.npy,
N x 4: x, y, z, r).

963,567 spheres of radius 0.5 mm on a hexagonal close-packed lattice whose neighbours are
2.01 r apart (every pair starts 0.01 r apart, no contact): rows of 99 along x, 115 rows in an
even layer and 114 in an odd one along y, 85 layers along z (ABAB stacking: an odd layer's
rows are shifted by a third of the row spacing in y; every other row by half the spacing in
x, the pattern flipping from layer to layer). The block's corner sphere is at (MARGIN,
MARGIN, r) in the box of scene.toml, so the bottom layer rests on its floor.

Usage: make_block.py OUT.npy
"""
import sys

import numpy as np

RADIUS = 0.0005
SPACING = 2.01 * RADIUS
ROW, ROWS_EVEN, ROWS_ODD, LAYERS = 99, 115, 114, 85
# The box of scene.toml is BOX wide; the block (about 0.0999 m wide) is centred in it.
BOX = 0.1047
MARGIN = (BOX - (ROW - 0.5) * SPACING) / 2


def block() -> np.ndarray:
    dy = SPACING * np.sqrt(3.0) / 2
    dz = SPACING * np.sqrt(2.0 / 3.0)
    layers = []
    for k in range(LAYERS):
        rows = ROWS_EVEN if k % 2 == 0 else ROWS_ODD
        j, i = np.meshgrid(np.arange(rows), np.arange(ROW), indexing="ij")
        x = MARGIN + i * SPACING + np.where((j + k) % 2 == 1, SPACING / 2, 0.0)
        y = MARGIN + j * dy + (dy / 3 if k % 2 == 1 else 0.0)
        z = np.full(x.shape, RADIUS + k * dz)
        layers.append(np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1))
    centres = np.concatenate(layers)
    return np.hstack([centres, np.full((len(centres), 1), RADIUS)])


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    spheres = block()
    assert len(spheres) == 963_567, len(spheres)
    np.save(sys.argv[1], spheres)
    lo, hi = spheres[:, :3].min(axis=0), spheres[:, :3].max(axis=0)
    print(f"{len(spheres)} spheres, centres from {lo} to {hi} m")


if __name__ == "__main__":
    main()
