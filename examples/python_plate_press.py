"""A plate pressing on a bed of spheres and lifting off again: the force–displacement curve of a
confined compression and its release, read from the plate's wall load at every step.

The bed is built from arrays (a jittered lattice of 5 mm spheres, no file), settles under
gravity, then a square plate (a mesh wall of two triangles) comes down at a constant speed.
`sim.wall_loads` gives the force the spheres exert on it; halfway, `sim.set_wall_motion` turns
the plate back up from where it is. Prints the curve (the bed gives back less than it took), and
plots it with matplotlib if present.

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

# The press, then the release: the plate's depth below the bed's top and the force on it, every
# millisecond. Halfway the plate turns back up (`set_wall_motion`: from where it is, at +5 cm/s).
press = 0.2 if args.quick else 0.3
plate_z, curve = height - speed * (sim.time - settle), []
for velocity in [-speed, speed]:
    if velocity > 0:
        sim.set_wall_motion(0, velocity=[0, 0, velocity])
    for _ in range(round(press / 1e-3)):
        sim.step(round(1e-3 / sim.dt))
        plate_z += velocity * 1e-3
        curve.append((top - plate_z, sim.wall_loads[0]["force"][2]))
curve = np.array(curve)
loading, unloading = curve[: len(curve) // 2], curve[len(curve) // 2 :]
for depth, force in curve[:: max(1, len(curve) // 12)]:
    print(f"plate {depth * 1e3:+6.2f} mm into the bed's top: {force:8.3f} N")
assert loading[-1, 1] > 0, "the bed pushes the plate up"
# The bed gives back less than it took: at the same depth it pushes less on the way up.
depth = loading[-1, 0] * 0.8
pushing = [np.interp(depth, *part[np.argsort(part[:, 0])].T) for part in (loading, unloading)]
assert pushing[1] < pushing[0], f"no hysteresis at {depth * 1e3:.2f} mm: {pushing}"
print(f"at {depth * 1e3:.2f} mm: {pushing[0]:.3f} N pressing, {pushing[1]:.3f} N releasing")

try:
    import matplotlib.pyplot as plt
except ImportError:
    pass
else:
    plt.plot(curve[:, 0] * 1e3, curve[:, 1])
    plt.axvline(0, color="grey", lw=0.5)
    plt.xlabel("plate below the bed's top [mm]")
    plt.ylabel("force on the plate [N]")
    plt.savefig("plate_press.png", dpi=120)
    print("wrote plate_press.png")
