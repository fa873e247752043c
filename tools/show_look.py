#!/usr/bin/env python3
"""Record a lit, coloured, moving look for the show150 MVR example (issue 37).

`footlight run --patch tests/data/mvr/show150.mvr` starts black: an MVR file
holds a rig, not a look. This script plays a look on that rig as a desk would
and records it with Footlight's own recorder, so that the README demo

    footlight replay tests/replays/show150-look.pcapng --patch tests/data/mvr/show150.mvr --loop

starts lit. Regenerate the recording (from the repository root, after
`cargo build --release` and `python3 -m pip install pygdtf==1.4.5 pymvr==1.0.7`):

    python3 tools/show_look.py --force

`--plan` prints the patch as read and the look at t = 0 without recording;
`--only Spot,Wash` lights only those fixture types (to judge one group).

How it works
------------
1. The show is read with the independent Python readers pymvr (fixtures,
   GDTF spec and mode, addresses with breaks, matrices) and pygdtf (each
   mode's DMX channels with their offsets, attribute, channel functions,
   channel sets and physical ranges, the geometry tree); Footlight's own
   importer is not used. Every DMX value is computed from the GDTF: a level
   is placed in the DMX range of the channel function of that attribute, a
   shutter goes to the start of the channel set named "Open", a wheel to
   its "Open"/"Out" set, pan/tilt angles are turned into DMX through the
   function's physical range, and anything the look does not name keeps the
   function's Default.
2. `footlight record --patch SHOW --artnet 127.0.0.1:PORT --sacn off --out OUT`
   is started on a free loopback port; the script sends ArtDmx (raw UDP
   packets built here, Art-Net 4, ProtVer 14, Port-Address = patch universe
   - 1, sequence 1-255 per universe) from 127.0.0.1 to it and stops it with
   SIGINT.
3. Timing: a 30 Hz tick for SECONDS (20 s). The first and the last tick
   (t = 0 and t = SECONDS, the same look: the recording loops without a
   jump) send every universe. In between a universe is sent only when its
   slots change, or after 1 s without a packet (a keep-alive). Pan/tilt is
   recomputed at 10 Hz per universe, the three moving-head universes
   staggered (one of them on each tick, 30 packets/s); the pixel-bar chase
   steps 3 times a second. Each packet carries the slots up to the
   universe's last patched slot (rounded up to even), not always 512. This
   keeps the file near 395 KB; every universe at 30 Hz would be ~1.5 MB.

The look (t in seconds, period SECONDS; x is a fixture's stage x in metres,
-7 stage right ... +7 stage left; the bundled stage is used, camera in the
stalls)
---------------------------------------------------------------------------
* Spot (44 moving heads, 27 ch "Standard"): dimmer 15 %, shutter Open,
  colour and gobo wheels Open, prism Out, iris open, zoom 10 deg, focus
  middle, CTO off, blades out. Odd-numbered spots are open white and draw
  figure-eights on the floor just upstage of the heads (+-1.2 m across,
  z -2.4 ... -3.4 m); even-numbered spots are coloured by CMY along the
  rig, blue (stage right) through magenta to amber (stage left), and draw
  figure-eights on the cyclorama (+-1 m across, 1.8-3.2 m high). Each
  head's figure is phase-shifted by its x, so the cyc shows a slow
  travelling wave; one figure takes SECONDS. Pan/tilt (16 bit) are solved
  from the fixture's matrix and its GDTF tilt axis.
* Wash (40 LED washes, 7 ch "8ch"): dimmer full, shutter Open, zoom 30 deg,
  RGBW across the rig: teal at the centre to deep blue at the sides (W 0).
* Bar8 (24 pixel bars, 25 ch): master dimmer full; each of the 8 cells gets
  a fully saturated hue from a rainbow that repeats every 7 m along the rig
  and travels from stage right to stage left, two cycles per SECONDS, in
  steps.
* Blinder (20, 2 ch, two tungsten lamps each): both lamps at 12 % (a warm
  fill; at full the 40 lamps flatten every colour on the stage).
* Fresnel (20, 2 ch): dimmer 35 %, zoom 60 deg: warm light on the apron.
* Hazer (2): off (haze and fan 0).
Levels were set by eye on `footlight render --dmx` stills; at full the
spots alone blow the cyclorama out to white.
"""
import argparse
import colorsys
import io
import math
import os
import signal
import socket
import subprocess
import sys
import time
import zipfile

