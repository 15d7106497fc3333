#!/usr/bin/env python3
"""Writes the seed corpora in corpus/<format>/: tiny valid files and edge cases (kept in git;
run again only to change them)."""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(fmt, name, data):
    os.makedirs(os.path.join(HERE, "corpus", fmt), exist_ok=True)
    with open(os.path.join(HERE, "corpus", fmt, name), "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_F = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (2, 0, 3)]

# OBJ
write("obj", "tetra.obj", "".join("v %g %g %g\n" % v for v in TETRA_V)
      + "".join("f %d %d %d\n" % tuple(i + 1 for i in f) for f in TETRA_F))
write("obj", "forms.obj", "# quad and pentagon\nmtllib a.mtl\no x\nv 0 0 0\nv 1 0 0\nv 1 1 0\n"
      "v 0 1 0\nv 0.5 2 0 1\nvt 0 0\nvn 0 0 1\ng g\ns off\nusemtl m\nf 1/1 2/1 3/1 4/1\n"
      "f 1//1 2//1 3//1 5//1 4//1\nf 4/1/1 3/1/1 5/1/1\nl 1 2\n")
write("obj", "relative.obj", "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf -3 -2 -1\r\nv 1e-3 -2.5E+2 +7\r\n"
      "f -1 \\\r\n -2 1\r\nf 1\r\nf 1 2\r\n")
write("obj", "forward.obj", "f 1 2 3\nv 0 0 0 # c\nv 1 0 0\nv 0 1 0\n")

# PLY


def ply(encoding, elements):
    """elements: (name, [(type, name, count_type or None)], [record: [values per property]])"""
    codes = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I",
             "float": "f", "double": "d"}
    head = "ply\nformat %s 1.0\ncomment seed\n" % encoding
    for name, props, records in elements:
        head += "element %s %d\n" % (name, len(records))
        for t, n, c in props:
            head += ("property list %s %s %s\n" % (c, t, n)) if c else ("property %s %s\n" % (t, n))
    head += "end_header\n"
    body = b""
    order = "<" if encoding == "binary_little_endian" else ">"
    for name, props, records in elements:
        for rec in records:
            line = []
            for (t, n, c), values in zip(props, rec):
                values = values if isinstance(values, list) else [values]
                if encoding == "ascii":
                    if c:
                        line.append(str(len(values)))
                    line += [repr(v) for v in values]
                else:
                    if c:
                        body += struct.pack(order + codes[c], len(values))
                    for v in values:
                        body += struct.pack(order + codes[t], v)
            if encoding == "ascii":
                body += (" ".join(line) + "\n").encode()
    return head.encode() + body


BUSY = [
    ("material", [("uchar", "red", None), ("float", "shine", None)], [[1, 0.5]]),
    ("vertex", [("uchar", "flags", None), ("float", "x", None), ("float", "tags", "uchar"),
                ("double", "y", None), ("short", "z", None), ("float", "u", None)],
     [[3, 0.0, [1.0], 0.0, 0, 0.5], [1, 1.0, [], 0.0, 0, 0.5], [0, 0.0, [2.0, 3.0], 1.0, 0, 0.5],
      [0, 0.0, [], 0.0, 1, 0.5]]),
    ("edge", [("int", "vertex1", None), ("int", "vertex2", None)], [[0, 1], [1, 2]]),
    ("face", [("uchar", "m", None), ("int", "vertex_indices", "uchar"), ("float", "tc", "ushort")],
     [[0, list(f), [0.5, 0.5]] for f in TETRA_F] + [[1, [0, 1], []]]),
]
SIMPLE = [
    ("vertex", [("float", "x", None), ("float", "y", None), ("float", "z", None)],
     [list(v) for v in TETRA_V]),
    ("face", [("uint", "vertex_index", "uint")], [[list(f)] for f in TETRA_F]),
]
for enc, short in (("ascii", "ascii"), ("binary_little_endian", "le"), ("binary_big_endian", "be")):
    write("ply", "busy_%s.ply" % short, ply(enc, BUSY))
    write("ply", "tetra_%s.ply" % short, ply(enc, SIMPLE))

# STL


def binary_stl(header, tris):
    data = header.ljust(80, b" ")[:80] + struct.pack("<I", len(tris))
    for t in tris:
        data += struct.pack("<12fH", 0, 0, 1, *[c for v in t for c in v], 0)
    return data


TRIS = [[TETRA_V[i] for i in f] for f in TETRA_F]
write("stl", "tetra_binary.stl", binary_stl(b"binary seed", TRIS))
write("stl", "solid_header_binary.stl", binary_stl(b"solid but binary", TRIS[:2]))
write("stl", "empty_binary.stl", binary_stl(b"nothing", []))
write("stl", "tetra_ascii.stl", "solid tetra\n" + "".join(
    "  facet normal 0 0 0\n    outer loop\n" + "".join("      vertex %g %g %g\n" % v for v in t)
    + "    endloop\n  endfacet\n" for t in TRIS) + "endsolid tetra\n")
