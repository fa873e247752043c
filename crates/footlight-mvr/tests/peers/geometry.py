#!/usr/bin/env python3
"""Independent placement of an MVR's 3D files with pymvr (issue 14 item 4).

Prints one JSON list: for every SceneObject, Truss, Support, VideoScreen and
Projector (through layers and group objects), every Geometry3D it places,
Symbols resolved through their Symdef, as [object name, file name, world
matrix as 16 numbers, row-major, millimetres]. Footlight's test
(tests/scene_import.rs) compares its own flattening with these numbers.
"""
import json
import sys

import pymvr


def mat(m):
    """pymvr's matrix (rows u, v, w, o: the images of the axes, then the offset) -> 4x4 row-major."""
    if m is None:
        return [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]
    rows = m.matrix
    out = [[float(rows[c][r]) for c in range(4)] for r in range(3)]
    return out + [[0.0, 0.0, 0.0, 1.0]]


def mul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def main(path):
    s = pymvr.GeneralSceneDescription(path)
    symdefs = {d.uuid: d.child_list for d in s.scene.aux_data.symdefs}
    out = []

    def geometries(name, g, world, depth=0):
        for g3 in g.geometry3d:
            out.append([name, g3.file_name, [x for row in mul(world, mat(g3.matrix)) for x in row]])
        for sym in g.symbol:
            if depth < 32 and sym.symdef in symdefs:
                geometries(name, symdefs[sym.symdef], mul(world, mat(sym.matrix)), depth + 1)

    def walk(cl, parent):
        if cl is None:
            return
        for kind in (cl.scene_objects, cl.trusses, cl.supports, cl.video_screens, cl.projectors):
            for o in kind:
                world = mul(parent, mat(o.matrix))
                if o.geometries is not None:
                    geometries(o.name, o.geometries, world)
                walk(getattr(o, "child_list", None), world)
        for f in cl.fixtures:
            walk(f.child_list, mul(parent, mat(f.matrix)))
        for g in cl.group_objects:
            walk(g.child_list, mul(parent, mat(g.matrix)))

    for layer in s.scene.layers:
        walk(layer.child_list, mat(layer.matrix))
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