import pygdtf
import pymvr
from pygdtf.utils import get_dmx_channels

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RATE = 30.0  # ticks per second
MOVE_EVERY = 3  # pan/tilt: every 3rd tick per universe (10 Hz), staggered
CHASE_STEPS_PER_S = 3.0
KEEPALIVE_S = 1.0
LEVEL = {"Spot": 0.15, "Wash": 1.0, "Bar8": 1.0, "Blinder": 0.12, "Fresnel": 0.35}  # dimmer per type
ONLY = None  # --only: the fixture types lit (a check of one group's light)


# ---------------------------------------------------------------- the show


class Channel:
    """One DMX channel of a fixture: absolute slots (coarse first), attribute,
    the cell it sits on (a GeometryReference name, or None) and its functions."""

    def __init__(self, universe, slots, attribute, cell, functions):
        self.universe = universe
        self.slots = slots
        self.attribute = attribute
        self.cell = cell
        self.functions = functions

    def function(self, attribute=None):
        """The first channel function of `attribute` (default: the channel's)."""
        attribute = attribute or self.attribute
        for f in self.functions:
            if str(f.attribute) == attribute:
                return f
        return None

    def scaled(self, value):
        """A GDTF DmxValue at this channel's resolution (GDTF shifts by bytes)."""
        shift = 8 * (len(self.slots) - value.byte_count)
        return value.value << shift if shift >= 0 else value.value >> -shift

    def default(self):
        return self.scaled(self.functions[0].default)

    def fraction(self, x, attribute=None):
        """x in 0..1 across the DMX range of the function of `attribute`."""
        f = self.function(attribute)
        lo, hi = self.scaled(f.dmx_from), self.scaled(f.dmx_to)
        return round(lo + max(0.0, min(1.0, x)) * (hi - lo))

    def physical(self, v, attribute=None):
        """A physical value (degrees, ...) through the function's physical range."""
        f = self.function(attribute)
        pf, pt = f.physical_from.value, f.physical_to.value
        x = (v - pf) / (pt - pf)
        if not 0.0 <= x <= 1.0:
            raise ValueError(f"{self.attribute} {v} outside {pf}..{pt}")
        return self.fraction(x, attribute)

    def channel_set(self, *names):
        """Start of the first channel set with one of `names` (e.g. "Open")."""
        for f in self.functions:
            for s in f.channel_sets:
                if s.name in names:
                    return self.scaled(s.dmx_from)
        raise KeyError(f"{self.attribute}: no channel set named {names}")


class Fixture:
    def __init__(self, name, number, kind, mode, position, axes, channels, cells, pivot):
        self.name = name
        self.number = number  # UnitNumber (1..n within its type in show150)
        self.kind = kind  # the GDTF's FixtureType name: Spot, Wash, Bar8 ...
        self.mode = mode
        self.position = position  # MVR origin in stage metres (x, y up, z to the audience)
        self.axes = axes  # MVR u, v, w: the fixture's local x, y, z in MVR axes
        self.channels = channels
        self.cells = cells  # cell name -> local x (m) of its GeometryReference
        self.pivot = pivot  # the tilt axis' offset from the origin, GDTF local (m)

    def by_attribute(self, attribute):
        return [c for c in self.channels if c.attribute == attribute]


def mvr_to_stage(p):
    """MVR millimetres, Z up -> stage metres, Y up (Footlight's stage_matrix)."""
    return (p[0] / 1000.0, p[2] / 1000.0, -p[1] / 1000.0)


def stage_to_mvr(p):
    return (p[0], -p[2], p[1])


