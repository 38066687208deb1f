"""Finds the touching pairs of a random polydisperse set with mochi's Python package and shows
how many contacts each sphere has (a histogram with matplotlib if present, a summary otherwise).

Run after `pip install ./python`:  python examples/python_detect.py
"""

import numpy as np

import mochi

rng = np.random.default_rng(0)
n = 20_000
centres = rng.uniform(0.0, 30.0, size=(n, 3))
radii = rng.uniform(0.2, 0.6, size=n)

for entry in mochi.backends():
    print(f"{entry['name']:>13}: {'yes' if entry['available'] else 'no '}  {entry['reason']}")

pairs = mochi.detect(centres, radii)
contacts = np.bincount(pairs.ravel(), minlength=n)
print(f"{n} spheres, {len(pairs)} touching pairs, {contacts.mean():.2f} contacts per sphere")

try:
    import matplotlib.pyplot as plt
except ImportError:
    print("contacts per sphere (count: spheres):", dict(enumerate(np.bincount(contacts).tolist())))
else:
    plt.hist(contacts, bins=np.arange(contacts.max() + 2) - 0.5)
    plt.xlabel("contacts per sphere")
    plt.ylabel("spheres")
    plt.savefig("contacts.png")
    print("wrote contacts.png")
