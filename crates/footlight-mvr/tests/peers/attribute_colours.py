#!/usr/bin/env python3
"""Independent reading of GDTF attribute colours with pygdtf.

Prints one JSON object: per GDTF file given on the command line, every
attribute of its AttributeDefinitions with its Color as [x, y, Y], or null
when the attribute has none. The Rust test
(crates/footlight-mvr/tests/cases/colour_without_emitters.rs) compares the
colours Footlight mixes for emitter-less ColorAdd channels with these.
"""
import json
import sys

import pygdtf

out = {}
for path in sys.argv[1:]:
    ft = pygdtf.FixtureType(path)
    out[path] = {
        a.name: ([a.color.x, a.color.y, a.color.Y] if a.color is not None else None) for a in ft.attributes
    }
print(json.dumps(out))
