"""LinuxCNC's standalone RS274 interpreter (`rs274`) as a reference oracle.

Shared by scripts/rs274-diff and scripts/bench/interp. Python 3.11 stdlib
only.

- ensure_rs274(): install the `linuxcnc-uspace` Debian package when `rs274`
  is missing (apt-get update + apt-get install; we run as root).
- write_tool_table(): a minimal tool table (T1..T99, zero length/diameter)
  so that `T7 M6` does not abort the run.
- run_rs274(): run it non-interactively and return its canonical-call text.
- parse_canon(): canonical-call text -> motion list in program units.

How rs274 is run (found by trying it, LinuxCNC 2.9 Debian bookworm):

    rs274 -t TOOLS.tbl -g PROGRAM.ngc OUT.txt  </dev/null

`-g` is "go" (batch) mode; without it rs274 shows an interactive menu on
stdin. No `-i` INI is needed. rs274 prints "executing" and, on an error,
the message and the offending source line, on stdout; the exit status is
1 on any error (including "File ended with no percent sign or program end",
which it reports after emitting every canonical call of a program that
lacks M2/M30). It writes nothing else to its working directory, but we
run it in a scratch directory anyway.

Output: one canonical call per line,

    "   16 N..... ARC_FEED(-2.7293, 2.4907, -1.5319, 1.2933, 1, -1.0000, 0.0000, 0.0000, 0.0000)"

i.e. a running call counter, the block's N word (`N.....` when it has
none: the SOURCE LINE NUMBER IS NOT PRINTED), then the call. Numbers are
printed with 4 decimals ("%.4f") in the PROGRAM's current length units
(USE_LENGTH_UNITS(CANON_UNITS_INCHES) after G20), and positions are in
program coordinates (G92/G5x offsets are sent separately as
SET_G92_OFFSET/SET_G5X_OFFSET and are not applied to the end points).

ARC_FEED(first_end, second_end, first_axis, second_axis, rotation,
axis_end_point, a, b, c[, u, v, w]): first/second are the plane's axes
(G17: X,Y  normal Z; G18: Z,X  normal Y; G19: Y,Z  normal X); rotation is
+n for n counter-clockwise turns about the plane normal (G3) and -n for
clockwise (G2); the centre's normal coordinate is not given (it is the
start point's).

Frames: parse_canon() reports every point in the MACHINE frame by default
(program coordinates rotated by SET_XY_ROTATION, plus SET_G5X_OFFSET and
SET_G92_OFFSET, which is what LinuxCNC's emccanon does before moving), the
frame our gsim reports in; frame="program" gives rs274's numbers as printed.
Offsets, like feed rates, are taken in the length units in force when they
were sent (emccanon converts them to its internal units at once), so a
later G20/G21 does not rescale them.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field

PACKAGE = "linuxcnc-uspace"
INCH = 25.4


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------
# Installation


def rs274_path() -> str | None:
    return shutil.which("rs274")


def ensure_rs274(quiet: bool = False) -> str:
    """Return the path of `rs274`, installing linuxcnc-uspace if needed."""
    p = rs274_path()
    if p:
        return p
    if os.geteuid() != 0:
        raise RuntimeError(
            "rs274 is missing and we are not root: install it with "
            f"'apt-get update && apt-get install -y {PACKAGE}'"
        )
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    # No recommends: rs274 needs only the hard dependencies, and the
    # recommended Qt, OpenCV and documentation packages would triple the
    # download on a fresh CI machine.
    for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "--no-install-recommends", PACKAGE]):
        log("rs274 not found: running " + " ".join(cmd))
        r = subprocess.run(
            cmd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL if quiet else sys.stderr,
            stderr=sys.stderr,
        )
        if r.returncode != 0:
            raise RuntimeError(f"'{' '.join(cmd)}' failed with status {r.returncode}")
    p = rs274_path()
    if not p:
        raise RuntimeError(f"{PACKAGE} installed but rs274 is still not on PATH")
    log(f"installed {PACKAGE}: {p}")
    return p


def ensure_gnu_time() -> str | None:
    """`/usr/bin/time` (GNU, for -v peak RSS), installing `time` if needed."""
    if os.path.exists("/usr/bin/time"):
        return "/usr/bin/time"
    if os.geteuid() != 0:
        return None
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "time"]):
        log("/usr/bin/time not found: running " + " ".join(cmd))
        r = subprocess.run(cmd, env=env, stdin=subprocess.DEVNULL, stdout=sys.stderr)
        if r.returncode != 0:
            return None
    return "/usr/bin/time" if os.path.exists("/usr/bin/time") else None


def ncfiles() -> list[str]:
    """The sample programs the package installs (every *.ngc under an
    `ncfiles` directory in `dpkg -L linuxcnc-uspace`), sorted."""
    try:
        out = subprocess.run(
            ["dpkg", "-L", PACKAGE], capture_output=True, text=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        return []
    files = [
        l.strip()
        for l in out.splitlines()
        if "/ncfiles/" in l and l.strip().lower().endswith(".ngc") and os.path.isfile(l.strip())
    ]
    return sorted(set(files))


# --------------------------------------------------------------------------
# Running


def write_tool_table(path: str, tools: int = 99) -> str:
    """A tool table with T1..Ttools in pockets 1..tools, zero offsets."""
    with open(path, "w") as f:
        for t in range(1, tools + 1):
            f.write(f"T{t} P{t} Z0 D0 ;microcam rs274-diff stand-in tool {t}\n")
    return path


@dataclass
class Rs274Run:
    status: int  # exit status, -1 on timeout
    canon: str  # canonical-call text
    messages: list[str]  # what it printed besides "executing"
    seconds: float = 0.0

    NO_END = "File ended with no percent sign or program end"

    @property
    def error(self) -> str | None:
        """None when it ran to the end; the first message otherwise."""
        if self.status == 0:
            return None
        if self.status == -1:
            return "timed out"
        return self.messages[0] if self.messages else f"exit status {self.status}"

    @property
    def ok(self) -> bool:
        """Ran the whole program. A program without M2/M30 counts as run
        (rs274 complains only after emitting all of it)."""
        return self.status == 0 or (self.status > 0 and self.error == self.NO_END)


def rs274_cmd(rs274: str, tool_table: str, program: str, out: str) -> list[str]:
    return [rs274, "-t", tool_table, "-g", program, out]


def run_rs274(program: str, rs274: str | None = None, timeout: float = 120.0,
              workdir: str | None = None, spline_ends: bool = False) -> Rs274Run:
    """Run rs274 on `program` in a scratch directory, stdin from /dev/null.
    With `spline_ends`, on a copy that also prints where each spline ends
    (spline_probe_copy)."""
    probe = None
    import time

    rs274 = rs274 or ensure_rs274()
    program = os.path.abspath(program)
    with tempfile.TemporaryDirectory(prefix="rs274-", dir=workdir) as tmp:
        if spline_ends:
            probe = os.path.join(tmp, "spline-probe-" + os.path.basename(program))
            try:
                if not spline_probe_copy(program, probe):
                    probe = None
            except OSError:
                probe = None
        tbl = write_tool_table(os.path.join(tmp, "tools.tbl"))
        out = os.path.join(tmp, "canon.txt")
        t0 = time.monotonic()
        try:
            r = subprocess.run(
                rs274_cmd(rs274, tbl, probe or program, out),
                cwd=tmp,
                stdin=subprocess.DEVNULL,
                capture_output=True,
                text=True,
                errors="replace",
                timeout=timeout,
            )
            status, text = r.returncode, (r.stdout or "") + (r.stderr or "")
        except subprocess.TimeoutExpired as e:
            status = -1
            text = (e.stdout or b"").decode(errors="replace") if isinstance(e.stdout, bytes) else (e.stdout or "")
        secs = time.monotonic() - t0
        canon = ""
        if os.path.exists(out):
            with open(out, errors="replace") as f:
                canon = f.read()
    msgs = [l.strip() for l in text.splitlines() if l.strip() and l.strip() != "executing"]
    run = Rs274Run(status, canon, msgs, secs)
    if probe and not run.ok:
        # The copy lives elsewhere (a subroutine file beside the program is
        # not found from there, say): judge the program by itself.
        return run_rs274(program, rs274, timeout, workdir)
    return run


# --------------------------------------------------------------------------
# Parsing the canonical calls

_LINE = re.compile(r"^\s*(\d+)\s+N(\.+|\d*)\s*([A-Z][A-Z0-9_]*)\((.*)\)\s*$")
_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)", re.I)

PLANES = {
    "CANON_PLANE_XY": "xy",
    "CANON_PLANE_XZ": "xz",  # G18 (ZX)
    "CANON_PLANE_YZ": "yz",  # G19
}
# Index of (first, second, normal) axes in (x, y, z) for each plane.
PLANE_AXES = {"xy": (0, 1, 2), "xz": (2, 0, 1), "yz": (1, 2, 0)}

# The message spline_probe_copy() has rs274 print after each spline line.
SPLINE_END_TAG = "rs274-diff spline end"

# A G5, G5.1 or G5.3 word (not G54.., G5.2 opens a NURBS block, G5.3 cuts it).
_SPLINE_END = re.compile(r"G\s*0*5\s*(?:\.\s*[13]\s*)?(?![0-9.])", re.I)
_COMMENT = re.compile(r"\([^)]*\)|;.*")


def spline_probe_copy(program: str, out_path: str) -> bool:
    """Write a copy of `program` to `out_path` with a line
    `(DEBUG,rs274-diff spline end #5420 #5421)` after every line holding a
    G5, G5.1 or G5.3 word, so that rs274, which prints a spline as
    `NURBS_FEED(n, ...)` with no point, also prints where it ends (its
    current X and Y, program frame and units). rs274 prints no line
    numbers, so the added lines change nothing else it prints. Returns
    False (and writes nothing) when the program has no such line."""
    with open(program, errors="replace") as f:
        lines = f.read().split("\n")
    out, found = [], False
    for line in lines:
        out.append(line)
        if _SPLINE_END.search(_COMMENT.sub("", line)):
            out.append(f"(DEBUG,{SPLINE_END_TAG} #5420 #5421)")
            found = True
    if found:
        with open(out_path, "w") as f:
            f.write("\n".join(out))
    return found


# Calls that move the machine in ways our toolpath model has no record for;
# seeing one means the program uses something we do not support.
EXOTIC_MOTION = {
    "STRAIGHT_PROBE", "NURBS_FEED", "RIGID_TAP", "SPLINE_FEED",
    "START_SPEED_FEED_SYNC",
}


@dataclass
class Motion:
    kind: str  # "rapid" | "line" | "arc" | exotic call name
    to: tuple[float, float, float]  # length units in force (see units), frame as asked
    units: str  # "mm" | "in"
    canon_line: int  # the call counter rs274 printed
    nword: str  # "N104" or ""
    feed: float | None = None  # units/min, for feed moves
    center: tuple[float, float, float] | None = None
    plane: str | None = None
    rotation: int = 0  # +n ccw, -n cw
    abc: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rotary axes, degrees (program frame)
    # NURBS_FEED: how many control points rs274 printed, and whether `to`
    # is known (rs274 prints no point of the curve: only a SPLINE_END_TAG
    # message after it tells where it ends, see spline_probe_copy).
    npoints: int | None = None
    to_known: bool = True

    @property
    def ccw(self) -> bool:
        return self.rotation > 0

    @property
    def turns(self) -> int:
        return abs(self.rotation)


@dataclass
class Canon:
    motions: list[Motion] = field(default_factory=list)
    dwells: list[float] = field(default_factory=list)
    spindle: list[float] = field(default_factory=list)
    units_seen: set[str] = field(default_factory=set)
    # Calls seen that we do not model (name -> count); informative.
    other: dict[str, int] = field(default_factory=dict)
    unparsed: list[str] = field(default_factory=list)
    feed_mode_nonzero: bool = False
    offsets_nonzero: list[str] = field(default_factory=list)


def _nums(args: str) -> list[float]:
    return [float(x) for x in _NUM.findall(args)]


UNIT_MM = {"mm": 1.0, "in": INCH, "cm": 10.0}


def parse_canon(text: str, frame: str = "machine") -> Canon:
    """Parse rs274's canonical-call output into motions, in the length units
    in force at each motion and in the machine frame (or frame="program")."""
    if frame not in ("machine", "program"):
        raise ValueError(f"frame must be 'machine' or 'program', not {frame!r}")
    c = Canon()
    units = "mm"  # rs274 always starts with USE_LENGTH_UNITS(CANON_UNITS_MM)
    plane = "xy"
    pos = [0.0, 0.0, 0.0]  # program frame, in `units`
    g5x = [0.0, 0.0, 0.0]  # mm
    g92 = [0.0, 0.0, 0.0]  # mm
    rot = 0.0  # degrees
    feed_per_rev = False  # SET_FEED_MODE(.., 1): G95
    rpm = 0.0
    feed_word = 0.0

    def feed_now():
        # In G95 rs274 prints the feed per revolution; the machine moves
        # at that times the spindle speed, which is what gsim reports.
        return feed_word * rpm if feed_per_rev else feed_word

    def place(p):
        """Program point (in `units`) -> the reported frame (in `units`)."""
        if frame == "program":
            return tuple(p)
        x, y, z = p
        if rot:
            ca, sa = math.cos(math.radians(rot)), math.sin(math.radians(rot))
            x, y = x * ca - y * sa, x * sa + y * ca
        k = UNIT_MM[units]
        return (x + (g5x[0] + g92[0]) / k, y + (g5x[1] + g92[1]) / k, z + (g5x[2] + g92[2]) / k)
    for raw in text.splitlines():
        if not raw.strip():
            continue
        m = _LINE.match(raw)
        if not m:
            c.unparsed.append(raw)
            continue
        counter, nw, name, args = int(m.group(1)), m.group(2), m.group(3), m.group(4)
        nword = "" if nw.startswith(".") else "N" + nw
        if name == "USE_LENGTH_UNITS":
            new = "in" if "INCH" in args else ("cm" if "CM" in args else "mm")
            if new != units:
                k = UNIT_MM[units] / UNIT_MM[new]
                pos = [v * k for v in pos]
                feed_word *= k
                units = new
        elif name == "SELECT_PLANE":
            plane = PLANES.get(args.strip(), args.strip())
        elif name == "SET_FEED_RATE":
            feed_word = _nums(args)[0]
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            v = _nums(args)
            to = (v[0], v[1], v[2])
            kind = "rapid" if name == "STRAIGHT_TRAVERSE" else "line"
            c.motions.append(Motion(kind, place(to), units, counter, nword,
                                    feed=None if kind == "rapid" else feed_now(),
                                    abc=tuple(v[3:6]) if len(v) >= 6 else (0.0, 0.0, 0.0)))
            c.units_seen.add(units)
            pos = list(to)
        elif name == "ARC_FEED":
            v = _nums(args)
            fe, se, fa, sa, ae = v[0], v[1], v[2], v[3], v[5]
            i1, i2, n = PLANE_AXES[plane]
            to = [0.0, 0.0, 0.0]
            to[i1], to[i2], to[n] = fe, se, ae
            cen = [0.0, 0.0, 0.0]
            cen[i1], cen[i2], cen[n] = fa, sa, pos[n]
            c.motions.append(Motion("arc", place(to), units, counter, nword, feed=feed_now(),
                                    center=place(cen), plane=plane, rotation=int(v[4]),
                                    abc=tuple(v[6:9]) if len(v) >= 9 else (0.0, 0.0, 0.0)))
            c.units_seen.add(units)
            pos = to
        elif name == "NURBS_FEED":
            # "NURBS_FEED(7, ...)": the control point count, no point.
            v = _nums(args)
            c.motions.append(Motion(name, place(pos), units, counter, nword,
                                    npoints=int(v[0]) if v else None, to_known=False))
        elif name == "MESSAGE" and SPLINE_END_TAG in args:
            # Where the spline just cut ends (#5420 #5421, program frame).
            v = _nums(args.split(SPLINE_END_TAG, 1)[1])
            last = c.motions[-1] if c.motions else None
            if len(v) >= 2 and last is not None and last.kind == "NURBS_FEED" and not last.to_known:
                pos = [v[0], v[1], pos[2]]
                last.to, last.to_known = place(pos), True
        elif name in EXOTIC_MOTION:
            v = _nums(args)
            to = tuple(v[:3]) if len(v) >= 3 else tuple(pos)
            c.motions.append(Motion(name, place(to), units, counter, nword))
            if len(v) >= 3 and name in ("STRAIGHT_PROBE", "RIGID_TAP"):
                pos = list(v[:3])
        elif name == "DWELL":
            c.dwells.append(_nums(args)[0])
        elif name == "SET_SPINDLE_SPEED":
            v = _nums(args)
            c.spindle.append(v[-1])
            rpm = v[-1]
        else:
            if name == "SET_FEED_MODE":
                v = _nums(args)
                feed_per_rev = len(v) >= 2 and v[1] == 1
                if any(x != 0 for x in v):
                    c.feed_mode_nonzero = True
            if name in ("SET_G92_OFFSET", "SET_G5X_OFFSET", "SET_XY_ROTATION"):
                v = _nums(args)
                vals = v[1:] if name == "SET_G5X_OFFSET" else v
                if any(abs(x) > 0 for x in vals):
                    c.offsets_nonzero.append(f"{name}({args})")
                k = UNIT_MM[units]
                if name == "SET_G5X_OFFSET":
                    g5x = [x * k for x in vals[:3]]
                elif name == "SET_G92_OFFSET":
                    g92 = [x * k for x in vals[:3]]
                else:
                    rot = vals[0] if vals else 0.0
            c.other[name] = c.other.get(name, 0) + 1
    return c