def geometry_offset(ft, root, name):
    """Translation of geometry `name` below `root` (sum of the positions on
    the way, rotations ignored: the test types only translate)."""

    def walk(g, acc):
        t = [acc[i] + g.position.matrix[i][3] for i in range(3)]
        if g.name == name:
            return t
        for c in getattr(g, "geometries", []) or []:
            found = walk(c, t)
            if found is not None:
                return found
        return None

    return walk(root, [0.0, 0.0, 0.0]) or [0.0, 0.0, 0.0]


def read_show(path):
    archive = zipfile.ZipFile(path)
    types = {}
    scene = pymvr.GeneralSceneDescription(path)
    fixtures = []

    def walk(child_list):
        for f in child_list.fixtures:
            fixtures.append(f)
            if f.child_list:
                walk(f.child_list)
        for g in child_list.group_objects:
            walk(g.child_list)

    for layer in scene.scene.layers:
        walk(layer.child_list)

    out = []
    for f in fixtures:
        if f.gdtf_spec not in types:
            types[f.gdtf_spec] = pygdtf.FixtureType(io.BytesIO(archive.read(f.gdtf_spec)))
        ft = types[f.gdtf_spec]
        mode = ft.dmx_modes.get_mode_by_name(f.gdtf_mode)
        root = ft.geometries.get_geometry_by_name(mode.geometry)
        addresses = sorted(f.addresses.addresses, key=lambda a: a.dmx_break)
        # Pixel cells: the GeometryReferences of the mode's root, with their x (m).
        cells = {
            g.name: g.position.matrix[0][3]
            for g in getattr(root, "geometries", []) or []
            if isinstance(g, pygdtf.GeometryReference)
        }
        channels = []
        tilt_geometry = None
        for index, brk in enumerate(get_dmx_channels(ft, f.gdtf_mode)):
            if not brk:
                continue
            if index >= len(addresses):
                raise SystemExit(f"{f.name}: DMX break {index + 1} has no address in the MVR")
            a = addresses[index]
            for c in brk:
                lc = c.logical_channels[0]
                attribute = str(lc.attribute)
                slots = [a.address + o - 1 for o in c.offset]
                if max(slots) > 512:
                    raise SystemExit(f"{f.name}: {attribute} past slot 512")
                cell = c.geometry if c.geometry in cells else None
                channels.append(Channel(a.universe, slots, attribute, cell, list(lc.channel_functions)))
                if attribute == "Tilt":
                    tilt_geometry = c.geometry
        m = f.matrix.matrix  # rows u, v, w, o (MVR, mm)
        pivot = geometry_offset(ft, root, tilt_geometry) if tilt_geometry else [0.0, 0.0, 0.0]
        out.append(
            Fixture(
                f.name,
                int(f.unit_number),
                ft.name,
                f.gdtf_mode,
                mvr_to_stage(m[3][:3]),
                [m[0][:3], m[1][:3], m[2][:3]],
                channels,
                cells,
                pivot,
            )
        )
    return out


# ---------------------------------------------------------------- the look


def cmy(rgb):
    return [1.0 - v for v in rgb]


def hue(h, s=1.0):
    return colorsys.hsv_to_rgb((h / 360.0) % 1.0, s, 1.0)


def cyc_z(x):
    """The bundled stage's cyclorama: a vertical cylinder of plan radius 15 m
    through z = -8 on the centre line (scenes/README.md)."""
    return 7.0 - math.sqrt(225.0 - x * x)


def spot_target(f, t, period):
    """Where spot `f` points at time t (stage metres)."""
    x0 = max(-5.2, min(5.2, 0.8 * f.position[0]))
    phase = math.pi * f.position[0] / 7.0
    w = 2.0 * math.pi * t / period
    if f.number % 2:  # odd: white, a figure-eight on the floor just upstage of the head
        return (x0 + 1.2 * math.sin(w + phase), 0.0, -2.9 + 0.5 * math.sin(2.0 * (w + phase)))
    x = x0 + 1.0 * math.sin(w + phase)
    return (x, 2.5 + 0.7 * math.sin(2.0 * (w + phase)), cyc_z(x))


