#!/usr/bin/env python3
"""Writes Footlight's GDTF and MVR test files with known answers (issue 14).

No manufacturer file can be downloaded where Footlight is developed, so the
importer's test data is written here, from the GDTF 1.2 / MVR 1.6 layouts
(DIN SPEC 15800:2022 and the XSDs in the mvrdevelopment/spec repository).
Python standard library only (zipfile, zlib, xml.sax.saxutils); the output
is deterministic: fixed zip timestamps, sorted entries, uuid5 identifiers.

    python3 tools/gen_gdtf_mvr.py            # writes tests/data/gdtf and tests/data/mvr
    python3 tools/gen_gdtf_mvr.py --check    # fails if the files on disk differ

Every value below is invented for the tests (estimated, not a datasheet);
the Rust tests and the Python peers (pygdtf, pymvr) read these files and
compare what they find with the numbers written here.

GDTF files (tests/data/gdtf/):
  Footlight@Spot.gdtf     moving spot: Base > Yoke (Axis) > Head (Axis) > Beam,
                          filters; modes Standard (27 ch, 16-bit pan/tilt/dimmer)
                          and Basic (8 ch, 24-bit dimmer); colour wheel (xyY),
                          gobo wheel (PNG slots in wheels/), prism facets,
                          zoom/focus/iris, CMY, CTO, shutter/strobe, 8 blades + rotation;
                          mode Extended (29 ch) adds gobo rotation and wheel spin, prism
                          rotation, frost and blade rotation
  Footlight@Wash.gdtf     RGBW LED wash, emitters with xyY and spectra, virtual-dimmer
                          relations; modes 8ch and 4ch
  Footlight@Bar8.gdtf     pixel bar: 8 GeometryReference cells of one Pixel beam;
                          modes 25ch (one break) and Split (2 breaks)
  Footlight@Blinder.gdtf  2-lamp tungsten blinder; modes 2ch and 1ch
  Footlight@Fresnel.gdtf  1 kW tungsten Fresnel with a DMX profile; modes 1ch, 2ch (zoom)
  Footlight@Hazer.gdtf    hazer, no beam: Haze density and Fan channels
  Footlight@Fan4.gdtf     4 GeometryReference cells turned 0/30/60/90 degrees about GDTF Y
                          (cell rotation); modes 4ch and 5ch (a master overriding every
                          cell's dimmer: Relation Type="Override")
  Footlight@SpectralLed.gdtf  RGBW LED whose emitters carry measured spectra (Gaussian
                          lines, a phosphor white; green also at Physical 50); mode 5ch
  Footlight@CmySpot.gdtf  discharge spot with measured C/M/Y flag filters; mode 4ch
  Footlight@ColourBar.gdtf, Footlight@Cluster4.gdtf, Footlight@ViperSpot.gdtf
                          the attributes real files use (issue 36): HSB, CIE, colour
                          macros, Color2, CTC, tint, mode masters, master and cell
                          dimmers, DimmerCurve, StrobeDuration, Gobo2, animation wheel
                          (see "Attributes real GDTFs use" below)
  Footlight@PixelBar16.gdtf  16-cell RGBW pixel bar with no <Emitter>: colours only in the
                          attribute definitions' Color (xyY); mode 65ch
  Footlight@LedRyWw.gdtf  RGB + amber (RY) + warm white (WW) can, no <Emitter>; RY and WW
                          without a Color (GDTF Annex B's nominal colours); mode 6ch

MVR files (tests/data/mvr/):
  features.mvr   layers, classes, group objects, focus points, truss and scene
                 objects with symdef/symbol instancing, a 2-break fixture, fixture
                 ids/unit numbers/colour/gobo fields, and one GDTF that is named
                 but not in the archive (placeholder test)
  show150.mvr    150 fixtures of the six types over 4 universes
  gate.mvr       5 Spots in the Extended mode (gobos, blades, prism, frost: golden image)
  venue.mvr      the MVR's geometry as the scene: a GLB floor, a GLB truss instanced
                 3x by a Symdef, a 3DS 1000 mm cube in a GroupObject, a missing model
  bodies.mvr     fixture bodies: a glb head model on a moving head, a 3ds can, a
                 primitives-only par (known dimensions; tests/bodies.rs)
  cells.mvr      two Fan4 5 m up: each cell's beam along its own matrix; Fan 2 (5ch at 1.11)
                 has the Override master
  colour.mvr     the ColourBar in all five modes, a Cluster4 and a ViperSpot 4 m up (COLOUR_RIG)
  led-bars.mvr   two PixelBar16 and a LedRyWw 4 m over a grey GLB floor (LED colour
                 without emitters, white balance auto)
  ../textures/checker.jpg  a baseline JPEG of flat 8x8 blocks (JPEG_BLOCKS), encoded here
  bad-*.mvr      refused archives: a `..` path, an absolute path, a >100:1 entry,
                 a header claiming > 1 GiB; and malformed XML (line/column test)

    python3 tools/gen_gdtf_mvr.py --deep /tmp/deep [--depth 10000]

writes only the hostile deep-nesting files of issue 35 (a GDTF, a TOML patch
and two MVRs nested 10,000 deep) into /tmp/deep, never into tests/data.
"""

import argparse
import io
import math
import struct
import sys
import uuid
import zipfile
import zlib
from pathlib import Path
from xml.sax.saxutils import quoteattr

ROOT = Path(__file__).resolve().parent.parent
GDTF_DIR = ROOT / "tests" / "data" / "gdtf"
MVR_DIR = ROOT / "tests" / "data" / "mvr"
NS = uuid.UUID("6f6f746c-6967-6874-2d6d-76722d746573")  # fixed namespace for uuid5

IDENTITY4 = "{1,0,0,0}{0,1,0,0}{0,0,1,0}{0,0,0,1}"


def uid(name):
    return str(uuid.uuid5(NS, name)).upper()


def m4(tx=0.0, ty=0.0, tz=0.0):
    """GDTF geometry matrix (metres): rows {u1,v1,w1,o1}..., translation in the 4th column."""
    return f"{{1,0,0,{tx:g}}}{{0,1,0,{ty:g}}}{{0,0,1,{tz:g}}}{{0,0,0,1}}"


def m4_rot_y(deg, tx=0.0, ty=0.0, tz=0.0):
    """GDTF geometry matrix (rows, as m4) rotating by `deg` about the geometry's Y axis: R_y = [[c,0,s],[0,1,0],[-s,0,c]]."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return f"{{{c:.9f},0,{s:.9f},{tx:g}}}{{0,1,0,{ty:g}}}{{{-s:.9f},0,{c:.9f},{tz:g}}}{{0,0,0,1}}"


def attrs(**kw):
    return "".join(f" {k}={quoteattr(str(v))}" for k, v in kw.items() if v is not None)


def el(tag, children=None, **kw):
    a = attrs(**kw)
    if not children:
        return f"<{tag}{a}/>"
    inner = "".join(children) if isinstance(children, list) else children
    return f"<{tag}{a}>{inner}</{tag}>"


# --- PNG (gobo slot images) -------------------------------------------------


def png_gray(width, height, pixel):
    """8-bit greyscale PNG; pixel(x, y) -> 0..255 (255 = light passes)."""
    raw = b"".join(b"\x00" + bytes(pixel(x, y) for x in range(width)) for y in range(height))

    def chunk(kind, data):
        c = kind + data
        return struct.pack(">I", len(data)) + c + struct.pack(">I", zlib.crc32(c) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


GOBO_SIZE = 64


def jpeg_gray_blocks(blocks):
    """Baseline greyscale JPEG (ITU-T T.81) of flat 8x8 blocks: `blocks` is a list of rows of 0..255
    values, one per block. Every quantiser step is 1 and each block has only its DC coefficient
    (F(0,0) = 8 (v - 128) for a flat block), so a decoder's IDCT gives back v exactly: the known
    answer of the JPEG tests, written without any JPEG library."""
    rows, cols = len(blocks), len(blocks[0])
    seg = lambda marker, payload: bytes([0xFF, marker]) + struct.pack(">H", len(payload) + 2) + payload  # noqa: E731
    dc_bits = [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0]  # T.81 Table K.3 (luminance DC)
    dc_vals = list(range(12))
    codes, code, k = {}, 0, 0
    for length, count in enumerate(dc_bits, start=1):
        for _ in range(count):
            codes[dc_vals[k]] = (code, length)
            code, k = code + 1, k + 1
        code <<= 1
    out = bytearray(b"\xff\xd8")
    out += seg(0xDB, bytes([0]) + bytes([1] * 64))
    out += seg(0xC0, struct.pack(">BHHB", 8, 8 * rows, 8 * cols, 1) + bytes([1, 0x11, 0]))
    out += seg(0xC4, bytes([0x00] + dc_bits + dc_vals))
    out += seg(0xC4, bytes([0x10, 1] + [0] * 15 + [0x00]))  # AC: only end-of-block, code "0"
    out += seg(0xDA, bytes([1, 1, 0x00, 0, 63, 0]))
    bits, pred = [], 0
    for row in blocks:
        for v in row:
            dc = 8 * (v - 128)
            diff, pred = dc - pred, dc
            size = abs(diff).bit_length()
            c, n = codes[size]
            bits += [(c >> (n - 1 - i)) & 1 for i in range(n)]
            extra = diff if diff >= 0 else diff - 1 + (1 << size)
            bits += [(extra >> (size - 1 - i)) & 1 for i in range(size)]
            bits.append(0)  # end of block
    bits += [1] * (-len(bits) % 8)
    for i in range(0, len(bits), 8):
        byte = int("".join(map(str, bits[i:i + 8])), 2)
        out.append(byte)
        if byte == 0xFF:
            out.append(0)
    out += b"\xff\xd9"
    return bytes(out)


# tests/data/textures/checker.jpg: 3x2 flat 8x8 blocks (24x16 texels), row by row.
JPEG_BLOCKS = [[255, 0, 128], [64, 200, 10]]


def gobo_ring(x, y):
    """Open ring: radius 0.5..0.9 of the half-size passes light (known area fraction)."""
    c = (GOBO_SIZE - 1) / 2
    r = math.hypot(x - c, y - c) / (GOBO_SIZE / 2)
    return 255 if 0.5 <= r <= 0.9 else 0


def gobo_bars(x, y):
    """Four vertical bars: columns 8 px wide every 16 px pass light."""
    return 255 if (x // 8) % 2 == 0 else 0


# --- GDTF ---------------------------------------------------------------------

FEATURES = {
    "Dimmer": ["Dimmer"],
    "Position": ["PanTilt"],
    "Gobo": ["Gobo"],
    "Color": ["Color", "RGB", "CIE"],
    "Beam": ["Beam"],
    "Focus": ["Focus"],
    "Shapers": ["Shapers"],
    "Control": ["Control"],
}

# name -> (feature, physical unit, pretty)
ATTRIBUTES = {
    "Dimmer": ("Dimmer.Dimmer", "LuminousIntensity", "Dim"),
    "Pan": ("Position.PanTilt", "Angle", "P"),
    "Tilt": ("Position.PanTilt", "Angle", "T"),
    "Shutter1": ("Beam.Beam", "None", "Sh1"),
    "Shutter1Strobe": ("Beam.Beam", "Frequency", "Strobe1"),
    "Color1": ("Color.Color", "None", "C1"),
    "Gobo1": ("Gobo.Gobo", "None", "G1"),
    "Gobo1Pos": ("Gobo.Gobo", "Angle", "G1 <>"),
    "Prism1": ("Beam.Beam", "None", "Prism1"),
    "Zoom": ("Focus.Focus", "Angle", "Zoom"),
    "Focus1": ("Focus.Focus", "None", "Focus1"),
    "Iris": ("Beam.Beam", "None", "Iris"),
    "ColorSub_C": ("Color.Color", "ColorComponent", "C"),
    "ColorSub_M": ("Color.Color", "ColorComponent", "M"),
    "ColorSub_Y": ("Color.Color", "ColorComponent", "Y"),
    "CTO": ("Color.Color", "Temperature", "CTO"),
    "ColorAdd_R": ("Color.RGB", "ColorComponent", "R"),
    "ColorAdd_G": ("Color.RGB", "ColorComponent", "G"),
    "ColorAdd_B": ("Color.RGB", "ColorComponent", "B"),
    "ColorAdd_W": ("Color.RGB", "ColorComponent", "W"),
    "ShaperRot": ("Shapers.Shapers", "Angle", "Shaper Rot"),
    "Haze": ("Control.Control", "None", "Haze"),
    "Fan": ("Control.Control", "None", "Fan"),
}
for i in range(1, 5):
    for ab in "AB":
        ATTRIBUTES[f"Blade{i}{ab}"] = ("Shapers.Shapers", "None", f"Blade {i}{ab}")
# The Spot's Extended mode (gate features: spins, prism rotation, frost, blade rotation).
ATTRIBUTES.update(
    {
        "Gobo1WheelSpin": ("Gobo.Gobo", "AngularSpeed", "G1 Wheel Spin"),
        "Gobo1PosRotate": ("Gobo.Gobo", "AngularSpeed", "G1 Rotate"),
        "Prism1Pos": ("Beam.Beam", "Angle", "Prism1 <>"),
        "Prism1PosRotate": ("Beam.Beam", "AngularSpeed", "Prism1 Rotate"),
        "Frost1": ("Beam.Beam", "None", "Frost1"),
    }
)
for i in range(1, 5):
    ATTRIBUTES[f"Blade{i}Rot"] = ("Shapers.Shapers", "Angle", f"Blade {i} Rot")


def attribute_definitions(names):
    groups = [
        el("FeatureGroup", [el("Feature", Name=f) for f in fs], Name=g, Pretty=g) for g, fs in FEATURES.items()
    ]
    atts = []
    for n in names:
        feature, unit, pretty = ATTRIBUTES[n]
        main = "Shutter1" if n == "Shutter1Strobe" else None
        atts.append(el("Attribute", Name=n, Pretty=pretty, Feature=feature, PhysicalUnit=unit, MainAttribute=main))
    return el(
        "AttributeDefinitions",
        [
            el("ActivationGroups", [el("ActivationGroup", Name="PanTilt"), el("ActivationGroup", Name="ColorRGB")]),
            el("FeatureGroups", groups),
            el("Attributes", atts),
        ],
    )


def dmx_value(v, nbytes):
    return f"{v}/{nbytes}"


class Chan:
    """One DMX channel: geometry, offsets (coarse first), channel functions.

    functions: list of (attribute, dmx_from, phys_from, phys_to, extra attrs dict,
    channel sets [(name, dmx_from, wheel_slot_index)])."""

    def __init__(self, geometry, offsets, functions, default=0, brk="1", initial=None):
        self.geometry = geometry
        self.offsets = offsets
        self.functions = functions
        self.default = default
        self.brk = brk
        self.initial = initial

    @property
    def bytes(self):
        return max(1, len(self.offsets))

    @property
    def attribute(self):
        return self.functions[0][0]

    def xml(self):
        n = self.bytes
        fns = []
        for k, f in enumerate(self.functions):
            attribute, dmx_from, p0, p1, extra, sets = (list(f) + [{}, []])[:6]
            set_nodes = [
                el("ChannelSet", Name=sn, DMXFrom=dmx_value(sf, n), WheelSlotIndex=ws) for sn, sf, ws in sets
            ]
            fns.append(
                el(
                    "ChannelFunction",
                    set_nodes,
                    Name=f"{attribute} {k + 1}",
                    Attribute=attribute,
                    OriginalAttribute="",
                    DMXFrom=dmx_value(dmx_from, n),
                    Default=dmx_value(self.default if k == 0 else dmx_from, n),
                    PhysicalFrom=f"{p0:g}",
                    PhysicalTo=f"{p1:g}",
                    RealFade="0",
                    **extra,
                )
            )
        logical = el("LogicalChannel", fns, Attribute=self.attribute, Snap="No", Master="None", MibFade="0")
        off = ",".join(str(o) for o in self.offsets)
        return el(
            "DMXChannel",
            [logical],
            DMXBreak=self.brk,
            Offset=off,
            Highlight="None",
            Geometry=self.geometry,
            InitialFunction=f"{self.geometry}_{self.attribute}.{self.attribute}.{self.attribute} 1",
        )


def simple(geometry, offsets, attribute, p0=0.0, p1=1.0, default=0, extra=None, brk="1"):
    return Chan(geometry, offsets, [(attribute, 0, p0, p1, extra or {}, [])], default=default, brk=brk)


def mode(name, geometry, channels, relations=()):
    rel = [
        el("Relation", Name=n, Master=m, Follower=f, Type=t) for n, m, f, t in relations
    ]
    return el(
        "DMXMode",
        [el("DMXChannels", [c.xml() for c in channels]), el("Relations", rel), el("FTMacros")],
        Name=name,
        Geometry=geometry,
    )


def fixture_type(name, short, attrs_used, wheels, physical, models, geometries, modes, description, manufacturer="Footlight"):
    ft = el(
        "FixtureType",
        [
            attribute_definitions(attrs_used),
            el("Wheels", wheels),
            el("PhysicalDescriptions", physical),
            el("Models", models),
            el("Geometries", geometries),
            el("DMXModes", modes),
            el("Revisions", [el("Revision", Text="generated by tools/gen_gdtf_mvr.py", Date="2026-11-30T00:00:00", UserID="0")]),
            el("FTPresets"),
            el("Protocols"),
        ],
        Name=name,
        ShortName=short,
        LongName=f"Footlight test {name}",
        Manufacturer=manufacturer,
        Description=description,
        FixtureTypeID=uid("ft/" + name),
        Thumbnail="",
        RefFT="",
        CanHaveChildren="Yes",
    )
    return '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n' + el("GDTF", [ft], DataVersion="1.2") + "\n"


def model(name, length, width, height, primitive, file=None):
    return el(
        "Model", Name=name, Length=f"{length:g}", Width=f"{width:g}", Height=f"{height:g}", PrimitiveType=primitive, File=file
    )


def beam(name, model_name, pos, children=None, **kw):
    defaults = dict(
        LampType="Discharge",
        PowerConsumption="1000",
        LuminousFlux="10000",
        ColorTemperature="6000",
        BeamAngle="25",
        FieldAngle="25",
        ThrowRatio="1",
        RectangleRatio="1.7777",
        BeamRadius="0.05",
        BeamType="Wash",
        ColorRenderingIndex="100",
    )
    defaults.update({k: str(v) for k, v in kw.items()})
    return el("Beam", children, Name=name, Model=model_name, Position=pos, **defaults)


def color_wheel():
    slots = [
        ("Open", "0.3127,0.3290,100"),
        ("Red", "0.6400,0.3300,21.26"),
        ("Green", "0.3000,0.6000,71.52"),
        ("Blue", "0.1500,0.0600,7.22"),
        ("Amber", "0.5700,0.4200,60"),
    ]
    return el("Wheel", [el("Slot", Name=n, Color=c) for n, c in slots], Name="Color1"), len(slots)


def gobo_wheel():
    slots = [
        el("Slot", Name="Open", Color="0.3127,0.3290,100"),
        el("Slot", Name="Ring", Color="0.3127,0.3290,100", MediaFileName="gobo_ring"),
        el("Slot", Name="Bars", Color="0.3127,0.3290,100", MediaFileName="gobo_bars"),
    ]
    return el("Wheel", slots, Name="Gobo1"), len(slots)


def prism_wheel():
    r3 = [(math.cos(a), math.sin(a)) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]
    facets = []
    for c, s in r3:
        # a facet tilted 5 degrees away from the axis, rotated about it by the facet angle
        t = math.radians(5.0)
        rot = f"{{{c:.6f},{-s:.6f},0}}{{{s:.6f},{c:.6f},0}}{{0,0,1}}"
        _ = t
        facets.append(el("Facet", Color="0.3127,0.3290,100", Rotation=rot))
    slots = [el("Slot", Name="Open", Color="0.3127,0.3290,100"), el("Slot", facets, Name="3-Facet", Color="0.3127,0.3290,100")]
    return el("Wheel", slots, Name="Prism1"), len(slots)


def spectrum(peak_nm, fwhm_nm):
    sigma = fwhm_nm / 2.3548
    pts = []
    for nm in range(380, 781, 10):
        e = math.exp(-0.5 * ((nm - peak_nm) / sigma) ** 2)
        pts.append(el("MeasurementPoint", WaveLength=str(nm), Energy=f"{e:.6f}"))
    return pts


def spot():
    cw, _ = color_wheel()
    gw, _ = gobo_wheel()
    pw, _ = prism_wheel()
    used = [
        "Dimmer", "Pan", "Tilt", "Shutter1", "Shutter1Strobe", "Color1", "Gobo1", "Gobo1Pos", "Prism1", "Zoom",
        "Focus1", "Iris", "ColorSub_C", "ColorSub_M", "ColorSub_Y", "CTO", "ShaperRot",
    ] + [f"Blade{i}{ab}" for i in range(1, 5) for ab in "AB"]
    used += ["Gobo1WheelSpin", "Gobo1PosRotate", "Prism1Pos", "Prism1PosRotate", "Frost1"] + [f"Blade{i}Rot" for i in range(1, 5)]
    physical = [
        el("Emitters"),
        el("Filters"),
        el("ColorSpace", Mode="sRGB"),
        el("DMXProfiles"),
        el("CRIs"),
        el("Connectors"),
        el("Properties", [el("OperatingTemperature", Low="0", High="40"), el("Weight", Value="30"), el("LegHeight", Value="0")]),
    ]
    models = [
        model("Base", 0.40, 0.30, 0.15, "Base"),
        model("Yoke", 0.35, 0.10, 0.35, "Yoke"),
        model("Head", 0.25, 0.25, 0.40, "Head"),
        model("Beam", 0.01, 0.14, 0.14, "Cylinder"),
    ]
    filters = [
        el("FilterColor", Name="ColorWheel", Model="Beam", Position=m4(0, 0, -0.05)),
        el("FilterGobo", Name="GoboWheel", Model="Beam", Position=m4(0, 0, -0.06)),
        el("FilterShaper", Name="Framing", Model="Beam", Position=m4(0, 0, -0.07)),
    ]
    lamp = beam(
        "Lens", "Beam", m4(0, 0, -0.25), LampType="Discharge", PowerConsumption="700", LuminousFlux="20000",
        ColorTemperature="7000", BeamAngle="15", FieldAngle="20", BeamRadius="0.07", BeamType="Spot", children=filters,
    )
    # The geometry names are deliberately not Base/Yoke/Head: importers must walk by reference.
    tree = el(
        "Geometry",
        [el("Axis", [el("Axis", [lamp], Name="Lantern", Model="Head", Position=m4(0, 0, -0.35))], Name="Arm", Model="Yoke", Position=m4(0, 0, -0.15))],
        Name="Foot",
        Model="Base",
        Position=m4(),
    )
    shutter = Chan(
        "Lens",
        [7],
        [
            ("Shutter1", 0, 0, 0, {}, [("Closed", 0, None)]),
            ("Shutter1", 32, 1, 1, {}, [("Open", 32, None)]),
            ("Shutter1Strobe", 64, 1, 25, {}, []),
        ],
        default=32,
    )
    color = Chan(
        "ColorWheel",
        [8],
        [("Color1", 0, 0, 0, {"Wheel": "Color1"}, [("Open", 0, 1), ("Red", 10, 2), ("Green", 20, 3), ("Blue", 30, 4), ("Amber", 40, 5)])],
    )
    gobo = Chan("GoboWheel", [9], [("Gobo1", 0, 0, 0, {"Wheel": "Gobo1"}, [("Open", 0, 1), ("Ring", 10, 2), ("Bars", 20, 3)])])
    prism = Chan(
        "Lens", [11], [("Prism1", 0, 0, 0, {"Wheel": "Prism1"}, [("Out", 0, 1)]), ("Prism1", 128, 0, 0, {"Wheel": "Prism1"}, [("3-Facet", 128, 2)])]
    )
    standard = [
        simple("Arm", [1, 2], "Pan", -270, 270, default=32768),
        simple("Lantern", [3, 4], "Tilt", -135, 135, default=32768),
        simple("Lens", [5, 6], "Dimmer", 0, 1),
        shutter,
        color,
        gobo,
        simple("GoboWheel", [10], "Gobo1Pos", -180, 180, default=128),
        prism,
        simple("Lens", [12], "Zoom", 10, 40),
        simple("Lens", [13], "Focus1", 0, 1),
        simple("Lens", [14], "Iris", 1, 0.2),
        simple("Lens", [15], "ColorSub_C", 0, 1),
        simple("Lens", [16], "ColorSub_M", 0, 1),
        simple("Lens", [17], "ColorSub_Y", 0, 1),
        simple("Lens", [18], "CTO", 7000, 3200),
    ]
    for k, (i, ab) in enumerate((i, ab) for i in range(1, 5) for ab in "AB"):
        standard.append(simple("Framing", [19 + k], f"Blade{i}{ab}", 0, 1))
    standard.append(simple("Framing", [27], "ShaperRot", -45, 45, default=128))
    basic = [
        simple("Arm", [1], "Pan", -270, 270, default=128),
        simple("Lantern", [2], "Tilt", -135, 135, default=128),
        simple("Lens", [3, 4, 5], "Dimmer", 0, 1),
        Chan("Lens", [6], shutter.functions, default=32),
        Chan("ColorWheel", [7], color.functions),
        Chan("GoboWheel", [8], gobo.functions),
    ]
    text = fixture_type(
        "Spot", "Spot", used, [cw, gw, pw], physical, models, [tree],
        [mode("Standard", "Foot", standard), mode("Basic", "Foot", basic), mode("Extended", "Foot", extended_spot_mode(shutter, color, prism))],
        "moving spot with every beam feature (test data, estimated values)",
    )
    media = {"wheels/gobo_ring.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_ring), "wheels/gobo_bars.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_bars)}
    return text, media


def extended_spot_mode(shutter, color, prism):
    """The Spot's Extended mode (29 ch): every gate feature (gobo index, rotation
    and wheel spin, prism index and rotation, frost, four blades with insertion
    A/B and rotation, shaper rotation). Offsets in EXTENDED_OFFSETS."""
    sets = [("Open", 0, 1), ("Ring", 10, 2), ("Bars", 20, 3)]
    chans = [
        simple("Arm", [1, 2], "Pan", -270, 270, default=32768),
        simple("Lantern", [3, 4], "Tilt", -135, 135, default=32768),
        simple("Lens", [5, 6], "Dimmer", 0, 1),
        Chan("Lens", [7], shutter.functions, default=32),
        Chan("ColorWheel", [8], color.functions),
        # 0-127 slots, 128-255 wheel spin -120..120 deg/s
        Chan("GoboWheel", [9], [("Gobo1", 0, 0, 0, {"Wheel": "Gobo1"}, sets), ("Gobo1WheelSpin", 128, -120, 120, {"Wheel": "Gobo1"}, [])]),
        # 0-127 index 0..360 deg, 128-255 rotation -360..360 deg/s
        Chan("GoboWheel", [10], [("Gobo1Pos", 0, 0, 360), ("Gobo1PosRotate", 128, -360, 360)]),
        Chan("Lens", [11], prism.functions),
        Chan("Lens", [12], [("Prism1Pos", 0, 0, 360), ("Prism1PosRotate", 128, -180, 180)]),
        simple("Lens", [13], "Zoom", 10, 40),
        simple("Lens", [14], "Focus1", 0, 1),
        simple("Lens", [15], "Iris", 1, 0.2),
        simple("Lens", [16], "Frost1", 0, 1),
    ]
    for k, (i, ab) in enumerate((i, ab) for i in range(1, 5) for ab in "AB"):
        chans.append(simple("Framing", [17 + k], f"Blade{i}{ab}", 0, 1))
    for i in range(1, 5):
        chans.append(simple("Framing", [24 + i], f"Blade{i}Rot", -45, 45, default=128))
    chans.append(simple("Framing", [29], "ShaperRot", -45, 45, default=128))
    return chans


EMITTERS = [
    ("Red", "0.7000,0.2990,20", 630, 20),
    ("Green", "0.1700,0.7000,60", 525, 30),
    ("Blue", "0.1400,0.0400,8", 460, 22),
    ("White", "0.3127,0.3290,100", None, None),
]


def emitters_xml(spectra=True):
    out = []
    for name, xyy, peak, fwhm in EMITTERS:
        meas = []
        if spectra and peak is not None:
            meas = [el("Measurement", spectrum(peak, fwhm), Physical="100", LuminousIntensity="1000", InterpolationTo="Linear")]
        # DominantWaveLength is optional in GDTF 1.2, but the `gdtf` crate 0.3 needs it next to Color
        # (white: 0, no dominant wavelength).
        out.append(el("Emitter", meas, Name=name, Color=xyy, DominantWaveLength=str(peak or 0)))
    return el("Emitters", out)


def led_can(emitters, **lamp):
    """Physical description, models and geometry of an LED can (a body with a
    lens beam 0.2 m in front, 6500 K wash) around `emitters`; `lamp` gives the
    beam's power, flux and angles."""
    physical = [emitters, el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.3, 0.3, 0.35, "Conventional"), model("Lens", 0.01, 0.2, 0.2, "Cylinder")]
    attrs = dict(LampType="LED", PowerConsumption=lamp["PowerConsumption"], LuminousFlux=lamp["LuminousFlux"], ColorTemperature="6500",
                 BeamAngle=lamp["BeamAngle"], FieldAngle=lamp["FieldAngle"], BeamRadius="0.1", BeamType="Wash")
    tree = el("Geometry", [beam("Front", "Lens", m4(0, 0, -0.2), **attrs)], Name="Can", Model="Body", Position=m4())
    return physical, models, tree


