"""CAM programs made at test time by CAM systems that Debian packages.

The rs274 differential needs programs as CAM systems write them. Besides
the real ones in the corpus (gcode-cam/, each with its source), it makes
more: a CAM system installed from Debian's archive is run on the project's
own drawings (testdata/samples) and the corpus's (dxf/). The programs are
never committed; what made each one is in
testdata/conformance/cam-generated.tsv, one row per program:

    program  generator  version  input  variant  options

- program: the file name under target/cam-generated/<variant>/
- generator / version: the Debian package and the version the row was
  written with (a different installed version is reported, not refused)
- input: `testdata/...` (the repository) or `corpus:dxf/...` (the corpus)
- variant: a name for one set of options
- options: JSON, the configuration set before the run (for dxf2gcode:
  {"config": {...}, "postpro": {...}}, sections and keys of its
  config.cfg and postpro_config.cfg)

Only dxf2gcode is used today (Debian package `dxf2gcode`, installed with
apt-get when missing, as root, like linuxcnc-uspace for rs274). It runs
headless through scripts/lib/dxf2gcode_batch.py, under Debian's
/usr/bin/python3. Outputs are kept between runs (a stamp file per variant
holds its rows and the installed version); a changed row or version makes
them again.

Python 3.11, stdlib only.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
TSV = os.path.join(REPO, "testdata", "conformance", "cam-generated.tsv")
OUT = os.path.join(REPO, "target", "cam-generated")
DRIVER = os.path.join(HERE, "dxf2gcode_batch.py")
DEBIAN_PYTHON = "/usr/bin/python3"
PACKAGE = "dxf2gcode"


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def read_rows(tsv: str = TSV) -> list[dict]:
    with open(tsv, newline="") as f:
        lines = [line for line in f if not line.startswith("#")]
    rows = list(csv.DictReader(lines, delimiter="\t"))
    for n, r in enumerate(rows, 2):
        for k in ("program", "generator", "version", "input", "variant", "options"):
            if not r.get(k):
                raise ValueError(f"{tsv}: row {n}: no {k}")
        r["options_json"] = json.loads(r["options"])
    return rows


def input_path(spec: str, corpus_root: str) -> str:
    if spec.startswith("corpus:"):
        return os.path.join(corpus_root, spec[len("corpus:"):])
    return os.path.join(REPO, spec)


def installed_version(package: str) -> str | None:
    r = subprocess.run(["dpkg-query", "-W", "-f=${Version}", package], capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 and r.stdout.strip() else None


def ensure_package(package: str) -> str:
    """Install a Debian package when missing (root only); return its version."""
    v = installed_version(package)
    if v and os.path.exists("/usr/bin/" + package):
        return v
    if os.geteuid() != 0:
        raise RuntimeError(f"{package} is missing and we are not root: "
                           f"install it with 'apt-get update && apt-get install -y {package}'")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "--no-install-recommends", package]):
        log(f"{package} not found: running " + " ".join(cmd))
        r = subprocess.run(cmd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=sys.stderr)
        if r.returncode != 0:
            raise RuntimeError(f"'{' '.join(cmd)}' failed with status {r.returncode}")
    v = installed_version(package)
    if not v:
        raise RuntimeError(f"{package} installed but dpkg does not list it")
    return v


def generate(corpus_root: str, tsv: str = TSV, out: str = OUT, timeout: float = 900.0) -> tuple[list[str], list[str]]:
    """Make every program of the TSV whose input exists. Returns (paths of
    the programs made or kept, notes on rows that made nothing)."""
    rows = read_rows(tsv)
    notes: list[str] = []
    made: list[str] = []
    by_variant: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        if r["generator"] != PACKAGE:
            notes.append(f"{r['program']}: unknown generator {r['generator']}")
            continue
        by_variant.setdefault((r["generator"], r["variant"]), []).append(r)
    if not by_variant:
        return made, notes
    version = ensure_package(PACKAGE)
    for (gen, variant), vrows in sorted(by_variant.items()):
        for r in vrows:
            if r["version"] != version:
                notes.append(f"{r['program']}: written with {gen} {r['version']}, running {version}")
        opts = vrows[0]["options_json"]
        if any(r["options_json"] != opts for r in vrows):
            raise ValueError(f"{tsv}: variant {variant}: rows with different options")
        vdir = os.path.join(out, variant)
        todo = [(input_path(r["input"], corpus_root), os.path.join(vdir, r["program"])) for r in vrows]
        present = [(i, o) for i, o in todo if os.path.isfile(i)]
        for i, o in todo:
            if not os.path.isfile(i):
                notes.append(f"{os.path.basename(o)}: input not found: {i}")
        stamp_text = json.dumps({"version": version, "options": opts, "rows": present}, sort_keys=True)
        stamp = os.path.join(vdir, ".stamp")
        have = open(stamp).read() if os.path.isfile(stamp) else None
        if have != stamp_text or not all(os.path.isfile(o) for _, o in present):
            if os.path.isdir(vdir):
                shutil.rmtree(vdir)
            os.makedirs(vdir)
            log(f"cam-generated: {gen} {version}, variant {variant}: {len(present)} drawings")
            failed = run_dxf2gcode(opts, present, timeout)
            for i, why in failed:
                notes.append(f"{variant}: {os.path.basename(i)}: {why}")
            with open(stamp, "w") as f:
                f.write(stamp_text)
        made.extend(o for _, o in present if os.path.isfile(o))
    return made, notes


def run_dxf2gcode(opts: dict, pairs: list[tuple[str, str]], timeout: float) -> list[tuple[str, str]]:
    """Run the batch driver in a scratch HOME; return (input, reason) of
    the drawings it made nothing of."""
    with tempfile.TemporaryDirectory(prefix="camgen-") as home:
        optfile = os.path.join(home, "options.json")
        with open(optfile, "w") as f:
            json.dump(opts, f)
        env = dict(os.environ, HOME=home, QT_QPA_PLATFORM="offscreen", XDG_RUNTIME_DIR=home,
                   PYTHONDONTWRITEBYTECODE="1")
        args = [DEBIAN_PYTHON, DRIVER, optfile] + [x for p in pairs for x in p]
        try:
            r = subprocess.run(args, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                               errors="replace", timeout=timeout, cwd=home)
        except subprocess.TimeoutExpired:
            return [(i, f"dxf2gcode timed out after {timeout:.0f} s") for i, o in pairs if not os.path.isfile(o)]
        said = {}
        for line in r.stdout.splitlines():
            if line.startswith("failed "):
                src, _, why = line[len("failed "):].partition(": ")
                said[src] = why
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        return [(i, said.get(i, f"nothing written (driver status {r.returncode}: {tail})"))
                for i, o in pairs if not os.path.isfile(o)]