def pan_tilt(f, target):
    """Pan and tilt (degrees) that point the head at `target`. In GDTF axes
    a hanging head's beam at pan p, tilt t is (-sin t sin p, sin t cos p,
    -cos t) (tilt about X, then pan about the yoke's Z)."""
    axes = [[a / math.sqrt(sum(b * b for b in ax)) for a in ax] for ax in f.axes]  # unit u, v, w
    # The tilt axis: GDTF local metres -> MVR axes -> stage axes.
    piv = [sum(f.pivot[k] * axes[k][i] for k in range(3)) for i in range(3)]
    pivot = [p + q for p, q in zip(f.position, (piv[0], piv[2], -piv[1]))]
    d = stage_to_mvr([target[i] - pivot[i] for i in range(3)])
    local = [sum(d[i] * ax[i] for i in range(3)) for ax in axes]
    length = math.sqrt(sum(c * c for c in local))
    lx, ly, lz = (c / length for c in local)
    tilt = math.degrees(math.acos(max(-1.0, min(1.0, -lz))))
    pan = math.degrees(math.atan2(-lx, ly))
    return pan, tilt


def spot_colour(f):
    """Even spots: a CMY colour along the rig; odd spots: open white."""
    if f.number % 2:
        return [0.0, 0.0, 0.0]
    s = (f.position[0] + 7.0) / 14.0  # 0 stage right .. 1 stage left
    return cmy(hue(220.0 + 170.0 * s, 1.0))  # blue, lavender, pink, amber


def wash_colour(f):
    s = min(1.0, abs(f.position[0]) / 7.0)  # 0 centre .. 1 sides
    return list(hue(185.0 + 50.0 * s, 1.0)) + [0.0]  # teal .. deep blue; W 0


def cell_colour(x, t, period):
    """The bars' chase: a rainbow that repeats every 7 m, two cycles per period."""
    step = math.floor(t * CHASE_STEPS_PER_S + 1e-9) / CHASE_STEPS_PER_S
    return hue(360.0 * (x / 7.0 - 2.0 * step / period))


def level(c, value):
    """A channel value as its bytes, coarse first."""
    n = len(c.slots)
    return [(int(value) >> (8 * (n - 1 - k))) & 0xFF for k in range(n)]


def fixture_values(f, t, period, move=True):
    """{(universe, slot): value} for fixture f at time t (move: also pan/tilt)."""
    out = {}

    def put(c, v):
        for slot, b in zip(c.slots, level(c, v)):
            out[(c.universe, slot)] = b

    for c in f.channels:
        put(c, c.default())  # everything the look does not name keeps its Default
    for c in f.channels:
        a = c.attribute
        if a == "Dimmer":
            put(c, c.fraction(LEVEL.get(f.kind, 1.0) if ONLY is None or f.kind in ONLY else 0.0))
        elif a.startswith("Shutter"):
            put(c, c.channel_set("Open"))
        elif a in ("Color1", "Gobo1"):
            put(c, c.channel_set("Open"))
        elif a == "Prism1":
            put(c, c.channel_set("Out", "Open"))
        elif a == "Iris":
            put(c, c.physical(1.0))  # fully open
        elif a == "Focus1":
            put(c, c.fraction(0.5))
        elif a == "CTO":
            put(c, c.fraction(0.0))
        elif a == "Zoom":
            f_ = c.function()
            lo, hi = f_.physical_from.value, f_.physical_to.value
            want = {"Spot": 10.0, "Wash": 30.0, "Fresnel": 60.0}.get(f.kind, 0.5 * (lo + hi))
            put(c, c.physical(max(min(lo, hi), min(max(lo, hi), want))))
        elif a.startswith("ColorSub_"):
            put(c, c.fraction(spot_colour(f)["CMY".index(a[-1])]))
        elif a.startswith("ColorAdd_"):
            if c.cell is not None:
                rgb = cell_colour(f.position[0] + f.cells[c.cell], t, period)
                put(c, c.fraction(rgb["RGB".index(a[-1])]))
            else:
                put(c, c.fraction(wash_colour(f)["RGBW".index(a[-1])]))
        elif a in ("Haze", "Fan"):
            put(c, 0)
    pan = f.by_attribute("Pan")
    tilt = f.by_attribute("Tilt")
    if pan and tilt:
        if move:
            p, tl = pan_tilt(f, spot_target(f, t, period))
            put(pan[0], pan[0].physical(p))
            put(tilt[0], tilt[0].physical(tl))
        else:
            for c in pan + tilt:
                for slot in c.slots:
                    out.pop((c.universe, slot), None)
    return out