def wash():
    used = ["Dimmer", "ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_W", "Zoom", "Shutter1", "Shutter1Strobe"]
    physical, models, tree = led_can(emitters_xml(), PowerConsumption="300", LuminousFlux="8000", BeamAngle="30", FieldAngle="45")
    rgbw = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue"), ("ColorAdd_W", "White")]
    ch8 = [simple("Front", [1], "Dimmer")]
    for k, (a, e) in enumerate(rgbw):
        ch8.append(simple("Front", [2 + k], a, default=255, extra={"Emitter": e}))
    ch8.append(simple("Front", [6], "Zoom", 12, 50))
    ch8.append(
        Chan("Front", [7], [("Shutter1", 0, 1, 1, {}, [("Open", 0, None)]), ("Shutter1Strobe", 16, 0.5, 20, {}, [])])
    )
    ch4 = [simple("Front", [1 + k], a, default=255, extra={"Emitter": e}) for k, (a, e) in enumerate(rgbw)]
    rel = [(f"Virtual dimmer {a}", "Front_Dimmer", f"Front_{a}.{a}.{a} 1", "Multiply") for a, _ in rgbw]
    text = fixture_type(
        "Wash", "Wash", used, [], physical, models, [tree], [mode("8ch", "Can", ch8, rel), mode("4ch", "Can", ch4)],
        "RGBW LED wash (test data, estimated values)",
    )
    return text, {}


BAR_CELLS = 8


def bar():
    used = ["Dimmer", "ColorAdd_R", "ColorAdd_G", "ColorAdd_B"]
    physical = [emitters_xml(spectra=False), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 1.0, 0.08, 0.1, "Cube"), model("Pixel", 0.1, 0.06, 0.01, "Cube")]
    pixel = beam("Pixel", "Pixel", m4(), LampType="LED", PowerConsumption="15", LuminousFlux="400", ColorTemperature="6500", BeamAngle="20", FieldAngle="30", BeamRadius="0.03", BeamType="Wash")
    x0 = -0.4375
    one = [
        el("GeometryReference", [el("Break", DMXOffset=str(2 + 3 * k), DMXBreak="1")], Name=f"Cell{k + 1}", Geometry="Pixel", Model="Pixel", Position=m4(x0 + 0.125 * k, 0, -0.05))
        for k in range(BAR_CELLS)
    ]
    split = [
        el("GeometryReference", [el("Break", DMXOffset=str(1 + 3 * k), DMXBreak="2")], Name=f"SplitCell{k + 1}", Geometry="Pixel", Model="Pixel", Position=m4(x0 + 0.125 * k, 0, -0.05))
        for k in range(BAR_CELLS)
    ]
    bar_one = el("Geometry", one, Name="Bar", Model="Body", Position=m4())
    bar_split = el("Geometry", split, Name="BarSplit", Model="Body", Position=m4())
    cells = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue")]
    m1 = [simple("Bar", [1], "Dimmer")] + [simple("Pixel", [1 + k], a, extra={"Emitter": e}) for k, (a, e) in enumerate(cells)]
    m2 = [simple("BarSplit", [1], "Dimmer")] + [
        simple("Pixel", [1 + k], a, extra={"Emitter": e}, brk="2") for k, (a, e) in enumerate(cells)
    ]
    text = fixture_type(
        "Bar8", "Bar8", used, [], physical, models, [bar_one, bar_split, pixel],
        [mode("25ch", "Bar", m1), mode("Split", "BarSplit", m2)],
        "8-cell RGB pixel bar (test data, estimated values)",
    )
    return text, {}


def blinder():
    used = ["Dimmer"]
    physical = [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.5, 0.3, 0.2, "Cube"), model("Lamp", 0.05, 0.2, 0.2, "Cylinder")]
    lamps = [
        beam(f"Cell{k + 1}", "Lamp", m4(-0.12 + 0.24 * k, 0, -0.1), LampType="Tungsten", PowerConsumption="650", LuminousFlux="18000", ColorTemperature="3000", BeamAngle="50", FieldAngle="90", BeamRadius="0.1", BeamType="Wash")
        for k in range(2)
    ]
    tree = el("Geometry", lamps, Name="Frame", Model="Body", Position=m4())
    m2 = [simple("Cell1", [1], "Dimmer"), simple("Cell2", [2], "Dimmer")]
    m1 = [simple("Frame", [1], "Dimmer")]
    text = fixture_type("Blinder", "Blinder", used, [], physical, models, [tree], [mode("2ch", "Frame", m2), mode("1ch", "Frame", m1)], "2-lamp tungsten blinder (test data, estimated values)")
    return text, {}


def fresnel():
    used = ["Dimmer", "Zoom"]
    # A square-law profile written as GDTF 1.2 cubic segments: y = x^2 on [0, 1].
    profile = el("DMXProfile", [el("Point", DMXPercentage="0", CFC0="0", CFC1="0", CFC2="1", CFC3="0")], Name="Square")
    physical = [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles", [profile]), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.35, 0.3, 0.3, "Conventional"), model("Lens", 0.01, 0.15, 0.15, "Cylinder")]
    tree = el(
        "Geometry",
        [beam("Lens", "Lens", m4(0, 0, -0.18), LampType="Tungsten", PowerConsumption="1000", LuminousFlux="25000", ColorTemperature="3200", BeamAngle="12", FieldAngle="20", BeamRadius="0.075", BeamType="Fresnel")],
        Name="Housing",
        Model="Body",
        Position=m4(),
    )
    m1 = [simple("Lens", [1], "Dimmer", extra={"DMXProfile": "Square"})]
    m2 = [simple("Lens", [1], "Dimmer", extra={"DMXProfile": "Square"}), simple("Lens", [2], "Zoom", 12, 60)]
    text = fixture_type("Fresnel", "Fresnel", used, [], physical, models, [tree], [mode("1ch", "Housing", m1), mode("2ch", "Housing", m2)], "1 kW tungsten Fresnel (test data, estimated values)")
    return text, {}


def hazer():
    used = ["Haze", "Fan"]
    physical = [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.5, 0.3, 0.3, "Cube")]
    tree = el("Geometry", Name="Box", Model="Body", Position=m4())
    m = [simple("Box", [1], "Haze", 0, 1), simple("Box", [2], "Fan", 0, 1)]
    text = fixture_type("Hazer", "Hazer", used, [], physical, models, [tree], [mode("2ch", "Box", m)], "hazer: density and fan (test data, estimated values)")
    return text, {}