write("stl", "two_solids_ascii.stl", "SOLID a\nFACET NORMAL 0 0 1\nOUTER LOOP\nVERTEX 0 0 0\n"
      "VERTEX 1 0 0\nVERTEX 0 1 0\nENDLOOP\nENDFACET\nENDSOLID a\nsolid b\nendsolid b\n")

# OFF
write("off", "tetra.off", "OFF\n# tetrahedron\n4 4 6\n" + "".join("%g %g %g\n" % v for v in TETRA_V)
      + "".join("3 %d %d %d\n" % f for f in TETRA_F))
write("off", "colours.off", "COFF 4 3 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n"
      "0 0 1 1 1 1 1\n3 0 2 1 1.0 0.0 0.0\n4 0 1 3 2\n2 1 3 # short face\n")
write("off", "noff.off", "NOFF\n3 1 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n\n3 0 1 2\n")

# NRRD (volumes)
import gzip as _gzip  # noqa: E402


def nrrd(fields, body):
    return ("NRRD0004\n" + "".join("%s: %s\n" % kv for kv in fields) + "\n").encode() + body


def gz(data):
    return _gzip.compress(data, mtime=0)


CUBE = [("type", "short"), ("dimension", "3"), ("space", "left-posterior-superior"),
        ("sizes", "2 2 2"), ("space directions", "(1,0,0) (0,1.5,0) (0,0,2.5)"),
        ("kinds", "domain domain domain"), ("endian", "little")]
SHORTS = struct.pack("<8h", -1024, 0, 1, 2, 3, 400, -5, 3071)
write("nrrd", "raw.nrrd", nrrd(CUBE + [("encoding", "raw"), ("space origin", "(-10,20.5,3)")], SHORTS))
write("nrrd", "gzip.nrrd", nrrd(CUBE + [("encoding", "gzip")], gz(SHORTS)))
write("nrrd", "ascii_spacings.nrrd", nrrd(
    [("type", "float"), ("dimension", "3"), ("sizes", "3 1 2"), ("spacings", "0.5 0.5 2"),
     ("encoding", "ascii")], b"1 2.5 -3\n4e2 nan 6\n"))
write("nrrd", "ras_be_4d.nrrd", nrrd(
    [("type", "unsigned short"), ("dimension", "4"), ("space", "RAS"), ("sizes", "1 2 1 2"),
     ("space directions", "none (0.7,0,0) (0,0.7,0) (0,0,1)"), ("endian", "big"),
     ("encoding", "raw"), ("byte skip", "-1")], b"junk" + struct.pack(">4H", 1, 2, 3, 65535)))
write("nrrd", "skip_gzip.nrrd", nrrd(
    [("type", "double"), ("dimension", "3"), ("sizes", "1 1 2"), ("endian", "little"),
     ("encoding", "gz"), ("byte skip", "3"), ("line skip", "0")], gz(b"abc" + struct.pack("<2d", 1.5, -2))))

# NIfTI-1 (volumes)


def nifti(datatype, bitpix, dims, data, big=False, qform=None, sform=None, slope=0.0, inter=0.0,
          units=2, pixdim=(1.0, 1.0, 1.0, 1.0)):
    o = ">" if big else "<"
    h = bytearray(352)
    struct.pack_into(o + "i", h, 0, 348)
    struct.pack_into(o + "8h", h, 40, len(dims), *(list(dims) + [1] * (7 - len(dims))))
    struct.pack_into(o + "hh", h, 70, datatype, bitpix)
    struct.pack_into(o + "8f", h, 76, *(list(pixdim) + [1.0] * (8 - len(pixdim))))
    struct.pack_into(o + "fff", h, 108, 352.0, slope, inter)
    h[123] = units
    if qform:
        struct.pack_into(o + "h", h, 252, 1)
        struct.pack_into(o + "6f", h, 256, *qform)
    if sform:
        struct.pack_into(o + "h", h, 254, 2)
        struct.pack_into(o + "12f", h, 280, *sform)
    h[344:348] = b"n+1\0"
    return bytes(h) + data


write("nifti", "float_sform.nii", nifti(16, 32, (2, 2, 1), struct.pack("<4f", 0, 1.5, -2, 1e9),
                                        sform=(-1, 0, 0, 10, 0, -1, 0, 20, 0, 0, 2, -5)))
write("nifti", "int16_qform_be.nii", nifti(4, 16, (2, 1, 2), struct.pack(">4h", -1, 2, 300, 4),
                                           big=True, qform=(0, 0, 0.7071068, 1, 2, 3),
                                           slope=2.0, inter=-1024.0, pixdim=(-1, 0.5, 0.5, 2)))
write("nifti", "uint8_pixdim.nii.gz", gz(nifti(2, 8, (3, 1, 1), b"\x00\x7f\xff", units=1,
                                               pixdim=(1, 0.001, 0.001, 0.002))))
write("nifti", "double_4d.nii", nifti(64, 64, (1, 1, 1, 1), struct.pack("<d", 3.25)))
