"""Payout devices: how a held coil lets its arm's line out (``[stowage] payout``), one
registry entry each.

- ``free``: the front level goes when the free part pulls it off the hub (fe.coil);
- ``rate``: as free, but the paid-out length never exceeds a law L(t) (``payout_rate`` or
  ``payout_length``).
"""

from __future__ import annotations

import numpy as np

from spinweb_fe.fe.choice import Choice, Param, registry

#: the last time of a payout_rate law's table [s]: L(t) = rate t up to here
RATE_HORIZON = 1e9


def rate_table(rate: float):
    """The paid-out length table of a constant payout rate [m/s]: L(t) = rate t."""
    return np.array([0.0, RATE_HORIZON]), np.array([0.0, rate * RATE_HORIZON])


def payout_table(st: dict):
    """((P,) times [s], (P,) paid-out lengths [m]) of a [stowage] table's law (resolved
    values), or None when its device has none."""
    if st.get("payout_rate") is not None:
        return rate_table(st["payout_rate"])
    if st.get("payout_length") is not None:
        times, lengths = zip(*st["payout_length"])
        return np.array(times, np.float64), np.array(lengths, np.float64)
    return None


def _table_rule(key, increasing, what):
    def check(tables):
        table = tables["stowage"].get(key)
        if table is None:
            return None
        times, values = zip(*table)
        if any(b <= a for a, b in zip(times, times[1:])) or times[0] < 0:
            return f"stowage.{key}", f"the times must be >= 0 and increase, got {list(times)} s"
        if increasing and (any(b < a for a, b in zip(values, values[1:])) or values[0] < 0):
            return f"stowage.{key}", (f"the {what} must be >= 0 and never decrease, got "
                                      f"{list(values)} m")
        return None
    return check


def _held(name, rule):
    def check(tables):
        if tables["stowage"]["coil"] != "held":
            return "stowage.payout", f"a {name} payout needs stowage.coil = 'held'"
        return rule(tables)
    return check


PAYOUTS = registry(
    Choice("free", 0, "the front advances when the free part pulls it off the hub",
           analytic="the coiled regime: the arm leaves the hub tangentially"),
    Choice("rate", 1, "as free, but never ahead of a prescribed paid-out length "
                      "(payout_rate or payout_length)",
           keys=(Param("payout_rate", "m/s", "pos", "payout = rate: paid-out length rate t"),
                 Param("payout_length", "s, m", None, "payout = rate: [[t, L], ...] paid-out "
                       "length L at time t, linear between the points", kind="table")),
           need=(("payout_rate", "payout_length"),),
           check=_held("rate", _table_rule("payout_length", True, "lengths")),
           analytic="the paying regime: the arm hangs from its departure point, which the "
                    "law moves back along the coil"),
)
