"""The size of a run before it starts, and the budget it must fit (docs/robustness.md).

Before anything is written, :func:`estimate` gives the run's nodes, elements, steps,
element-updates (elements x steps), wall time at this machine's rate (measured on the
case's own model, a few milliseconds of steps), memory, output bytes and frames;
:func:`check_budget` refuses (InputError, exit code 2) a run beyond

- a day of wall time (``WALL_BUDGET_S``),
- ``MEMORY_FRACTION`` = 80 % of the machine's memory (or of the container's limit),
- the free space of the disk that holds the result folder,
- the file-size limit (``ulimit -f``) for results.h5,

unless it is forced (``spinweb run --force``).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import NamedTuple

from spinweb_fe.errors import InputError
from spinweb_fe.io.results import CHUNK_VALUES
from spinweb_fe.io.space import MARGIN, RESERVE, fmt_bytes, free_bytes, size_limit
from spinweb_fe.run.loop import time_steps

WALL_BUDGET_S = 86400.0     # a day
MEMORY_FRACTION = 0.8
MEMORY_BASE = 200 * 2 ** 20  # [bytes] the interpreter, numpy, numba, h5py
MEMORY_PER_ELEMENT = 700     # [bytes] set-up peak per element (measured: 600 for tethers)
VTU_FACTOR = 0.6             # compressed VTU size / (80 n + 42 m) bytes (measured: 0.2-0.4)
CALIBRATION_UPDATES = 1e6    # element-updates of the timed steps (about 10 ms)
FORCE_HINT = "--force runs it anyway"


class Estimate(NamedTuple):
    """What a run will cost. Sizes in bytes, times in seconds."""

    nodes: int
    elements: int
    steps: int              # steps still to run
    element_updates: float  # elements x steps
    rate: float             # measured element-updates/s (nan: not measured)
    wall_s: float           # element_updates / rate
    memory: float
    output: float           # results.h5, frames and checkpoint
    rows: int
    frames: int
    results_h5: float = 0.0  # the part of ``output`` in results.h5 (the largest file)

    def lines(self, threads) -> list:
        """Two log lines: the size, and the cost."""
        speed = ("" if not math.isfinite(self.wall_s) else
                 f", about {fmt_duration(self.wall_s)} at {self.rate:.3g} element-updates/s "
                 f"(measured here, {threads} thread{'s' if threads > 1 else ''})")
        return [f"size: {self.nodes} nodes, {self.elements} elements, {self.steps} steps, "
                f"{self.element_updates:.3g} element-updates{speed}",
                f"estimate: memory about {fmt_bytes(self.memory)}, output about "
                f"{fmt_bytes(self.output)} ({self.rows} history rows, {self.frames} frames)"]


def fmt_duration(s) -> str:
    """Seconds as '0.52 s', '3.1 min', '5.2 h' or '20 days'."""
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= size:
            v = s / size
            return "1 day" if unit == "days" and f"{v:.3g}" == "1" else f"{v:.3g} {unit}"
    return f"{s:.2g} s"


def machine_memory() -> int:
    """Bytes of memory of this machine, or the container's limit if that is lower."""
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(path).read_text().strip()
        except OSError:
            continue
        if text.isdigit():
            total = min(total, int(text))
    return total


def case_elements(case) -> float:
    """About the number of cable elements of a case, before its mesh is built."""
    if case.scene == "web":
        w = case.web
        n = w.side / w.mesh_width
        return 2.0 * n * (n + 1.0) * w.elements_per_segment
    return float(case.tethers.count) * case.tethers.elements


def memory_bytes(elements) -> float:
    return MEMORY_BASE + MEMORY_PER_ELEMENT * float(elements)


def check_memory(case, force=False):
    """Before the mesh is built: refuse a case whose set-up would not fit in memory."""
    _check_memory(case, memory_bytes(case_elements(case)), case_elements(case), force)


def _check_memory(case, need, elements, force):
    limit = MEMORY_FRACTION * machine_memory()
    if need > limit and not force:
        raise InputError(case.source, "", f"the run needs about {fmt_bytes(need)} of memory "
                         f"({elements:.3g} elements), more than "
                         f"{100 * MEMORY_FRACTION:.0f} % of this machine's "
                         f"{fmt_bytes(limit / MEMORY_FRACTION)} ({FORCE_HINT})")


