"""The profile of the crossing audit's and the cable contact's passes (issue #42): the cycle
counter's ticks the step loop added per pass (fe.contact.clock) in seconds, and the counts
beside them.

The ticks become seconds at a rate measured over the run: the counter and
``time.perf_counter`` read together when the run starts (the feature's ``prepare``) and when
it is written (or :meth:`Profile.seconds` is asked), so that the rate is the counter's own,
whatever its nominal frequency. The counters carry on over the list's rebuilds, are no part
of a checkpoint (a restarted run's profile is of its own part of the run) and do not count
trial steps (record.feature ``trial``: copies).

In results.h5 (attributes of ``/crossings/profile``, docs/results.md): ``audit_<pass>_s``
and ``contact_<pass>_s`` [s], ``audit_<count>`` and ``contact_<count>`` [1], and
``ticks_per_s`` [1/s], the counter's measured rate.
"""

from __future__ import annotations

import time

import numpy as np

from spinweb_fe.fe.contact.clock import counter_now, interval_cost

#: a rate measured over less than this [s] is measured again over this long
SHORTEST = 0.05


class Profile:
    """The clock (ticks) and tally (counts) arrays a kernel adds to, named.

    Parameters
    ----------
    clocks, tallies : tuple of str
        The names of the slots (fe.contact.clock's AUDIT_CLOCK, AUDIT_TALLY or
        CONTACT_CLOCK, CONTACT_TALLY).
    """

    def __init__(self, clocks, tallies):
        self.clocks, self.tallies = tuple(clocks), tuple(tallies)
        self.clock = np.zeros(len(clocks), np.int64)
        self.tally = np.zeros(len(tallies), np.int64)
        self._t0 = None

    def start(self) -> None:
        """The rate's first reading (the first call only: a run's later calls go on)."""
        if self._t0 is None:
            self._t0 = (time.perf_counter(), int(counter_now()))

    def rate(self) -> float:
        """The counter's ticks per second [1/s], from :meth:`start` to now."""
        if self._t0 is None or time.perf_counter() - self._t0[0] < SHORTEST:
            self._t0 = (time.perf_counter(), int(counter_now()))
            while time.perf_counter() - self._t0[0] < SHORTEST:
                pass
        t1, c1 = time.perf_counter(), int(counter_now())
        return (c1 - self._t0[1]) / (t1 - self._t0[0])

    def seconds(self) -> dict:
        """Each pass's seconds [s] (``<name>_s``), each count (``<name>``), the rate
        (``ticks_per_s``) and the ticks an empty timed interval costs (``interval_ticks``:
        the sampled intervals carry it besides their work)."""
        rate = self.rate()
        out = {f"{name}_s": float(v) / rate for name, v in zip(self.clocks, self.clock)}
        out.update({name: int(v) for name, v in zip(self.tallies, self.tally)})
        out["ticks_per_s"] = rate
        out["interval_ticks"] = int(interval_cost(1000))
        return out

    def write(self, group, prefix: str) -> None:
        """:meth:`seconds` as attributes ``<prefix>_<name>`` of the h5 ``group``."""
        for name, v in self.seconds().items():
            key = name if name in ("ticks_per_s", "interval_ticks") else f"{prefix}_{name}"
            group.attrs[key] = v
        group.attrs["units"] = ("*_s: s (cycle-counter ticks at ticks_per_s [1/s]); the rest "
                                "counts over the run (fe.contact.clock, record.profile)")


#: (feature, pass, the count shown beside it) of :func:`report`'s lines
LINES = (("audit", "motion", "steps"), ("audit", "certificates", "pairs_read"),
         ("audit", "exact", "pairs_exact_branch"), ("audit", "wide", "wide_pairs"),
         ("contact", "near_selection", "near_pairs"),
         ("contact", "closest_points", "near_pairs"), ("contact", "push", "pairs_in_contact"),
         ("contact", "motion", "steps"), ("contact", "friction", "pairs_in_contact"),
         ("contact", "failsafe_round0", "round0_pairs_tested"),
         ("contact", "failsafe_rounds", "later_round_pairs_looked_at"),
         ("contact", "impact_zones", "impact_zone_calls"),
         ("contact", "reaction", "reactions"),
         ("contact", "after_reactions", "calls_after_reactions"))


def report(attrs) -> list:
    """One line per pass that took time (``spinweb info``): its seconds, per step, and the
    count beside it, from the attributes :meth:`Profile.write` wrote."""
    steps = {w: int(attrs.get(f"{w}_steps", 0)) for w in ("audit", "contact")}
    lines = []
    for which, name, count in LINES:
        sec = float(attrs.get(f"{which}_{name}_s", 0.0))
        if sec <= 0.0 or not steps[which]:
            continue
        lines.append(f"  {which} {name.replace('_', ' ')}: {sec:.4g} s "
                     f"({1e6 * sec / steps[which]:.4g} us/step; "
                     f"{count.replace('_', ' ')} {int(attrs[f'{which}_{count}'])})")
    return (["profile of the passes (cycle counter, over the loop's steps):"] + lines
            if lines else [])