# Fan4: four GeometryReference cells of one Pixel beam, cell k turned by
# FAN_ANGLES[k] degrees about the GDTF Y axis (its beam, -Z at rest, then
# points along R_y(a)·(-Z) = (-sin a, 0, -cos a) in fixture axes). Known
# answer in tests/pixels.rs (cell rotation).
FAN_ANGLES = (0.0, 30.0, 60.0, 90.0)


def fan():
    used = ["Dimmer"]
    physical = [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.5, 0.08, 0.1, "Cube"), model("Pixel", 0.1, 0.06, 0.01, "Cube")]
    pixel = beam("Pixel", "Pixel", m4(), LampType="LED", PowerConsumption="15", LuminousFlux="400", ColorTemperature="6500", BeamAngle="10", FieldAngle="14", BeamRadius="0.03", BeamType="Wash")
    refs = [
        el("GeometryReference", [el("Break", DMXOffset=str(1 + k), DMXBreak="1")], Name=f"Fan{k + 1}", Geometry="Pixel", Model="Pixel", Position=m4_rot_y(a, -0.15 + 0.1 * k, 0, -0.05))
        for k, a in enumerate(FAN_ANGLES)
    ]
    tree = el("Geometry", refs, Name="Fan", Model="Body", Position=m4())
    m1 = [simple("Pixel", [1], "Dimmer")]
    # Mode 5ch: a master on slot 5 overriding every cell's dimmer (GDTF Relation Type="Override";
    # known answer in tests/pixels.rs: master above 0 -> every cell at the master's level).
    m2 = [simple("Pixel", [1], "Dimmer"), simple("Fan", [5], "Dimmer")]
    over = [("Master override", "Fan_Dimmer", "Pixel_Dimmer.Dimmer.Dimmer 1", "Override")]
    modes = [mode("4ch", "Fan", m1), mode("5ch", "Fan", m2, over)]
    text = fixture_type("Fan4", "Fan4", used, [], physical, models, [tree, pixel], modes, "4 cells turned 0/30/60/90 degrees (test data, estimated values)")
    return text, {}


# --- Spectral colour: emitters with measured spectra, CMY flags with measured transmissions ---

# Emitters of the SpectralLed: (name, DominantWaveLength, Color xyY, components [(weight, peak nm,
# FWHM nm)]). Color's xy is a rounded nominal value (the spectrum is what counts) and its Y the
# luminous share; every LuminousIntensity is 1000 (Color's Y wins). The `gdtf` crate 0.3 cannot
# read an Emitter without Color (its DominantWaveLength-only variant fails in XML), so every
# emitter has one. Points every 2 nm from 380 to 780 nm, peak-normalised energies.
SPECTRAL_EMITTERS = [
    ("Red", 630, "0.7000,0.3000,12.5", [(1.0, 630, 18)]),
    ("Green", 525, "0.1700,0.7000,37.5", [(1.0, 525, 32)]),
    ("Blue", 455, "0.1400,0.0400,5", [(1.0, 455, 20)]),
    # Phosphor white: a blue pump plus a broad phosphor band.
    ("White", 575, "0.3127,0.3290,50", [(0.35, 450, 20), (1.0, 570, 110)]),
]
# Green also carries a measurement at Physical 50 with another shape (peak 515 nm): the
# importer must take the full-output one (Physical 100).
SPECTRAL_GREEN_HALF = (400, [(1.0, 515, 32)])


def gauss_sum(nm, comps):
    return sum(w * math.exp(-0.5 * ((nm - p) / (f / 2.3548)) ** 2) for w, p, f in comps)


def spectral_points(comps, step=2):
    return [el("MeasurementPoint", WaveLength=str(nm), Energy=f"{gauss_sum(nm, comps):.6f}") for nm in range(380, 781, step)]


def spectral_led():
    used = ["Dimmer", "ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_W"]
    emitters = []
    for name, dwl, xyy, comps in SPECTRAL_EMITTERS:
        meas = [el("Measurement", spectral_points(comps), Physical="100", LuminousIntensity="1000", InterpolationTo="Linear")]
        if name == "Green":
            half_li, half = SPECTRAL_GREEN_HALF
            meas.insert(0, el("Measurement", spectral_points(half), Physical="50", LuminousIntensity=str(half_li), InterpolationTo="Linear"))
        emitters.append(el("Emitter", meas, Name=name, Color=xyy, DominantWaveLength=str(dwl)))
    physical, models, tree = led_can(el("Emitters", emitters), PowerConsumption="250", LuminousFlux="6000", BeamAngle="25", FieldAngle="40")
    rgbw = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue"), ("ColorAdd_W", "White")]
    ch = [simple("Front", [1], "Dimmer")]
    for k, (a, e) in enumerate(rgbw):
        ch.append(simple("Front", [2 + k], a, extra={"Emitter": e}))
    text = fixture_type(
        "SpectralLed", "SpectralLed", used, [], physical, models, [tree], [mode("5ch", "Can", ch)],
        "RGBW LED with measured emitter spectra (test data: Gaussian lines, estimated values)",
    )
    return text, {}


# CMY flags of the CmySpot: full-insertion transmission (0..1) as a function of nm. Points
# every 5 nm from 380 to 780 nm. Color is a nominal xyY (the measurement is what counts).
CMY_FLAGS = [
    ("Cyan", "ColorSub_C", "0.2000,0.3000,70", lambda nm: 0.03 + 0.92 / (1.0 + math.exp((nm - 585.0) / 10.0))),
    ("Magenta", "ColorSub_M", "0.3200,0.1700,35", lambda nm: 1.0 - 0.88 * math.exp(-0.5 * ((nm - 540.0) / 25.0) ** 2)),
    ("Yellow", "ColorSub_Y", "0.4400,0.5000,85", lambda nm: 0.02 + 0.93 / (1.0 + math.exp((500.0 - nm) / 9.0))),
]


def cmy_spot():
    used = ["Dimmer", "ColorSub_C", "ColorSub_M", "ColorSub_Y"]
    filters = []
    for name, _, xyy, t in CMY_FLAGS:
        pts = [el("MeasurementPoint", WaveLength=str(nm), Energy=f"{t(nm):.6f}") for nm in range(380, 781, 5)]
        filters.append(el("Filter", [el("Measurement", pts, Physical="100", Transmission="50", InterpolationTo="Linear")], Name=name, Color=xyy))
    physical = [el("Emitters"), el("Filters", filters), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.4, 0.3, 0.5, "Conventional"), model("Lens", 0.01, 0.15, 0.15, "Cylinder")]
    tree = el(
        "Geometry",
        [beam("Front", "Lens", m4(0, 0, -0.3), LampType="Discharge", PowerConsumption="700", LuminousFlux="15000", ColorTemperature="6000", BeamAngle="20", FieldAngle="25", BeamType="Spot")],
        Name="Head",
        Model="Body",
        Position=m4(),
    )
    ch = [simple("Front", [1], "Dimmer")]
    for k, (name, attr, _, _) in enumerate(CMY_FLAGS):
        ch.append(simple("Front", [2 + k], attr, extra={"Filter": name}))
    text = fixture_type(
        "CmySpot", "CmySpot", used, [], physical, models, [tree], [mode("4ch", "Head", ch)],
        "CMY spot with measured flag transmissions (test data, estimated values)",
    )
    return text, {}


TYPES = {
    "Footlight@Fan4.gdtf": fan,
    "Footlight@Spot.gdtf": spot,
    "Footlight@Wash.gdtf": wash,
    "Footlight@Bar8.gdtf": bar,
    "Footlight@Blinder.gdtf": blinder,
    "Footlight@Fresnel.gdtf": fresnel,
    "Footlight@Hazer.gdtf": hazer,
    "Footlight@SpectralLed.gdtf": spectral_led,
    "Footlight@CmySpot.gdtf": cmy_spot,
}

def zip_bytes(entries, compress=zipfile.ZIP_DEFLATED):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = compress
            info.external_attr = 0o644 << 16
            data = entries[name]
            z.writestr(info, data.encode() if isinstance(data, str) else data)
    return buf.getvalue()


def gdtf_bytes(name):
    text, media = TYPES[name]()
    return zip_bytes({"description.xml": text, **media})


# --- MVR ----------------------------------------------------------------------


def mvr_matrix(x_mm, y_mm, z_mm, rot_z_deg=0.0, rot_x_deg=0.0):
    """MVR matrix text {u}{v}{w}{o}: u, v, w the rotated axes (Rz then Rx), o the offset in mm."""
    cz, sz = math.cos(math.radians(rot_z_deg)), math.sin(math.radians(rot_z_deg))
    cx, sx = math.cos(math.radians(rot_x_deg)), math.sin(math.radians(rot_x_deg))
    # R = Rz * Rx; columns are the images of the axes
    r = [
        [cz, -sz * cx, sz * sx],
        [sz, cz * cx, -cz * sx],
        [0.0, sx, cx],
    ]
    u = (r[0][0], r[1][0], r[2][0])
    v = (r[0][1], r[1][1], r[2][1])
    w = (r[0][2], r[1][2], r[2][2])
    f = lambda t: ",".join(f"{c:.6f}" for c in t)  # noqa: E731
    return f"{{{f(u)}}}{{{f(v)}}}{{{f(w)}}}{{{x_mm:.3f},{y_mm:.3f},{z_mm:.3f}}}"


def fixture_xml(name, spec, mode_name, fid, unit, matrix, addresses, klass=None, focus=None, color=None, gobo=None):
    kids = [el("Matrix", matrix)]
    if klass:
        kids.append(el("Classing", klass))
    kids += [el("GDTFSpec", spec), el("GDTFMode", mode_name)]
    if focus:
        kids.append(el("Focus", focus))
    kids.append(el("CastShadow", "false"))
    kids.append(el("Addresses", [el("Address", str(a), **{"break": str(b)}) for b, a in addresses]))
    kids += [el("FixtureID", str(fid)), el("FixtureIDNumeric", str(fid)), el("UnitNumber", str(unit))]
    if color:
        kids.append(el("Color", color))
    if gobo:
        kids.append(el("Gobo", gobo[0], rotation=str(gobo[1])))
    return el("Fixture", kids, name=name, uuid=uid("fixture/" + name))


def gsd(layers, aux):
    body = el("Scene", [el("AUXData", aux), el("Layers", layers)])
    root = el("GeneralSceneDescription", [el("UserData"), body], verMajor="1", verMinor="6", provider="Footlight gen_gdtf_mvr.py", providerVersion="1")
    return '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n' + root + "\n"


def absolute(universe, address):
    return (universe - 1) * 512 + address


def features_mvr():
    lights = uid("class/Lighting")
    scenery = uid("class/Scenery")
    truss_def = uid("symdef/truss-2m")
    focus = uid("focus/centre")
    aux = [
        el("Class", name="Lighting", uuid=lights),
        el("Class", name="Scenery", uuid=scenery),
        el("Symdef", [el("ChildList", [el("Geometry3D", [el("Matrix", "{1,0,0}{0,1,0}{0,0,1}{0,0,0}")], fileName="truss_2m.glb")])], name="Truss 2 m", uuid=truss_def),
    ]
    truss_kids = []
    for k in range(3):
        truss_kids.append(
            el("Truss", [el("Matrix", mvr_matrix(-3000 + 2000 * k, 2000, 7000)), el("Classing", scenery), el("Geometries", [el("Symbol", [el("Matrix", "{1,0,0}{0,1,0}{0,0,1}{0,0,0}")], uuid=uid(f"symbol/{k}"), symdef=truss_def)])], name=f"Truss {k + 1}", uuid=uid(f"truss/{k}"))
        )
    floor = el("SceneObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", scenery), el("Geometries", [el("Geometry3D", fileName="stage_floor.glb")])], name="Stage floor", uuid=uid("scene/floor"))
    focus_point = el("FocusPoint", [el("Matrix", mvr_matrix(0, 0, 0))], name="Centre", uuid=focus)
    group_fixtures = [
        fixture_xml("Spot 1", "Footlight@Spot.gdtf", "Standard", 101, 1, mvr_matrix(-2000, 2000, 6800), [(0, absolute(1, 1))], lights, focus, gobo=("gobo_ring", 15.0)),
        fixture_xml("Spot 2", "Footlight@Spot.gdtf", "Basic", 102, 2, mvr_matrix(2000, 2000, 6800, rot_z_deg=90.0), [(0, absolute(1, 41))], lights, focus),
    ]
    group = el("GroupObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", lights), el("ChildList", group_fixtures)], name="Spots", uuid=uid("group/spots"))
    rig = [
        group,
        fixture_xml("Wash 1", "Footlight@Wash.gdtf", "8ch", 201, 1, mvr_matrix(0, 1000, 6500), [(0, absolute(1, 101))], lights, color="0.3127,0.3290,100.000000"),
        fixture_xml("Bar split", "Footlight@Bar8.gdtf", "Split", 301, 1, mvr_matrix(0, 3000, 6000), [(0, absolute(1, 201)), (1, absolute(2, 1))], lights),
        fixture_xml("Blinder 1", "Footlight@Blinder.gdtf", "2ch", 401, 1, mvr_matrix(-4000, -1000, 5000, rot_x_deg=90.0), [(0, absolute(1, 301))], lights),
        fixture_xml("Fresnel 1", "Footlight@Fresnel.gdtf", "2ch", 501, 1, mvr_matrix(3000, -2000, 6000), [(0, absolute(1, 311))], lights),
        fixture_xml("Hazer 1", "Footlight@Hazer.gdtf", "2ch", 601, 1, mvr_matrix(-5000, 4000, 0), [(0, "3.1")], lights),
        fixture_xml("Ghost 1", "Footlight@Missing.gdtf", "Mode 1", 701, 1, mvr_matrix(4000, 2000, 6800), [(0, absolute(1, 401))], lights),
        fixture_xml("Ghost 2", "Footlight@Missing.gdtf", "Mode 1", 702, 2, mvr_matrix(5000, 2000, 6800), [(0, absolute(1, 421))], lights),
    ]
    layers = [
        el("Layer", [el("ChildList", truss_kids + [floor, focus_point])], name="Venue", uuid=uid("layer/venue")),
        el("Layer", [el("Matrix", mvr_matrix(0, 0, 500)), el("ChildList", rig)], name="Rig", uuid=uid("layer/rig")),
    ]
    entries = {"GeneralSceneDescription.xml": gsd(layers, aux)}
    for n in ["Footlight@Spot.gdtf", "Footlight@Wash.gdtf", "Footlight@Bar8.gdtf", "Footlight@Blinder.gdtf", "Footlight@Fresnel.gdtf", "Footlight@Hazer.gdtf"]:
        entries[n] = gdtf_bytes(n)
    return zip_bytes(entries)


# --- venue geometry (issue 14 item 4): a GLB floor and truss, a 3DS cube ---------


