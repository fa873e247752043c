#!/usr/bin/env python3
"""festival.mvr read independently with pymvr and pygdtf (tests/cases/festival.rs).

Prints one JSON object: the MVR's fixtures (pymvr), each GDTFSpec resolved in
the archive the way Footlight documents it (as written, else `<spec>.gdtf`,
else the GDTF whose FixtureType Name is the spec, read with pygdtf), the
lights each fixture is (pygdtf: the mode's emitting GeometryReferences when
there are two or more, else its plain beams when two or more, else one; a
fixture whose GDTF is missing is one placeholder light), and the universes
of the fixtures that have a GDTF.
"""
import json
import os
import sys
import tempfile
import zipfile

import pygdtf
import pymvr


def has_beam(ft, g):
    if isinstance(g, pygdtf.GeometryBeam):
        return True
    if isinstance(g, pygdtf.GeometryReference):
        return has_beam(ft, ft.geometries.get_geometry_by_name(g.geometry))
    return any(has_beam(ft, c) for c in getattr(g, "geometries", []) or [])


def emitting_references(ft, g, acc):
    for c in getattr(g, "geometries", []) or []:
        if isinstance(c, pygdtf.GeometryReference):
            if has_beam(ft, c):
                acc.append(c.name)
            continue
        emitting_references(ft, c, acc)
    return acc


def plain_beams(g, acc):
    if isinstance(g, pygdtf.GeometryReference):
        return acc
    if isinstance(g, pygdtf.GeometryBeam):
        acc.append(g.name)
        return acc
    for c in getattr(g, "geometries", []) or []:
        plain_beams(c, acc)
    return acc


def lights(ft, mode_name):
    mode = next(m for m in ft.dmx_modes if m.name == mode_name)
    root = ft.geometries.get_geometry_by_name(mode.geometry)
    refs = emitting_references(ft, root, [])
    if len(refs) >= 2:
        return len(refs)
    beams = plain_beams(root, [])
    return len(beams) if len(beams) >= 2 else 1


def main(path):
    tmp = tempfile.mkdtemp()
    z = zipfile.ZipFile(path)
    names = z.namelist()
    types = {}
    for n in names:
        if n.lower().endswith(".gdtf"):
            p = os.path.join(tmp, n.replace("/", "_"))
            with open(p, "wb") as f:
                f.write(z.read(n))
            types[n] = pygdtf.FixtureType(p)

    def resolve(spec):
        # pymvr itself appends ".gdtf" to a spec written without it.
        if spec in names:
            return spec
        if spec + ".gdtf" in names:
            return spec + ".gdtf"
        bare = spec[:-5] if spec.lower().endswith(".gdtf") else spec
        for n, ft in types.items():
            if ft.name.strip().lower() == bare.strip().lower():
                return n
        return None

    scene = pymvr.GeneralSceneDescription(path)
    fixtures = []

    def walk(cl):
        for f in cl.fixtures:
            fixtures.append(f)
            if f.child_list:
                walk(f.child_list)
        for g in cl.group_objects:
            walk(g.child_list)

    for layer in scene.scene.layers:
        walk(layer.child_list)
    per_type, specs, universes, total = {}, {}, set(), 0
    for f in fixtures:
        file = resolve(f.gdtf_spec)
        specs[f.gdtf_spec] = file
        n = lights(types[file], f.gdtf_mode) if file else 1
        key = file or f.gdtf_spec
        t = per_type.setdefault(key, {"fixtures": 0, "lights": 0})
        t["fixtures"] += 1
        t["lights"] += n
        total += n
        if file:
            universes.update(a.universe for a in f.addresses.addresses if a.dmx_break == 0)
    json.dump({"fixtures": len(fixtures), "lights": total, "universes": sorted(universes), "types": per_type, "specs": specs}, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
