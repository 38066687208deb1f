"""An agglomerate of wet grains dropped on the floor: it survives a slow impact and breaks up in
a fast one. The fragments are counted from the contacts (`sim.contact_data()`: the liquid
bridges that still hold), before and after the impact.

The grains are 1 mm spheres packed in a ball, every neighbour wetted by a bridge of 1 nl of water
(`cohesion = "capillary"`): a bridge pulls with 2πRγ·cos θ at contact (R = r for two equal
spheres) and ruptures at a gap of (1 + θ/2)·V^⅓ (0.1 mm). The criterion, to an order of
magnitude: the agglomerate breaks where the impact's kinetic energy per grain, ½ m v², exceeds
the work of pulling its share of bridges apart, about (z/2)·E_b with z ≈ 6 bridges a grain and
E_b ≈ ½·2πrγ·(1 + θ/2)·V^⅓ a bridge: v_c = √(z·E_b/m), about 0.1 m/s here. The slow drop (a
fifth of it) leaves one piece; the fast one (twenty times it) leaves many.

Run after `pip install ./python`:  python examples/python_agglomerate.py [--quick] [--backend B]
(cohesion runs on every backend: `auto` picks the fastest)
"""

import argparse

import numpy as np

import mochi

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="a smaller agglomerate")
parser.add_argument("--backend", default="auto")
args = parser.parse_args()

r, gamma, volume = 1e-3, 0.072, 1e-12
ball = 2.5 if args.quick else 4.0  # radius of the agglomerate, in diameters
# A cubic lattice of spheres pressed 1 µm into each other, trimmed to a ball, just above the floor.
k = np.arange(-int(ball), int(ball) + 1)
cells = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3)
cells = cells[np.linalg.norm(cells, axis=1) <= ball]
spacing = 2 * r - 1e-6
positions = 0.05 + spacing * cells
positions[:, 2] += 0.0 - positions[:, 2].min() + r + 1e-4  # 0.1 mm above the floor
radii = np.full(len(positions), r)
mass = 2500 * 4 / 3 * np.pi * r**3
bond = 0.5 * 2 * np.pi * r * gamma * volume ** (1 / 3)
critical = np.sqrt(6 * bond / mass)
print(f"{len(positions)} grains; break-up at about {critical:.3f} m/s (order of magnitude)")


def fragments(sim):
    """The sizes of the groups of grains joined by bridges, largest first."""
    pairs = sim.contact_data()["pairs"]
    pairs = pairs[pairs[:, 1] >= 0]
    parent = np.arange(len(sim))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in pairs:
        parent[root(i)] = root(j)
    roots = np.array([root(i) for i in range(len(sim))])
    return sorted(np.bincount(roots)[np.unique(roots)], reverse=True)


pieces = {}
for speed in [0.2 * critical, 20 * critical]:
    sim = mochi.Simulation.from_arrays(
        positions,
        radii,
        velocities=np.tile([0.0, 0.0, -speed], (len(positions), 1)),
        backend=args.backend,
        box_lo=[0, 0, 0],
        box_hi=[0.1, 0.1, 0.1],
        density=2500,
        cohesion="capillary",
        liquid_volume=volume,
        surface_tension=gamma,
    )
    before = fragments(sim)
    # Down to the floor, the impact, and a while after.
    sim.step(round((1e-4 / speed + 0.02) / sim.dt))
    after = fragments(sim)
    pieces[speed] = after
    print(
        f"dropped at {speed:.3f} m/s: {len(before)} piece before, {len(after)} after "
        f"(largest {after[0]} of {len(sim)} grains)"
    )
slow, fast = pieces.values()
assert len(slow) == 1, f"the slow drop broke it: {slow[:10]}"
assert len(fast) > 5 and fast[0] < 0.9 * len(positions), f"the fast drop did not: {fast[:10]}"
