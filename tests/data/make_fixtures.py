#!/usr/bin/env python3
"""Writes the mesh fixtures of tests/mesh.rs: one box in every supported format, plus a few
broken files. Run from this folder: python3 make_fixtures.py. Every coordinate is exactly
representable in f32, so all formats describe the same mesh bit for bit."""
import struct

X, Y, Z = (-0.5, 1.25), (0.0, 2.0), (0.75, 1.5)
V = [(X[i & 1 ^ (i >> 1) & 1], Y[(i >> 1) & 1], Z[i >> 2]) for i in range(8)]
# 0:(x0,y0,z0) 1:(x1,y0,z0) 2:(x1,y1,z0) 3:(x0,y1,z0), then the same at z1: counter-clockwise
# quads seen from outside.
QUADS = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]
TRIS = [t for a, b, c, d in QUADS for t in ((a, b, c), (a, c, d))]


def obj():
    lines = ["# a box, with the statements a mesh reader must skip", "mtllib box.mtl", "o box"]
    lines += ["v %r %r %r" % v for v in V]
    lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vn 0 0 -1", "g sides", "usemtl plain", "s off"]
    for k, (a, b, c, d) in enumerate(QUADS):
        if k == 0:
            lines.append("f %d/1/1 %d/2/1 %d/3/1 %d/1/1" % (a + 1, b + 1, c + 1, d + 1))
        elif k == 1:  # relative indices: -8 is the first vertex
            lines.append("f %d %d %d %d" % tuple(i - 8 for i in (a, b, c, d)))
        else:
            lines.append("f %d//1 %d//1 %d//1 %d//1" % (a + 1, b + 1, c + 1, d + 1))
    lines.append("l 1 2")
    return "\n".join(lines) + "\n"


def ply_header(fmt, extra=""):
    return (
        "ply\nformat %s 1.0\ncomment a box\nelement vertex 8\nproperty float x\n"
        "property float y\nproperty float z\n%selement face 6\n"
        "property list uchar int vertex_indices\nend_header\n" % (fmt, extra)
    )


def ply_binary(order):
    out = ply_header("binary_%s_endian" % ("little" if order == "<" else "big")).encode()
    for v in V:
        out += struct.pack(order + "3f", *v)
    for q in QUADS:
        out += struct.pack(order + "B4i", 4, *q)
    return out


def stl_ascii():
    lines = ["solid box"]
    for t in TRIS:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += ["      vertex %r %r %r" % V[i] for i in t]
        lines += ["    endloop", "  endfacet"]
    return "\n".join(lines + ["endsolid box"]) + "\n"


def stl_binary():
    header = b"solid box: a binary STL whose header starts with solid, as some exporters write"
    out = header.ljust(80, b" ")[:80] + struct.pack("<I", len(TRIS))
    for t in TRIS:
        out += struct.pack("<3f", 0, 0, 0)
        for i in t:
            out += struct.pack("<3f", *V[i])
        out += b"\0\0"
    return out


def write(name, data):
    with open(name, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


full_ply_ascii = ply_header("ascii") + "".join("%r %r %r\n" % v for v in V)
full_ply_ascii += "".join("4 %d %d %d %d\n" % q for q in QUADS)
write("box.obj", obj())
write("box_ascii.ply", full_ply_ascii)
write("box_binary_le.ply", ply_binary("<"))
write("box_binary_be.ply", ply_binary(">"))
write("box_ascii.stl", stl_ascii())
write("box_binary.stl", stl_binary())
# Broken files.
write("truncated.stl", stl_binary()[: 84 + 50 * 5 + 17])
write("bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
write("missing_property.ply", full_ply_ascii.replace("property float z\n", "").replace(
    "".join("%r %r %r\n" % v for v in V), "".join("%r %r\n" % v[:2] for v in V)))
write("empty.obj", "")
write("box.xyz", "0 0 0\n")
