"""Run a case's step loop under Linux ``perf`` with numba's compiled functions named.

    perf record -F 4000 -o perf.data python -m tools.perf_loop cases/paper_free_arms.toml 10 \
        [KEY=VALUE ...]
    perf report -i perf.data --no-children --sort sym -g none

numba's JIT code has no symbols, so perf shows bare addresses. After compiling (or loading)
the loop, this script writes ``/tmp/perf-PID.map`` (perf's map for JIT code: start, size,
name per line) with every compiled overload's entry address, from numba's dispatchers and
their code libraries, and numba's reference-count functions ``NRT_incref`` /
``NRT_decref``; then it runs the case to ``END`` seconds (no frames) and prints the loop
time. Sizes are the distance to the next known address, so a function's own samples and
those of callees LLVM inlined into it are counted together.
"""

from __future__ import annotations

import gc
import os
import sys

from numba.core.registry import CPUDispatcher
from numba.core.runtime import nrt

from spinweb_fe.case import load
from spinweb_fe.case.scene import prepare
from spinweb_fe.run.features import features_of
from spinweb_fe.run.loop import Schedule, simulate, time_steps


def jit_symbols():
    """[(address, name)] of every compiled overload and of NRT_incref / NRT_decref."""
    syms = []
    for obj in gc.get_objects():
        if isinstance(obj, CPUDispatcher):
            for cres in obj.overloads.values():
                try:
                    addr = cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)
                except Exception:  # noqa: BLE001 - an overload without a native entry
                    continue
                if addr:
                    syms.append((addr, obj.py_func.__name__))
    lib = nrt.rtsys._library
    syms += [(lib.get_pointer_to_function(n), n) for n in ("NRT_incref", "NRT_decref")]
    return sorted(syms)


def write_map(syms, path):
    with open(path, "w") as f:
        for k, (addr, name) in enumerate(syms):
            size = min(syms[k + 1][0] - addr if k + 1 < len(syms) else 4096, 1 << 20)
            f.write(f"{addr:x} {size:x} {name}\n")


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 2:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    case = load(args[0], [f"time.end={args[1]}", "output.frame_dt=0", *args[2:]])
    _, model, control, state, dt = prepare(case)
    features = features_of(model, state, case)
    time_steps(model, control, state, dt, 1, 22, 100, features)  # compile or load the loop
    write_map(jit_symbols(), f"/tmp/perf-{os.getpid()}.map")
    res = simulate(model, control, state, dt, Schedule(case.time.end, case.output.history_dt),
                   features=features)
    print(f"loop {res.loop_s:.3f} s, {res.steps} steps")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