def measure_rate(model, control, state, dt, threads, rec_every, features=None) -> tuple:
    """(element-updates/s of this model's step loop with the run's ``features`` (None: the
    model's) on this machine, the seconds it took to compile the loop or load it from the
    cache)."""
    nsteps = int(max(1, min(CALIBRATION_UPDATES // max(model.n_elems, 1), 256 * rec_every)))
    compile_s, seconds, ran = time_steps(model, control, state, dt, threads, rec_every,
                                         nsteps, features)
    return model.n_elems * max(ran, 1) / max(seconds, 1e-9), compile_s


def estimate(case, model, dt, step0=0, rate=math.nan, checkpoint=False) -> Estimate:
    """The run's size and cost (see the module docstring); ``step0``: a restart's first step."""
    t_end, out = case.time.end, case.output
    n_total = int(math.ceil(t_end / dt - 1e-9))
    steps = n_total - step0
    n, m, arms = model.n_nodes, model.n_elems, model.mesh.n_arms
    updates = float(m) * steps
    rec_every = max(1, round(out.history_dt / dt))
    rows = -(-steps // rec_every) + 1
    frame_every = max(1, round(out.frame_dt / dt)) if out.frame_dt > 0 else 0
    frames = steps // frame_every + 1 if frame_every else 0
    per_row = 17 + 9 * arms  # scalar columns and the per-arm ones
    history = 8.0 * per_row * (rows + 1024)  # and the last chunk of every column
    frame = 8.0 * (3 * n + 2 * m + 1) + VTU_FACTOR * (80 * n + 42 * m) + 100
    if frames:  # the last chunk of /frames/position and /frames/tension, allocated whole
        frame_chunks = 2 * 8.0 * max(CHUNK_VALUES, 3 * n, m)
    mesh = 8.0 * (10 * n + 3 * m) + 2048 * (per_row + 8)  # and the datasets' headers
    ckpt = 2 * 8.0 * 10 * n if checkpoint else 0.0
    output = history + frames * frame + (frame_chunks if frames else 0.0) + mesh + ckpt
    h5 = output - ckpt - frames * (VTU_FACTOR * (80 * n + 42 * m) + 100)
    return Estimate(n, m, steps, updates, rate, updates / rate if rate > 0 else math.nan,
                    memory_bytes(m), output, rows, frames, h5)


def check_budget(case, est: Estimate, folder, force=False):
    """Refuse (InputError) a run beyond the budget of the module docstring, unless forced."""
    if force:
        return
    if math.isfinite(est.wall_s) and est.wall_s > WALL_BUDGET_S:
        raise InputError(case.source, "", f"the run needs {est.element_updates:.3g} "
                         f"element-updates ({est.steps} steps of {est.elements} elements), "
                         f"about {fmt_duration(est.wall_s)} at this machine's "
                         f"{est.rate:.3g} element-updates/s, more than the budget of "
                         f"{fmt_duration(WALL_BUDGET_S)} (a coarser mesh, a larger time.dt or "
                         f"a shorter time.end; {FORCE_HINT})")
    _check_memory(case, est.memory, est.elements, force)
    limit = size_limit()
    if est.results_h5 + MARGIN + RESERVE > limit:
        raise InputError(folder, "", f"the run writes about {fmt_bytes(est.results_h5)} into "
                         f"results.h5 ({est.rows} history rows, {est.frames} frames), more "
                         f"than the file-size limit (ulimit -f) of {fmt_bytes(limit)} less "
                         f"{fmt_bytes(MARGIN + RESERVE)} for its last flush (a larger "
                         f"output.history_dt or output.frame_dt; {FORCE_HINT}, and stops at "
                         "the limit)")
    free = free_bytes(folder)
    if est.output > free:
        raise InputError(folder, "", f"the run writes about {fmt_bytes(est.output)} "
                         f"({est.rows} history rows, {est.frames} frames), more than the "
                         f"{fmt_bytes(free)} free there (a larger output.frame_dt, another "
                         f"folder; {FORCE_HINT})")
