#!/usr/bin/env python3
"""Finite-element reference for `bisturi tissue indent`, solved with CalculiX (ccx).

The same problem as the bisturi command (docs/sim/tissue.md, "Checking it against a solid"),
as an axisymmetric model in (r, z):

  sphere  radius S; its bottom cap (a fiftieth of its height, z < -S + 2S/50) is rigid and
          held, so the body is the sphere cut at that plane with the cut face fixed.
  block   the cube of side S as the cylinder of the same cross-section area (radius
          S / sqrt(pi)) and height S, its bottom face fixed.

The probe is a rigid sphere of radius R touching the top at the start and moved along -z;
it is modelled as a thick shell (radii R/2 to R) a thousand times stiffer than the tissue,
its inner face driven, in frictionless surface-to-surface contact with the tissue. The
tissue is compressible neo-Hookean (C10 = G/2, D1 = 2/K) with NLGEOM, in CAX8 elements
graded towards the contact. Units in the input deck: mm, N, MPa.

Standard library only. Run with --help for the options.
"""

import argparse
import json
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

# The presets of docs/sim/tissue.md that matter here: E (kPa), nu.
PRESETS = {
    "liver": (4.0, 0.45),
    "kidney": (4.4, 0.45),
    "spleen": None,  # left to --youngs-kPa: only liver and kidney are checked here
}
PRESETS = {k: v for k, v in PRESETS.items() if v}

CAP_FRACTION = 1.0 / 50.0  # bisturi holds the sphere's bottom cap of this fraction of its height
PROBE_STIFFNESS = 1000.0   # probe modulus over the tissue's: its compliance is 0.1 % of the tissue's
SLICE_FACTOR = 180.0       # ccx expands CAX elements over 2 degrees: x180 gives the full ring


# ---------------------------------------------------------------------------------------------
# Hertz contact, as bisturi computes it.

def hertz_approach(force, e_star, probe_r, body_r):
    """Approach of a rigid sphere probe_r pressed by `force` onto a body of curvature radius
    body_r (math.inf: a half space)."""
    reff = probe_r if math.isinf(body_r) else probe_r * body_r / (probe_r + body_r)
    return (9.0 * force * force / (16.0 * e_star * e_star * reff)) ** (1.0 / 3.0)


def hertz_force(depth, e_star, probe_r, body_r, sphere):
    """Force for an approach `depth`: at the probe alone (block) or at the probe and at the
    plane in series (sphere: the plane sees a sphere of radius body_r)."""
    if depth <= 0.0:
        return 0.0

    def approach(f):
        a = hertz_approach(f, e_star, probe_r, body_r)
        if sphere:
            a += hertz_approach(f, e_star, 1e300, body_r)  # the plane: radius R, the sphere alone
        return a

    lo, hi = 0.0, 1.0
    while approach(hi) < depth:
        hi *= 2.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if approach(mid) < depth:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ---------------------------------------------------------------------------------------------
# Meshing: structured blocks by transfinite interpolation, CAX8 (eight-node quadrilaterals).

def graded(n, first, length):
    """n+1 parameters in [0, 1]: the first interval `first` (in units of `length`), the others
    growing geometrically; uniform when that would not be finer than uniform."""
    h = first / length
    if h * n >= 1.0:
        return [k / n for k in range(n + 1)]
    lo, hi = 1.0, 10.0
    for _ in range(200):  # the ratio q with h (q^n - 1) / (q - 1) = 1
        q = 0.5 * (lo + hi)
        if h * (q ** n - 1.0) / (q - 1.0) < 1.0:
            lo = q
        else:
            hi = q
    t, s = [0.0], h
    for _ in range(n):
        t.append(t[-1] + s)
        s *= q
    return [x / t[-1] for x in t]


def with_midpoints(t):
    """The 2n+1 parameters of a quadratic edge: the n+1 corners and the midpoints between."""
    out = []
    for a, b in zip(t, t[1:]):
        out += [a, 0.5 * (a + b)]
    return out + [t[-1]]


def line(p, q, t):
    return [(p[0] + (q[0] - p[0]) * s, p[1] + (q[1] - p[1]) * s) for s in t]


