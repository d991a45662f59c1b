"""Bit-for-bit regression of result files: run every case of cases/ to a short end time, then
compare two such sets dataset by dataset.

    python benchmarks/regression.py run OUT [--end 0.2] [--cases 'cases/*.toml']
    python benchmarks/regression.py compare OLD NEW

``run`` calls the command line in a subprocess (``python -m spinweb_fe run``), so the same
script drives any checkout: put that checkout first on PYTHONPATH to run it. ``compare``
reads every dataset under ``/history``, ``/frames`` and ``/mesh`` of each pair of
``results.h5`` files and reports the first difference of each (exact equality, NaN equal
to NaN); it exits 1 when anything differs or a file is missing on one side.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
GROUPS = ("history", "frames", "mesh")


def run_all(out: Path, end: float, pattern: str) -> int:
    out.mkdir(parents=True, exist_ok=True)
    log = {}
    for case in sorted(glob.glob(str(ROOT / pattern))):
        stem = Path(case).stem
        t0 = time.perf_counter()
        cmd = [sys.executable, "-m", "spinweb_fe", "run", case, "-o", str(out / stem),
               "--set", f"time.end={end}", "--no-progress"]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
        log[stem] = {"exit": proc.returncode, "wall_s": time.perf_counter() - t0}
        print(f"{stem}: exit {proc.returncode}, {log[stem]['wall_s']:.1f} s", flush=True)
        if proc.returncode:
            print(proc.stderr[-2000:], file=sys.stderr)
    (out / "runs.json").write_text(json.dumps(log, indent=1))
    return 0 if all(v["exit"] == 0 for v in log.values()) else 1


def _datasets(h5):
    found = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            found[name] = obj[()]
    for g in GROUPS:
        if g in h5:
            h5[g].visititems(lambda n, o, g=g: visit(f"{g}/{n}", o))
    return found


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind == "f":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


def compare(old: Path, new: Path) -> int:
    bad = 0
    stems = sorted({p.parent.name for p in old.glob("*/results.h5")}
                   | {p.parent.name for p in new.glob("*/results.h5")})
    for stem in stems:
        fa, fb = old / stem / "results.h5", new / stem / "results.h5"
        if not (fa.is_file() and fb.is_file()):
            print(f"{stem}: missing on one side")
            bad += 1
            continue
        with h5py.File(fa, "r") as ha, h5py.File(fb, "r") as hb:
            da, db = _datasets(ha), _datasets(hb)
        diffs = []
        for name in sorted(set(da) | set(db)):
            if name not in da or name not in db:
                diffs.append(f"{name} only in {'old' if name in da else 'new'}")
            elif not _same(da[name], db[name]):
                a, b = np.asarray(da[name]), np.asarray(db[name])
                if a.shape == b.shape and a.dtype.kind == b.dtype.kind == "f":
                    k = int(np.argmax(~((a == b) | (np.isnan(a) & np.isnan(b))).ravel()))
                    diffs.append(f"{name} differs (first at flat index {k}: "
                                 f"{a.ravel()[k]!r} vs {b.ravel()[k]!r})")
                else:
                    diffs.append(f"{name} differs ({a.shape} {a.dtype} vs {b.shape} {b.dtype})")
        status = "identical" if not diffs else f"{len(diffs)} datasets differ"
        print(f"{stem}: {len(da)} datasets, {status}")
        for d in diffs:
            print(f"    {d}")
        bad += bool(diffs)
    return 1 if bad else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("out", type=Path)
    r.add_argument("--end", type=float, default=0.2)
    r.add_argument("--cases", default="cases/*.toml")
    c = sub.add_parser("compare")
    c.add_argument("old", type=Path)
    c.add_argument("new", type=Path)
    a = ap.parse_args(argv)
    if a.cmd == "run":
        return run_all(a.out, a.end, a.cases)
    return compare(a.old, a.new)


if __name__ == "__main__":
    sys.exit(main())
