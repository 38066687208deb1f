"""A plate pressing on a bed of spheres: the force–displacement curve of a confined compression,
read from the plate's wall load at every step of the press.

The bed is built from arrays (a jittered lattice of 5 mm spheres, no file), settles under
gravity, then a square plate (a mesh wall of two triangles) comes down at a constant speed.
`sim.wall_loads` gives the force the spheres exert on it. Prints the curve, and plots it with
matplotlib if present.

Run after `pip install ./python`:  python examples/python_plate_press.py [--quick] [--backend B]
"""

import argparse
import tempfile
from pathlib import Path

import numpy as np

import mochi

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="a smaller bed, a shorter press")
parser.add_argument("--backend", default="auto")
args = parser.parse_args()

# The bed: n × n × 4 spheres of radius 4.5–5 mm on a lattice of 11.1 mm, jittered.
n = 5 if args.quick else 8
spacing, r = 0.0111, 0.005
rng = np.random.default_rng(1)
cells = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(4), indexing="ij"), -1)
positions = spacing / 2 + spacing * cells.reshape(-1, 3) + rng.uniform(-2e-4, 2e-4, (4 * n * n, 3))
radii = rng.uniform(0.9, 1.0, len(positions)) * r
side = n * spacing

# The plate: the unit square scaled to the box's floor, 2 mm above the bed, coming down at 5 cm/s
# once the bed has settled (its `start`).
settle, speed = 0.05, 0.05
height = (positions[:, 2] + radii).max() + 0.002
plate = Path(tempfile.mkdtemp()) / "plate.obj"
plate.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
wall = {
    "mesh": str(plate),
    "scale": side,
    "translate": [0, 0, height],
    "velocity": [0, 0, -speed],
    "start": settle,
}
sim = mochi.Simulation.from_arrays(
    positions,
    radii,
    backend=args.backend,
    box_lo=[0, 0, 0],
    box_hi=[side, side, 0.1],
    wall=[wall],
)
print(sim, f"dt = {sim.dt:.3g} s")
sim.step(round(settle / sim.dt))
top = (sim.positions[:, 2] + sim.radii).max()
print(f"settled: the bed's top at {top * 1e3:.1f} mm, {sim.contacts} contacts")

# The press: the plate's height and the force on it, every millisecond.
press = 0.2 if args.quick else 0.3
curve = []
for _ in range(round(press / 1e-3)):
    sim.step(round(1e-3 / sim.dt))
    plate_z = height - speed * (sim.time - settle)
    force = sim.wall_loads[0]["force"][2]
    curve.append((top - plate_z, force))
curve = np.array(curve)
for depth, force in curve[:: max(1, len(curve) // 10)]:
    print(f"plate {depth * 1e3:+6.2f} mm into the bed's top: {force:8.3f} N")
assert curve[-1, 1] > 0, "the bed pushes the plate up"

try:
    import matplotlib.pyplot as plt
except ImportError:
    pass
else:
    plt.plot(curve[:, 0] * 1e3, curve[:, 1])
    plt.xlabel("plate below the bed's top [mm]")
    plt.ylabel("force on the plate [N]")
    plt.savefig("plate_press.png", dpi=120)
    print("wrote plate_press.png")