def arc(radius, phi0, phi1, t, centre=(0.0, 0.0)):
    """Points on a circle by polar angle phi from +z (phi = 0 the top pole)."""
    out = []
    for s in t:
        phi = phi0 + (phi1 - phi0) * s
        out.append((centre[0] + radius * math.sin(phi), centre[1] + radius * math.cos(phi)))
    return out


def arclength_params(pts):
    d = [0.0]
    for a, b in zip(pts, pts[1:]):
        d.append(d[-1] + math.dist(a, b))
    return [x / d[-1] for x in d]


def coons(bottom, top, left, right):
    """Grid points [j][i] of the patch bounded by four point lists (bottom/top along i, left/
    right along j; corners shared). Blending parameters follow each side's arclength, so the
    sides' grading carries into the interior."""
    ni, nj = len(bottom), len(left)
    sb, st, sl, sr = (arclength_params(x) for x in (bottom, top, left, right))
    p00, p10, p01, p11 = bottom[0], bottom[-1], top[0], top[-1]
    grid = []
    for j in range(nj):
        row = []
        for i in range(ni):
            u, v = sb[i], sl[j]
            for _ in range(20):  # u depends on v and v on u: a few fixed-point sweeps settle it
                u = (1 - v) * sb[i] + v * st[i]
                v = (1 - u) * sl[j] + u * sr[j]
            pt = []
            for c in range(2):
                pt.append((1 - v) * bottom[i][c] + v * top[i][c] + (1 - u) * left[j][c]
                          + u * right[j][c]
                          - ((1 - u) * (1 - v) * p00[c] + u * (1 - v) * p10[c]
                             + (1 - u) * v * p01[c] + u * v * p11[c]))
            row.append(tuple(pt))
        grid.append(row)
    return grid


class Mesh:
    """Nodes merged by position (blocks share their edges), CAX8 elements, and the faces and
    node sets the deck needs."""

    def __init__(self):
        self.nodes = []      # (r, z)
        self.index = {}
        self.elements = []   # (elset, [8 node ids])
        self.faces = {}      # surface name -> [(element id, face label)]

    def node(self, p):
        key = (round(p[0], 7), round(p[1], 7))
        if key not in self.index:
            self.nodes.append(p)
            self.index[key] = len(self.nodes)
        return self.index[key]

    def add_block(self, elset, grid, surfaces=None):
        """Elements of a grid of (2n+1) x (2m+1) points; surfaces maps a side ('bottom',
        'top', 'left', 'right') to the surface name its element faces join."""
        surfaces = surfaces or {}
        ids = [[self.node(p) for p in row] for row in grid]
        nj, ni = (len(grid) - 1) // 2, (len(grid[0]) - 1) // 2
        for j in range(nj):
            for i in range(ni):
                a, b = 2 * i, 2 * j
                corners = [ids[b][a], ids[b][a + 2], ids[b + 2][a + 2], ids[b + 2][a]]
                mids = [ids[b][a + 1], ids[b + 1][a + 2], ids[b + 2][a + 1], ids[b + 1][a]]
                self.elements.append((elset, corners + mids))
                e = len(self.elements)
                # CAX faces: S1 nodes 1-2 (bottom), S2 2-3 (right), S3 3-4 (top), S4 4-1 (left).
                for side, on, label in (("bottom", j == 0, "S1"), ("right", i == ni - 1, "S2"),
                                        ("top", j == nj - 1, "S3"), ("left", i == 0, "S4")):
                    if on and side in surfaces:
                        self.faces.setdefault(surfaces[side], []).append((e, label))

    def nodes_where(self, test):
        return [k + 1 for k, p in enumerate(self.nodes) if test(p)]


