#!/usr/bin/env python3
# One-off conversion of CGAL's liver.inr.gz (INRIMAGE-4, uint8) to a cropped gzip NRRD.
import gzip, sys
raw = gzip.open(sys.argv[1]).read()
end = raw.index(b'##}\n') + 4
fields = dict(l.split('=', 1) for l in raw[:end].decode().splitlines() if '=' in l)
X, Y, Z = int(fields['XDIM']), int(fields['YDIM']), int(fields['ZDIM'])
assert fields['TYPE'] == 'unsigned fixed' and fields['PIXSIZE'] == '8 bits' and fields['VDIM'] == '1'
sp = [float(fields['VX']), float(fields['VY']), float(fields['VZ'])]
data = raw[end:end + X * Y * Z]
assert len(data) == X * Y * Z
print({v: data.count(bytes([v])) for v in (0, 85, 127, 255)}, len(data))
lo = [X, Y, Z]; hi = [-1, -1, -1]
for z in range(Z):
    for y in range(Y):
        row = data[(z * Y + y) * X:(z * Y + y + 1) * X]
        s = row.lstrip(b'\0')
        if not s: continue
        x0 = X - len(s); x1 = len(row.rstrip(b'\0')) - 1
        lo = [min(lo[0], x0), min(lo[1], y), min(lo[2], z)]
        hi = [max(hi[0], x1), max(hi[1], y), max(hi[2], z)]
print('labelled bbox', lo, hi)
m = 2  # margin: the surface needs outside samples around it
dims = [X, Y, Z]
lo = [max(0, l - m) for l in lo]; hi = [min(d - 1, h + m) for h, d in zip(hi, dims)]
n = [h - l + 1 for l, h in zip(lo, hi)]
out = bytearray()
for z in range(lo[2], hi[2] + 1):
    for y in range(lo[1], hi[1] + 1):
        b = (z * Y + y) * X
        out += data[b + lo[0]:b + hi[0] + 1]
origin = [l * s for l, s in zip(lo, sp)]
header = ('NRRD0004\n'
          '# Liver segmentation from CGAL 5.5 example data (data/images/liver.inr.gz, CC0 1.0),\n'
          f'# cropped to its labelled region plus {m} samples: original sample {lo} is sample 0.\n'
          '# Labels: 255 liver, 127 and 85 two other structures, 0 background.\n'
          'type: uint8\ndimension: 3\nspace: left-posterior-superior\n'
          f'sizes: {n[0]} {n[1]} {n[2]}\n'
          f'space directions: ({sp[0]},0,0) (0,{sp[1]},0) (0,0,{sp[2]})\n'
          'kinds: domain domain domain\nencoding: gzip\n'
          f'space origin: ({origin[0]:.6g},{origin[1]:.6g},{origin[2]:.6g})\n\n')
with open(sys.argv[2], 'wb') as f:
    f.write(header.encode())
    f.write(gzip.compress(bytes(out), compresslevel=9, mtime=0))
print('dims', n, 'bytes', len(out))