class Look:
    def __init__(self, fixtures, period):
        self.fixtures = fixtures
        self.period = period
        self.universes = sorted({c.universe for f in fixtures for c in f.channels})
        # Slots sent per universe: up to the last patched slot, even (Art-Net).
        self.length = {}
        for u in self.universes:
            top = max(s for f in fixtures for c in f.channels if c.universe == u for s in c.slots)
            self.length[u] = top + (top % 2)
        self.moving = sorted({c.universe for f in fixtures for c in f.channels if c.attribute in ("Pan", "Tilt")})
        self.pan_tilt = {}  # (universe, slot) -> last value, held between pan/tilt updates

    def frames(self, t, move_universes):
        """Slots of every universe at t; pan/tilt recomputed only for the
        fixtures on `move_universes`, else held."""
        frames = {u: bytearray(self.length[u]) for u in self.universes}
        for f in self.fixtures:
            move = any(c.universe in move_universes for c in f.channels if c.attribute in ("Pan", "Tilt"))
            for (u, slot), v in fixture_values(f, t, self.period, move).items():
                frames[u][slot - 1] = v
            if move:
                for c in f.channels:
                    if c.attribute in ("Pan", "Tilt"):
                        for slot in c.slots:
                            self.pan_tilt[(c.universe, slot)] = frames[c.universe][slot - 1]
        for (u, slot), v in self.pan_tilt.items():
            frames[u][slot - 1] = v
        return frames


# ---------------------------------------------------------------- Art-Net


def art_dmx(port_address, sequence, slots):
    """ArtDmx (OpCode 0x5000), ProtVer 14, Physical 0."""
    assert 2 <= len(slots) <= 512 and len(slots) % 2 == 0
    return (
        b"Art-Net\x00"
        + (0x5000).to_bytes(2, "little")
        + (14).to_bytes(2, "big")
        + bytes([sequence, 0, port_address & 0xFF, (port_address >> 8) & 0x7F])
        + len(slots).to_bytes(2, "big")
        + bytes(slots)
    )


def free_udp_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def port_bound(port):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.bind(("127.0.0.1", port))
        return False
    except OSError:
        return True
    finally:
        s.close()