def sphere_tissue(mesh, size, fine, n):
    """The sphere of radius `size` cut at its held cap, as an O-grid: a core square and three
    ring blocks (top, side, bottom), graded to `fine` at the top pole."""
    c = 0.45 * size
    z0 = -size + 2.0 * size * CAP_FRACTION
    phi_end = math.acos(z0 / size)
    q1, q3 = math.pi / 4, 3 * math.pi / 4
    n1, n2, m = n, max(4, n // 2), max(6, (3 * n) // 4)
    top_arc = graded(n1, fine, size * q1)
    radial_top = [1 - x for x in reversed(graded(m, fine, size - c))]  # fine at the surface
    u1, u2, um = ([k / k_n for k in range(k_n + 1)] for k_n in (n1, n2, m))
    diag45 = line((c, c), arc(size, q1, q1, [0])[0], with_midpoints(um))
    diag135 = line((c, -c), arc(size, q3, q3, [0])[0], with_midpoints(um))
    # Top block: i along +r, j up towards the arc from phi = 0 to 45 degrees.
    mesh.add_block("TISSUE", coons(line((0, c), (c, c), with_midpoints(u1)),
                                   arc(size, 0.0, q1, with_midpoints(top_arc)),
                                   line((0, c), (0, size), with_midpoints(radial_top)),
                                   diag45), {"top": "TOP"})
    # Side block: i down along the core's right edge, j out to the arc from 45 to 135 degrees.
    side_arc = graded(n2, size * q1 * (top_arc[-1] - top_arc[-2]), size * (q3 - q1))
    mesh.add_block("TISSUE", coons(line((c, c), (c, -c), with_midpoints(u2)),
                                   arc(size, q1, q3, with_midpoints(side_arc)),
                                   diag45, diag135), {"top": "TOP"})
    # Bottom block: i from r = c to the axis, j down to the arc below 135 degrees and the cut.
    n_arc = max(2, n1 // 3)
    lower = arc(size, q3, phi_end, with_midpoints([k / n_arc for k in range(n_arc + 1)]))
    flat = line((math.sqrt(size * size - z0 * z0), z0), (0.0, z0),
                with_midpoints([k / (n1 - n_arc) for k in range(n1 - n_arc + 1)]))
    mesh.add_block("TISSUE", coons(line((c, -c), (0, -c), with_midpoints(u1)),
                                   lower + flat[1:], diag135,
                                   line((0, -c), (0, z0), with_midpoints(um))))
    # Core: i along +r, j up.
    mesh.add_block("TISSUE", coons(line((0, -c), (c, -c), with_midpoints(u1)),
                                   line((0, c), (c, c), with_midpoints(u1)),
                                   line((0, -c), (0, c), with_midpoints(u2)),
                                   line((c, -c), (c, c), with_midpoints(u2))))
    return size, lambda p: abs(p[1] - z0) < 1e-6


def cylinder_tissue(mesh, size, fine, n):
    """The cube of side `size` as the cylinder of the same cross-section (radius size/sqrt(pi))
    and height, graded to `fine` at the top of the axis."""
    radius = size / math.sqrt(math.pi)
    along_r = with_midpoints(graded(n, fine, radius))
    along_z = with_midpoints([1 - x for x in reversed(graded(n, fine, size))])
    mesh.add_block("TISSUE", coons(line((0, 0), (radius, 0), along_r),
                                   line((0, size), (radius, size), along_r),
                                   line((0, 0), (0, size), along_z),
                                   line((radius, 0), (radius, size), along_z)), {"top": "TOP"})
    return size, lambda p: abs(p[1]) < 1e-6


def probe_shell(mesh, radius, centre_z, fine, n):
    """The probe: a shell from radius/2 to radius about (0, centre_z), from the bottom pole to
    135 degrees round (past the equator, for deep indentation). j runs inwards so that the
    elements turn anticlockwise; the outer face is the contact surface."""
    around = with_midpoints(graded(n, fine, radius * 0.75 * math.pi))
    grid = []
    for rho in (radius * (1.0 - 0.5 * s) for s in with_midpoints([k / 4 for k in range(5)])):
        grid.append(arc(rho, math.pi, math.pi * 0.25, around, centre=(0.0, centre_z)))
    mesh.add_block("PROBE", grid, {"bottom": "PROBE_OUT"})
    return lambda p: abs(math.dist(p, (0.0, centre_z)) - 0.5 * radius) < 1e-6


# ---------------------------------------------------------------------------------------------
# The CalculiX deck.

def neo_hooke(e_kpa, nu):
    """C10 and D1 (MPa units) of the compressible neo-Hookean law with the small-strain
    shear and bulk moduli of E and nu."""
    e = e_kpa * 1e-3
    g = e / (2.0 * (1.0 + nu))
    k = e / (3.0 * (1.0 - 2.0 * nu))
    return g / 2.0, 2.0 / k


def id_lines(ids, per_line=12):
    return "\n".join(", ".join(str(x) for x in ids[k:k + per_line])
                     for k in range(0, len(ids), per_line))


def write_deck(path, mesh, sets, e_kpa, nu, depth, fractions, fine):
    c10, d1 = neo_hooke(e_kpa, nu)
    out = ["*HEADING", "bisturi indent reference (indent_ccx.py)", "*NODE"]
    out += [f"{k + 1}, {p[0]:.9g}, {p[1]:.9g}" for k, p in enumerate(mesh.nodes)]
    for elset in ("TISSUE", "PROBE"):
        out.append(f"*ELEMENT, TYPE=CAX8, ELSET={elset}")
        out += [f"{e + 1}, " + ", ".join(map(str, nodes))
                for e, (name, nodes) in enumerate(mesh.elements) if name == elset]
    for name, ids in sets.items():
        out += [f"*NSET, NSET={name}", id_lines(ids)]
    for name, faces in mesh.faces.items():
        out.append(f"*SURFACE, NAME={name}, TYPE=ELEMENT")
        out += [f"{e}, {label}" for e, label in faces]
    # A penalty stiffness that keeps the overclosure at a few % of the finest element.
    penalty = 200.0 * e_kpa * 1e-3 / fine
    out += ["*MATERIAL, NAME=TISSUE", "*HYPERELASTIC, NEO HOOKE", f"{c10:.9g}, {d1:.9g}",
            "*MATERIAL, NAME=PROBE", "*ELASTIC", f"{PROBE_STIFFNESS * e_kpa * 1e-3:.9g}, 0.3",
            "*SOLID SECTION, ELSET=TISSUE, MATERIAL=TISSUE",
            "*SOLID SECTION, ELSET=PROBE, MATERIAL=PROBE",
            "*SURFACE INTERACTION, NAME=FRICTIONLESS",
            "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", f"{penalty:.9g}",
            "*CONTACT PAIR, INTERACTION=FRICTIONLESS, TYPE=SURFACE TO SURFACE",
            "TOP, PROBE_OUT",
            "*TIME POINTS, NAME=SAMPLES", ", ".join(f"{t:.9g}" for t in fractions),
            "*STEP, NLGEOM, INC=10000", "*STATIC",
            f"{0.25 * fractions[0]:.6g}, 1.0, 1e-7, {0.5 * fractions[0]:.6g}",
            "*BOUNDARY", "BASE, 1, 2, 0.0", "AXIS, 1, 1, 0.0",
            "DRIVE, 1, 1, 0.0", f"DRIVE, 2, 2, {-depth:.9g}",
            "*NODE PRINT, NSET=DRIVE, TOTALS=ONLY, TIME POINTS=SAMPLES", "RF",
            "*END STEP"]
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def build_model(args, workdir, fractions):
    """Meshes the problem, writes the deck and returns its job name and node count."""
    mesh = Mesh()
    fine = args.fine_mm
    if args.shape == "sphere":
        top, is_base = sphere_tissue(mesh, args.size_mm, fine, args.elements)
    else:
        top, is_base = cylinder_tissue(mesh, args.size_mm, fine, args.elements)
    is_drive = probe_shell(mesh, args.probe_radius_mm, top + args.probe_radius_mm, fine,
                           args.elements)
    sets = {"BASE": mesh.nodes_where(is_base),
            "AXIS": mesh.nodes_where(lambda p: abs(p[0]) < 1e-9 and not is_drive(p)),
            "DRIVE": mesh.nodes_where(is_drive)}
    job = "indent"
    write_deck(os.path.join(workdir, job + ".inp"), mesh, sets, args.e_kpa, args.nu,
               args.depth_mm, fractions, fine)
    return job, len(mesh.nodes), sum(1 for name, _ in mesh.elements if name == "TISSUE")


# ---------------------------------------------------------------------------------------------
# Running ccx and reading its results.

def find_ccx():
    ccx = shutil.which("ccx")
    if not ccx:
        sys.exit("indent_ccx: CalculiX's ccx is not on PATH. Install the Debian package "
                 "calculix-ccx (tools/install-deps.sh --bench-peers installs it).")
    return ccx


def run_ccx(ccx, workdir, job, depth):
    """Runs ccx, showing the step's progress as depth on stderr; exits with the tail of its
    output when it fails."""
    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    log_path = os.path.join(workdir, job + ".log")
    tail = []
    with open(log_path, "w") as log:
        proc = subprocess.Popen([ccx, "-i", job], cwd=workdir, env=env, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        for line_ in proc.stdout:
            log.write(line_)
            tail = (tail + [line_.rstrip()])[-30:]
            m = re.search(r"actual total time\s*=\s*([0-9.Ee+-]+)", line_)
            if m:
                t = float(m.group(1))
                print(f"\rccx: depth {t * depth:7.3f} of {depth:g} mm", end="", file=sys.stderr,
                      flush=True)
        proc.wait()
    print(file=sys.stderr)
    dat = os.path.join(workdir, job + ".dat")
    failed = proc.returncode != 0 or any("*ERROR" in t for t in tail) or not os.path.exists(dat)
    if failed:
        sys.exit("indent_ccx: ccx failed (exit %d). Last lines of its output:\n  %s\n"
                 "work dir: %s (log %s)" % (proc.returncode, "\n  ".join(tail), workdir,
                                            log_path))


def read_forces(dat_path):
    """(time, axial force on the whole ring) for each printed total of the driven nodes."""
    out = []
    with open(dat_path) as f:
        text = f.read()
    pattern = r"total force \(fx,fy,fz\) for set DRIVE and time\s+([0-9.Ee+-]+)\s+" \
              r"([0-9.Ee+-]+)\s+([0-9.Ee+-]+)\s+([0-9.Ee+-]+)"
    for m in re.finditer(pattern, text):
        # The reaction holds the probe down against the tissue: minus its z is the force.
        out.append((float(m.group(1)), -float(m.group(3)) * SLICE_FACTOR))
    return out


# ---------------------------------------------------------------------------------------------
# bisturi.

def run_bisturi(args):
    cmd = [args.bisturi, "tissue", "indent", "--shape", args.shape,
           "--size-mm", repr(args.size_mm), "--probe-radius-mm", repr(args.probe_radius_mm),
           "--depth-mm", repr(args.depth_mm), "--points", str(args.points),
           "--poisson", repr(args.nu), "--json"]
    cmd += ["--material", args.material] if args.material else ["--youngs-kPa", repr(args.e_kpa)]
    cmd += shlex.split(args.bisturi_args or "")
    print("bisturi: " + " ".join(shlex.quote(c) for c in cmd), file=sys.stderr)
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        sys.exit("indent_ccx: bisturi failed (exit %d):\n%s" % (proc.returncode,
                                                                proc.stderr[-2000:]))
    return json.loads(proc.stdout)


# ---------------------------------------------------------------------------------------------
# Output.

def svg_plot(path, title, depth, series):
    """Force (mN) against depth (mm), one polyline with markers per series, axes and a
    legend; `series` is [(label, colour, values in N)]."""
    w, h, left, right, top, bottom = 640, 420, 70, 20, 40, 50
    fmax = max(max(v) for _, _, v in series) * 1e3 * 1.05 or 1.0
    dmax = max(depth)

    def x(d):
        return left + (w - left - right) * d / dmax

    def y(f):
        return h - bottom - (h - top - bottom) * f / fmax

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
             f'font-family="sans-serif" font-size="12">',
             f'<rect width="{w}" height="{h}" fill="white"/>',
             f'<text x="{w / 2}" y="22" text-anchor="middle" font-size="14">{title}</text>']
    for k in range(6):
        fv, dv = fmax * k / 5, dmax * k / 5
        parts.append(f'<line x1="{left}" y1="{y(fv):.1f}" x2="{w - right}" y2="{y(fv):.1f}" '
                     f'stroke="#ddd"/><text x="{left - 6}" y="{y(fv) + 4:.1f}" '
                     f'text-anchor="end">{fv:.3g}</text>')
        parts.append(f'<text x="{x(dv):.1f}" y="{h - bottom + 16}" '
                     f'text-anchor="middle">{dv:.3g}</text>')
    parts.append(f'<rect x="{left}" y="{top}" width="{w - left - right}" '
                 f'height="{h - top - bottom}" fill="none" stroke="black"/>')
    parts.append(f'<text x="{(left + w - right) / 2}" y="{h - 12}" text-anchor="middle">'
                 f'depth (mm)</text>')
    parts.append(f'<text x="16" y="{(top + h - bottom) / 2}" text-anchor="middle" '
                 f'transform="rotate(-90 16 {(top + h - bottom) / 2})">force (mN)</text>')
    for n, (label, colour, values) in enumerate(series):
        pts = [(0.0, 0.0)] + list(zip(depth, (v * 1e3 for v in values)))
        path_ = " ".join(f"{x(d):.1f},{y(f):.1f}" for d, f in pts)
        parts.append(f'<polyline points="{path_}" fill="none" stroke="{colour}" '
                     f'stroke-width="2"/>')
        parts += [f'<circle cx="{x(d):.1f}" cy="{y(f):.1f}" r="3" fill="{colour}"/>'
                  for d, f in pts[1:]]
        ly = top + 18 + 18 * n
        parts.append(f'<line x1="{left + 12}" y1="{ly}" x2="{left + 36}" y2="{ly}" '
                     f'stroke="{colour}" stroke-width="2"/><text x="{left + 42}" '
                     f'y="{ly + 4}">{label}</text>')
    parts.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(parts) + "\n")


def print_table(result):
    have_b = "bisturi_N" in result
    head = f"{'depth_mm':>9} {'fem_N':>12} {'hertz_N':>12} {'fem/hertz':>10}"
    if have_b:
        head += f" {'bisturi_N':>12} {'bisturi/fem-1':>14}"
    print(head)
    for k, d in enumerate(result["depth_mm"]):
        fem, hz = result["fem_N"][k], result["hertz_N"][k]
        row = f"{d:9.3f} {fem:12.5g} {hz:12.5g} {fem / hz:10.3f}"
        if have_b:
            row += f" {result['bisturi_N'][k]:12.5g} {100 * result['relative_error'][k]:13.1f}%"
        print(row)


# ---------------------------------------------------------------------------------------------

def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Finite-element (CalculiX) reference for `bisturi tissue indent`: an "
                    "axisymmetric neo-Hookean sphere or block pressed by a rigid sphere, "
                    "beside Hertz and, with --bisturi, bisturi's own curve (its default model).")
    p.add_argument("--shape", choices=("sphere", "block"), required=True,
                   help="sphere: radius S, bottom cap held; block: cube of side S, as a "
                        "cylinder of the same cross-section and height, bottom held")
    p.add_argument("--size-mm", type=float, required=True, help="S (mm)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--material", choices=sorted(PRESETS), help="a tissue preset")
    g.add_argument("--youngs-kPa", type=float, help="Young's modulus (kPa)")
    p.add_argument("--poisson", type=float, help="Poisson's ratio (default: the preset's, 0.45)")
    p.add_argument("--probe-radius-mm", type=float, required=True, help="R (mm)")
    p.add_argument("--depth-mm", type=float,
                   help="D, the deepest indentation (mm; default 20 %% strain: 0.2 x the "
                        "sphere's diameter 2S or the block's height S)")
    p.add_argument("--points", type=int, default=8, help="depths sampled up to D (default 8)")
    p.add_argument("--elements", type=int, default=24,
                   help="elements along the graded edges (default 24)")
    p.add_argument("--fine-mm", type=float,
                   help="element size at the contact (mm; default R/50)")
    p.add_argument("--bisturi", metavar="PATH", help="also run PATH tissue indent and compare")
    p.add_argument("--bisturi-args", metavar="ARGS",
                   help='extra arguments for bisturi, e.g. "--vertices 20000 --settle-steps 400"')
    p.add_argument("--json", metavar="OUT", help="write the arrays as JSON")
    p.add_argument("--svg", metavar="OUT", help="write a force-depth plot as SVG")
    p.add_argument("--workdir", metavar="DIR", help="where ccx runs (default a temporary dir)")
    p.add_argument("--keep", action="store_true", help="keep the work dir")
    args = p.parse_args(argv)
    if args.material:
        args.e_kpa, preset_nu = PRESETS[args.material]
    else:
        args.e_kpa, preset_nu = args.youngs_kPa, 0.45
    args.nu = preset_nu if args.poisson is None else args.poisson
    if not 0.0 <= args.nu < 0.5 or args.e_kpa <= 0.0:
        p.error("need E > 0 and 0 <= nu < 0.5")
    if args.depth_mm is None:
        args.depth_mm = 0.2 * (2.0 * args.size_mm if args.shape == "sphere" else args.size_mm)
    if args.fine_mm is None:
        args.fine_mm = args.probe_radius_mm / 50.0
    if args.points < 1 or args.elements < 4:
        p.error("need --points >= 1 and --elements >= 4")
    return args


