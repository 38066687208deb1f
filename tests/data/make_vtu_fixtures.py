#!/usr/bin/env python3
"""Writes the .vtu fixtures of src/io/frame_read.rs: three spheres as other tools write them,
with the standard library only (no meshio, no VTK). Run from this folder:
python3 make_vtu_fixtures.py. Every value is exactly representable in f32, so all files
describe the same spheres bit for bit.

- vtu_meshio_ascii.vtu: as meshio.write(..., binary=False) writes it (format="ascii", values
  "{:.11e}" one a line), the radii named "Radius" and the velocities "v".
- vtu_meshio_binary.vtu: as meshio.write(..., compression=None) writes it (format="binary":
  base64 of a UInt32 header and the data encoded together), "radius" and "velocity".
- vtu_meshio_zlib.vtu: as meshio.write(...) writes it by default (compressor
  vtkZLibDataCompressor: base64 of the header, then of the zlib blocks), a "diameter" and no
  velocities.
- vtu_vtk_appended_zlib.vtu: as VTK writes appended raw data (UInt32 headers), zlib blocks of
  16 bytes (several per array, the last one partial), "radii" and "velocity" as Float32.
- vtu_vtk_big_endian.vtu: BigEndian, UInt64 headers, the points inline (format="binary", the
  header encoded apart from the data, as VTK writes it) and the point data appended base64,
  "r" and "velocity", with the field data TimeValue and step.
"""
import base64
import struct
import zlib

CENTRES = [(0.0, 1.0, 2.0), (3.5, -4.0, 5.0), (0.25, 0.5, -0.125)]
RADII = [0.25, 0.5, 0.125]
VELOCITIES = [(1.0, 0.0, 0.0), (0.0, -2.0, 0.5), (0.0, 0.0, 0.0)]
N = len(RADII)
CODES = {"Float32": "f", "Float64": "d", "Int32": "i", "Int64": "q", "UInt8": "B", "UInt32": "I", "UInt64": "Q"}


def pack(order, vtk_type, values):
    return struct.pack(order + CODES[vtk_type] * len(values), *values)


def flat(rows):
    return [x for row in rows for x in row]


def cells(int_type):
    """(name, type, components, values) of the cells: one vertex per sphere."""
    return [
        ("connectivity", int_type, 1, list(range(N))),
        ("offsets", int_type, 1, list(range(1, N + 1))),
        ("types", "UInt8", 1, [1] * N),
    ]


def grid(header, arrays, field="", tail=""):
    """The XML of a grid: `arrays` are (section, element text) in Points, Cells, PointData."""
    out = header + "<UnstructuredGrid>\n" + field
    out += '<Piece NumberOfPoints="%d" NumberOfCells="%d">\n' % (N, N)
    for section in ["Points", "Cells", "PointData"]:
        out += "<%s>\n" % section
        out += "".join(text for s, text in arrays if s == section)
        out += "</%s>\n" % section
    return out + "</Piece>\n</UnstructuredGrid>\n" + tail


def element(name, vtk_type, components, attributes, text):
    comps = ' NumberOfComponents="%d"' % components if components > 1 else ""
    return '<DataArray type="%s" Name="%s"%s %s>%s</DataArray>\n' % (
        vtk_type, name, comps, attributes, text)


MESHIO_HEADER = (
    '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1" '
    'byte_order="LittleEndian"%s>\n<!--This file was created by meshio v5.3.5-->\n'
)


def meshio_arrays(point_data):
    return [("Points", "Points", "Float64", 3, flat(CENTRES))] + [
        ("Cells",) + c for c in cells("Int64")] + point_data


def meshio_ascii():
    arrays = []
    for section, name, t, comps, values in meshio_arrays(
            [("PointData", "Radius", "Float64", 1, RADII),
             ("PointData", "v", "Float64", 3, flat(VELOCITIES))]):
        fmt = "{:.11e}" if t.startswith("Float") else "{:d}"
        text = "\n" + "".join((fmt + "\n").format(x) for x in values)
        arrays.append((section, element(name, t, comps, 'format="ascii"', text)))
    return grid(MESHIO_HEADER % "", arrays) + "</VTKFile>\n"


