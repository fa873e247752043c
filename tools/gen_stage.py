#!/usr/bin/env python3
"""Generate Footlight's bundled test stage, ``scenes/stage.glb``.

The scene re-creates the test scene of Vierjahn et al. 2010, "Improving
Photon Mapping Towards an Interactive Stage Lighting Framework", section 4:
"a stage set inspired by the Cornell Box ... The scene contained 38,000
triangles. A specular material was attached to 24 percent of these."

It is a Cornell-box-like stage open towards the audience: red wall stage
right, green wall stage left, a white-ish floor, a curved cyclorama at the
back and black masking at the top, with real set pieces (staircase, rostra,
columns, table and chairs, glass and chrome spheres, a mirror, a glass pane,
a chrome torus sculpture, curtain legs) so that triangle IDs mean something.

Conventions: metres, glTF axes (right-handed, +Y up). Origin = centre of the
setting line at floor level, +X = stage left (right of the image seen from
the audience), +Z = towards the audience, upstage is -Z.

Standard library only and deterministic: rerunning gives a byte-identical
file. The script validates what it wrote (reading it back from disk) and
exits non-zero if anything is wrong.

Usage: python3 tools/gen_stage.py [--out PATH]
"""

import argparse
import json
import math
import os
import struct
import sys

GENERATOR = "footlight tools/gen_stage.py"
TARGET_TRIANGLES = 38000
TRIANGLE_TOLERANCE = 1000
SPECULAR_RANGE = (0.23, 0.25)

# glTF constants
FLOAT = 5126
UNSIGNED_INT = 5125
ARRAY_BUFFER = 34962
ELEMENT_ARRAY_BUFFER = 34963
TRIANGLES = 4
GLB_MAGIC = 0x46546C67  # b"glTF"
CHUNK_JSON = 0x4E4F534A  # b"JSON"
CHUNK_BIN = 0x004E4942  # b"BIN\0"


# --------------------------------------------------------------------------
# Small vector / quaternion helpers
# --------------------------------------------------------------------------

def v_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def v_sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def v_scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def v_dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def v_cross(a, b):
    return (a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


def v_len(a):
    return math.sqrt(v_dot(a, a))


def v_norm(a):
    n = v_len(a)
    if n == 0.0:
        raise ValueError("cannot normalise a zero vector")
    return (a[0] / n, a[1] / n, a[2] / n)


def snap(x):
    """Round to 1e-7 so last-ulp libm differences cannot change the file."""
    x = round(x, 7)
    return 0.0 if x == 0.0 else x  # no negative zero


def q_axis_angle(axis, degrees):
    """Quaternion [x, y, z, w] for a rotation about a unit axis."""
    h = math.radians(degrees) / 2.0
    s = math.sin(h)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(h))