def compute(args, workdir):
    ccx = find_ccx()
    fractions = [k / args.points for k in range(1, args.points + 1)]
    job, nodes, elements = build_model(args, workdir, fractions)
    print(f"ccx: {elements} CAX8 tissue elements, {nodes} nodes, finest {args.fine_mm:g} mm, "
          f"in {workdir}", file=sys.stderr)
    run_ccx(ccx, workdir, job, args.depth_mm)
    forces = dict(read_forces(os.path.join(workdir, job + ".dat")))
    missing = [t for t in fractions if not any(abs(t - s) < 1e-6 for s in forces)]
    if missing:
        sys.exit(f"indent_ccx: ccx printed no force at step times {missing}; work dir {workdir}")
    fem = [next(f for s, f in forces.items() if abs(t - s) < 1e-6) for t in fractions]
    e_star = args.e_kpa * 1e3 / (1.0 - args.nu ** 2)
    sphere = args.shape == "sphere"
    body_r = args.size_mm * 1e-3 if sphere else math.inf
    depth = [t * args.depth_mm for t in fractions]
    hertz = [hertz_force(d * 1e-3, e_star, args.probe_radius_mm * 1e-3, body_r, sphere)
             for d in depth]
    return {"shape": args.shape, "size_mm": args.size_mm,
            "material": args.material or "custom", "youngs_modulus_kPa": args.e_kpa,
            "poisson_ratio": args.nu, "probe_radius_mm": args.probe_radius_mm,
            "element": "CAX8", "tissue_elements": elements, "nodes": nodes,
            "finest_mm": args.fine_mm, "depth_mm": depth, "fem_N": fem, "hertz_N": hertz}