def glb_bytes(positions, indices, colour, name, texture=None):
    """A minimal GLB (glTF 2.0 binary): one mesh, one node, one matte material.

    positions: list of (x, y, z) in metres, glTF axes (Y up); indices: list of
    (a, b, c) triangles, counter-clockwise seen from outside; texture: None or
    (PNG bytes, one (u, v) per position): a base-colour texture in the GLB's
    binary chunk, sampled NEAREST.
    """
    import json

    pos = b"".join(struct.pack("<3f", *p) for p in positions)
    idx = b"".join(struct.pack("<3H", *t) for t in indices)
    idx += b"\0" * (-len(idx) % 4)
    bin_chunk = pos + idx
    if texture is not None:
        png, uvs = texture
        uv = b"".join(struct.pack("<2f", *t) for t in uvs)
        uv_at = len(bin_chunk)
        bin_chunk += uv
        png_at = len(bin_chunk)
        bin_chunk += png + b"\0" * (-len(png) % 4)
    lo = [min(p[k] for p in positions) for k in range(3)]
    hi = [max(p[k] for p in positions) for k in range(3)]
    doc = {
        "asset": {"version": "2.0", "generator": "Footlight gen_gdtf_mvr.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(colour) + [1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}],
        "buffers": [{"byteLength": len(bin_chunk)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos), "target": 34962},
            {"buffer": 0, "byteOffset": len(pos), "byteLength": 6 * len(indices), "target": 34963},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5123, "count": 3 * len(indices), "type": "SCALAR"},
        ],
    }
    if texture is not None:
        doc["bufferViews"] += [
            {"buffer": 0, "byteOffset": uv_at, "byteLength": len(uv)},
            {"buffer": 0, "byteOffset": png_at, "byteLength": len(png)},
        ]
        doc["accessors"].append({"bufferView": 2, "componentType": 5126, "count": len(uvs), "type": "VEC2"})
        doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 2
        doc["images"] = [{"bufferView": 3, "mimeType": "image/png"}]
        doc["samplers"] = [{"magFilter": 9728, "minFilter": 9728}]
        doc["textures"] = [{"source": 0, "sampler": 0}]
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    js = json.dumps(doc, separators=(",", ":"), sort_keys=True).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(bin_chunk), 0x004E4942) + bin_chunk
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def box_mesh(lo, hi):
    """The 8 corners and 12 outward-wound triangles of an axis-aligned box."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
    # corner index = 4*ix + 2*iy + iz
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    for a, b, c, d in quads:
        tris += [(a, b, c), (a, c, d)]
    return v, tris


def three_ds_bytes(positions, faces, name):
    """A minimal 3DS file: MAIN3DS > EDIT3DS > EDIT_OBJECT > OBJ_TRIMESH with
    TRI_VERTEXL (0x4110) and TRI_FACEL1 (0x4120). Units as given (MVR: mm, Z up)."""

    def chunk(cid, payload):
        return struct.pack("<HI", cid, 6 + len(payload)) + payload

    verts = struct.pack("<H", len(positions)) + b"".join(struct.pack("<3f", *p) for p in positions)
    tris = struct.pack("<H", len(faces)) + b"".join(struct.pack("<4H", a, b, c, 0) for a, b, c in faces)
    trimesh = chunk(0x4100, chunk(0x4110, verts) + chunk(0x4120, tris))
    obj = chunk(0x4000, name.encode() + b"\0" + trimesh)
    return chunk(0x4D4D, chunk(0x0002, struct.pack("<I", 3)) + chunk(0x3D3D, obj))


def png_rgb(width, height, pixel):
    """8-bit RGB PNG; pixel(x, y) -> (r, g, b) bytes (sRGB-encoded), rows from the top."""
    raw = b"".join(b"\x00" + b"".join(bytes(pixel(x, y)) for x in range(width)) for y in range(height))

    def chunk(kind, data):
        c = kind + data
        return struct.pack(">I", len(data)) + c + struct.pack(">I", zlib.crc32(c) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


def three_ds_material(name, colour24=None, texmap=None):
    """A 3DS MAT_ENTRY (0xAFFF): MAT_NAME (0xA000), MAT_DIFFUSE (0xA020) > COLOR_24 (0x0011, the
    gamma-corrected bytes), MAT_TEXMAP (0xA200) > MAT_MAPNAME (0xA300)."""

    def chunk(cid, payload):
        return struct.pack("<HI", cid, 6 + len(payload)) + payload

    body = chunk(0xA000, name.encode() + b"\0")
    if colour24 is not None:
        body += chunk(0xA020, chunk(0x0011, bytes(colour24)))
    if texmap is not None:
        body += chunk(0xA200, chunk(0x0030, struct.pack("<H", 100)) + chunk(0xA300, texmap.encode() + b"\0"))
    return chunk(0xAFFF, body)


def three_ds_scene(meshes, materials):
    """A 3DS file with materials: meshes are (name, positions, faces, uvs or None, material name);
    the material is assigned as real exporters do, a MSH_MAT_GROUP (0x4130) nested in the
    FACE_ARRAY (0x4120) naming every face; TEX_VERTS (0x4140) carry the UVs (3DS: v up from the
    image's bottom edge)."""

    def chunk(cid, payload):
        return struct.pack("<HI", cid, 6 + len(payload)) + payload

    objects = b""
    for name, positions, faces, uvs, material in meshes:
        verts = struct.pack("<H", len(positions)) + b"".join(struct.pack("<3f", *p) for p in positions)
        group = material.encode() + b"\0" + struct.pack("<H", len(faces)) + b"".join(struct.pack("<H", i) for i in range(len(faces)))
        tris = struct.pack("<H", len(faces)) + b"".join(struct.pack("<4H", a, b, c, 0) for a, b, c in faces) + chunk(0x4130, group)
        tex = chunk(0x4140, struct.pack("<H", len(uvs)) + b"".join(struct.pack("<2f", *t) for t in uvs)) if uvs else b""
        objects += chunk(0x4000, name.encode() + b"\0" + chunk(0x4100, chunk(0x4110, verts) + tex + chunk(0x4120, tris)))
    return chunk(0x4D4D, chunk(0x0002, struct.pack("<I", 3)) + chunk(0x3D3D, b"".join(materials) + objects))


# venue.mvr's cube.3ds materials (known answers in tests/scene_import.rs).
CUBE_PAINT = (200, 60, 20)  # COLOR_24 of the cube
PANEL_COLOUR = (90, 90, 200)  # COLOR_24 of the panel, replaced by its map PANEL.PNG
SIGN_COLOUR = (30, 160, 90)  # COLOR_24 of the sign, whose map sign.png is not in the archive
# PANEL.PNG: 8x8 texels in four 4x4 blocks (bilinear sampling is exact away from block edges):
# block (bx, by) from the top-left has colour PANEL_BLOCKS[bx + 2 * by].
PANEL_BLOCKS = [(255, 0, 0), (0, 200, 0), (30, 60, 255), (128, 128, 128)]


def quad_3ds(x0, x1, z_mm):
    """A horizontal 1000 mm square at MVR-frame height z_mm, x in [x0, x1], y in [-500, 500],
    facing +z (up), with 3DS UVs u = (x - x0)/1000, v = (y + 500)/1000."""
    v = [(x0, -500.0, z_mm), (x1, -500.0, z_mm), (x1, 500.0, z_mm), (x0, 500.0, z_mm)]
    uv = [((x - x0) / 1000.0, (y + 500.0) / 1000.0) for x, y, _ in v]
    return v, [(0, 1, 2), (0, 2, 3)], uv


def venue_mvr():
    """venue.mvr: the MVR's geometry is the scene (known answers in tests/scene_import.rs).

    * floor.glb: a 10 m x 8 m matte floor quad at glTF y = 0 (2 triangles), placed at the origin,
      factor 0.5 times a 2x2 NEAREST checker texture in the GLB: sRGB 255 where x and z have the
      same sign, 64 elsewhere (u = (x + 5)/10, v = (z + 4)/8);
    * truss.glb: a 2 m x 0.3 m x 0.3 m box along glTF x (12 triangles), a Symdef instanced by 3
      Truss objects at MVR (-2500 + 2500 k, 2000, 6000) mm -> stage x = -2.5 + 2.5k, y = 6, z = -2 m;
    * cube.3ds: a 1000 mm cube x, y in [-500, 500], z in [0, 1000] mm (MVR frame, Z up) at
      MVR (2000, 0, 0) mm inside a GroupObject -> stage x in [1.5, 2.5], y in [0, 1], z in [-0.5, 0.5],
      material "Cube paint" (COLOR_24 CUBE_PAINT); in the same file two 1 m squares facing up at
      500 mm: "panel" (x 1000..2000 mm -> stage x 3..4, y 0.5, z -0.5..0.5) in "Panel print" with
      the map PANEL.PNG (panel.png at the archive root, PANEL_BLOCKS) and UVs, and "sign"
      (x -2000..-1000 mm -> stage x 0..1) in "Sign", whose map sign.png the archive lacks;
    * a Support naming chain_hoist.glb, which the archive does not hold -> a stand-in cube + warning;
    * one Spot fixture (the show's one light), 7 m above the stage centre.
    """
    scenery = uid("class/Scenery")
    truss_def = uid("symdef/venue-truss")
    ident = "{1,0,0}{0,1,0}{0,0,1}{0,0,0}"
    aux = [
        el("Class", name="Scenery", uuid=scenery),
        el("Symdef", [el("ChildList", [el("Geometry3D", [el("Matrix", ident)], fileName="truss.glb")])], name="Truss 2 m", uuid=truss_def),
    ]
    floor = el("SceneObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", scenery), el("Geometries", [el("Geometry3D", fileName="floor.glb")])], name="Floor", uuid=uid("venue/floor"))
    trusses = [
        el("Truss", [el("Matrix", mvr_matrix(-2500 + 2500 * k, 2000, 6000)), el("Classing", scenery), el("Geometries", [el("Symbol", [el("Matrix", ident)], uuid=uid(f"venue/symbol/{k}"), symdef=truss_def)])], name=f"Truss {k + 1}", uuid=uid(f"venue/truss/{k}"))
        for k in range(3)
    ]
    cube = el("SceneObject", [el("Matrix", mvr_matrix(2000, 0, 0)), el("Geometries", [el("Geometry3D", fileName="cube.3ds")])], name="Cube", uuid=uid("venue/cube"))
    group = el("GroupObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("ChildList", [cube])], name="Set pieces", uuid=uid("venue/group"))
    hoist = el("Support", [el("Matrix", mvr_matrix(-4000, 2000, 6000)), el("Geometries", [el("Geometry3D", fileName="chain_hoist.glb")])], name="Hoist 1", uuid=uid("venue/hoist"))
    spot = fixture_xml("Spot 1", "Footlight@Spot.gdtf", "Basic", 1, 1, mvr_matrix(0, 0, 7000), [(0, 1)])
    layers = [el("Layer", [el("ChildList", [floor, group, hoist, spot] + trusses)], name="Venue", uuid=uid("layer/venue-geometry"))]
    floor_v = [(-5.0, 0.0, -4.0), (5.0, 0.0, -4.0), (5.0, 0.0, 4.0), (-5.0, 0.0, 4.0)]
    floor_t = [(0, 3, 2), (0, 2, 1)]  # counter-clockwise seen from +y
    floor_uv = [((x + 5.0) / 10.0, (z + 4.0) / 8.0) for x, _, z in floor_v]
    checker = png_gray(2, 2, lambda x, y: 255 if x == y else 64)
    truss_v, truss_t = box_mesh((-1.0, -0.15, -0.15), (1.0, 0.15, 0.15))
    cube_v, cube_t = box_mesh((-500.0, -500.0, 0.0), (500.0, 500.0, 1000.0))
    entries = {
        "GeneralSceneDescription.xml": gsd(layers, aux),
        "Footlight@Spot.gdtf": gdtf_bytes("Footlight@Spot.gdtf"),
        "floor.glb": glb_bytes(floor_v, floor_t, (0.5, 0.5, 0.5), "floor", (checker, floor_uv)),
        "truss.glb": glb_bytes(truss_v, truss_t, (0.2, 0.2, 0.2), "truss"),
        "cube.3ds": three_ds_scene(
            [
                ("cube", cube_v, cube_t, None, "Cube paint"),
                ("panel", *quad_3ds(1000.0, 2000.0, 500.0), "Panel print"),
                ("sign", *quad_3ds(-2000.0, -1000.0, 500.0), "Sign"),
            ],
            [
                three_ds_material("Cube paint", CUBE_PAINT),
                three_ds_material("Panel print", PANEL_COLOUR, "PANEL.PNG"),
                three_ds_material("Sign", SIGN_COLOUR, "sign.png"),
            ],
        ),
        "panel.png": png_rgb(8, 8, lambda x, y: PANEL_BLOCKS[x // 4 + 2 * (y // 4)]),
    }
    return zip_bytes(entries)


SHOW = [
    # (spec, mode, count, footprint, height mm, y mm)
    ("Footlight@Spot.gdtf", "Standard", 44, 27, 7000, 2000),
    ("Footlight@Wash.gdtf", "8ch", 40, 7, 6500, 0),
    ("Footlight@Bar8.gdtf", "25ch", 24, 25, 6000, 4000),
    ("Footlight@Blinder.gdtf", "2ch", 20, 2, 5000, -2000),
    ("Footlight@Fresnel.gdtf", "2ch", 20, 2, 6000, -4000),
    ("Footlight@Hazer.gdtf", "2ch", 2, 2, 0, 5000),
]


def show_mvr():
    lights = uid("class/Lighting")
    fixtures = []
    universe, address = 1, 1
    fid = 1000
    for spec, mode_name, count, footprint, height, y in SHOW:
        for k in range(count):
            if address + footprint - 1 > 512:
                universe, address = universe + 1, 1
            x = (k - (count - 1) / 2) * (14000 / max(count - 1, 1))
            fid += 1
            fixtures.append(
                fixture_xml(f"{spec.split('@')[1][:-5]} {k + 1}", spec, mode_name, fid, k + 1, mvr_matrix(x, y, height), [(0, absolute(universe, address))], lights)
            )
            address += footprint
    assert len(fixtures) == 150, len(fixtures)
    layers = [el("Layer", [el("ChildList", fixtures)], name="Rig", uuid=uid("layer/show-rig"))]
    aux = [el("Class", name="Lighting", uuid=lights)]
    entries = {"GeneralSceneDescription.xml": gsd(layers, aux)}
    for spec, *_ in SHOW:
        entries[spec] = gdtf_bytes(spec)
    return zip_bytes(entries)


# gate.mvr: five Extended-mode spots 4 m up at stage z = -2 m, 1.65 m apart,
# turned 90 degrees about MVR X so their rest beams point upstage onto the
# cyclorama (seen face-on from the stage's camera), each at universe 1
# address 1 + 30 k. The golden test (tests/gate.rs) sets their gobos,
# blades, prism and frost with --set.
GATE_SPOTS = 5


def gate_mvr():
    lights = uid("class/Lighting")
    fixtures = [
        fixture_xml(f"Gate spot {k + 1}", "Footlight@Spot.gdtf", "Extended", 2000 + k, k + 1, mvr_matrix(-3300 + 1650 * k, 2000, 4000, rot_x_deg=90.0), [(0, 1 + 30 * k)], lights)
        for k in range(GATE_SPOTS)
    ]
    layers = [el("Layer", [el("ChildList", fixtures)], name="Gate rig", uuid=uid("layer/gate-rig"))]
    entries = {"GeneralSceneDescription.xml": gsd(layers, [el("Class", name="Lighting", uuid=lights)])}
    entries["Footlight@Spot.gdtf"] = gdtf_bytes("Footlight@Spot.gdtf")
    return zip_bytes(entries)


def cells_mvr():
    """cells.mvr: one Fan4 hung 5 m up, unrotated (its GDTF -Z is the MVR's -Z: down)."""
    lights = uid("class/Lighting")
    f = fixture_xml("Fan 1", "Footlight@Fan4.gdtf", "4ch", 801, 1, mvr_matrix(0, 0, 5000), [(0, 1)], lights)
    f2 = fixture_xml("Fan 2", "Footlight@Fan4.gdtf", "5ch", 802, 2, mvr_matrix(2000, 0, 5000), [(0, 11)], lights)
    layers = [el("Layer", [el("ChildList", [f, f2])], name="Cells", uuid=uid("layer/cells"))]
    entries = {"GeneralSceneDescription.xml": gsd(layers, [el("Class", name="Lighting", uuid=lights)])}
    entries["Footlight@Fan4.gdtf"] = gdtf_bytes("Footlight@Fan4.gdtf")
    return zip_bytes(entries)


def minimal_gsd():
    f = fixture_xml("Spot 1", "Footlight@Spot.gdtf", "Basic", 1, 1, mvr_matrix(0, 0, 6000), [(0, 1)])
    return gsd([el("Layer", [el("ChildList", [f])], name="L", uuid=uid("layer/min"))], [])


def patch_header(data, old_name, field_offsets, value):
    """Overwrites the 4-byte uncompressed-size field of entry `old_name` in the local header and the central directory."""
    b = bytearray(data)
    name = old_name.encode()
    i = 0
    while True:
        i = b.find(b"PK\x03\x04", i)
        if i < 0:
            break
        n = struct.unpack_from("<H", b, i + 26)[0]
        if bytes(b[i + 30 : i + 30 + n]) == name:
            struct.pack_into("<I", b, i + field_offsets[0], value)
        i += 4
    i = 0
    while True:
        i = b.find(b"PK\x01\x02", i)
        if i < 0:
            break
        n = struct.unpack_from("<H", b, i + 28)[0]
        if bytes(b[i + 46 : i + 46 + n]) == name:
            struct.pack_into("<I", b, i + field_offsets[1], value)
        i += 4
    return bytes(b)


def bad_files():
    gsd_text = minimal_gsd()
    spot_bytes = gdtf_bytes("Footlight@Spot.gdtf")
    out = {}
    out["bad-dotdot.mvr"] = zip_bytes({"GeneralSceneDescription.xml": gsd_text, "../evil.gdtf": spot_bytes})
    out["bad-absolute.mvr"] = zip_bytes({"GeneralSceneDescription.xml": gsd_text, "/etc/evil.gdtf": spot_bytes})
    # 4 MiB of zeros deflate to ~4 KiB: a 1000:1 entry.
    out["bad-ratio.mvr"] = zip_bytes({"GeneralSceneDescription.xml": gsd_text, "zeros.bin": b"\0" * (4 << 20)})
    # A stored entry whose headers claim 3 GiB uncompressed.
    stored = zip_bytes({"GeneralSceneDescription.xml": gsd_text, "huge.bin": b"x" * 1024}, compress=zipfile.ZIP_STORED)
    out["bad-huge.mvr"] = patch_header(stored, "huge.bin", (22, 24), 3 << 30)
    broken = gsd_text.replace("<GDTFMode>Basic</GDTFMode>", "<GDTFMode>Basic</GDTFMod>")
    out["bad-xml.mvr"] = zip_bytes({"GeneralSceneDescription.xml": broken, "Footlight@Spot.gdtf": spot_bytes})
    return out


# --- fixture bodies (issue 14 item 5): a glb model, a 3ds model, primitives only ---


def body_types():
    """The three GDTF types of bodies.mvr (known answers in tests/bodies.rs).

    * BodyGlb: a moving head. Foot (model Foot: Cube 0.4 x 0.4 x 0.2 m) > Arm
      (Axis, Pan, no model) > Lantern (Axis, Tilt, at z = -0.3 m; model Head
      0.3 x 0.2 x 0.5 m, File "head" = models/gltf/head.glb: a glTF box
      x in [0, 2], y in [0, 1], z in [0, 4] (Y up) -> GDTF X in [0, 2],
      Y in [-4, 0], Z in [0, 1] -> scaled to X in [0, 0.3], Y in [-0.2, 0],
      Z in [0, 0.5]) > Lens (Beam at z = -0.1 m, no model, BeamRadius 0.08:
      a lens disc). Pan -180..180, tilt -90..90 (16-bit).
    * Body3ds: a fixed can. Can (model Can 0.25 x 0.25 x 0.4 m, File "can" =
      models/3ds/can.3ds: a box x, y in [-100, 100], z in [0, 300] mm ->
      X, Y in [-0.125, 0.125], Z in [0, 0.4] m) > Lens (Beam at the origin,
      no model, BeamRadius 0.1).
    * BodyPrim: a fixed par, primitives only. Shell (model Shell: Cylinder
      0.3 x 0.3 x 0.4 m, Z in [-0.2, 0.2]) > Lens (Beam at z = -0.2 m, model
      Lens: Cylinder 0.24 x 0.24 x 0.01 m).
    """
    physical = [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    head_v, head_t = box_mesh((0.0, 0.0, 0.0), (2.0, 1.0, 4.0))
    lamp = dict(LampType="LED", PowerConsumption="300", LuminousFlux="10000", ColorTemperature="6500", BeamAngle="20", FieldAngle="30", BeamType="Spot")
    glb_tree = el(
        "Geometry",
        [el("Axis", [el("Axis", [beam("Lens", None, m4(0, 0, -0.1), BeamRadius="0.08", **lamp)], Name="Lantern", Model="Head", Position=m4(0, 0, -0.3))], Name="Arm", Position=m4())],
        Name="Foot",
        Model="Foot",
        Position=m4(),
    )
    glb_mode = [simple("Arm", [1, 2], "Pan", -180, 180, default=32768), simple("Lantern", [3, 4], "Tilt", -90, 90, default=32768), simple("Lens", [5], "Dimmer", 0, 1)]
    glb = fixture_type(
        "BodyGlb", "BodyGlb", ["Dimmer", "Pan", "Tilt"], [], physical,
        [model("Foot", 0.4, 0.4, 0.2, "Cube"), model("Head", 0.3, 0.2, 0.5, "Undefined", file="head")],
        [glb_tree], [mode("5ch", "Foot", glb_mode)], "moving head with a glb head model (test data, estimated values)",
    )
    can_v, can_t = box_mesh((-100.0, -100.0, 0.0), (100.0, 100.0, 300.0))
    can_tree = el("Geometry", [beam("Lens", None, m4(), BeamRadius="0.1", **lamp)], Name="Can", Model="Can", Position=m4())
    can = fixture_type(
        "Body3ds", "Body3ds", ["Dimmer"], [], physical, [model("Can", 0.25, 0.25, 0.4, "Undefined", file="can")],
        [can_tree], [mode("1ch", "Can", [simple("Lens", [1], "Dimmer", 0, 1)])], "fixed can with a 3ds model (test data, estimated values)",
    )
    prim_tree = el("Geometry", [beam("Lens", "Lens", m4(0, 0, -0.2), BeamRadius="0.12", **lamp)], Name="Shell", Model="Shell", Position=m4())
    prim = fixture_type(
        "BodyPrim", "BodyPrim", ["Dimmer"], [], physical, [model("Shell", 0.3, 0.3, 0.4, "Cylinder"), model("Lens", 0.24, 0.24, 0.01, "Cylinder")],
        [prim_tree], [mode("1ch", "Shell", [simple("Lens", [1], "Dimmer", 0, 1)])], "fixed par, primitive models only (test data, estimated values)",
    )
    return {
        "Footlight@BodyGlb.gdtf": zip_bytes({"description.xml": glb, "models/gltf/head.glb": glb_bytes(head_v, head_t, (0.2, 0.2, 0.2), "head")}),
        "Footlight@Body3ds.gdtf": zip_bytes({"description.xml": can, "models/3ds/can.3ds": three_ds_bytes(can_v, can_t, "can")}),
        "Footlight@BodyPrim.gdtf": zip_bytes({"description.xml": prim}),
    }


# bodies.mvr: one fixture of each body type, 4 m up, 2 m apart along stage x,
# unrotated (GDTF Z up = stage y up: the beams point straight down).
BODY_FIXTURES = [("Head glb", "Footlight@BodyGlb.gdtf", "5ch", -2000), ("Can 3ds", "Footlight@Body3ds.gdtf", "1ch", 0), ("Par prim", "Footlight@BodyPrim.gdtf", "1ch", 2000)]


def bodies_mvr():
    lights = uid("class/Lighting")
    fixtures = [
        fixture_xml(name, spec, mode_name, 3001 + k, k + 1, mvr_matrix(x, 0, 4000), [(0, 1 + 10 * k)], lights)
        for k, (name, spec, mode_name, x) in enumerate(BODY_FIXTURES)
    ]
    layers = [el("Layer", [el("ChildList", fixtures)], name="Bodies", uuid=uid("layer/bodies"))]
    entries = {"GeneralSceneDescription.xml": gsd(layers, [el("Class", name="Lighting", uuid=lights)])}
    entries.update(body_types())
    return zip_bytes(entries)


# --- festival.mvr (issue 38 item 7, issue 36 items 3-4): a festival-scale show -------------
#
# Six manufacturers' files as a festival rig hangs them (makers and numbers invented,
# estimated): pixel bars of 16 cells with no emitters and no dimmer, 20-cell LED wash
# heads (master dimmer, per-cell RGBW, ColorMixMode, HSB), profiles with two rotating
# gobo wheels (mode masters: index or rotation), 8-cell blinders (DimmerCurve,
# StrobeDuration, ColorAdd_WW/CW), beams named by an extension-less GDTFSpec (one
# `<name>.gdtf`, one only by its FixtureType Name) and 40-cell strobe battens; three
# fixtures of a GDTF the archive lacks; a venue (ground, deck, roof: > 200,000 triangles)
# whose glTF models read a texture file and a buffer file from the archive; no camera.
# Known answers in FESTIVAL_JSON (tests/data/mvr/festival.json).

FESTIVAL_MVR = MVR_DIR / "festival.mvr"
FESTIVAL_JSON = MVR_DIR / "festival.json"

FESTIVAL_ATTRIBUTES = {
    "ColorMacro1": ("Color.Color", "None", "Color Macro 1"),
    "ColorMixMode": ("Control.Control", "None", "Color Mix Mode"),
    "HSB_Hue": ("Color.Color", "Angle", "Hue"),
    "HSB_Saturation": ("Color.Color", "ColorComponent", "Saturation"),
    "HSB_Brightness": ("Color.Color", "ColorComponent", "Brightness"),
    "Gobo2": ("Gobo.Gobo", "None", "G2"),
    "Gobo2Pos": ("Gobo.Gobo", "Angle", "G2 <>"),
    "Gobo2PosRotate": ("Gobo.Gobo", "AngularSpeed", "G2 Rotate"),
    "StrobeDuration": ("Beam.Beam", "Time", "Strobe Duration"),
    "DimmerCurve": ("Control.Control", "None", "Dimmer Curve"),
    "ColorAdd_WW": ("Color.RGB", "ColorComponent", "WW"),
    "ColorAdd_CW": ("Color.RGB", "ColorComponent", "CW"),
}
for _name, _def in FESTIVAL_ATTRIBUTES.items():
    ATTRIBUTES.setdefault(_name, _def)

# (file in the archive, GDTFSpec the MVR writes, mode, fixtures, cells per fixture, footprint)
FESTIVAL_TYPES = [
    ("Lumenstrip@PixelBar 16.gdtf", "Lumenstrip@PixelBar 16.gdtf", "65ch", 96, 16, 65),
    ("Orbis@Wash 20.gdtf", "Orbis@Wash 20.gdtf", "Extended", 48, 20, 92),
    ("Nordlicht@Profile 1200.gdtf", "Nordlicht@Profile 1200.gdtf", "Standard", 24, 1, 22),
    ("Blitzwerk@Cluster S2.gdtf", "Blitzwerk@Cluster S2", "20ch", 24, 8, 20),
    ("Raylight@Sharpline_330@rev2.gdtf", "Sharpline 330", "Standard", 12, 1, 11),
    ("Pyxis@Stroboline 40.gdtf", "Pyxis@Stroboline 40.gdtf", "123ch", 24, 40, 123),
]
# Named by three fixtures, not in the archive: dark placeholders (one warning, one summary line).
FESTIVAL_MISSING = ("Lumenstrip@Floor Wash 7.gdtf", "Mode 1", 3, 1, 10)


def festival_pretty(text):
    """One element per line, as exporters write their XML (so a warning's line number
    points at the element it names; the other generated files are one long line)."""
    return text.replace("><", ">\n<")


def festival_physical(emitters=None):
    return [emitters or el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]


def festival_cells(names_geometry, count, first_offset, stride, positions, break_="1"):
    """`count` GeometryReferences of `names_geometry` (name prefix, referenced geometry), the
    k-th at positions[k] with its channels from DMX offset first_offset + stride * k."""
    prefix, geometry = names_geometry
    return [
        el("GeometryReference", [el("Break", DMXOffset=str(first_offset + stride * k), DMXBreak=break_)], Name=f"{prefix}{k + 1}", Geometry=geometry, Position=positions[k])
        for k in range(count)
    ]


def festival_pixel_bar():
    """Lumenstrip PixelBar 16: a 1 m bar of 16 RGBW pixels, no emitters defined and no
    dimmer (the colour channels are the level), a colour macro on the last slot; its
    models name files the archive lacks (bodies: the primitive, one warning per file)."""
    used = ["ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_W", "ColorMacro1"]
    models = [model("Body", 1.0, 0.05, 0.07, "Cube", file="px16_body"), model("Pixel", 0.0625, 0.04, 0.01, "Cube", file="px16_pixel")]
    pixel = beam("Pixel", "Pixel", m4(), LampType="LED", PowerConsumption="6", LuminousFlux="250", ColorTemperature="6500", BeamAngle="15", FieldAngle="25", BeamRadius="0.02", BeamType="Wash")
    refs = festival_cells(("Pixel", "Pixel"), 16, 1, 4, [m4(-0.46875 + 0.0625 * k, 0, -0.035) for k in range(16)])
    tree = el("Geometry", refs, Name="Bar", Model="Body", Position=m4())
    chans = [simple("Pixel", [1 + k], a) for k, a in enumerate(["ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_W"])]
    chans.append(Chan("Bar", [65], [("ColorMacro1", 0, 0, 0, {}, [("Off", 0, None)]), ("ColorMacro1", 8, 0, 0, {}, [("Rainbow", 8, None)])]))
    return fixture_type(
        "PixelBar 16", "PX16", used, [], festival_physical(), models, [tree, pixel], [mode("65ch", "Bar", chans)],
        "16-pixel RGBW bar, no emitters, no dimmer (festival test data, estimated values)", manufacturer="Lumenstrip",
    ), {}


def festival_wash():
    """Orbis Wash 20: a moving head of 20 RGBW cells in a ring (emitters with xyY), a
    master dimmer, zoom, shutter/strobe, ColorMixMode and HSB on the head."""
    used = ["Pan", "Tilt", "Dimmer", "Shutter1", "Shutter1Strobe", "Zoom", "ColorMixMode", "HSB_Hue", "HSB_Saturation", "HSB_Brightness", "ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_W"]
    models = [model("Base", 0.4, 0.3, 0.15, "Base"), model("Yoke", 0.4, 0.1, 0.4, "Yoke"), model("Head", 0.35, 0.35, 0.3, "Head"), model("Cell", 0.05, 0.05, 0.01, "Cylinder")]
    cell = beam("Cell", "Cell", m4(), LampType="LED", PowerConsumption="40", LuminousFlux="900", ColorTemperature="6500", BeamAngle="6", FieldAngle="10", BeamRadius="0.025", BeamType="Wash")
    ring = []
    for k in range(20):
        r, a = (0.06, 2 * math.pi * k / 6) if k < 6 else (0.13, 2 * math.pi * (k - 6) / 14)
        ring.append(m4(r * math.cos(a), r * math.sin(a), -0.15))
    head = el("Axis", festival_cells(("Cell", "Cell"), 20, 13, 4, ring), Name="Head", Model="Head", Position=m4(0, 0, -0.3))
    tree = el("Geometry", [el("Axis", [head], Name="Yoke", Model="Yoke", Position=m4(0, 0, -0.15))], Name="Base", Model="Base", Position=m4())
    rgbw = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue"), ("ColorAdd_W", "White")]
    chans = [
        simple("Yoke", [1, 2], "Pan", -270, 270, default=32768),
        simple("Head", [3, 4], "Tilt", -135, 135, default=32768),
        simple("Head", [5, 6], "Dimmer", 0, 1),
        Chan("Head", [7], [("Shutter1", 0, 0, 0, {}, [("Closed", 0, None)]), ("Shutter1", 16, 1, 1, {}, [("Open", 16, None)]), ("Shutter1Strobe", 32, 1, 20, {}, [])], default=16),
        simple("Head", [8], "Zoom", 6, 45),
        Chan("Head", [9], [("ColorMixMode", 0, 0, 0, {}, [("RGBW", 0, None)]), ("ColorMixMode", 128, 1, 1, {}, [("HSB", 128, None)])]),
        simple("Head", [10], "HSB_Hue", 0, 360),
        simple("Head", [11], "HSB_Saturation", 0, 1),
        simple("Head", [12], "HSB_Brightness", 0, 1),
    ]
    chans += [simple("Cell", [1 + k], a, extra={"Emitter": e}) for k, (a, e) in enumerate(rgbw)]
    return fixture_type(
        "Wash 20", "W20", used, [], festival_physical(emitters_xml(spectra=False)), models, [tree, cell], [mode("Extended", "Base", chans)],
        "20-cell RGBW wash head (festival test data, estimated values)", manufacturer="Orbis",
    ), {}


def festival_gobo_wheel(name, slots):
    return el("Wheel", [el("Slot", Name="Open", Color="0.3127,0.3290,100")] + [el("Slot", Name=n, Color="0.3127,0.3290,100", MediaFileName=f) for n, f in slots], Name=name)


def festival_rotating_gobos(geometry, wheel, offset, sets):
    """A rotating gobo wheel's two channels: the wheel (0-63 slots indexed, 64-127 the
    same slots rotating, 128-255 wheel spin) and its rotation channel, whose two
    functions both start at DMX 0, each active by mode master (the wheel channel's
    range): WheelPos index 0..360 deg while indexed, PosRotate -200..200 deg/s while rotating."""
    master = f"{geometry}_{wheel}"
    slots = [(n, 8 * k, k + 1) for k, n in enumerate(sets)]
    rotating = [(f"{n} rotating", 64 + 8 * k, k + 1) for k, n in enumerate(sets)]
    wheel_chan = Chan(
        geometry,
        [offset],
        [(wheel, 0, 0, 0, {"Wheel": wheel}, slots + rotating), (f"{wheel}WheelSpin", 128, -120, 120, {"Wheel": wheel}, [])],
    )
    index = {"ModeMaster": master, "ModeFrom": "0/1", "ModeTo": "63/1"}
    rotate = {"ModeMaster": master, "ModeFrom": "64/1", "ModeTo": "127/1"}
    pos_chan = Chan(geometry, [offset + 1], [(f"{wheel}Pos", 0, 0, 360, index, []), (f"{wheel}PosRotate", 0, -200, 200, rotate, [])], default=0)
    return [wheel_chan, pos_chan]


def festival_profile():
    """Nordlicht Profile 1200: a moving profile with a colour wheel, two rotating gobo
    wheels (mode-mastered index/rotation), prism, frost, zoom, focus, iris, CMY, CTO."""
    cw, _ = color_wheel()
    g1 = festival_gobo_wheel("Gobo1", [("Ring", "gobo_ring"), ("Bars", "gobo_bars")])
    g2 = festival_gobo_wheel("Gobo2", [("Dots", "fest_dots"), ("Half", "fest_half")])
    pw, _ = prism_wheel()
    used = [
        "Pan", "Tilt", "Dimmer", "Shutter1", "Shutter1Strobe", "Color1", "Gobo1", "Gobo1WheelSpin", "Gobo1Pos", "Gobo1PosRotate",
        "Gobo2", "Gobo2Pos", "Gobo2PosRotate", "Prism1", "Prism1PosRotate", "Frost1", "Zoom", "Focus1", "Iris",
        "ColorSub_C", "ColorSub_M", "ColorSub_Y", "CTO",
    ]
    ATTRIBUTES.setdefault("Gobo2WheelSpin", ("Gobo.Gobo", "AngularSpeed", "G2 Wheel Spin"))
    used.append("Gobo2WheelSpin")
    models = [model("Base", 0.45, 0.35, 0.18, "Base"), model("Yoke", 0.4, 0.12, 0.45, "Yoke"), model("Head", 0.3, 0.3, 0.6, "Head"), model("Lens", 0.01, 0.16, 0.16, "Cylinder")]
    filters = [
        el("FilterColor", Name="ColorWheel", Model="Lens", Position=m4(0, 0, -0.05)),
        el("FilterGobo", Name="GoboWheel1", Model="Lens", Position=m4(0, 0, -0.06)),
        el("FilterGobo", Name="GoboWheel2", Model="Lens", Position=m4(0, 0, -0.07)),
    ]
    lens = beam("Lens", "Lens", m4(0, 0, -0.3), LampType="LED", PowerConsumption="1200", LuminousFlux="42000", ColorTemperature="6800", BeamAngle="7", FieldAngle="9", BeamRadius="0.08", BeamType="Spot", children=filters)
    tree = el("Geometry", [el("Axis", [el("Axis", [lens], Name="Head", Model="Head", Position=m4(0, 0, -0.4))], Name="Yoke", Model="Yoke", Position=m4(0, 0, -0.18))], Name="Base", Model="Base", Position=m4())
    chans = [
        simple("Yoke", [1, 2], "Pan", -270, 270, default=32768),
        simple("Head", [3, 4], "Tilt", -135, 135, default=32768),
        simple("Lens", [5, 6], "Dimmer", 0, 1),
        Chan("Lens", [7], [("Shutter1", 0, 0, 0, {}, [("Closed", 0, None)]), ("Shutter1", 32, 1, 1, {}, [("Open", 32, None)]), ("Shutter1Strobe", 64, 1, 25, {}, [])], default=32),
        Chan("ColorWheel", [8], [("Color1", 0, 0, 0, {"Wheel": "Color1"}, [("Open", 0, 1), ("Red", 10, 2), ("Green", 20, 3), ("Blue", 30, 4), ("Amber", 40, 5)])]),
    ]
    chans += festival_rotating_gobos("GoboWheel1", "Gobo1", 9, ["Open", "Ring", "Bars"])
    chans += festival_rotating_gobos("GoboWheel2", "Gobo2", 11, ["Open", "Dots", "Half"])
    chans += [
        Chan("Lens", [13], [("Prism1", 0, 0, 0, {"Wheel": "Prism1"}, [("Out", 0, 1)]), ("Prism1", 128, 0, 0, {"Wheel": "Prism1"}, [("3-Facet", 128, 2)])]),
        simple("Lens", [14], "Prism1PosRotate", -180, 180, default=128),
        simple("Lens", [15], "Frost1", 0, 1),
        simple("Lens", [16], "Zoom", 5, 50),
        simple("Lens", [17], "Focus1", 0, 1),
        simple("Lens", [18], "Iris", 1, 0.15),
        simple("Lens", [19], "ColorSub_C", 0, 1),
        simple("Lens", [20], "ColorSub_M", 0, 1),
        simple("Lens", [21], "ColorSub_Y", 0, 1),
        simple("Lens", [22], "CTO", 6800, 3200),
    ]
    dots = png_gray(GOBO_SIZE, GOBO_SIZE, lambda x, y: 255 if ((x // 8) + (y // 8)) % 2 == 0 and (x % 8 - 4) ** 2 + (y % 8 - 4) ** 2 < 9 else 0)
    half = png_gray(GOBO_SIZE, GOBO_SIZE, lambda x, y: 255 if x < GOBO_SIZE // 2 else 0)
    media = {"wheels/gobo_ring.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_ring), "wheels/gobo_bars.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_bars), "wheels/fest_dots.png": dots, "wheels/fest_half.png": half}
    return fixture_type(
        "Profile 1200", "P1200", used, [cw, g1, g2, pw], festival_physical(), models, [tree], [mode("Standard", "Base", chans)],
        "moving profile with two rotating gobo wheels (festival test data, estimated values)", manufacturer="Nordlicht",
    ), media


def festival_blinder():
    """Blitzwerk Cluster S2: 8 lamps in a 2 x 4 grid, each a warm and a cool white
    emitter; master dimmer, dimmer curve, strobe rate and duration."""
    used = ["Dimmer", "DimmerCurve", "Shutter1", "Shutter1Strobe", "StrobeDuration", "ColorAdd_WW", "ColorAdd_CW"]
    emitters = el("Emitters", [el("Emitter", Name="Warm", Color="0.4600,0.4100,100", DominantWaveLength="0"), el("Emitter", Name="Cool", Color="0.3130,0.3290,100", DominantWaveLength="0")])
    models = [model("Frame", 0.6, 0.3, 0.12, "Cube"), model("Lamp", 0.12, 0.12, 0.02, "Cylinder")]
    lamp = beam("Lamp", "Lamp", m4(), LampType="LED", PowerConsumption="90", LuminousFlux="6000", ColorTemperature="4000", BeamAngle="40", FieldAngle="70", BeamRadius="0.06", BeamType="Wash")
    grid = [m4(-0.225 + 0.15 * (k % 4), -0.075 + 0.15 * (k // 4), -0.06) for k in range(8)]
    tree = el("Geometry", festival_cells(("Lamp", "Lamp"), 8, 5, 2, grid), Name="Frame", Model="Frame", Position=m4())
    chans = [
        simple("Frame", [1], "Dimmer", 0, 1),
        Chan("Frame", [2], [("DimmerCurve", 0, 0, 0, {}, [("Linear", 0, None)]), ("DimmerCurve", 64, 1, 1, {}, [("Square", 64, None)]), ("DimmerCurve", 128, 2, 2, {}, [("S-curve", 128, None)])]),
        Chan("Frame", [3], [("Shutter1", 0, 1, 1, {}, [("Open", 0, None)]), ("Shutter1Strobe", 16, 1, 25, {}, [])]),
        simple("Frame", [4], "StrobeDuration", 0.005, 0.2),
        simple("Lamp", [1], "ColorAdd_WW", extra={"Emitter": "Warm"}),
        simple("Lamp", [2], "ColorAdd_CW", extra={"Emitter": "Cool"}),
    ]
    return fixture_type(
        "Cluster S2", "CS2", used, [], festival_physical(emitters), models, [tree, lamp], [mode("20ch", "Frame", chans)],
        "8-lamp warm/cool blinder (festival test data, estimated values)", manufacturer="Blitzwerk",
    ), {}


def festival_beam():
    """Raylight Sharpline 330: a beam light (colour wheel, gobo wheel, prism, frost);
    the MVR names it only by its FixtureType Name, "Sharpline 330"."""
    cw, _ = color_wheel()
    gw, _ = gobo_wheel()
    pw, _ = prism_wheel()
    used = ["Pan", "Tilt", "Dimmer", "Shutter1", "Shutter1Strobe", "Color1", "Gobo1", "Prism1", "Frost1", "Focus1"]
    models = [model("Base", 0.35, 0.3, 0.15, "Base"), model("Yoke", 0.3, 0.1, 0.35, "Yoke"), model("Head", 0.22, 0.22, 0.35, "Head"), model("Lens", 0.01, 0.12, 0.12, "Cylinder")]
    filters = [el("FilterColor", Name="ColorWheel", Model="Lens", Position=m4(0, 0, -0.04)), el("FilterGobo", Name="GoboWheel", Model="Lens", Position=m4(0, 0, -0.05))]
    lens = beam("Lens", "Lens", m4(0, 0, -0.2), LampType="Discharge", PowerConsumption="330", LuminousFlux="12000", ColorTemperature="7800", BeamAngle="2", FieldAngle="3", BeamRadius="0.06", BeamType="Spot", children=filters)
    tree = el("Geometry", [el("Axis", [el("Axis", [lens], Name="Head", Model="Head", Position=m4(0, 0, -0.3))], Name="Yoke", Model="Yoke", Position=m4(0, 0, -0.15))], Name="Base", Model="Base", Position=m4())
    chans = [
        simple("Yoke", [1, 2], "Pan", -270, 270, default=32768),
        simple("Head", [3, 4], "Tilt", -135, 135, default=32768),
        simple("Lens", [5], "Dimmer", 0, 1),
        Chan("Lens", [6], [("Shutter1", 0, 0, 0, {}, [("Closed", 0, None)]), ("Shutter1", 32, 1, 1, {}, [("Open", 32, None)]), ("Shutter1Strobe", 64, 1, 25, {}, [])], default=32),
        Chan("ColorWheel", [7], [("Color1", 0, 0, 0, {"Wheel": "Color1"}, [("Open", 0, 1), ("Red", 10, 2), ("Green", 20, 3), ("Blue", 30, 4), ("Amber", 40, 5)])]),
        Chan("GoboWheel", [8], [("Gobo1", 0, 0, 0, {"Wheel": "Gobo1"}, [("Open", 0, 1), ("Ring", 10, 2), ("Bars", 20, 3)])]),
        Chan("Lens", [9], [("Prism1", 0, 0, 0, {"Wheel": "Prism1"}, [("Out", 0, 1)]), ("Prism1", 128, 0, 0, {"Wheel": "Prism1"}, [("3-Facet", 128, 2)])]),
        simple("Lens", [10], "Frost1", 0, 1),
        simple("Lens", [11], "Focus1", 0, 1),
    ]
    media = {"wheels/gobo_ring.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_ring), "wheels/gobo_bars.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_bars)}
    return fixture_type(
        "Sharpline 330", "SL330", used, [cw, gw, pw], festival_physical(), models, [tree], [mode("Standard", "Base", chans)],
        "beam light (festival test data, estimated values)", manufacturer="Raylight",
    ), media


def festival_strobe():
    """Pyxis Stroboline 40: a 1.2 m batten of 40 RGB cells (emitters with xyY), master
    dimmer, strobe rate and duration."""
    used = ["Dimmer", "Shutter1", "Shutter1Strobe", "StrobeDuration", "ColorAdd_R", "ColorAdd_G", "ColorAdd_B"]
    models = [model("Batten", 1.2, 0.1, 0.1, "Cube"), model("Cell", 0.03, 0.06, 0.01, "Cube")]
    cell = beam("Cell", "Cell", m4(), LampType="LED", PowerConsumption="12", LuminousFlux="500", ColorTemperature="6500", BeamAngle="90", FieldAngle="120", BeamRadius="0.015", BeamType="Wash")
    refs = festival_cells(("Cell", "Cell"), 40, 4, 3, [m4(-0.585 + 0.03 * k, 0, -0.05) for k in range(40)])
    tree = el("Geometry", refs, Name="Batten", Model="Batten", Position=m4())
    rgb = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue")]
    chans = [
        simple("Batten", [1], "Dimmer", 0, 1),
        Chan("Batten", [2], [("Shutter1", 0, 1, 1, {}, [("Open", 0, None)]), ("Shutter1Strobe", 16, 1, 25, {}, [])]),
        simple("Batten", [3], "StrobeDuration", 0.005, 0.2),
    ]
    chans += [simple("Cell", [1 + k], a, extra={"Emitter": e}) for k, (a, e) in enumerate(rgb)]
    return fixture_type(
        "Stroboline 40", "SB40", used, [], festival_physical(emitters_xml(spectra=False)), models, [tree, cell], [mode("123ch", "Batten", chans)],
        "40-cell RGB strobe batten (festival test data, estimated values)", manufacturer="Pyxis",
    ), {}


FESTIVAL_BUILDERS = {
    "Lumenstrip@PixelBar 16.gdtf": festival_pixel_bar,
    "Orbis@Wash 20.gdtf": festival_wash,
    "Nordlicht@Profile 1200.gdtf": festival_profile,
    "Blitzwerk@Cluster S2.gdtf": festival_blinder,
    "Raylight@Sharpline_330@rev2.gdtf": festival_beam,
    "Pyxis@Stroboline 40.gdtf": festival_strobe,
}


def festival_gltf_doc(meshes, buffer_uri, image_uri=None):
    """A glTF 2.0 document and its binary buffer: meshes are (name, positions, triangles,
    uvs or None, base colour, index bytes 2 or 4); a textured mesh samples image_uri
    (a file beside the model in the archive) with REPEAT wrapping; buffer_uri None puts
    the buffer in the GLB's binary chunk."""
    import array
    import json

    bin_chunk = bytearray()
    views, accessors, gl_meshes, materials, nodes = [], [], [], [], []

    def view(data, target=None):
        while len(bin_chunk) % 4:
            bin_chunk.append(0)
        v = {"buffer": 0, "byteOffset": len(bin_chunk), "byteLength": len(data)}
        if target:
            v["target"] = target
        bin_chunk.extend(data)
        views.append(v)
        return len(views) - 1

    def floats(values):
        a = array.array("f", values)
        if sys.byteorder != "little":
            a.byteswap()
        return a.tobytes()

    for name, positions, tris, uvs, colour, index_bytes in meshes:
        flat = [c for p in positions for c in p]
        pv = view(floats(flat), 34962)
        lo = [min(p[k] for p in positions) for k in range(3)]
        hi = [max(p[k] for p in positions) for k in range(3)]
        accessors.append({"bufferView": pv, "componentType": 5126, "count": len(positions), "type": "VEC3", "min": lo, "max": hi})
        attributes = {"POSITION": len(accessors) - 1}
        code = "H" if index_bytes == 2 else "I"
        ia = array.array(code, [i for t in tris for i in t])
        if sys.byteorder != "little":
            ia.byteswap()
        iv = view(ia.tobytes(), 34963)
        accessors.append({"bufferView": iv, "componentType": 5123 if index_bytes == 2 else 5125, "count": 3 * len(tris), "type": "SCALAR"})
        indices = len(accessors) - 1
        material = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(colour) + [1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}
        if uvs is not None:
            uv = view(floats([c for t in uvs for c in t]), 34962)
            accessors.append({"bufferView": uv, "componentType": 5126, "count": len(uvs), "type": "VEC2"})
            attributes["TEXCOORD_0"] = len(accessors) - 1
            material["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
        materials.append(material)
        gl_meshes.append({"name": name, "primitives": [{"attributes": attributes, "indices": indices, "material": len(materials) - 1}]})
        nodes.append({"mesh": len(gl_meshes) - 1, "name": name})
    while len(bin_chunk) % 4:
        bin_chunk.append(0)
    buffer = {"byteLength": len(bin_chunk)}
    if buffer_uri:
        buffer["uri"] = buffer_uri
    doc = {
        "asset": {"version": "2.0", "generator": "Footlight gen_gdtf_mvr.py (festival)"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": gl_meshes,
        "materials": materials,
        "buffers": [buffer],
        "bufferViews": views,
        "accessors": accessors,
    }
    if image_uri:
        doc["images"] = [{"uri": image_uri}]
        doc["samplers"] = [{"magFilter": 9729, "minFilter": 9729, "wrapS": 10497, "wrapT": 10497}]
        doc["textures"] = [{"source": 0, "sampler": 0}]
    return json.dumps(doc, separators=(",", ":"), sort_keys=True).encode(), bytes(bin_chunk)


def festival_glb(meshes, image_uri):
    js, bin_chunk = festival_gltf_doc(meshes, None, image_uri)
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(bin_chunk), 0x004E4942) + bin_chunk
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def festival_grid(nx, nz, x0, x1, z0, z1, height):
    """A tessellated surface over x0..x1, z0..z1 (glTF metres, Y up): (nx + 1)(nz + 1)
    vertices at y = height(x, z), 2 nx nz triangles facing +y, UVs one repeat per 4 m."""
    pos, uvs, tris = [], [], []
    for j in range(nz + 1):
        z = z0 + (z1 - z0) * j / nz
        for i in range(nx + 1):
            x = x0 + (x1 - x0) * i / nx
            pos.append((x, height(x, z), z))
            uvs.append((x / 4.0, z / 4.0))
    w = nx + 1
    for j in range(nz):
        for i in range(nx):
            a = j * w + i
            tris += [(a, a + w, a + w + 1), (a, a + w + 1, a + 1)]
    return pos, tris, uvs


def festival_venue():
    """The venue's models, stage axes (glTF: metres, Y up, +Z toward the audience):
    * festival_ground.glb: 160 m x 160 m of ground, 255 x 255 quads (130,050 triangles,
      16-bit indices), flat within 40 m of the stage and gently rolling beyond, its
      texture textures/grass.png a file in the archive (uri, not a data: URI);
    * festival_stage.gltf + festival_stage.bin (a buffer file in the archive, 32-bit
      indices): the deck top (24 m x 14 m at 1.8 m, 120 x 70 quads: 16,800 triangles)
      and a barrel roof over it (26 m span, 12-15 m high, 240 x 120 quads: 57,600 triangles).
    Returns the archive entries and the triangles per model."""
    def ground_height(x, z):
        r = max(abs(x), abs(z)) - 40.0
        return 0.0 if r <= 0 else round(0.6 * math.sin(x / 9.0) * math.sin(z / 11.0) * min(r / 20.0, 1.0), 3)

    gp, gt, gu = festival_grid(255, 255, -80.0, 80.0, -80.0, 80.0, ground_height)
    glb = festival_glb([("ground", gp, gt, gu, (0.8, 0.8, 0.8), 2)], "textures/grass.png")
    dp, dt, _ = festival_grid(120, 70, -12.0, 12.0, -10.0, 4.0, lambda x, z: 1.8)

    def roof_height(x, z):
        return round(12.0 + 3.0 * math.cos(math.pi * x / 26.0), 4)

    rp, rt, _ = festival_grid(240, 120, -13.0, 13.0, -11.0, 5.0, roof_height)
    rt = [(a, c, b) for a, b, c in rt]  # facing down, onto the stage
    js, stage_bin = festival_gltf_doc([("deck", dp, dt, None, (0.35, 0.25, 0.18), 4), ("roof", rp, rt, None, (0.15, 0.15, 0.17), 4)], "festival_stage.bin")

    def grass(x, y):
        v = 40 + (x * 7 + y * 13) % 24
        return (v // 2, 60 + v, v // 3)

    entries = {
        "festival_ground.glb": glb,
        "festival_stage.gltf": js,
        "festival_stage.bin": stage_bin,
        "textures/grass.png": png_rgb(32, 32, grass),
    }
    triangles = {"festival_ground.glb": len(gt), "festival_stage.gltf": len(dt) + len(rt)}
    return entries, triangles


def festival_positions(spec, count):
    """MVR matrices (mm, Z up; MVR +Y upstage) of `count` fixtures of one type: the rig's lines."""
    out = []
    for k in range(count):
        if spec.startswith("Lumenstrip@PixelBar"):
            line, i = divmod(k, 24)
            out.append(mvr_matrix(-11500 + 1000 * i, -3000 + 2000 * line, 9500))
        elif spec.startswith("Orbis"):
            line, i = divmod(k, 24)
            out.append(mvr_matrix(-11500 + 1000 * i, -2000 + 4000 * line, 10200))
        elif spec.startswith("Nordlicht"):
            out.append(mvr_matrix(-11500 + 1000 * k, -6000, 10500))
        elif spec.startswith("Blitzwerk"):
            line, i = divmod(k, 12)
            out.append(mvr_matrix(-11000 + 2000 * i, -7500 - 500 * line, 8000, rot_x_deg=-70.0))
        elif spec.startswith("Raylight"):
            out.append(mvr_matrix(-11000 + 2000 * k, 3500, 1800, rot_x_deg=180.0))
        elif spec.startswith("Pyxis"):
            line, i = divmod(k, 12)
            out.append(mvr_matrix(-11000 + 2000 * i, 1000 + 2000 * line, 9000))
        else:
            out.append(mvr_matrix(-4000 + 4000 * k, -8500, 200, rot_x_deg=-90.0))
    return out


def festival_mvr():
    """festival.mvr and its known answers (see FESTIVAL_TYPES)."""
    lights = uid("class/Lighting")
    scenery = uid("class/Scenery")
    groups, answers = [], {"types": {}}
    universe, address, fid = 1, 1, 10000
    universes = set()
    fixtures_total, cells_total = 0, 0
    rows = FESTIVAL_TYPES + [(FESTIVAL_MISSING[0], FESTIVAL_MISSING[0]) + FESTIVAL_MISSING[1:]]
    for file, spec, mode_name, count, cells, footprint in rows:
        kids = []
        name = file.split("@")[1].split("@")[0].removesuffix(".gdtf").replace("_", " ")
        for k, matrix in enumerate(festival_positions(file, count)):
            if address + footprint - 1 > 512:
                universe, address = universe + 1, 1
            fid += 1
            if file != FESTIVAL_MISSING[0]:
                universes.add(universe)  # a placeholder is not patched (no GDTF: no footprint)
            kids.append(fixture_xml(f"{name} {k + 1}", spec, mode_name, fid, k + 1, matrix, [(0, absolute(universe, address))], lights))
            address += footprint
        # Each type starts on a fresh universe, as a festival patch does.
        universe, address = universe + 1, 1
        groups.append(el("GroupObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", lights), el("ChildList", kids)], name=name, uuid=uid(f"festival/group/{file}")))
        fixtures_total += count
        if file != FESTIVAL_MISSING[0]:
            cells_total += count * cells
        answers["types"][file] = {"spec": spec, "mode": mode_name, "fixtures": count, "cells_per_fixture": cells, "footprint": footprint}
    venue, triangles = festival_venue()
    objects = [
        el("SceneObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", scenery), el("Geometries", [el("Geometry3D", fileName="festival_ground.glb")])], name="Ground", uuid=uid("festival/ground")),
        el("SceneObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", scenery), el("Geometries", [el("Geometry3D", fileName="festival_stage.gltf")])], name="Stage and roof", uuid=uid("festival/stage")),
    ]
    layers = [
        el("Layer", [el("ChildList", objects)], name="Venue", uuid=uid("festival/layer/venue")),
        el("Layer", [el("ChildList", groups)], name="Rig", uuid=uid("festival/layer/rig")),
    ]
    aux = [el("Class", name="Lighting", uuid=lights), el("Class", name="Scenery", uuid=scenery)]
    entries = {"GeneralSceneDescription.xml": festival_pretty(gsd(layers, aux)), **venue}
    for file, builder in FESTIVAL_BUILDERS.items():
        text, media = builder()
        entries[file] = zip_bytes({"description.xml": festival_pretty(text), **media})
    answers.update(
        {
            "fixtures": fixtures_total,
            "emitters": cells_total,
            "placeholders": FESTIVAL_MISSING[2],
            "lights": cells_total + FESTIVAL_MISSING[2],
            "universes": sorted(universes),
            "triangles": triangles,
            "triangles_total": sum(triangles.values()),
        }
    )
    return zip_bytes(entries), answers


def festival_outputs():
    import json

    data, answers = festival_mvr()
    answers["mvr_bytes"] = len(data)
    text = json.dumps(answers, indent=2, sort_keys=True) + "\n"
    return {FESTIVAL_MVR: data, FESTIVAL_JSON: text.encode()}, answers


# --- LED colour without emitters (issue 36 item 1) -----------------------------
# Real LED fixtures' GDTF files (pixel bars, panels) often define no <Emitter>:
# their ColorAdd_* channels link none, and the colour is only in the attribute
# definitions' Color (CIE xyY), or nowhere. Footlight@PixelBar16.gdtf gives every
# ColorAdd attribute a Color (in the sRGB gamut, so the test's own xyY -> linear
# sRGB needs no gamut fit); Footlight@LedRyWw.gdtf gives R/G/B theirs and none to
# RY and WW (Footlight falls back to GDTF Annex B's nominal colours, estimated).
# led-bars.mvr hangs two bars and one can 4 m over a grey floor (known answers:
# crates/footlight-mvr/tests/cases/colour_without_emitters.rs, tests/led_white.rs).
LED_COLOURS = {
    "ColorAdd_R": "0.6200,0.3350,20",
    "ColorAdd_G": "0.3100,0.5850,70",
    "ColorAdd_B": "0.1580,0.0750,8",
    "ColorAdd_W": "0.3220,0.3318,100",
}
LED_EXTRA = {"ColorAdd_RY": ("Color.RGB", "ColorComponent", "Amber"), "ColorAdd_WW": ("Color.RGB", "ColorComponent", "WW")}
PIXELBAR_CELLS = 16


def led_attribute_definitions(names, colours):
    """attribute_definitions(names) with a Color on the attributes in `colours` (ColorRGB group)."""
    groups = [el("FeatureGroup", [el("Feature", Name=f) for f in fs], Name=g, Pretty=g) for g, fs in FEATURES.items()]
    atts = []
    for n in names:
        feature, unit, pretty = ATTRIBUTES.get(n) or LED_EXTRA[n]
        group = "ColorRGB" if n.startswith("ColorAdd_") else None
        atts.append(el("Attribute", Name=n, Pretty=pretty, ActivationGroup=group, Feature=feature, PhysicalUnit=unit, Color=colours.get(n)))
    return el(
        "AttributeDefinitions",
        [
            el("ActivationGroups", [el("ActivationGroup", Name="PanTilt"), el("ActivationGroup", Name="ColorRGB")]),
            el("FeatureGroups", groups),
            el("Attributes", atts),
        ],
    )


def led_without_emitters(name, names, colours, physical, models, geometries, modes, description):
    """A fixture type (as fixture_type) whose AttributeDefinitions are led_attribute_definitions(names, colours)."""
    known = [n for n in names if n in ATTRIBUTES]
    text = fixture_type(name, name, known, [], physical, models, geometries, modes, description)
    plain = attribute_definitions(known)
    assert text.count(plain) == 1
    return text.replace(plain, led_attribute_definitions(names, colours), 1)


def no_emitters_physical():
    return [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]


def pixel_bar16():
    """16-cell RGBW pixel bar, 1 m, no emitters: mode 65ch (master dimmer, then R G B W per cell)."""
    rgbw = ["ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_W"]
    models = [model("Body", 1.0, 0.06, 0.08, "Cube"), model("Pixel", 0.06, 0.04, 0.01, "Cube")]
    pixel = beam("Pixel", "Pixel", m4(), LampType="LED", PowerConsumption="10", LuminousFlux="400", ColorTemperature="6000", BeamAngle="20", FieldAngle="30", BeamRadius="0.02", BeamType="Wash")
    x0 = -0.5 + 0.5 / PIXELBAR_CELLS
    cells = [
        el("GeometryReference", [el("Break", DMXOffset=str(2 + 4 * k), DMXBreak="1")], Name=f"Pixel{k + 1}", Geometry="Pixel", Model="Pixel", Position=m4(x0 + k / PIXELBAR_CELLS, 0, -0.04))
        for k in range(PIXELBAR_CELLS)
    ]
    tree = el("Geometry", cells, Name="Bar", Model="Body", Position=m4())
    chans = [simple("Bar", [1], "Dimmer")] + [simple("Pixel", [1 + k], a) for k, a in enumerate(rgbw)]
    text = led_without_emitters(
        "PixelBar16", ["Dimmer"] + rgbw, LED_COLOURS, no_emitters_physical(), models, [tree, pixel],
        [mode("65ch", "Bar", chans)], "16-cell RGBW pixel bar without emitters; colours in the attribute definitions (test data, estimated values)",
    )
    return text, {}


def led_ry_ww():
    """RGB + amber (RY) + warm white (WW) LED can, no emitters; RY and WW have no Color: mode 6ch."""
    names = ["Dimmer", "ColorAdd_R", "ColorAdd_G", "ColorAdd_B", "ColorAdd_RY", "ColorAdd_WW"]
    colours = {k: v for k, v in LED_COLOURS.items() if k != "ColorAdd_W"}
    physical, models, tree = led_can(el("Emitters"), PowerConsumption="60", LuminousFlux="1500", BeamAngle="25", FieldAngle="40")
    chans = [simple("Front", [1 + k], a) for k, a in enumerate(names)]
    text = led_without_emitters(
        "LedRyWw", names, colours, physical, models, [tree], [mode("6ch", "Can", chans)],
        "RGB + amber + warm white LED can without emitters; RY and WW without a Color (test data, estimated values)",
    )
    return text, {}


LED_TYPES = {"Footlight@PixelBar16.gdtf": pixel_bar16, "Footlight@LedRyWw.gdtf": led_ry_ww}


def led_bars_mvr():
    """led-bars.mvr: two PixelBar16 (65ch at 1.1 and 1.101) 4 m up, 2 m apart along stage x, beams
    down, and a LedRyWw (6ch at 1.201) 4 m up at stage z = -2 m, over a 12 m x 8 m grey (0.5) floor."""
    lights, scenery = uid("class/Lighting"), uid("class/Scenery")
    fixtures = [
        fixture_xml("Bar 1", "Footlight@PixelBar16.gdtf", "65ch", 901, 1, mvr_matrix(-1000, 0, 4000), [(0, 1)], lights),
        fixture_xml("Bar 2", "Footlight@PixelBar16.gdtf", "65ch", 902, 2, mvr_matrix(1000, 0, 4000), [(0, 101)], lights),
        fixture_xml("Can RY WW", "Footlight@LedRyWw.gdtf", "6ch", 903, 1, mvr_matrix(0, 2000, 4000), [(0, 201)], lights),
    ]
    floor = el("SceneObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", scenery), el("Geometries", [el("Geometry3D", fileName="floor.glb")])], name="Floor", uuid=uid("led-bars/floor"))
    layers = [el("Layer", [el("ChildList", [floor] + fixtures)], name="LED rig", uuid=uid("layer/led-bars"))]
    aux = [el("Class", name="Lighting", uuid=lights), el("Class", name="Scenery", uuid=scenery)]
    floor_v = [(-6.0, 0.0, -4.0), (6.0, 0.0, -4.0), (6.0, 0.0, 4.0), (-6.0, 0.0, 4.0)]
    entries = {"GeneralSceneDescription.xml": gsd(layers, aux), "floor.glb": glb_bytes(floor_v, [(0, 3, 2), (0, 2, 1)], (0.5, 0.5, 0.5), "floor")}
    for spec, make in LED_TYPES.items():
        text, media = make()
        entries[spec] = zip_bytes({"description.xml": text, **media})
    return zip_bytes(entries)


# --- Attributes real GDTFs use (issue 36 items 2 and 5) ------------------------------------
#
# Three types shaped like the manufacturers' files of issue 36 (makers' names left out,
# values invented, estimated). Known answers: crates/footlight-mvr/tests/cases/attributes.rs
# (against pygdtf and independent colour computations) and tests/cli.rs.
#   Footlight@ColourBar.gdtf  a 4-cell RGBW LED bar with no dimmer (shaped like an Astera
#       AX2 PixelBar): modes RGBW (16ch), HSB (16ch: 16-bit hue, saturation, brightness per
#       cell), CIE (20ch: 16-bit x and y, brightness per cell), Mixed (23ch: ColorMixMode
#       selecting RGBW or HSB on every cell's four channels by mode master, LEDZoneMode,
#       ColorMacro1 on a wheel of slot colours, Color2 on a wheel of xyY gels, 16-bit CTC,
#       Green/Magenta) and CCT (4ch: dimmer, 16-bit CTC, Green/Magenta).
#   Footlight@Cluster4.gdtf  a 4-cell RGBW LED blinder (shaped like a ROXX Cluster B4-FC):
#       a master dimmer (default 0) on the frame and a dimmer in every cell (GeometryReference),
#       DimmerCurve (Linear, Square, S-Curve, Log), DimmerMode (speed names only), a Shutter1
#       whose strobe range a StrobeMode channel selects (mode master: 0-127 strobe, 128-255
#       open), StrobeDuration and Tint: mode Full (27ch).
#   Footlight@ViperSpot.gdtf  a discharge moving spot (shaped like a MAC Viper): Gobo1 with
#       index and rotating slot ranges selecting Gobo1Pos (index) or Gobo1PosRotate
#       (rotation) on one 16-bit channel (default 32768) by mode master, Gobo2 (static
#       gobos), AnimationWheel1 with AnimationWheel1Pos/PosRotate, Color1 and Color2 wheels,
#       CTO as a 0..1 amount (no kelvin), Prism1 with Prism1PosRotate, Frost1: mode Standard (26ch).
# colour.mvr hangs the bar in every mode, the cluster and the spot (COLOUR_RIG).

ATTRS_36 = {
    "HSB_Hue": ("Color.Color", "Angle", "H"),
    "HSB_Saturation": ("Color.Color", "Percent", "S"),
    "HSB_Brightness": ("Color.Color", "Percent", "B"),
    "CIE_X": ("Color.CIE", "None", "X"),
    "CIE_Y": ("Color.CIE", "None", "Y"),
    "CIE_Brightness": ("Color.CIE", "Percent", "Bright"),
    "ColorMixMode": ("Control.Control", "None", "Mix Mode"),
    "LEDZoneMode": ("Control.Control", "None", "Zone Mode"),
    "ColorMacro1": ("Color.Color", "None", "Macro"),
    "Color2": ("Color.Color", "None", "C2"),
    "CTC": ("Color.Color", "Temperature", "CTC"),
    "Green/Magenta": ("Color.Color", "None", "G/M"),
    "Tint": ("Color.Color", "None", "Tint"),
    "DimmerCurve": ("Control.Control", "None", "Dim Curve"),
    "DimmerMode": ("Control.Control", "None", "Dim Mode"),
    "StrobeMode": ("Control.Control", "None", "Strobe Mode"),
    "StrobeDuration": ("Beam.Beam", "Time", "Strobe Duration"),
    "Gobo2": ("Gobo.Gobo", "None", "G2"),
    "AnimationWheel1": ("Gobo.Gobo", "None", "Anim"),
    "AnimationWheel1Pos": ("Gobo.Gobo", "Angle", "Anim <>"),
    "AnimationWheel1PosRotate": ("Gobo.Gobo", "AngularSpeed", "Anim Rotate"),
}


def own_attributes(make):
    """`make` run with ATTRS_36's definitions in ATTRIBUTES (the festival types define
    some of the same names their own way), so these files do not depend on which
    section of this script defines a name first."""

    def run():
        saved = dict(ATTRIBUTES)
        ATTRIBUTES.update(ATTRS_36)
        try:
            return make()
        finally:
            ATTRIBUTES.clear()
            ATTRIBUTES.update(saved)

    return run

COLOUR_BAR_CELLS = 4
# ColorMacro1's wheel: slot colours (xyY) a macro mixes to; slot 1 is "Off" (no macro).
MACRO_SLOTS = [("Off", "0.3127,0.3290,100"), ("Red", "0.6400,0.3300,100"), ("Amber", "0.5700,0.4200,100"), ("Lavender", "0.2500,0.2000,100")]
# Color2's wheel: gels as xyY (Y = luminous transmittance, percent).
GEL_SLOTS = [("Open", "0.3127,0.3290,100"), ("Blue gel", "0.2000,0.2000,30"), ("Amber gel", "0.5000,0.4200,60")]


def colour_bar():
    rgbw = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue"), ("ColorAdd_W", "White")]
    used = ["Dimmer"] + [a for a, _ in rgbw] + [
        "HSB_Hue", "HSB_Saturation", "HSB_Brightness", "CIE_X", "CIE_Y", "CIE_Brightness", "ColorMixMode", "LEDZoneMode",
        "ColorMacro1", "Color2", "CTC", "Green/Magenta",
    ]
    physical = [emitters_xml(spectra=False), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Body", 0.5, 0.05, 0.06, "Cube"), model("Pixel", 0.1, 0.04, 0.01, "Cube")]
    pixel = beam("Pixel", "Pixel", m4(), LampType="LED", PowerConsumption="12", LuminousFlux="500", ColorTemperature="6500", BeamAngle="25", FieldAngle="40", BeamRadius="0.02", BeamType="Wash")
    wheels = [
        el("Wheel", [el("Slot", Name=n, Color=c) for n, c in MACRO_SLOTS], Name="ColorMacro1"),
        el("Wheel", [el("Slot", Name=n, Color=c) for n, c in GEL_SLOTS], Name="Color2"),
    ]

    def bar(name, first, stride):
        refs = [
            el("GeometryReference", [el("Break", DMXOffset=str(first + stride * k), DMXBreak="1")], Name=f"{name}Cell{k + 1}", Geometry="Pixel", Model="Pixel", Position=m4(-0.1875 + 0.125 * k, 0, -0.03))
            for k in range(COLOUR_BAR_CELLS)
        ]
        return el("Geometry", refs, Name=name, Model="Body", Position=m4())

    rgbw_mode = [simple("Pixel", [1 + k], a, default=0, extra={"Emitter": e}) for k, (a, e) in enumerate(rgbw)]
    hsb_mode = [
        simple("Pixel", [1, 2], "HSB_Hue", 0, 360),
        simple("Pixel", [3], "HSB_Saturation", 0, 100, default=255),
        simple("Pixel", [4], "HSB_Brightness", 0, 100, default=255),
    ]
    cie_mode = [
        simple("Pixel", [1, 2], "CIE_X", 0, 1, default=20493),
        simple("Pixel", [3, 4], "CIE_Y", 0, 1, default=21561),
        simple("Pixel", [5], "CIE_Brightness", 0, 100, default=255),
    ]
    rgb_on = {"ModeMaster": "MixBar_ColorMixMode", "ModeFrom": "0/1", "ModeTo": "127/1"}
    hsb_on = {"ModeMaster": "MixBar_ColorMixMode", "ModeFrom": "128/1", "ModeTo": "255/1"}
    hsb_attrs = ["HSB_Hue", "HSB_Saturation", "HSB_Brightness"]
    hsb_ranges = [(0, 360), (0, 100), (0, 100)]
    mixed_cells = []
    for k, (a, e) in enumerate(rgbw):
        fns = [(a, 0, 0, 1, {"Emitter": e, **rgb_on}, [])]
        if k < 3:
            fns.append((hsb_attrs[k], 0, hsb_ranges[k][0], hsb_ranges[k][1], hsb_on, []))
        mixed_cells.append(Chan("Pixel", [1 + k], fns))
    macro_sets = [("Off", 0, None)] + [(n, 32 + 32 * k, k + 2) for k, (n, _) in enumerate(MACRO_SLOTS[1:])]
    gel_sets = [(n, 40 * k, k + 1) for k, (n, _) in enumerate(GEL_SLOTS)]
    mixed = [
        Chan("MixBar", [1], [("ColorMixMode", 0, 0, 1, {}, [("RGBW", 0, None), ("HSB", 128, None)])]),
        Chan("MixBar", [2], [("LEDZoneMode", 0, 0, 1, {}, [("All", 0, None), ("Zones", 128, None)])]),
        Chan("MixBar", [3], [("ColorMacro1", 0, 0, 0, {"Wheel": "ColorMacro1"}, macro_sets)]),
        Chan("MixBar", [4], [("Color2", 0, 0, 0, {"Wheel": "Color2"}, gel_sets)]),
        simple("MixBar", [5, 6], "CTC", 2700, 8000, default=65535),
        simple("MixBar", [7], "Green/Magenta", -1, 1, default=128),
    ] + mixed_cells
    cct = [
        simple("CctBar", [1], "Dimmer"),
        simple("CctBar", [2, 3], "CTC", 2700, 8000, default=65535),
        simple("CctBar", [4], "Green/Magenta", -1, 1, default=128),
    ]
    modes = [
        mode("RGBW", "RgbwBar", rgbw_mode),
        mode("HSB", "HsbBar", hsb_mode),
        mode("CIE", "CieBar", cie_mode),
        mode("Mixed", "MixBar", mixed),
        mode("CCT", "CctBar", cct),
    ]
    geometries = [bar("RgbwBar", 1, 4), bar("HsbBar", 1, 4), bar("CieBar", 1, 5), bar("MixBar", 8, 4), bar("CctBar", 5, 0), pixel]
    text = fixture_type(
        "ColourBar", "ColourBar", used, wheels, physical, models, geometries, modes,
        "4-cell RGBW LED bar without a dimmer: RGBW, HSB, CIE, mixed (mode master) and CCT modes (test data, estimated values)",
    )
    return text, {}


def cluster4():
    rgbw = [("ColorAdd_R", "Red"), ("ColorAdd_G", "Green"), ("ColorAdd_B", "Blue"), ("ColorAdd_W", "White")]
    used = ["Dimmer", "DimmerCurve", "DimmerMode", "Shutter1", "Shutter1Strobe", "StrobeMode", "StrobeDuration", "Tint"] + [a for a, _ in rgbw]
    physical = [emitters_xml(spectra=False), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Frame", 0.4, 0.4, 0.1, "Cube"), model("Lens", 0.15, 0.15, 0.02, "Cylinder")]
    lens = beam("Lens", "Lens", m4(), LampType="LED", PowerConsumption="60", LuminousFlux="2500", ColorTemperature="6500", BeamAngle="30", FieldAngle="45", BeamRadius="0.07", BeamType="Wash")
    refs = [
        el("GeometryReference", [el("Break", DMXOffset=str(8 + 5 * k), DMXBreak="1")], Name=f"Lens{k + 1}", Geometry="Lens", Model="Lens", Position=m4(-0.1 + 0.2 * (k % 2), -0.1 + 0.2 * (k // 2), -0.05))
        for k in range(4)
    ]
    frame = el("Geometry", refs, Name="Frame", Model="Frame", Position=m4())
    strobe_on = {"ModeMaster": "Frame_StrobeMode", "ModeFrom": "0/1", "ModeTo": "127/1"}
    strobe_off = {"ModeMaster": "Frame_StrobeMode", "ModeFrom": "128/1", "ModeTo": "255/1"}
    full = [
        simple("Frame", [1], "Dimmer", default=0),
        Chan("Frame", [2], [("DimmerCurve", 0, 0, 1, {}, [("Linear", 0, None), ("Square", 64, None), ("S-Curve", 128, None), ("Log", 192, None)])]),
        Chan("Frame", [3], [("DimmerMode", 0, 0, 1, {}, [("Fast", 0, None), ("Smooth", 128, None)])]),
        Chan(
            "Frame",
            [4],
            [
                ("Shutter1", 0, 1, 1, strobe_on, [("Open", 0, None)]),
                ("Shutter1Strobe", 16, 1, 20, strobe_on, []),
                ("Shutter1", 0, 1, 1, strobe_off, [("Open", 0, None)]),
            ],
        ),
        simple("Frame", [5], "StrobeDuration", 0.01, 0.2),
        Chan("Frame", [6], [("StrobeMode", 0, 0, 1, {}, [("Strobe", 0, None), ("Open", 128, None)])]),
        simple("Frame", [7], "Tint", -1, 1, default=128),
        simple("Lens", [1], "Dimmer", default=255),
    ] + [simple("Lens", [2 + k], a, default=255, extra={"Emitter": e}) for k, (a, e) in enumerate(rgbw)]
    text = fixture_type(
        "Cluster4", "Cluster4", used, [], physical, models, [frame, lens], [mode("Full", "Frame", full)],
        "4-cell RGBW LED blinder: master and cell dimmers, dimmer curve, strobe mode and duration, tint (test data, estimated values)",
    )
    return text, {}


def viper_spot():
    cw, _ = color_wheel()
    c2 = el("Wheel", [el("Slot", Name=n, Color=c) for n, c in GEL_SLOTS], Name="Color2")
    g1, _ = gobo_wheel()
    g2 = el("Wheel", [el("Slot", Name="Open", Color="0.3127,0.3290,100"), el("Slot", Name="Dots", Color="0.3127,0.3290,100", MediaFileName="viper_dots")], Name="Gobo2")
    anim = el("Wheel", [el("Slot", Name="Out", Color="0.3127,0.3290,100"), el("Slot", Name="Stripes", Color="0.3127,0.3290,100", MediaFileName="viper_stripes")], Name="AnimationWheel1")
    pw, _ = prism_wheel()
    used = [
        "Pan", "Tilt", "Dimmer", "Shutter1", "Shutter1Strobe", "Color1", "Color2", "Gobo1", "Gobo1WheelSpin", "Gobo1Pos", "Gobo1PosRotate",
        "Gobo2", "AnimationWheel1", "AnimationWheel1Pos", "AnimationWheel1PosRotate", "Prism1", "Prism1PosRotate", "Frost1", "Zoom", "Focus1",
        "CTO", "ColorSub_C", "ColorSub_M", "ColorSub_Y",
    ]
    physical = [el("Emitters"), el("Filters"), el("ColorSpace", Mode="sRGB"), el("DMXProfiles"), el("CRIs"), el("Connectors"), el("Properties")]
    models = [model("Base", 0.4, 0.3, 0.15, "Base"), model("Yoke", 0.35, 0.1, 0.35, "Yoke"), model("Head", 0.25, 0.25, 0.45, "Head"), model("Lens", 0.01, 0.14, 0.14, "Cylinder")]
    filters = [
        el("FilterColor", Name="Colours", Model="Lens", Position=m4(0, 0, -0.05)),
        el("FilterGobo", Name="Gobos", Model="Lens", Position=m4(0, 0, -0.06)),
    ]
    lens = beam("Lens", "Lens", m4(0, 0, -0.25), LampType="Discharge", PowerConsumption="1000", LuminousFlux="26000", ColorTemperature="6000", BeamAngle="12", FieldAngle="16", BeamRadius="0.07", BeamType="Spot", children=filters)
    tree = el("Geometry", [el("Axis", [el("Axis", [lens], Name="Head", Model="Head", Position=m4(0, 0, -0.35))], Name="Yoke", Model="Yoke", Position=m4(0, 0, -0.15))], Name="Base", Model="Base", Position=m4())
    index = {"ModeMaster": "Gobos_Gobo1", "ModeFrom": "0/1", "ModeTo": "63/1"}
    rotate = {"ModeMaster": "Gobos_Gobo1", "ModeFrom": "64/1", "ModeTo": "127/1"}
    slots = [("Open", 0, 1), ("Ring", 10, 2), ("Bars", 20, 3), ("Open rotating", 64, 1), ("Ring rotating", 74, 2), ("Bars rotating", 84, 3)]
    chans = [
        simple("Yoke", [1, 2], "Pan", -270, 270, default=32768),
        simple("Head", [3, 4], "Tilt", -135, 135, default=32768),
        simple("Lens", [5, 6], "Dimmer", 0, 1),
        Chan("Lens", [7], [("Shutter1", 0, 0, 0, {}, [("Closed", 0, None)]), ("Shutter1", 32, 1, 1, {}, [("Open", 32, None)]), ("Shutter1Strobe", 64, 1, 25, {}, [])], default=32),
        Chan("Colours", [8], [("Color1", 0, 0, 0, {"Wheel": "Color1"}, [("Open", 0, 1), ("Red", 10, 2), ("Green", 20, 3), ("Blue", 30, 4), ("Amber", 40, 5)])]),
        Chan("Colours", [9], [("Color2", 0, 0, 0, {"Wheel": "Color2"}, [(n, 40 * k, k + 1) for k, (n, _) in enumerate(GEL_SLOTS)])]),
        Chan("Gobos", [10], [("Gobo1", 0, 0, 0, {"Wheel": "Gobo1"}, slots), ("Gobo1WheelSpin", 128, -120, 120, {"Wheel": "Gobo1"}, [])]),
        Chan("Gobos", [11, 12], [("Gobo1Pos", 0, -180, 180, index, []), ("Gobo1PosRotate", 0, -200, 200, rotate, [])], default=32768),
        Chan("Gobos", [13], [("Gobo2", 0, 0, 0, {"Wheel": "Gobo2"}, [("Open", 0, 1), ("Dots", 128, 2)])]),
        Chan("Gobos", [14], [("AnimationWheel1", 0, 0, 0, {"Wheel": "AnimationWheel1"}, [("Out", 0, 1), ("Stripes", 128, 2)])]),
        Chan("Gobos", [15], [("AnimationWheel1Pos", 0, 0, 360), ("AnimationWheel1PosRotate", 128, -100, 100)]),
        Chan("Lens", [16], [("Prism1", 0, 0, 0, {"Wheel": "Prism1"}, [("Out", 0, 1)]), ("Prism1", 128, 0, 0, {"Wheel": "Prism1"}, [("3-Facet", 128, 2)])]),
        simple("Lens", [17], "Prism1PosRotate", -180, 180, default=128),
        simple("Lens", [18], "Frost1", 0, 1),
        simple("Lens", [19], "Zoom", 10, 40),
        simple("Lens", [20], "Focus1", 0, 1),
        simple("Lens", [21], "CTO", 0, 1),
        simple("Lens", [22], "ColorSub_C", 0, 1),
        simple("Lens", [23], "ColorSub_M", 0, 1),
        simple("Lens", [24], "ColorSub_Y", 0, 1),
    ]
    dots = png_gray(GOBO_SIZE, GOBO_SIZE, lambda x, y: 255 if (x % 16 - 8) ** 2 + (y % 16 - 8) ** 2 < 25 else 0)
    stripes = png_gray(GOBO_SIZE, GOBO_SIZE, lambda x, y: 255 if (x + y) // 6 % 2 == 0 else 0)
    media = {
        "wheels/gobo_ring.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_ring),
        "wheels/gobo_bars.png": png_gray(GOBO_SIZE, GOBO_SIZE, gobo_bars),
        "wheels/viper_dots.png": dots,
        "wheels/viper_stripes.png": stripes,
    }
    text = fixture_type(
        "ViperSpot", "ViperSpot", used, [cw, c2, g1, g2, anim, pw], physical, models, [tree], [mode("Standard", "Base", chans)],
        "discharge moving spot: gobo index/rotation by mode master, second gobo, animation wheel, two colour wheels (test data, estimated values)",
    )
    return text, media


ATTRIBUTE_TYPES = {
    "Footlight@ColourBar.gdtf": own_attributes(colour_bar),
    "Footlight@Cluster4.gdtf": own_attributes(cluster4),
    "Footlight@ViperSpot.gdtf": own_attributes(viper_spot),
}

# colour.mvr: (name, spec, mode, id, universe 1 address), 4 m up over a grey floor, 1.5 m apart.
COLOUR_RIG = [
    ("Bar Mixed", "Footlight@ColourBar.gdtf", "Mixed", 3601, 1),
    ("Bar RGBW", "Footlight@ColourBar.gdtf", "RGBW", 3602, 31),
    ("Bar CCT", "Footlight@ColourBar.gdtf", "CCT", 3603, 51),
    ("Cluster", "Footlight@Cluster4.gdtf", "Full", 3604, 61),
    ("Viper", "Footlight@ViperSpot.gdtf", "Standard", 3605, 101),
    ("Bar HSB", "Footlight@ColourBar.gdtf", "HSB", 3606, 131),
    ("Bar CIE", "Footlight@ColourBar.gdtf", "CIE", 3607, 151),
]


def colour_mvr():
    lights, scenery = uid("class/Lighting"), uid("class/Scenery")
    fixtures = [
        fixture_xml(name, spec, m, fid, 1, mvr_matrix(-4500 + 1500 * k, 0, 4000), [(0, addr)], lights)
        for k, (name, spec, m, fid, addr) in enumerate(COLOUR_RIG)
    ]
    floor = el("SceneObject", [el("Matrix", mvr_matrix(0, 0, 0)), el("Classing", scenery), el("Geometries", [el("Geometry3D", fileName="floor.glb")])], name="Floor", uuid=uid("colour/floor"))
    layers = [el("Layer", [el("ChildList", [floor] + fixtures)], name="Colour rig", uuid=uid("layer/colour"))]
    aux = [el("Class", name="Lighting", uuid=lights), el("Class", name="Scenery", uuid=scenery)]
    floor_v = [(-7.0, 0.0, -4.0), (7.0, 0.0, -4.0), (7.0, 0.0, 4.0), (-7.0, 0.0, 4.0)]
    entries = {"GeneralSceneDescription.xml": gsd(layers, aux), "floor.glb": glb_bytes(floor_v, [(0, 3, 2), (0, 2, 1)], (0.5, 0.5, 0.5), "floor")}
    for spec, make in ATTRIBUTE_TYPES.items():
        text, media = make()
        entries[spec] = zip_bytes({"description.xml": text, **media})
    return zip_bytes(entries)


def outputs():
    files = {}
    for name in TYPES:
        files[GDTF_DIR / name] = gdtf_bytes(name)
    files[MVR_DIR / "features.mvr"] = features_mvr()
    files[MVR_DIR / "show150.mvr"] = show_mvr()
    files[MVR_DIR / "gate.mvr"] = gate_mvr()
    files[MVR_DIR / "venue.mvr"] = venue_mvr()
    files[MVR_DIR / "bodies.mvr"] = bodies_mvr()
    files[MVR_DIR / "cells.mvr"] = cells_mvr()
    for name, make in LED_TYPES.items():
        files[GDTF_DIR / name] = zip_bytes({"description.xml": make()[0]})
    files[MVR_DIR / "led-bars.mvr"] = led_bars_mvr()
    for name, make in ATTRIBUTE_TYPES.items():
        text, media = make()
        files[GDTF_DIR / name] = zip_bytes({"description.xml": text, **media})
    files[MVR_DIR / "colour.mvr"] = colour_mvr()
    files[ROOT / "tests" / "data" / "textures" / "checker.jpg"] = jpeg_gray_blocks(JPEG_BLOCKS)
    for name, data in bad_files().items():
        files[MVR_DIR / name] = data
    return files


def deep_files(depth):
    """Hostile files nested `depth` deep (issue 35), never written to tests/data:
    Footlight@Deep.gdtf (the Spot with a chain of `depth` <Geometry> in its beam),
    deep-gdtf.toml (a TOML patch naming it), deep-gdtf.mvr (an MVR hanging it) and
    deep-groups.mvr (a fixture inside `depth` nested GroupObjects). Footlight refuses
    each before parsing, naming the file and the limit; the Rust tests build their
    own (tests/cli.rs, crates/footlight-mvr/tests/cases/limits.rs)."""
    spot_xml, media = spot()
    chain = "".join(f'<Geometry Name="D{i}" Position="{m4()}">' for i in range(depth)) + "</Geometry>" * depth
    deep_xml = spot_xml.replace("<FilterShaper", chain + "<FilterShaper", 1)
    deep_gdtf = zip_bytes({"description.xml": deep_xml, **media})
    spec = "Footlight@Deep.gdtf"
    fixture = fixture_xml("Deep 1", spec, "Standard", 1, 1, mvr_matrix(0, 0, 5000), [(0, 1)])

    def show(child_list):
        layer = f'<Layer name="Rig" uuid="{uid("layer/deep")}"><ChildList>{child_list}</ChildList></Layer>'
        return zip_bytes({"GeneralSceneDescription.xml": gsd([layer], []), spec: deep_gdtf})

    groups = "".join(f'<GroupObject name="G{i}" uuid="{uid(f"group/deep/{i}")}"><ChildList>' for i in range(depth))
    groups += fixture + "</ChildList></GroupObject>" * depth
    toml = (
        "# A TOML patch naming a GDTF nested too deep (tools/gen_gdtf_mvr.py --deep).\n"
        f'[[fixture]]\nid = 1\nname = "Deep"\ntype = "{spec}"\nmode = "Standard"\n'
        "universe = 1\naddress = 1\nposition = [0.0, 5.0, 0.0]\n"
    )
    return {
        spec: deep_gdtf,
        "deep-gdtf.toml": toml.encode(),
        "deep-gdtf.mvr": show(fixture),
        "deep-groups.mvr": show(groups),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the files on disk instead of writing")
    ap.add_argument("--deep", metavar="DIR", type=Path, help="write only the hostile deep-nesting files (issue 35) into DIR")
    ap.add_argument("--depth", type=int, default=10_000, help="nesting depth of the --deep files (default 10000)")
    ap.add_argument("--festival", action="store_true", help="write (or with --check compare) only tests/data/mvr/festival.mvr and festival.json")
    args = ap.parse_args()
    if args.festival:
        files, answers = festival_outputs()
        for path, data in files.items():
            if args.check:
                if not path.is_file() or path.read_bytes() != data:
                    print(f"out of date (run tools/gen_gdtf_mvr.py --festival): {path.relative_to(ROOT)}", file=sys.stderr)
                    return 1
                continue
            path.write_bytes(data)
        print(
            f"festival.mvr: {answers['fixtures']} fixtures ({answers['placeholders']} of them named by a GDTF not in the archive), "
            f"{answers['emitters']} emitters (cells) + {answers['placeholders']} placeholders = {answers['lights']} lights, "
            f"{len(answers['universes'])} universes, "
            f"triangles {answers['triangles']} ({answers['triangles_total']} in all), {answers['mvr_bytes']} bytes"
        )
        return 0
    if args.deep:
        args.deep.mkdir(parents=True, exist_ok=True)
        for name, data in deep_files(args.depth).items():
            (args.deep / name).write_bytes(data)
        print(f"wrote {', '.join(sorted(deep_files(0)))} ({args.depth} deep) into {args.deep}")
        return 0
    files = outputs()
    stale = []
    for path, data in files.items():
        if args.check:
            if not path.is_file() or path.read_bytes() != data:
                stale.append(str(path.relative_to(ROOT)))
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    if stale:
        print("out of date (run tools/gen_gdtf_mvr.py):", *stale, sep="\n  ", file=sys.stderr)
        return 1
    if not args.check:
        print(f"wrote {len(files)} files under tests/data/gdtf and tests/data/mvr")
    return 0


if __name__ == "__main__":
    sys.exit(main())
