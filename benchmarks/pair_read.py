"""What one read of a whole pair list costs, and why (issue #42).

    python -m benchmarks.pair_read [--pairs 310000] [--repeat 40]

Every step the audit reads each listed pair's certificate:
``level[p] - cum[e] - cum[f] > sep`` (fe.contact.touch.certified_crossings). In the loop
that costs 3.3-4.5 ns a pair (docs/performance.md). This benchmark times the test
alone on a synthetic list shaped like the coiled paper web's: 310 000 pairs of 3 220
elements, the first element ascending, 4 % of the pairs looked at. It runs each read
three ways:

- ``cached``: the list stays in the caches between reads;
- ``flushed``: a 128 MB array is written before each read, as the plain step and the
  other passes do in the loop;
- ``flushed_int32``: the same with int32 element indices, 16 bytes a pair instead of 24.

It also times ``compact``, a branch-free variant: every index is written and the count
advances by the test's result.

Writes benchmarks/results/pair_read.json with the machine (CPU model, ISA, load) and
the fastest read of ``repeat``, in ns a pair.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from numba import njit

from benchmarks.common import machine

OUT = Path(__file__).resolve().parent / "results" / "pair_read.json"
ELEMENTS = 3220
LOOKED = 0.04


@njit(cache=True)
def branchy(pairs, level, cum, sep):
    s = 0
    for p in range(pairs.shape[0]):
        if level[p] - cum[pairs[p, 0]] - cum[pairs[p, 1]] > sep:
            continue
        s += p
    return s


@njit(cache=True)
def compact(pairs, level, cum, sep, idx):
    k = 0
    for p in range(pairs.shape[0]):
        idx[k] = p
        k += level[p] - cum[pairs[p, 0]] - cum[pairs[p, 1]] <= sep
    s = 0
    for i in range(k):
        s += idx[i]
    return s


@njit(cache=True)
def flush(junk):
    for i in range(0, junk.shape[0], 8):  # one write a 64-byte line
        junk[i] += 1.0


def synthetic(m, seed=0):
    rng = np.random.default_rng(seed)
    e = np.sort(rng.integers(0, ELEMENTS, m))
    f = rng.integers(0, ELEMENTS, m)
    pairs = np.stack([e, f], 1).astype(np.int64)
    cum = rng.random(ELEMENTS) * 0.01
    gap = np.where(rng.random(m) < LOOKED, -1.0, 0.005 + rng.random(m) * 0.01)
    return pairs, cum[e] + cum[f] + gap, cum


def fastest(fn, args, repeat, junk=None):
    fn(*args)
    best = np.inf
    for _ in range(repeat):
        if junk is not None:
            flush(junk)
        t = time.perf_counter()
        fn(*args)
        best = min(best, time.perf_counter() - t)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=310000)
    ap.add_argument("--repeat", type=int, default=40)
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args(argv)
    pairs, level, cum = synthetic(a.pairs)
    sep = 1e-7
    junk = np.ones(16_000_000)
    rec = {"machine_start": machine(), "pairs": a.pairs, "elements": ELEMENTS,
           "looked_share": LOOKED, "repeat": a.repeat, "ns_per_pair": {}}
    runs = {
        "cached": (branchy, (pairs, level, cum, sep), None),
        "compact_cached": (compact, (pairs, level, cum, sep, np.empty(a.pairs, np.int64)),
                           None),
        "flushed": (branchy, (pairs, level, cum, sep), junk),
        "flushed_int32": (branchy, (pairs.astype(np.int32), level, cum, sep), junk),
    }
    for name, (fn, args, j) in runs.items():
        rec["ns_per_pair"][name] = fastest(fn, args, a.repeat, j) / a.pairs * 1e9
        print(f"{name:16s} {rec['ns_per_pair'][name]:.2f} ns a pair")
    rec["machine_end"] = machine()
    Path(a.out).write_text(json.dumps(rec, indent=1))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
