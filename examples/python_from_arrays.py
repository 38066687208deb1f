"""A scene built from arrays, as one builds it for DEM-Engine: spheres from NumPy (positions,
radii, velocities, materials), two materials, walls and settings as keyword arguments, no
file. A stream of steel spheres is shot into a bed of glass ones; the script reports the
energies as the impact spends them.

Run after `pip install ./python`:  python examples/python_from_arrays.py [--quick] [--backend B]
"""

import argparse

import numpy as np

import mochi

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="a smaller bed")
parser.add_argument("--backend", default="auto")
args = parser.parse_args()

# A bed of glass spheres (material 0) on the floor, and a column of steel ones (material 1)
# above it moving down at 1 m/s.
n = 6 if args.quick else 12
r = 0.004
cells = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(3), indexing="ij"), -1)
bed = r + 2.05 * r * cells.reshape(-1, 3)
column = np.column_stack([np.full(5, n * r), np.full(5, n * r), 0.05 + 2.5 * r * np.arange(5)])
positions = np.vstack([bed, column])
radii = np.full(len(positions), r)
velocities = np.zeros_like(positions)
velocities[len(bed) :, 2] = -1.0
materials = np.r_[np.zeros(len(bed), int), np.ones(len(column), int)]

side = 2.05 * r * n
with mochi.Simulation.from_arrays(
    positions,
    radii,
    velocities=velocities,
    materials=materials,
    backend=args.backend,
    box_lo=[0, 0, 0],
    box_hi=[side, side, 0.1],
    # Scene keys: the materials' tables (`material`, a list: the short form of `materials`,
    # which names the spheres' array here), indexed by the spheres' `materials`, and the friction
    # every material takes where its table gives none.
    material=[
        {"name": "glass", "density": 2500, "young_modulus": 6e7, "restitution": 0.9},
        {"name": "steel", "density": 7800, "young_modulus": 2e8, "restitution": 0.8},
    ],
    friction=0.3,
) as sim:
    print(sim, sim.material_names, f"dt = {sim.dt:.3g} s")
    for k in range(5):
        sim.step(round(0.01 / sim.dt))
        print(
            f"t = {sim.time:.3f} s: kinetic {sim.kinetic_energy * 1e3:.3f} mJ, rotational "
            f"{sim.rotational_energy * 1e3:.3f} mJ, {sim.contacts} contacts"
        )
    assert sim.kinetic_energy < 0.5 * 5 * 7800 * 4 / 3 * np.pi * r**3, "the impact spent energy"