def play(look, target, seconds, log):
    """Sends the look to `target` for `seconds` at RATE; returns packets sent."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sequence = {u: 0 for u in look.universes}
    last_sent = {}
    last_slots = {}
    ticks = int(round(seconds * RATE))
    sent = 0
    start = time.monotonic()
    for i in range(ticks + 1):
        t = i / RATE
        first_or_last = i in (0, ticks)
        if first_or_last:
            move = set(look.moving)
        else:
            move = {u for k, u in enumerate(look.moving) if i % MOVE_EVERY == k % MOVE_EVERY}
        frames = look.frames(t, move)
        due = start + t
        wait = due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        for u in look.universes:
            slots = bytes(frames[u])
            changed = last_slots.get(u) != slots
            stale = t - last_sent.get(u, -1e9) >= KEEPALIVE_S - 1e-9
            if first_or_last or changed or stale:
                sequence[u] = sequence[u] % 255 + 1
                sock.sendto(art_dmx(u - 1, sequence[u], slots), target)
                last_sent[u] = t
                last_slots[u] = slots
                sent += 1
        if i % int(RATE * 5) == 0:
            log(f"t = {t:4.1f} s, {sent} packets sent")
    sock.close()
    return sent


# ---------------------------------------------------------------- main


def print_plan(fixtures, look):
    kinds = {}
    for f in fixtures:
        kinds.setdefault((f.kind, f.mode), []).append(f)
    for (kind, mode), fs in kinds.items():
        first, last = fs[0], fs[-1]
        attrs = ", ".join(sorted({c.attribute for c in first.channels}))
        print(f"{kind} ({mode}): {len(fs)} fixtures, {len(first.channels)} channels ({attrs})")
        for f in (first, last):
            c = min(f.channels, key=lambda c: (c.universe, c.slots[0]))
            print(f"  {f.name}: {c.universe}.{c.slots[0]} at {tuple(round(v, 2) for v in f.position)}")
    frames = look.frames(0.0, set(look.moving))
    for u in look.universes:
        lit = sum(1 for v in frames[u] if v)
        print(f"universe {u} (Port-Address {u - 1}): {look.length[u]} slots sent, {lit} non-zero")
    for f in fixtures:
        if f.by_attribute("Pan") and f.number in (1, 2, 22, 23, 43, 44):
            p, t = pan_tilt(f, spot_target(f, 0.0, look.period))
            print(f"  {f.name} at t=0: pan {p:.1f} deg, tilt {t:.1f} deg")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--show", default="tests/data/mvr/show150.mvr")
    ap.add_argument("--out", default="tests/replays/show150-look.pcapng")
    ap.add_argument("--footlight", default="target/release/footlight")
    ap.add_argument("--seconds", type=float, default=20.0, help="length of the look (one full figure)")
    ap.add_argument("--port", type=int, default=0, help="loopback UDP port for the recorder (0: a free one)")
    ap.add_argument("--force", action="store_true", help="replace an existing --out")
    ap.add_argument("--only", help="light only these fixture types (comma-separated), for checking one group")
    ap.add_argument("--plan", action="store_true", help="print the patch and the look at t = 0; record nothing")
    args = ap.parse_args()
    os.chdir(ROOT)
    global ONLY
    ONLY = set(args.only.split(",")) if args.only else None
    if not 1.0 <= args.seconds <= 120.0:
        raise SystemExit("--seconds: 1-120")
    fixtures = read_show(args.show)
    look = Look(fixtures, args.seconds)
    if args.plan:
        print_plan(fixtures, look)
        return
    if os.path.exists(args.out) and not args.force:
        raise SystemExit(f"{args.out} exists; add --force to replace it")
    if not os.path.exists(args.footlight):
        raise SystemExit(f"{args.footlight} missing: run `cargo build --release` first")
    port = args.port or free_udp_port()
    log = lambda m: print(f"show_look: {m}", file=sys.stderr, flush=True)  # noqa: E731
    cmd = [args.footlight, "record", "--patch", args.show, "--artnet", f"127.0.0.1:{port}", "--sacn", "off"]
    cmd += ["--out", args.out, "--force"]
    log(" ".join(cmd))
    recorder = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        line = recorder.stdout.readline()  # "recording DMX to ... until Ctrl-C"
        if "recording" not in line:
            raise SystemExit(f"recorder did not start: {line!r}")
        deadline = time.monotonic() + 30.0
        while not port_bound(port):
            if recorder.poll() is not None or time.monotonic() > deadline:
                raise SystemExit("recorder did not bind its Art-Net port")
            time.sleep(0.05)
        time.sleep(0.2)
        sent = play(look, ("127.0.0.1", port), args.seconds, log)
        time.sleep(0.5)
        recorder.send_signal(signal.SIGINT)
        out, _ = recorder.communicate(timeout=30)
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
    log(out.strip())
    if recorder.returncode != 0:
        raise SystemExit(f"recorder exited with {recorder.returncode}")
    if f"wrote {sent} packets" not in out:
        raise SystemExit(f"sent {sent} packets, but the recorder says: {out.strip()}")
    log(f"{args.out}: {os.path.getsize(args.out)} bytes, {sent} packets, {args.seconds:.0f} s")


if __name__ == "__main__":
    main()
