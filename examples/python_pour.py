"""Runs a short pour with mochi's Python package, writes a frame, loads it back and plots the
speeds (a histogram) and a side view of the heap with matplotlib if present (a summary
otherwise). Works as a script or cell by cell in Jupyter.

Run after `pip install ./python`:  python examples/python_pour.py
"""

from pathlib import Path

import numpy as np

import mochi

# A small pour: a polydisperse column that collapses into a heap (any scene key works, as a
# keyword argument or in a dict).
sim = mochi.Simulation("pour", spheres=2000, seed=1, backend="auto")
print(sim, f"dt = {sim.dt:.3g} s")

steps = 3000
try:
    from tqdm.auto import tqdm
except ImportError:
    sim.step(steps)
else:
    with tqdm(total=steps, unit="step") as bar:
        sim.step(steps, progress=bar.update)
print(f"t = {sim.time:.4f} s after {sim.step_count} steps, {sim.contacts} contacts")

frame_path = Path("pour_frame.vtu")
sim.write_frame(frame_path)  # ParaView reads it; so does mochi.read_frame
frame = mochi.read_frame(frame_path)
speed = np.linalg.norm(frame["velocities"], axis=1)
centres, radii = frame["positions"], frame["radii"]
print(
    f"{frame_path}: step {frame['step']}, {len(radii)} spheres, speed mean {speed.mean():.3f} "
    f"max {speed.max():.3f} m/s, heap top z = {(centres[:, 2] + radii).max():.3f} m"
)

try:
    import matplotlib.pyplot as plt
except ImportError:
    counts, edges = np.histogram(speed, bins=8)
    for count, lo, hi in zip(counts, edges, edges[1:]):
        print(f"speed {lo:6.3f} .. {hi:6.3f} m/s: {count} spheres")
else:
    fig, (hist, side) = plt.subplots(1, 2, figsize=(11, 4.5))
    hist.hist(speed, bins=40)
    hist.set_xlabel("speed [m/s]")
    hist.set_ylabel("spheres")
    # Side view (x, z): each sphere a disc of its own radius, coloured by speed.
    from matplotlib.collections import EllipseCollection

    discs = EllipseCollection(
        2 * radii, 2 * radii, 0.0, units="xy", offsets=centres[:, [0, 2]],
        offset_transform=side.transData, array=speed, cmap="viridis",
    )
    side.add_collection(discs)
    side.autoscale_view()
    fig.colorbar(discs, ax=side, label="speed [m/s]")
    side.set_aspect("equal")
    side.set_xlabel("x [m]")
    side.set_ylabel("z [m]")
    fig.tight_layout()
    fig.savefig("pour.png", dpi=120)
    print("wrote pour.png")
