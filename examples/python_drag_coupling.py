"""Coupling mochi with your own code: a fluid drag computed in Python and applied between steps.

Spheres fall through a still fluid: before every step, user code reads the velocities, computes a
linear (Stokes) drag, −c v, and hands it to the step as an external force
(`sim.external_forces = f`: added to each sphere's contacts and gravity until changed; a GPU
backend keeps it on the device), as a coupled solver would. The spheres reach their terminal
speed, m g / c; the script compares. Gravity and contacts are mochi's; the drag is the user's.

Run after `pip install ./python`:  python examples/python_drag_coupling.py [--quick] [--backend B]
"""

import argparse

import numpy as np

import mochi

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="fewer spheres, a shorter fall")
parser.add_argument("--backend", default="auto")
args = parser.parse_args()

# Spheres of 2 mm far apart in a tall box, at rest.
n = 8 if args.quick else 64
rng = np.random.default_rng(2)
positions = np.column_stack([rng.uniform(0.01, 0.09, n), rng.uniform(0.01, 0.09, n), np.full(n, 0.9)])
positions[:, 0] = 0.01 + 0.08 * np.arange(n) / n  # apart: no contacts while they fall
radii = np.full(n, 0.002)
sim = mochi.Simulation.from_arrays(
    positions, radii, backend=args.backend, box_lo=[0, 0, 0], box_hi=[0.1, 0.1, 1.0]
)
density, g = 500.0, 9.81
mass = density * 4 / 3 * np.pi * radii**3
c = 6 * np.pi * 1.0 * radii  # Stokes: 6 π μ r, in a fluid of viscosity 1 Pa·s
terminal = mass * g / c
print(sim, f"terminal speed {terminal[0]:.4f} m/s")

for _ in range(300 if args.quick else 1000):
    sim.external_forces = -c[:, None] * sim.velocities  # the drag of the velocities now
    sim.step(1)
speed = -sim.velocities[:, 2]
print(f"t = {sim.time:.3f} s: falling at {speed.mean():.4f} m/s, terminal {terminal[0]:.4f} m/s")
assert abs(speed.mean() / terminal[0] - 1) < 0.01, "the spheres fall at the drag's terminal speed"
