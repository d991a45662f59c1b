"""What a sweep may ask of the machine: its number of runs and of worker processes, checked
before anything runs (docs/sweep.md, docs/robustness.md "Sweeps").

- **Runs.** The sweep's process keeps every run's case and row, and Dask's scheduler and
  client a task and a future for each: measured 27 KB per run (4 KB of the sweep's records
  for a 1000-run grid of the demo, 23 KB of Dask's, RSS over 3000 tasks), counted as
  :data:`RUN_BYTES`. A sweep whose runs would take more than :data:`RUN_SHARE` of the
  machine's memory is refused (the workers need the rest); a 1e9-run grid ended in a
  MemoryError after minutes, a 1e6-run grid was accepted.
- **Workers.** Each worker process holds a run: :func:`spinweb_fe.run.estimate.memory_bytes`
  of the largest run's elements (200 MB of interpreter and libraries and 700 B per element)
  and Dask's own :data:`WORKER_EXTRA` (an idle worker with spinweb imported measured 177 MB
  of RSS). More workers than fit in :data:`spinweb_fe.run.estimate.MEMORY_FRACTION` of the
  memory are refused; ``--workers 10000`` started 178 processes and took 9 GB before it was
  stopped.

Both are refused in one line with the numbers (InputError, exit 2); ``--force`` starts the
sweep anyway.
"""

from __future__ import annotations

import math
import os

from spinweb_fe.errors import InputError
from spinweb_fe.io.space import fmt_bytes
from spinweb_fe.run.estimate import MEMORY_FRACTION, machine_memory, memory_bytes

RUN_BYTES = 32 * 1024  # [bytes] a run's records in the sweep's process (measured 27 KB)
RUN_SHARE = 0.25  # of the memory, for the sweep's own records (the workers have the rest)
WORKER_EXTRA = 32 * 2 ** 20  # [bytes] Dask's part of a worker process, beyond a run
FORCE = "--force starts it anyway"


def count_runs(entries: int, grid_sizes, members: int) -> int:
    """Runs of a sweep: its [[runs]] entries times the grid's points times its members (a
    Python integer: no overflow, nothing built)."""
    return entries * math.prod(grid_sizes) * max(members, 1)


def check_runs(n: int, source, force: bool = False, memory: float | None = None) -> None:
    """Refuse (InputError naming the numbers) a sweep of more runs than fit in RUN_SHARE of
    the memory, unless forced."""
    memory = machine_memory() if memory is None else memory
    most = int(RUN_SHARE * memory // RUN_BYTES)
    if n > most and not force:
        raise InputError(source, "grid", f"{n:,} runs, more than this machine can keep "
                         f"track of: about {most:,} runs of {fmt_bytes(RUN_BYTES)} each fit "
                         f"in {100 * RUN_SHARE:.0f} % of its {fmt_bytes(memory)} (fewer grid "
                         f"values or members, or several sweeps; {FORCE})")


def worker_bytes(elements: float) -> float:
    """About the memory of one worker running a case of ``elements`` cable elements."""
    return memory_bytes(elements) + WORKER_EXTRA


def check_workers(workers: int, elements: float, force: bool = False,
                  memory: float | None = None) -> None:
    """Refuse (InputError naming the numbers) more worker processes than fit in
    MEMORY_FRACTION of the memory, each running the sweep's largest case, unless forced."""
    memory = machine_memory() if memory is None else memory
    each = worker_bytes(elements)
    most = max(1, int(MEMORY_FRACTION * memory // each))
    if workers > most and not force:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
            else os.cpu_count()
        raise InputError("--workers", "", f"{workers} worker processes of about "
                         f"{fmt_bytes(each)} each ({elements:.3g} elements) need "
                         f"{fmt_bytes(workers * each)}, more than "
                         f"{100 * MEMORY_FRACTION:.0f} % of this machine's "
                         f"{fmt_bytes(memory)}: at most {most} (it has {cores} cores; "
                         f"{FORCE})")
