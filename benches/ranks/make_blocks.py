#!/usr/bin/env python3
"""The HCP block of benches/hcp_block (963,567 spheres of radius 0.5 mm) repeated COPIES times
along x, each copy in its own 0.1047 m of a box COPIES times as long: the dense frictional bed
of one GPU, for as many GPUs as copies (weak scaling), or the same bed for 1 and more GPUs
(strong scaling).

Usage: make_blocks.py COPIES OUT.npy
"""
import importlib.util
import pathlib
import sys

import numpy as np

here = pathlib.Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location("make_block", here.parent / "hcp_block" / "make_block.py")
make_block = importlib.util.module_from_spec(spec)
spec.loader.exec_module(make_block)


def main() -> None:
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    copies = int(sys.argv[1])
    one = make_block.block()
    blocks = []
    for c in range(copies):
        b = one.copy()
        b[:, 0] += c * make_block.BOX
        blocks.append(b)
    spheres = np.concatenate(blocks)
    np.save(sys.argv[2], spheres)
    print(f"{len(spheres)} spheres in {copies} blocks along x")


if __name__ == "__main__":
    main()
