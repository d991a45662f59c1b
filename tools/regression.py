"""Bit-for-bit regression of result files: run every case of cases/ and a list of feature
variants (free hub, gravity gradient, perturbations, friction, strength, damping, a loose
coil) to a short end time, then compare two such sets dataset by dataset.

    python tools/regression.py run OUT [--end 0.25] [--cases 'cases/*.toml'] [--threads N]
                                       [--no-variants] [--only STEM ...]
    python tools/regression.py compare OLD NEW

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
GROUPS = ("history", "frames", "mesh", "crossings", "linking", "verdict")
FREE = ("hub.motion='free'",)
#: (name, case file, --set overrides): scenes the case files do not cover
VARIANTS = (
    ("v_free_tethers_tilt_gravity", "paper_free_arms",
     FREE + ("perturbation.hub_tilt_rate=0.05", "environment.gravity_gradient=true",
             "environment.orbit_radius=6.771e6", "environment.orbit_tilt=0.5")),
    ("v_free_two_stage_tilt", "paper_two_stage_web",
     FREE + ("perturbation.z_amplitude=1.0", "perturbation.hub_tilt_rate=0.01")),
    ("v_free_feedback_random", "paper_feedback_web",
     FREE + ("perturbation.shape='random'", "perturbation.z_amplitude=0.5",
             "perturbation.seed=3")),
    ("v_free_payout_web", "paper_payout_web", FREE),
    ("v_free_ramp_vz", "paper_ramp_web", FREE + ("perturbation.vz_amplitude=0.1",)),
    ("v_free_eq7_delay", "paper_free_arms_eq7",
     FREE + ("perturbation.arm=2", "perturbation.delay=0.05",
             "perturbation.tip_mass_scale=1.05")),
    ("v_fixed_tilt_web", "paper_free_web", ("perturbation.z_amplitude=1.0",)),
    ("v_fixed_friction", "paper_free_arms", ("hub.friction=0.3",)),
    ("v_fixed_delay_scale", "paper_free_web",
     ("perturbation.arm=1", "perturbation.delay=0.05", "perturbation.tip_mass_scale=1.05")),
    ("v_fixed_rupture", "paper_free_web",
     ("cable.failure_strain=0.002", "cable.rupture=true")),
    ("v_free_strength", "paper_free_arms", FREE + ("cable.failure_strain=0.01",)),
    ("v_fixed_damped", "paper_free_arms", ("cable.damping_ratio=0.05",)),
    ("v_fixed_loose", "paper_free_arms", ("stowage.coil='loose'",)),
    ("v_contact_feedback_layers", "paper_feedback_web",
     ("fold.layer_gap=0.005", "contact.cables=true", "contact.friction=0.3",
      "audit.crossings=true")),
    ("v_contact_free_tilt", "paper_free_web",
     FREE + ("fold.layer_gap=0.005", "perturbation.vz_amplitude=0.1",
             "perturbation.hub_tilt_rate=0.01", "contact.cables=true",
             "audit.crossings=true")),
    ("v_audit_free_layers", "paper_free_web", ("fold.layer_gap=0.005", "audit.crossings=true")),
)


def _run(out: Path, stem: str, case: str, sets, end: float, threads) -> dict:
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "spinweb_fe", "run", case, "-o", str(out / stem),
           "--set", f"time.end={end}", "--no-progress"]
    for s in sets:
        cmd += ["--set", s]
    if threads:
        cmd += ["--threads", str(threads)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
    row = {"exit": proc.returncode, "wall_s": time.perf_counter() - t0, "sets": list(sets)}
    print(f"{stem}: exit {proc.returncode}, {row['wall_s']:.1f} s", flush=True)
    if proc.returncode:
        print(proc.stderr[-2000:], file=sys.stderr)
    return row


def run_all(out: Path, end: float, pattern: str, threads=None, variants=True,
            only=None) -> int:
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(Path(c).stem, c, ()) for c in sorted(glob.glob(str(ROOT / pattern)))]
    if variants:
        jobs += [(name, str(ROOT / "cases" / f"{base}.toml"), sets)
                 for name, base, sets in VARIANTS]
    log = {stem: _run(out, stem, case, sets, end, threads) for stem, case, sets in jobs
           if not only or stem in only}
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
    r.add_argument("--end", type=float, default=0.25)
    r.add_argument("--cases", default="cases/*.toml")
    r.add_argument("--threads", type=int, default=None)
    r.add_argument("--no-variants", action="store_true")
    r.add_argument("--only", nargs="*", default=None)
    c = sub.add_parser("compare")
    c.add_argument("old", type=Path)
    c.add_argument("new", type=Path)
    a = ap.parse_args(argv)
    if a.cmd == "run":
        return run_all(a.out, a.end, a.cases, a.threads, not a.no_variants, a.only)
    return compare(a.old, a.new)


if __name__ == "__main__":
    sys.exit(main())
