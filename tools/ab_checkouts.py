"""Before/after: one benchmark of two checkouts, run in turn (A B A B ...) in one call.

    python -m tools.ab_checkouts --old ../baseline --new . --rounds 3 --out FILE.json \
        -- benchmarks.throughput --mesh-width 0.5 --end 0.02 --json

Each round runs the benchmark of each checkout, old then new, with that checkout first on
PYTHONPATH, so that the machine's drift hits both alike: a module name
(``benchmarks.throughput``) runs as ``python -m <module> <args>`` from the checkout's root; a
file path relative to the checkout (``benchmarks/throughput.py``, for a checkout from before
benchmarks/ was a package) runs as ``python <checkout>/<path> <args>`` from the file's folder.
The JSON object on the last line of each run's output (or, with ``--result``, the JSON file
the script writes, relative to the checkout) is kept. With ``--cold`` every run gets an
empty numba cache (compile time); otherwise each checkout keeps its own cache (loaded from
the second run on). Writes every run, the machine and the git commit of each checkout into
``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.common import machine


def commit(root: Path) -> str:
    try:
        return subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def command(root: Path, script: str, args) -> tuple:
    """(command line, working folder) of one run of ``script`` (a module name or a file path
    relative to the checkout) in the checkout ``root``."""
    if script.endswith(".py"):
        path = root / script
        return [sys.executable, str(path), *args], path.parent
    return [sys.executable, "-m", script, *args], root


def run_once(root: Path, script: str, args, result, cold: bool):
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd, cwd = command(root, script, args)
    with tempfile.TemporaryDirectory() as cache:
        if cold:
            env["NUMBA_CACHE_DIR"] = cache
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    if proc.returncode:
        raise SystemExit(f"{root}: {script} failed:\n{proc.stderr[-3000:]}")
    if result:
        return json.loads((root / result).read_text())
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", type=Path, required=True)
    ap.add_argument("--new", type=Path, required=True)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--result", default=None, help="JSON file the script writes (relative)")
    ap.add_argument("--cold", action="store_true", help="empty numba cache for every run")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("script", help="module (benchmarks.throughput) or file relative to the "
                                   "checkout (benchmarks/throughput.py)")
    ap.add_argument("args", nargs=argparse.REMAINDER)
    a = ap.parse_args(argv)
    roots = {"old": a.old.resolve(), "new": a.new.resolve()}
    runs = {"old": [], "new": []}
    for k in range(a.rounds):
        for side, root in roots.items():
            runs[side].append(run_once(root, a.script, a.args, a.result, a.cold))
            print(f"round {k} {side} done", flush=True)
    out = {"machine": machine(), "script": a.script, "args": a.args, "cold_cache": a.cold,
           "commits": {s: commit(r) for s, r in roots.items()}, "runs": runs}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