def main(argv):
    args = parse_args(argv)
    workdir = args.workdir or tempfile.mkdtemp(prefix="indent_ccx_")
    os.makedirs(workdir, exist_ok=True)
    result = compute(args, workdir)
    if args.bisturi:
        b = run_bisturi(args)
        result["bisturi_N"] = b["force_N"]
        result["bisturi_vertices"] = b.get("vertices")
        result["relative_error"] = [bf / f - 1.0 for bf, f in zip(b["force_N"], result["fem_N"])]
    title = (f"{args.shape} S = {args.size_mm:g} mm, {result['material']} "
             f"(E = {args.e_kpa:g} kPa, nu = {args.nu:g}), probe R = {args.probe_radius_mm:g} mm")
    print(title)
    print_table(result)
    ratio = result["fem_N"][0] / result["hertz_N"][0]
    print(f"FEM against Hertz at the shallowest depth ({result['depth_mm'][0]:g} mm): "
          f"{100 * (ratio - 1):+.1f} %")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=2)
    if args.svg:
        series = [("FEM (CalculiX)", "#1f77b4", result["fem_N"]),
                  ("Hertz", "#7f7f7f", result["hertz_N"])]
        if "bisturi_N" in result:
            series.append(("bisturi", "#d62728", result["bisturi_N"]))
        svg_plot(args.svg, title, result["depth_mm"], series)
    if not args.workdir and not args.keep:
        shutil.rmtree(workdir, ignore_errors=True)
    elif not args.workdir:
        print(f"work dir kept: {workdir}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
