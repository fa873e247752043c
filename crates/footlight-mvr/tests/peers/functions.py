#!/usr/bin/env python3
"""pygdtf's reading of the channel functions of Footlight's GDTF test files
(issue 36: the attributes real files use, mode masters).

Prints one JSON object: per GDTF file, per DMX mode, every DMX channel
instance (after pygdtf's geometry-reference expansion) with its DMX break,
offsets, geometry and channel functions: attribute, DMX from and to (raw value
and byte count, as pygdtf computes the ends: within the functions of one mode
master), physical from and to, mode master (the linked node's text, "None"
without one), mode from and to, linked wheel and channel sets (name, DMX from,
wheel slot index, 0 without one); and per wheel its slots' CIE xyY colours.
The Rust test (tests/cases/attributes.rs) compares its own reading with these.
"""
import json
import sys

import pygdtf
from pygdtf.utils import get_dmx_channels


def link(node):
    return str(node.str_link) if node is not None and node.str_link is not None else "None"


def function(f):
    return {
        "attribute": str(f.attribute),
        "name": f.name,
        "dmx_from": [f.dmx_from.value, f.dmx_from.byte_count],
        "dmx_to": [f.dmx_to.value, f.dmx_to.byte_count],
        "physical": [float(f.physical_from.value), float(f.physical_to.value)],
        "mode_master": link(f.mode_master),
        "mode_from": [f.mode_from.value, f.mode_from.byte_count],
        "mode_to": [f.mode_to.value, f.mode_to.byte_count],
        "wheel": link(f.wheel),
        "sets": [[s.name, s.dmx_from.value, s.dmx_from.byte_count, s.wheel_slot_index or 0] for s in f.channel_sets],
    }


def gdtf(path):
    ft = pygdtf.FixtureType(path)
    modes = {}
    for m in ft.dmx_modes:
        channels = []
        for b, chans in enumerate(get_dmx_channels(ft, m.name)):
            for c in chans:
                channels.append(
                    {
                        "break": b + 1,
                        "offsets": list(c.offset or []),
                        "name": c.name,
                        "geometry": c.geometry,
                        "functions": [function(f) for lc in c.logical_channels for f in lc.channel_functions],
                    }
                )
        modes[m.name] = channels
    wheels = {
        w.name: [[s.name, float(s.color.x), float(s.color.y), float(s.color.Y), s.media_file_name.name if s.media_file_name else ""] for s in w.wheel_slots]
        for w in ft.wheels
    }
    return {"name": ft.name, "modes": modes, "wheels": wheels}


if __name__ == "__main__":
    print(json.dumps({p: gdtf(p) for p in sys.argv[1:]}))