def q_mul(a, b):
    """Hamilton product a*b (apply b first, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def q_to_mat3(q):
    x, y, z, w = q
    return ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
            (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
            (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))


def q_from_mat3(m):
    """Quaternion [x, y, z, w] from a rotation matrix (rows)."""
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w = 0.25 * s
        x = (m[2][1] - m[1][2]) / s
        y = (m[0][2] - m[2][0]) / s
        z = (m[1][0] - m[0][1]) / s
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        w = (m[2][1] - m[1][2]) / s
        x = 0.25 * s
        y = (m[0][1] + m[1][0]) / s
        z = (m[0][2] + m[2][0]) / s
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        w = (m[0][2] - m[2][0]) / s
        x = (m[0][1] + m[1][0]) / s
        y = 0.25 * s
        z = (m[1][2] + m[2][1]) / s
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
        w = (m[1][0] - m[0][1]) / s
        x = (m[0][2] + m[2][0]) / s
        y = (m[1][2] + m[2][1]) / s
        z = 0.25 * s
    return (x, y, z, w)


def q_look_at(eye, target, up=(0.0, 1.0, 0.0)):
    """Rotation that turns a glTF camera (looking along local -Z, +Y up)
    from eye towards target."""
    fwd = v_norm(v_sub(target, eye))
    zaxis = v_scale(fwd, -1.0)
    xaxis = v_norm(v_cross(up, zaxis))
    yaxis = v_cross(zaxis, xaxis)
    m = ((xaxis[0], yaxis[0], zaxis[0]),
         (xaxis[1], yaxis[1], zaxis[1]),
         (xaxis[2], yaxis[2], zaxis[2]))
    return q_from_mat3(m)


def clean_quat(q):
    """Normalise and round a quaternion for the JSON."""
    n = math.sqrt(sum(c * c for c in q))
    return [round(c / n, 9) + 0.0 for c in q]


def mat4_trs(t, r, s):
    """Column-vector 4x4 matrix (rows) for T * R * S, as glTF defines it."""
    m3 = q_to_mat3(r)
    return [[m3[i][0] * s[0], m3[i][1] * s[1], m3[i][2] * s[2], t[i]]
            for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def mat4_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)]
            for i in range(4)]


def mat4_point(m, p):
    return tuple(m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3]
                 for i in range(3))


def mat4_dir(m, d):
    return tuple(m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2]
                 for i in range(3))


IDENTITY4 = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0],
             [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]


def node_matrix(node):
    if "matrix" in node:
        c = node["matrix"]  # column-major
        return [[c[j * 4 + i] for j in range(4)] for i in range(4)]
    return mat4_trs(node.get("translation", [0.0, 0.0, 0.0]),
                    node.get("rotation", [0.0, 0.0, 0.0, 1.0]),
                    node.get("scale", [1.0, 1.0, 1.0]))


# --------------------------------------------------------------------------
# Geometry builder
# --------------------------------------------------------------------------

class Geometry:
    """Indexed triangles with per-vertex normals.

    Every triangle is wound counter-clockwise seen from the side its vertex
    normals point to (the builder checks and fixes each one), and exactly
    degenerate triangles (poles, cap centres) are dropped.
    """

    def __init__(self):
        self.pos = []
        self.nrm = []
        self.tri = []

    def vertex(self, p, n):
        n = v_norm(n)
        self.pos.append((snap(p[0]), snap(p[1]), snap(p[2])))
        self.nrm.append((snap(n[0]), snap(n[1]), snap(n[2])))
        return len(self.pos) - 1

    def triangle(self, a, b, c):
        pa, pb, pc = self.pos[a], self.pos[b], self.pos[c]
        fn = v_cross(v_sub(pb, pa), v_sub(pc, pa))
        if v_len(fn) < 1e-10:
            return
        ns = v_add(v_add(self.nrm[a], self.nrm[b]), self.nrm[c])
        d = v_dot(v_norm(fn), v_norm(ns))
        if abs(d) < 0.05:
            raise ValueError("triangle nearly perpendicular to its normals")
        if d < 0:
            b, c = c, b
        self.tri.append((a, b, c))

    def grid(self, rows):
        """rows: list of rows, each a list of (point, normal)."""
        idx = [[self.vertex(p, n) for p, n in row] for row in rows]
        for i in range(len(idx) - 1):
            for j in range(len(idx[i]) - 1):
                a, b = idx[i][j], idx[i][j + 1]
                c, d = idx[i + 1][j + 1], idx[i + 1][j]
                self.triangle(a, b, c)
                self.triangle(a, c, d)

    def quad(self, p0, p1, p2, p3, n):
        a, b, c, d = (self.vertex(p, n) for p in (p0, p1, p2, p3))
        self.triangle(a, b, c)
        self.triangle(a, c, d)

    def box(self, lo, hi):
        """Axis-aligned box with flat normals (4 split vertices per face)."""
        for axis in range(3):
            u, w = (axis + 1) % 3, (axis + 2) % 3
            for sign in (-1.0, 1.0):
                n = [0.0, 0.0, 0.0]
                n[axis] = sign
                corners = []
                for cu, cw in ((lo[u], lo[w]), (hi[u], lo[w]),
                               (hi[u], hi[w]), (lo[u], hi[w])):
                    p = [0.0, 0.0, 0.0]
                    p[axis] = hi[axis] if sign > 0 else lo[axis]
                    p[u], p[w] = cu, cw
                    corners.append(tuple(p))
                self.quad(*corners, tuple(n))

    def box_c(self, centre, size):
        lo = tuple(centre[i] - size[i] / 2.0 for i in range(3))
        hi = tuple(centre[i] + size[i] / 2.0 for i in range(3))
        self.box(lo, hi)

    def lathe(self, pieces, segments, centre=(0.0, 0.0, 0.0)):
        """Surface of revolution about the local Y axis.

        pieces: list of smooth profile pieces, each a list of
        (r, y, nr, ny) with the outward profile normal (nr, ny). Vertices
        are split between pieces, so a piece boundary is a crease.
        """
        ring = []
        for k in range(segments + 1):
            phi = 2.0 * math.pi * (k % segments) / segments
            ring.append((math.cos(phi), math.sin(phi)))
        for piece in pieces:
            rows = []
            for r, y, nr, ny in piece:
                rows.append([((centre[0] + r * c, centre[1] + y,
                               centre[2] + r * s), (nr * c, ny, nr * s))
                             for c, s in ring])
            self.grid(rows)

    def finish(self):
        """Drop vertices no triangle uses; returns self."""
        used = sorted({i for t in self.tri for i in t})
        remap = {old: new for new, old in enumerate(used)}
        self.pos = [self.pos[i] for i in used]
        self.nrm = [self.nrm[i] for i in used]
        self.tri = [tuple(remap[i] for i in t) for t in self.tri]
        return self


# ---- profile helpers for lathe() -----------------------------------------

def arc(cr, cy, radius, a0, a1, steps):
    """Profile arc around (cr, cy) from angle a0 to a1 (radians), normals
    pointing away from the arc centre."""
    out = []
    for i in range(steps + 1):
        a = a0 + (a1 - a0) * i / steps
        c, s = math.cos(a), math.sin(a)
        if abs(c) < 1e-12:
            c = 0.0
        if abs(s) < 1e-12:
            s = 0.0
        r = cr + radius * c
        if abs(r) < 1e-12:
            r = 0.0
        out.append((r, cy + radius * s, c, s))
    return out


def disc(r, y, up):
    """Flat cap from the axis to radius r (up: normal +Y, else -Y)."""
    ny = 1.0 if up else -1.0
    return [(0.0, y, 0.0, ny), (r, y, 0.0, ny)]


def wall(r, y0, y1):
    return [(r, y0, 1.0, 0.0), (r, y1, 1.0, 0.0)]


def ring_flat(r0, r1, y, up):
    ny = 1.0 if up else -1.0
    return [(r0, y, 0.0, ny), (r1, y, 0.0, ny)]


# ---- shapes ---------------------------------------------------------------

def cylinder(g, radius, height, segments, base=(0.0, 0.0, 0.0)):
    g.lathe([disc(radius, 0.0, False), wall(radius, 0.0, height),
             disc(radius, height, True)], segments, base)


def uv_sphere(g, radius, n_lon, n_lat, centre=(0.0, 0.0, 0.0)):
    g.lathe([arc(0.0, 0.0, radius, -math.pi / 2, math.pi / 2, n_lat)],
            n_lon, centre)


def torus(g, major, minor, n_major, n_minor, centre=(0.0, 0.0, 0.0)):
    """Torus around the local Y axis (ring in the XZ plane)."""
    prof = arc(major, 0.0, minor, 0.0, 2.0 * math.pi, n_minor)
    prof[-1] = prof[0]  # close the seam exactly
    g.lathe([prof], n_major, centre)


# --------------------------------------------------------------------------
# The stage
# --------------------------------------------------------------------------

STAGE_HALF_WIDTH = 6.0
STAGE_BACK = -8.0
STAGE_FRONT = 1.0
WALL_HEIGHT = 7.0

# name: (baseColor RGB, metallic, roughness, transmission or None, doubleSided)
MATERIALS = [
    ("stage_floor_white", (0.55, 0.5, 0.45), 0.0, 0.8, None, False),
    ("wall_red_stage_right", (0.63, 0.065, 0.05), 0.0, 0.9, None, False),
    ("wall_green_stage_left", (0.14, 0.45, 0.091), 0.0, 0.9, None, False),
    ("cyclorama_light_grey", (0.7, 0.7, 0.7), 0.0, 0.9, None, False),
    ("masking_grey_black", (0.04, 0.04, 0.045), 0.0, 0.95, None, False),
    ("rostrum_grey", (0.35, 0.33, 0.3), 0.0, 0.8, None, False),
    ("stair_wood", (0.45, 0.3, 0.18), 0.0, 0.7, None, False),
    ("column_stone", (0.75, 0.72, 0.66), 0.0, 0.85, None, False),
    ("table_wood", (0.4, 0.24, 0.12), 0.0, 0.65, None, False),
    ("chair_paint_blue", (0.1, 0.15, 0.4), 0.0, 0.7, None, False),
    ("curtain_velvet_red", (0.3, 0.02, 0.03), 0.0, 0.95, None, True),
    ("plinth_white", (0.8, 0.8, 0.78), 0.0, 0.75, None, False),
    ("frame_black", (0.04, 0.04, 0.04), 0.0, 0.7, None, False),
    # specular
    ("chrome", (0.9, 0.9, 0.9), 1.0, 0.05, None, False),
    ("mirror", (0.95, 0.95, 0.95), 1.0, 0.0, None, False),
    ("polished_black_floor", (0.02, 0.02, 0.02), 0.0, 0.1, None, False),
    ("glass", (1.0, 1.0, 1.0), 0.0, 0.0, 0.9, False),
]
GLASS_IOR = 1.5


def is_specular(mat):
    pbr = mat.get("pbrMetallicRoughness", {})
    return (pbr.get("metallicFactor", 1.0) >= 0.8
            or pbr.get("roughnessFactor", 1.0) <= 0.2)


def is_transmissive(mat):
    ext = mat.get("extensions", {}).get("KHR_materials_transmission")
    return bool(ext) and ext.get("transmissionFactor", 0.0) > 0.0


def build_meshes():
    """Returns {mesh name: [(Geometry, material name), ...]} (ordered)."""
    meshes = {}
    W, B, F, H = STAGE_HALF_WIDTH, STAGE_BACK, STAGE_FRONT, WALL_HEIGHT

    # Stage deck: the floor is its top face (y = 0); the apron front face
    # (z = +1) drops 1 m to the auditorium floor.
    g = Geometry()
    g.box((-W - 0.2, -1.0, B), (W + 0.2, 0.0, F))
    meshes["deck"] = [(g.finish(), "stage_floor_white")]

    g = Geometry()
    g.box((-W - 0.2, 0.0, B), (-W, H, F))
    meshes["wall_stage_right"] = [(g.finish(), "wall_red_stage_right")]
    g = Geometry()
    g.box((W, 0.0, B), (W + 0.2, H, F))
    meshes["wall_stage_left"] = [(g.finish(), "wall_green_stage_left")]

    # Masking: three borders (hanging 1 m) and two ceiling pieces, leaving
    # gaps for the lighting bars between them and in front.
    g = Geometry()
    for z in (-0.1, -3.0, -5.8):
        g.box((-W, H - 1.0, z - 0.02), (W, H, z + 0.02))
    for z0, z1 in ((B, -6.2), (-3.6, -2.6)):
        g.box((-W, H, z0), (W, H + 0.05, z1))
    meshes["masking"] = [(g.finish(), "masking_grey_black")]

    # Cyclorama: a section of a vertical cylinder (plan radius R, vertex at
    # z = -8 on the centre line) whose bottom curves into the floor through
    # a quarter-circle cove. Each row spans x = -6 .. +6 exactly so the cyc
    # meets both side walls; raised 5 mm so the cove never touches the deck.
    R, cove, lift = 15.0, 1.2, 0.005
    zc = B + R
    n_theta, n_vertical, n_cove = 128, 6, 22
    profile = []  # (d inward from the cylinder, y, normal angle a)
    for i in range(n_vertical):
        y = H - (H - cove) * i / n_vertical
        profile.append((0.0, y, 0.0))
    for i in range(n_cove + 1):
        a = (math.pi / 2) * i / n_cove
        profile.append((cove - cove * math.cos(a), cove - cove * math.sin(a), a))
    rows = []
    for d, y, a in profile:
        rr = R - d
        t_max = math.asin(W / rr)
        row = []
        for j in range(n_theta + 1):
            t = t_max * (2.0 * j / n_theta - 1.0)
            s, c = math.sin(t), math.cos(t)
            p = (rr * s, y + lift, zc - rr * c)
            inward = (-s, 0.0, c)
            n = v_add(v_scale(inward, math.cos(a)), (0.0, math.sin(a), 0.0))
            row.append((p, n))
        rows.append(row)
    g = Geometry()
    g.grid(rows)
    meshes["cyclorama"] = [(g.finish(), "cyclorama_light_grey")]

    # Polished black strip along the downstage edge.
    g = Geometry()
    g.box((-5.0, 0.0, 0.3), (5.0, 0.004, 0.9))
    meshes["polished_strip"] = [(g.finish(), "polished_black_floor")]

    # Staircase: five solid steps (rise 0.16, going 0.35) climbing towards
    # local -Z up to the 0.8 m rostrum.
    g = Geometry()
    rise, going, width = 0.16, 0.35, 1.6
    for k in range(5):
        g.box((-width / 2, 0.0, -(k + 1) * going),
              (width / 2, (k + 1) * rise, -k * going))
    meshes["staircase"] = [(g.finish(), "stair_wood")]

    # Rostrum: unit box (x, z in [-0.5, 0.5], y in [0, 1]); nodes scale it.
    g = Geometry()
    g.box((-0.5, 0.0, -0.5), (0.5, 1.0, 0.5))
    meshes["rostrum_unit_box"] = [(g.finish(), "rostrum_grey")]

    # Column: a turned column (lathe, 48 segments) with plinth, torus
    # moulding, entasis shaft, echinus and abacus; 4.9 m high.
    seg = 48
    shaft_y0, shaft_y1, r0, r1 = 0.22, 4.6, 0.24, 0.20
    shaft = []
    n_shaft = 9
    for i in range(n_shaft + 1):
        t = i / n_shaft
        y = shaft_y0 + (shaft_y1 - shaft_y0) * t
        r = r0 - (r0 - r1) * t * t
        drdy = -(r0 - r1) * 2.0 * t / (shaft_y1 - shaft_y0)
        shaft.append((r, y, 1.0, -drdy))
    # Echinus: quarter ellipse (radii 0.10 across, 0.15 up) flaring out
    # under the abacus; the normal of (a cos t, b sin t) is (b cos t, a sin t).
    echinus = []
    for i in range(7):
        a = -math.pi / 2 + (math.pi / 2) * i / 6
        c, s = math.cos(a), math.sin(a)
        if abs(c) < 1e-12:
            c = 0.0
        echinus.append((0.20 + 0.10 * c, 4.75 + 0.15 * s, 0.15 * c, 0.10 * s))
    pieces = [
        disc(0.34, 0.0, False),
        wall(0.34, 0.0, 0.12),
        ring_flat(0.34, 0.26, 0.12, True),
        arc(0.26, 0.17, 0.05, -math.pi / 2, math.pi / 2, 8),  # torus moulding
        ring_flat(0.26, 0.24, 0.22, True),
        shaft,
        echinus,
        ring_flat(0.30, 0.36, 4.75, False),
        wall(0.36, 4.75, 4.9),
        disc(0.36, 4.9, True),
    ]
    g = Geometry()
    g.lathe(pieces, seg)
    meshes["column"] = [(g.finish(), "column_stone")]

    # Table: wooden top and four chrome legs (two primitives in one mesh).
    top, legs = Geometry(), Geometry()
    top.box((-0.7, 0.72, -0.45), (0.7, 0.76, 0.45))
    for x in (-0.62, 0.62):
        for z in (-0.37, 0.37):
            cylinder(legs, 0.03, 0.719, 24, (x, 0.0, z))
    meshes["table"] = [(top.finish(), "table_wood"), (legs.finish(), "chrome")]

    # Chair facing +Z (backrest at -Z).
    g = Geometry()
    g.box((-0.23, 0.42, -0.22), (0.23, 0.46, 0.22))  # seat
    g.box((-0.23, 0.46, -0.22), (0.23, 0.95, -0.18))  # backrest
    for x in (-0.2, 0.17):
        for z in (-0.22, 0.19):
            g.box((x, 0.0, z), (x + 0.03, 0.42, z + 0.03))
    meshes["chair"] = [(g.finish(), "chair_paint_blue")]

    # Pedestal for the glass sphere.
    g = Geometry()
    cylinder(g, 0.25, 0.9, 48)
    meshes["pedestal"] = [(g.finish(), "plinth_white")]

    g = Geometry()
    uv_sphere(g, 0.4, 48, 24)
    meshes["glass_sphere"] = [(g.finish(), "glass")]

    g = Geometry()
    uv_sphere(g, 0.6, 64, 30)
    meshes["chrome_sphere"] = [(g.finish(), "chrome")]

    # Mirror panel: mirror plane (facing +Z, 2 mm in front of the backing
    # board) in a black frame standing on two feet.
    mirror, frame = Geometry(), Geometry()
    mirror.quad((-0.55, 0.3, 0.002), (0.55, 0.3, 0.002),
                (0.55, 2.2, 0.002), (-0.55, 2.2, 0.002), (0.0, 0.0, 1.0))
    frame.box((-0.6, 0.25, -0.03), (0.6, 2.25, 0.0))  # backing board
    frame.box((-0.6, 0.25, 0.0), (-0.55, 2.25, 0.03))
    frame.box((0.55, 0.25, 0.0), (0.6, 2.25, 0.03))
    frame.box((-0.55, 2.2, 0.0), (0.55, 2.25, 0.03))
    frame.box((-0.55, 0.25, 0.0), (0.55, 0.3, 0.03))
    frame.box((-0.5, 0.0, -0.25), (-0.45, 0.25, 0.2))  # feet
    frame.box((0.45, 0.0, -0.25), (0.5, 0.25, 0.2))
    meshes["mirror_panel"] = [(mirror.finish(), "mirror"),
                              (frame.finish(), "frame_black")]

    # Glass pane (a thin closed box) held by a slotted black base.
    pane, base = Geometry(), Geometry()
    pane.box((-0.5, 0.001, -0.01), (0.5, 1.8, 0.01))
    base.box((-0.55, 0.0, 0.011), (0.55, 0.06, 0.05))
    base.box((-0.55, 0.0, -0.05), (0.55, 0.06, -0.011))
    meshes["glass_pane"] = [(pane.finish(), "glass"),
                            (base.finish(), "frame_black")]

    # Sculpture: white plinth with a chrome torus standing on it.
    g = Geometry()
    g.box((-0.3, 0.0, -0.3), (0.3, 1.0, 0.3))
    meshes["sculpture_plinth"] = [(g.finish(), "plinth_white")]
    g = Geometry()
    torus(g, 0.5, 0.12, 60, 24)
    meshes["sculpture_torus"] = [(g.finish(), "chrome")]

    # Curtain leg: a draped, wavy surface 1.2 m wide, hanging from 6.8 m;
    # folds deepen towards the floor and drift slightly. Faces +Z; the
    # material is double-sided.
    width, top_y, bottom_y = 1.2, 6.8, 0.01
    nu, nv = 96, 26
    lam = 0.3  # fold wavelength
    rows = []
    for i in range(nv + 1):
        y = bottom_y + (top_y - bottom_y) * i / nv
        h = (y - bottom_y) / (top_y - bottom_y)
        amp = 0.10 - 0.05 * h
        damp = -0.05 / (top_y - bottom_y)
        ph = 0.6 * h * h
        dph = 1.2 * h / (top_y - bottom_y)
        row = []
        for j in range(nu + 1):
            x = -width / 2 + width * j / nu
            arg = 2.0 * math.pi * x / lam + ph
            z = amp * math.sin(arg)
            dzdx = amp * math.cos(arg) * 2.0 * math.pi / lam
            dzdy = damp * math.sin(arg) + amp * math.cos(arg) * dph
            row.append(((x, y, z), (-dzdx, -dzdy, 1.0)))
        rows.append(row)
    g = Geometry()
    g.grid(rows)
    meshes["curtain_leg"] = [(g.finish(), "curtain_velvet_red")]

    return meshes


def build_nodes():
    """Node tree: list of dicts with name, optional mesh/camera, TRS and
    children (nested dicts). Rotations are given as quaternions."""
    def qy(deg):
        return q_axis_angle((0.0, 1.0, 0.0), deg)

    def qx(deg):
        return q_axis_angle((1.0, 0.0, 0.0), deg)

    def n(name, mesh=None, t=None, r=None, s=None, children=(), **kw):
        d = {"name": name}
        if mesh:
            d["mesh"] = mesh
        if t is not None:
            d["translation"] = [round(c, 9) + 0.0 for c in t]
        if r is not None:
            d["rotation"] = clean_quat(r)
        if s is not None:
            d["scale"] = list(s)
        d["children"] = list(children)
        d.update(kw)
        return d

    eye, target = (0.0, 1.7, 14.0), (0.0, 1.8, -3.0)
    return [
        n("deck", "deck"),
        n("wall_stage_right_red", "wall_stage_right"),
        n("wall_stage_left_green", "wall_stage_left"),
        n("cyclorama", "cyclorama"),
        n("masking", "masking"),
        n("polished_strip", "polished_strip"),
        # The rostra share one unit box, sized by non-uniform node scales.
        n("rostrum_upstage", "rostrum_unit_box", t=(-1.5, 0.0, -5.0),
          s=(5.0, 0.8, 2.0)),
        n("rostrum_stage_left", "rostrum_unit_box", t=(2.9, 0.0, -4.7),
          s=(2.2, 1.2, 1.6)),
        n("staircase", "staircase", t=(-2.5, 0.0, -2.25)),
        # One column mesh on four nodes; the stage-left pair is turned a
        # half segment so their seams differ (same shape, a rotation test).
        n("column_sr_down", "column", t=(-4.6, 0.0, -1.2)),
        n("column_sr_up", "column", t=(-4.6, 0.0, -4.8)),
        n("column_sl_down", "column", t=(4.6, 0.0, -1.2), r=qy(7.5)),
        n("column_sl_up", "column", t=(4.6, 0.0, -4.8), r=qy(7.5)),
        n("curtain_leg_sr", "curtain_leg", t=(-5.39, 0.0, -0.3)),
        n("curtain_leg_sl", "curtain_leg", t=(5.39, 0.0, -0.3)),
        # Nested transforms: the chairs are placed relative to the group.
        n("table_group", None, t=(2.6, 0.0, -1.2), r=qy(-20.0), children=[
            n("table", "table"),
            n("chair_front", "chair", t=(0.0, 0.0, 0.8), r=qy(180.0)),
            n("chair_sr", "chair", t=(-1.0, 0.0, 0.0), r=qy(90.0)),
            n("chair_sl", "chair", t=(1.0, 0.0, 0.0), r=qy(-90.0)),
        ]),
        n("pedestal", "pedestal", t=(-3.0, 0.0, -0.6), children=[
            n("glass_sphere", "glass_sphere", t=(0.0, 0.9 + 0.4 + 0.001, 0.0)),
        ]),
        n("chrome_sphere", "chrome_sphere", t=(0.2, 0.601, -1.9)),
        n("mirror_panel", "mirror_panel", t=(-4.0, 0.0, -3.0), r=qy(35.0)),
        n("glass_pane", "glass_pane", t=(-1.4, 0.0, -0.6), r=qy(25.0)),
        # The sculpture stands on top of the 1.2 m stage-left rostrum.
        n("sculpture", "sculpture_plinth", t=(2.9, 1.2, -4.7), r=qy(10.0),
          children=[
              n("sculpture_torus", "sculpture_torus",
                t=(0.0, 1.0 + 0.5 + 0.12 + 0.001, 0.0),
                r=q_mul(qy(15.0), qx(90.0))),
          ]),
        n("audience", None, t=eye, r=q_look_at(eye, target),
          camera_def={"name": "audience", "type": "perspective",
                      "perspective": {"yfov": 0.7, "aspectRatio": 1.6,
                                      "znear": 0.1, "zfar": 100.0}}),
    ]


# --------------------------------------------------------------------------
# glTF / GLB assembly
# --------------------------------------------------------------------------

def material_json(name, rgb, metallic, roughness, transmission, double_sided):
    m = {"name": name,
         "pbrMetallicRoughness": {"baseColorFactor": [rgb[0], rgb[1], rgb[2], 1.0],
                                  "metallicFactor": metallic,
                                  "roughnessFactor": roughness}}
    if double_sided:
        m["doubleSided"] = True
    if transmission is not None:
        m["extensions"] = {
            "KHR_materials_transmission": {"transmissionFactor": transmission},
            "KHR_materials_ior": {"ior": GLASS_IOR},
        }
    return m


def pack_f32(values):
    data = struct.pack("<%df" % len(values), *values)
    return data, struct.unpack("<%df" % len(values), data)


def build_gltf():
    """Returns (gltf dict, bin bytes)."""
    meshes = build_meshes()
    node_tree = build_nodes()

    materials = [material_json(*m) for m in MATERIALS]
    mat_index = {m["name"]: i for i, m in enumerate(materials)}

    binary = bytearray()
    views, accessors, mesh_json = [], [], []
    mesh_index = {}

    def add_view(data, target):
        while len(binary) % 4:
            binary.append(0)
        views.append({"buffer": 0, "byteOffset": len(binary),
                      "byteLength": len(data), "target": target})
        binary.extend(data)
        return len(views) - 1

    for mesh_name, prims in meshes.items():
        pj = []
        for geo, mat in prims:
            flat_p = [c for p in geo.pos for c in p]
            flat_n = [c for n in geo.nrm for c in n]
            flat_i = [i for t in geo.tri for i in t]
            pdata, p32 = pack_f32(flat_p)
            ndata, _ = pack_f32(flat_n)
            idata = struct.pack("<%dI" % len(flat_i), *flat_i)
            count = len(geo.pos)
            pmin = [min(p32[k::3]) for k in range(3)]
            pmax = [max(p32[k::3]) for k in range(3)]
            accessors.append({"bufferView": add_view(pdata, ARRAY_BUFFER),
                              "componentType": FLOAT, "count": count,
                              "type": "VEC3", "min": pmin, "max": pmax})
            pos_acc = len(accessors) - 1
            accessors.append({"bufferView": add_view(ndata, ARRAY_BUFFER),
                              "componentType": FLOAT, "count": count,
                              "type": "VEC3"})
            nrm_acc = len(accessors) - 1
            accessors.append({"bufferView": add_view(idata, ELEMENT_ARRAY_BUFFER),
                              "componentType": UNSIGNED_INT,
                              "count": len(flat_i), "type": "SCALAR"})
            idx_acc = len(accessors) - 1
            pj.append({"attributes": {"POSITION": pos_acc, "NORMAL": nrm_acc},
                       "indices": idx_acc, "material": mat_index[mat],
                       "mode": TRIANGLES})
        mesh_index[mesh_name] = len(mesh_json)
        mesh_json.append({"name": mesh_name, "primitives": pj})
    while len(binary) % 4:
        binary.append(0)

    nodes, cameras = [], []

    def add_node(d):
        j = {"name": d["name"]}
        idx = len(nodes)
        nodes.append(j)
        if "mesh" in d:
            j["mesh"] = mesh_index[d["mesh"]]
        if "camera_def" in d:
            cameras.append(d["camera_def"])
            j["camera"] = len(cameras) - 1
        for key in ("translation", "rotation", "scale"):
            if key in d:
                j[key] = d[key]
        if d["children"]:
            j["children"] = [add_node(c) for c in d["children"]]
        return idx

    roots = [add_node(d) for d in node_tree]

    # Expected statistics, counted over mesh instances (a mesh on k nodes
    # counts k times), so an importer can check what it flattened.
    per_mat = [0] * len(materials)

    def count(d):
        for geo, mat in meshes.get(d.get("mesh"), []):
            per_mat[mat_index[mat]] += len(geo.tri)
        for c in d["children"]:
            count(c)

    for d in node_tree:
        count(d)
    scene_extras = {
        "triangles": sum(per_mat),
        "specular_triangles": sum(t for t, m in zip(per_mat, materials)
                                  if is_specular(m)),
        "transmissive_triangles": sum(t for t, m in zip(per_mat, materials)
                                      if is_transmissive(m)),
        "specular_rule": "metallicFactor >= 0.8 or roughnessFactor <= 0.2",
        "source": "Vierjahn et al. 2010, section 4: 38,000 triangles, "
                  "24 % specular",
    }

    gltf = {
        "asset": {"version": "2.0", "generator": GENERATOR,
                  "extras": {"description": (
                      "Footlight test stage after Vierjahn et al. 2010: a "
                      "Cornell-box-inspired stage set. Metres, +Y up, origin "
                      "= centre of the setting line at floor level, +X = "
                      "stage left, +Z = towards the audience.")}},
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior"],
        "scene": 0,
        "scenes": [{"name": "stage", "nodes": roots, "extras": scene_extras}],
        "nodes": nodes,
        "cameras": cameras,
        "meshes": mesh_json,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
    }
    return gltf, bytes(binary)


def glb_bytes(gltf):
    js = json.dumps(gltf, separators=(",", ":"), ensure_ascii=True).encode("ascii")
    js += b" " * ((-len(js)) % 4)
    return js


def write_glb(path, gltf, binary):
    js = glb_bytes(gltf)
    binary = binary + b"\0" * ((-len(binary)) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    out = bytearray()
    out += struct.pack("<III", GLB_MAGIC, 2, total)
    out += struct.pack("<II", len(js), CHUNK_JSON) + js
    out += struct.pack("<II", len(binary), CHUNK_BIN) + binary
    with open(path, "wb") as f:
        f.write(out)


# --------------------------------------------------------------------------
# Reading back and checking (independent of the builder's data structures)
# --------------------------------------------------------------------------

class CheckError(Exception):
    pass


def check(cond, msg):
    if not cond:
        raise CheckError(msg)


def read_glb(path):
    with open(path, "rb") as f:
        data = f.read()
    check(len(data) >= 20, "file too short")
    magic, version, length = struct.unpack_from("<III", data, 0)
    check(magic == GLB_MAGIC, "bad GLB magic")
    check(version == 2, "GLB version is not 2")
    check(length == len(data), "GLB length %d != file size %d" % (length, len(data)))
    check(length % 4 == 0, "GLB length not a multiple of 4")
    jlen, jtype = struct.unpack_from("<II", data, 12)
    check(jtype == CHUNK_JSON, "first chunk is not JSON")
    check(jlen % 4 == 0, "JSON chunk not padded to 4 bytes")
    jraw = data[20:20 + jlen]
    stripped = jraw.rstrip(b" ")
    check(len(jraw) - len(stripped) < 4, "JSON padding longer than 3 bytes")
    gltf = json.loads(jraw.decode("utf-8"))
    off = 20 + jlen
    check(off + 8 <= len(data), "BIN chunk missing")
    blen, btype = struct.unpack_from("<II", data, off)
    check(btype == CHUNK_BIN, "second chunk is not BIN")
    check(blen % 4 == 0, "BIN chunk not padded to 4 bytes")
    check(off + 8 + blen == len(data), "trailing bytes after the BIN chunk")
    binary = data[off + 8:off + 8 + blen]
    return gltf, binary


def read_accessor(gltf, binary, ai, want_type, want_ct):
    acc = gltf["accessors"][ai]
    check(acc["type"] == want_type, "accessor %d type %s" % (ai, acc["type"]))
    check(acc["componentType"] == want_ct, "accessor %d componentType" % ai)
    view = gltf["bufferViews"][acc["bufferView"]]
    check(view["buffer"] == 0, "bufferView in a buffer other than 0")
    check("byteStride" not in view, "unexpected byteStride")
    ncomp = {"SCALAR": 1, "VEC3": 3}[want_type]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    size = acc["count"] * ncomp * 4
    check(acc.get("byteOffset", 0) + size <= view["byteLength"],
          "accessor %d overruns its bufferView" % ai)
    fmt = "<%d%s" % (acc["count"] * ncomp, "f" if want_ct == FLOAT else "I")
    vals = struct.unpack_from(fmt, binary, start)
    if ncomp == 3:
        return acc, [vals[i:i + 3] for i in range(0, len(vals), 3)]
    return acc, list(vals)


def verify(path):
    """Checks the written file; returns statistics computed from it."""
    gltf, binary = read_glb(path)
    check(gltf["asset"]["version"] == "2.0", "asset.version")
    check(gltf["asset"]["generator"] == GENERATOR, "asset.generator")
    check(len(gltf["buffers"]) == 1 and "uri" not in gltf["buffers"][0],
          "exactly one buffer, in the BIN chunk")
    blen = gltf["buffers"][0]["byteLength"]
    check(blen <= len(binary) and len(binary) - blen < 4,
          "buffer byteLength does not match the BIN chunk")
    used = set(gltf.get("extensionsUsed", []))
    check({"KHR_materials_transmission", "KHR_materials_ior"} <= used,
          "extensionsUsed incomplete")
    check("extensionsRequired" not in gltf, "extensionsRequired present")
    for i, v in enumerate(gltf["bufferViews"]):
        check(v.get("byteOffset", 0) % 4 == 0, "bufferView %d misaligned" % i)
        check(v.get("byteOffset", 0) + v["byteLength"] <= blen,
              "bufferView %d outside the buffer" % i)

    materials = gltf["materials"]
    for i, m in enumerate(materials):
        check(m.get("name"), "material %d has no name" % i)
        pbr = m["pbrMetallicRoughness"]
        if not is_specular(m):
            check(pbr["metallicFactor"] == 0.0 and pbr["roughnessFactor"] >= 0.6,
                  "diffuse material %s out of range" % m["name"])
        if is_transmissive(m):
            check(is_specular(m), "transmissive material %s not specular" % m["name"])
            check("KHR_materials_ior" in m["extensions"], "glass without ior")

    # Meshes: per primitive triangle count, checked geometry.
    mesh_prims = []  # mesh -> [(material, triangles, positions)]
    for mi, mesh in enumerate(gltf["meshes"]):
        prims = []
        for prim in mesh["primitives"]:
            check(prim.get("mode", 4) == TRIANGLES, "mode is not TRIANGLES")
            check(0 <= prim["material"] < len(materials), "bad material index")
            pacc, pos = read_accessor(gltf, binary, prim["attributes"]["POSITION"],
                                      "VEC3", FLOAT)
            _, nrm = read_accessor(gltf, binary, prim["attributes"]["NORMAL"],
                                   "VEC3", FLOAT)
            _, idx = read_accessor(gltf, binary, prim["indices"], "SCALAR",
                                   UNSIGNED_INT)
            name = mesh["name"]
            check(len(pos) == len(nrm), "%s: POSITION/NORMAL counts differ" % name)
            check(len(idx) % 3 == 0 and idx, "%s: index count" % name)
            check(max(idx) < len(pos), "%s: index out of range" % name)
            check(len(set(idx)) == len(pos), "%s: unused vertices" % name)
            for p in pos + nrm:
                check(all(math.isfinite(c) for c in p), "%s: NaN/inf" % name)
            for n in nrm:
                check(abs(v_len(n) - 1.0) < 1e-5, "%s: normal not unit" % name)
            check(pacc["min"] == [min(p[k] for p in pos) for k in range(3)],
                  "%s: POSITION min wrong" % name)
            check(pacc["max"] == [max(p[k] for p in pos) for k in range(3)],
                  "%s: POSITION max wrong" % name)
            for t in range(0, len(idx), 3):
                a, b, c = idx[t:t + 3]
                fn = v_cross(v_sub(pos[b], pos[a]), v_sub(pos[c], pos[a]))
                check(v_len(fn) > 0.0, "%s: degenerate triangle" % name)
                ns = v_add(v_add(nrm[a], nrm[b]), nrm[c])
                check(v_dot(fn, ns) > 0.0,
                      "%s: triangle %d wound against its normals" % (name, t // 3))
            prims.append((prim["material"], len(idx) // 3, pos))
        mesh_prims.append(prims)

    # Node tree: single parents, reachable, transforms sane.
    nodes = gltf["nodes"]
    parent = {}
    for i, nd in enumerate(nodes):
        for c in nd.get("children", []):
            check(c not in parent, "node %d has two parents" % c)
            parent[c] = i
        if "rotation" in nd:
            q = nd["rotation"]
            check(abs(math.sqrt(sum(c * c for c in q)) - 1.0) < 1e-6,
                  "node %s rotation not unit" % nd["name"])
    roots = gltf["scenes"][gltf["scene"]]["nodes"]
    check(not any(r in parent for r in roots), "a scene root has a parent")
    check(any(len(set(nd.get("scale", [1, 1, 1]))) > 1 for nd in nodes),
          "no node with a non-uniform scale")
    check(parent, "no nested nodes")
    mesh_users = [nd["mesh"] for nd in nodes if "mesh" in nd]
    check(len(mesh_users) > len(set(mesh_users)), "no mesh reused")

    stats = {"per_material": [0] * len(materials), "instances": 0}
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    seen = set()
    camera = None

    def walk(i, m):
        nonlocal camera
        check(i not in seen, "node %d visited twice (cycle?)" % i)
        seen.add(i)
        nd = nodes[i]
        w = mat4_mul(m, node_matrix(nd))
        if "mesh" in nd:
            stats["instances"] += 1
            for mat, tris, pos in mesh_prims[nd["mesh"]]:
                stats["per_material"][mat] += tris
                for p in pos:
                    q = mat4_point(w, p)
                    for k in range(3):
                        lo[k] = min(lo[k], q[k])
                        hi[k] = max(hi[k], q[k])
        if "camera" in nd:
            camera = (nd, w)
        for c in nd.get("children", []):
            walk(c, w)

    for r in roots:
        walk(r, IDENTITY4)
    check(len(seen) == len(nodes), "nodes not reachable from the scene")

    total = sum(stats["per_material"])
    spec = sum(t for t, m in zip(stats["per_material"], materials) if is_specular(m))
    trans = sum(t for t, m in zip(stats["per_material"], materials)
                if is_transmissive(m))
    check(abs(total - TARGET_TRIANGLES) <= TRIANGLE_TOLERANCE,
          "total triangles %d not within %d +- %d"
          % (total, TARGET_TRIANGLES, TRIANGLE_TOLERANCE))
    check(SPECULAR_RANGE[0] <= spec / total <= SPECULAR_RANGE[1],
          "specular fraction %.4f out of range" % (spec / total))
    check(trans > 0, "no transmissive triangles")
    extras = gltf["scenes"][gltf["scene"]].get("extras", {})
    check((extras.get("triangles"), extras.get("specular_triangles"),
           extras.get("transmissive_triangles")) == (total, spec, trans),
          "scene extras disagree with the counted triangles")

    check(camera is not None and camera[0]["name"] == "audience",
          "no camera node 'audience'")
    cam = gltf["cameras"][camera[0]["camera"]]
    check(cam["type"] == "perspective", "camera not perspective")
    eye = mat4_point(camera[1], (0.0, 0.0, 0.0))
    fwd = v_norm(mat4_dir(camera[1], (0.0, 0.0, -1.0)))
    want = v_norm(v_sub((0.0, 1.8, -3.0), eye))
    check(v_dot(fwd, want) > 0.99999, "camera does not look at the stage")
    up = mat4_dir(camera[1], (0.0, 1.0, 0.0))
    check(up[1] > 0.99, "camera is not upright")

    stats.update(total=total, specular=spec, transmissive=trans,
                 bbox=(lo, hi), camera_eye=eye, camera_forward=fwd,
                 meshes=len(gltf["meshes"]), nodes=len(nodes),
                 unique_triangles=sum(t for prims in mesh_prims for _, t, _ in prims))
    return gltf, stats


def print_stats(gltf, stats, path):
    mats = gltf["materials"]
    total = stats["total"]
    print("wrote %s (%d bytes)" % (path, os.path.getsize(path)))
    print("nodes %d, meshes %d, mesh instances %d, materials %d"
          % (stats["nodes"], stats["meshes"], stats["instances"], len(mats)))
    print("triangles in the scene (instanced): %d (unique in the file: %d)"
          % (total, stats["unique_triangles"]))
    print("triangles per material:")
    for m, t in zip(mats, stats["per_material"]):
        tag = ("specular, transmissive" if is_transmissive(m)
               else "specular" if is_specular(m) else "diffuse")
        print("  %-24s %6d  %5.2f %%  %s" % (m["name"], t, 100.0 * t / total, tag))
    print("specular fraction: %d / %d = %.2f %%"
          % (stats["specular"], total, 100.0 * stats["specular"] / total))
    print("transmissive fraction: %d / %d = %.2f %%"
          % (stats["transmissive"], total, 100.0 * stats["transmissive"] / total))
    lo, hi = stats["bbox"]
    print("bounding box (world, m): min (%.3f, %.3f, %.3f) max (%.3f, %.3f, %.3f)"
          % (lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]))
    e, f = stats["camera_eye"], stats["camera_forward"]
    print("camera 'audience': eye (%.3f, %.3f, %.3f), forward (%.5f, %.5f, %.5f)"
          % (e + f))
    print("self-check: OK")


def main(argv=None):
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(repo, "scenes", "stage.glb"),
                    help="output path (default: scenes/stage.glb in the repo)")
    args = ap.parse_args(argv)

    gltf, binary = build_gltf()
    out = os.path.abspath(args.out)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmp = out + ".tmp"
    write_glb(tmp, gltf, binary)
    try:
        read_back, stats = verify(tmp)
    except (CheckError, KeyError, ValueError, struct.error) as e:
        os.remove(tmp)
        print("gen_stage.py: SELF-CHECK FAILED: %s: %s" % (type(e).__name__, e),
              file=sys.stderr)
        return 1
    os.replace(tmp, out)
    print_stats(read_back, stats, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
