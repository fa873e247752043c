#!/usr/bin/env python3
"""Independent reading of Footlight's GDTF/MVR test files with pygdtf and pymvr.

Prints one JSON object: per GDTF file, per mode, the channels per DMX break
(offsets, attribute), the geometry tree (names, kinds) walked from the mode,
the beams' angles, the emitters' and filters' measurements (Physical,
LuminousIntensity, WaveLength/Energy points), the emitting GeometryReferences (pixel cells: name,
beam position, breaks), the wheel slot counts, each slot's gobo image name and
prism facet angles; per MVR file, every fixture's
spec, mode, addresses, ids and local matrix. The Rust test
(tests/peers.rs) compares its own reader with these numbers.
"""
import json
import math
import sys

import pygdtf
import pymvr
from pygdtf.utils import get_dmx_channels


def tree(ft, g):
    out = {"name": g.name, "kind": type(g).__name__, "children": []}
    if isinstance(g, pygdtf.GeometryReference):
        ref = ft.geometries.get_geometry_by_name(g.geometry)
        out["children"].append(tree(ft, ref))
        return out
    for c in getattr(g, "geometries", []) or []:
        out["children"].append(tree(ft, c))
    return out


def beams(ft, g, acc):
    if isinstance(g, pygdtf.GeometryBeam):
        acc.append([g.name, float(g.beam_angle), float(g.field_angle), float(g.luminous_flux), str(g.beam_type.value)])
    if isinstance(g, pygdtf.GeometryReference):
        beams(ft, ft.geometries.get_geometry_by_name(g.geometry), acc)
    for c in getattr(g, "geometries", []) or []:
        beams(ft, c, acc)
    return acc


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def first_beam_matrix(ft, g, m):
    """Matrix of the first beam under g (g's own position already in m), depth-first."""
    if isinstance(g, pygdtf.GeometryBeam):
        return m
    for c in getattr(g, "geometries", []) or []:
        found = first_beam_matrix(ft, c, matmul(m, c.position.matrix))
        if found is not None:
            return found
    return None


def cells(ft, g, m, acc):
    """Emitting GeometryReferences under g: name, their beam's translation from
    the fixture origin, and their breaks [[DMXBreak, DMXOffset]]."""
    for c in getattr(g, "geometries", []) or []:
        mc = matmul(m, c.position.matrix)
        if isinstance(c, pygdtf.GeometryReference):
            ref = ft.geometries.get_geometry_by_name(c.geometry)
            beam = first_beam_matrix(ft, ref, mc)  # the reference's position replaces the referenced geometry's
            if beam is not None:
                breaks = [[b.dmx_break, b.dmx_offset.address] for b in c.breaks]
                acc.append([c.name, [beam[0][3], beam[1][3], beam[2][3]], breaks])
            continue
        cells(ft, c, mc, acc)
    return acc


def gdtf(path):
    ft = pygdtf.FixtureType(path)
    modes = {}
    for m in ft.dmx_modes:
        breaks = get_dmx_channels(ft, m.name)
        root = ft.geometries.get_geometry_by_name(m.geometry)
        modes[m.name] = {
            "breaks": [[[list(c.offset), str(c.logical_channels[0].attribute)] for c in b] for b in breaks],
            "tree": tree(ft, root),
            "beams": beams(ft, root, []),
            "cells": cells(ft, root, root.position.matrix, []),
            "relations": [[r.name, str(r.master), str(r.follower), str(r.type)] for r in m.relations],
        }
    slots = {
        w.name: [
            {
                "name": sl.name,
                "media": (sl.media_file_name.name if sl.media_file_name and sl.media_file_name.name else ""),
                "facets": [math.atan2(f.rotation.matrix[1][0], f.rotation.matrix[0][0]) for f in sl.facets],
            }
            for sl in w.wheel_slots
        ]
        for w in ft.wheels
    }
    def measurements(items):
        return {
            i.name: [
                [float(m.physical), float(m.luminous_intensity), [[float(p.wave_length), float(p.energy)] for p in m.measurement_points]]
                for m in i.measurements
            ]
            for i in items
        }

    return {
        "name": ft.name,
        "wheels": {w.name: len(w.wheel_slots) for w in ft.wheels},
        "wheel_slots": slots,
        "modes": modes,
        "emitters": measurements(ft.emitters),
        "filters": measurements(ft.filters),
    }


def mvr(path):
    s = pymvr.GeneralSceneDescription(path)
    out = []

    def walk(cl):
        for f in cl.fixtures:
            out.append(
                {
                    "name": f.name,
                    "spec": f.gdtf_spec,
                    "mode": f.gdtf_mode,
                    "addresses": [[a.dmx_break, a.universe, a.address] for a in f.addresses.addresses],
                    "fixture_id": str(f.fixture_id),
                    "unit_number": f.unit_number,
                    "matrix": f.matrix.matrix,
                }
            )
            if f.child_list:
                walk(f.child_list)
        for g in cl.group_objects:
            walk(g.child_list)

    for layer in s.scene.layers:
        walk(layer.child_list)
    return out


if __name__ == "__main__":
    result = {"gdtf": {}, "mvr": {}}
    for p in sys.argv[1:]:
        if p.endswith(".gdtf"):
            result["gdtf"][p] = gdtf(p)
        else:
            result["mvr"][p] = mvr(p)
    json.dump(result, sys.stdout)
