"""Continue a run from its checkpoint (``spinweb run --restart DIR``)."""

from __future__ import annotations

import copy
from pathlib import Path

from spinweb_fe import case as case_mod
from spinweb_fe.case.text import parse_toml
from spinweb_fe.errors import InputError
from spinweb_fe.io.checkpoint import (CHECKPOINT_NAME, check_results_for_restart,
                                      check_run_entries, read_checkpoint)
from spinweb_fe.io.folder import Aside, FolderLock, aside_state, busy, check_entries, holder
from spinweb_fe.run.driver import run_case

#: keys that a restart may change (everything else would break bit-identical continuation)
RESTART_KEYS = {"time.end", "title"}


def _flat(d):
    """{'a': {'b': 1}} -> {'a.b': 1} (case dicts have two levels)."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update({f"{k}.{kk}": vv for kk, vv in v.items()})
        else:
            out[k] = v
    return out


def restart_case(out_dir, sets=(), progress=True, checkpoint_dt=None, threads=None,
                 force=False):
    """Continue the run in ``out_dir`` from ``out_dir/checkpoint.h5``.

    ``results.h5`` is cut back to the checkpoint's history rows and frames, and the run
    continues from the stored state (already started: no second half-step shift), so the
    histories equal those of an uninterrupted run bit for bit.

    Parameters
    ----------
    out_dir : str or Path
        Folder of the interrupted run.
    sets : iterable of str
        ``key=value`` overrides; only ``time.end`` (and ``title``) may change.
    checkpoint_dt : float or None [s]
        Checkpoint interval of the continued run (None: the checkpoint's).
    threads : int or None
        Threads of the continued run (None: the checkpoint's; another count continues
        correctly but not bit-identically).
    force : bool
        Run even if the estimate exceeds the budget.

    Returns
    -------
    spinweb_fe.run.loop.RunResult
        The continued part of the run.
    """
    out_dir = Path(out_dir)
    if (info := holder(out_dir)) is not None:
        raise busy(out_dir, info)
    check_entries(out_dir)  # a lock and a .previous that spinweb can use, or one line
    if aside_state(out_dir)[0] != "missing":  # a run killed before its first rows: undo it
        with FolderLock(out_dir):
            Aside.recover(out_dir)
    check_run_entries(out_dir)
    ck = read_checkpoint(out_dir / CHECKPOINT_NAME)
    stored = parse_toml(ck.case_toml, out_dir / CHECKPOINT_NAME)
    raw = case_mod.apply_overrides(copy.deepcopy(stored), sets)
    case = case_mod.validate(raw, ck.case_source)
    before = _flat(case_mod.validate(stored, ck.case_source).to_dict())
    after = _flat(case.to_dict())
    changed = sorted(k for k in set(before) | set(after)
                     if before.get(k) != after.get(k) and k not in RESTART_KEYS)
    if changed:
        raise InputError("--set", changed[0], "cannot change on --restart (only time.end can)")
    check_results_for_restart(out_dir, ck)
    dt_ck = ck.checkpoint_dt if checkpoint_dt is None else checkpoint_dt
    return run_case(case, out_dir, progress=progress, checkpoint_dt=dt_ck, resume=ck,
                    threads=threads, force=force)