def meshio_binary():
    arrays = []
    for section, name, t, comps, values in meshio_arrays(
            [("PointData", "radius", "Float64", 1, RADII),
             ("PointData", "velocity", "Float64", 3, flat(VELOCITIES))]):
        data = pack("<", t, values)
        text = base64.b64encode(struct.pack("<I", len(data)) + data).decode()
        arrays.append((section, element(name, t, comps, 'format="binary"', "\n" + text + "\n")))
    return grid(MESHIO_HEADER % "", arrays) + "</VTKFile>\n"


def zlib_block(data, order, header_code, block_size):
    """(header, compressed blocks) of `data` in blocks of `block_size` bytes."""
    blocks = [data[k:k + block_size] for k in range(0, len(data), block_size)]
    packed = [zlib.compress(b) for b in blocks]
    last = len(blocks[-1]) if blocks and len(blocks[-1]) < block_size else 0
    sizes = [len(blocks), block_size, last] + [len(p) for p in packed]
    return struct.pack(order + header_code * len(sizes), *sizes), b"".join(packed)


def meshio_zlib():
    arrays = []
    for section, name, t, comps, values in meshio_arrays(
            [("PointData", "diameter", "Float64", 1, [2 * r for r in RADII])]):
        header, blocks = zlib_block(pack("<", t, values), "<", "I", 32768)
        text = base64.b64encode(header).decode() + base64.b64encode(blocks).decode()
        arrays.append((section, element(name, t, comps, 'format="binary"', "\n" + text + "\n")))
    compressor = ' compressor="vtkZLibDataCompressor"'
    return grid(MESHIO_HEADER % compressor, arrays) + "</VTKFile>\n"


def vtk_appended_zlib():
    arrays, data = [], b""
    for section, name, t, comps, values in [
            ("Points", "Points", "Float32", 3, flat(CENTRES)),
            *[("Cells",) + c for c in cells("Int32")],
            ("PointData", "radii", "Float32", 1, RADII),
            ("PointData", "velocity", "Float32", 3, flat(VELOCITIES))]:
        header, blocks = zlib_block(pack("<", t, values), "<", "I", 16)
        attributes = 'format="appended" offset="%d"' % len(data)
        arrays.append((section, element(name, t, comps, attributes, "")))
        data += header + blocks
    head = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt32" '
            'compressor="vtkZLibDataCompressor">\n')
    xml = grid(head, arrays, tail='<AppendedData encoding="raw">\n   _')
    return xml.encode() + data + b"\n</AppendedData>\n</VTKFile>\n"


def vtk_big_endian():
    arrays, data = [], ""
    apart = lambda b: (base64.b64encode(struct.pack(">Q", len(b))).decode()
                       + base64.b64encode(b).decode())
    for section, name, t, comps, values in [
            ("Points", "Points", "Float64", 3, flat(CENTRES)),
            *[("Cells",) + c for c in cells("Int64")],
            ("PointData", "r", "Float32", 1, RADII),
            ("PointData", "velocity", "Float64", 3, flat(VELOCITIES))]:
        encoded = apart(pack(">", t, values))
        if section == "Points":
            arrays.append((section, element(name, t, comps, 'format="binary"',
                                            "\n  " + encoded + "\n")))
        else:
            attributes = 'format="appended" offset="%d"' % len(data)
            arrays.append((section, element(name, t, comps, attributes, "")))
            data += encoded
    field = ('<FieldData>\n'
             '<DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" format="binary">'
             + apart(pack(">", "Float64", [0.375])) + '</DataArray>\n'
             '<DataArray type="UInt64" Name="step" NumberOfTuples="1" format="ascii">'
             '12</DataArray>\n</FieldData>\n')
    head = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            'byte_order="BigEndian" header_type="UInt64">\n')
    tail = '<AppendedData encoding="base64">\n   _' + data + "\n</AppendedData>\n"
    return grid(head, arrays, field, tail) + "</VTKFile>\n"


def write(name, data):
    with open(name, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


write("vtu_meshio_ascii.vtu", meshio_ascii())
write("vtu_meshio_binary.vtu", meshio_binary())
write("vtu_meshio_zlib.vtu", meshio_zlib())
write("vtu_vtk_appended_zlib.vtu", vtk_appended_zlib())
write("vtu_vtk_big_endian.vtu", vtk_big_endian())
