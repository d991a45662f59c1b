"""Monte-Carlo members of a sweep: the ``[random]`` table's distributions, drawn member by
member (docs/sweep.md), and the pass rate of their verdicts with its confidence interval.

A sweep file with ``members = N`` (and ``seed``) runs every run of its grid and lists N
times, member m with the keys of ``[random]`` drawn from ``numpy.random.default_rng((seed,
m))``, one key after the other in the order written: member m draws the same values
whatever N is and whatever the other members drew, so one member can be run again alone
(``spinweb sweep FILE --only NAME``).

Distributions (values in the case's SI units)::

    [random]
    "tip_mass.mass" = {dist = "normal", mean = 10.0, std = 0.5}          # optional low, high
    "perturbation.delay" = {dist = "uniform", low = 0.0, high = 0.02}
    "perturbation.arm" = {dist = "choice", values = [0, 1, 2, 3]}
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spinweb_fe.case.text import show
from spinweb_fe.errors import InputError

#: distribution name -> (required parameters, optional parameters)
DISTRIBUTIONS = {"normal": (("mean", "std"), ("low", "high")),
                 "uniform": (("low", "high"), ()),
                 "choice": (("values",), ())}
#: the confidence of the pass rate's interval
CONFIDENCE = 0.95
MAX_MEMBERS = 100_000
MAX_SEED = 2 ** 63  # summary.h5 stores the seed as a 64-bit integer


@dataclass(frozen=True)
class Draw:
    """One key's distribution."""

    key: str
    dist: str
    params: dict

    def sample(self, rng):
        p = self.params
        if self.dist == "uniform":
            return float(rng.uniform(p["low"], p["high"]))
        if self.dist == "choice":
            return p["values"][int(rng.integers(len(p["values"])))]
        x = float(rng.normal(p["mean"], p["std"]))
        return min(max(x, p.get("low", -math.inf)), p.get("high", math.inf))

    def describe(self) -> str:
        p = self.params
        if self.dist == "normal":
            clip = "".join(f", {k} {p[k]:g}" for k in ("low", "high") if k in p)
            return f"normal({p['mean']:g}, {p['std']:g}{clip})"
        if self.dist == "uniform":
            return f"uniform({p['low']:g}, {p['high']:g})"
        return f"choice({p['values']})"


def _number(v):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:  # an integer beyond the floats
        return False


def flatten_random(table: dict, prefix: str = "") -> dict:
    """Nested [random] tables -> {dotted key: its distribution table} (a table with a
    ``dist`` key is a distribution, any other table a level of the key)."""
    out = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and "dist" not in v:
            out.update(flatten_random(v, key + "."))
        else:
            out[key] = v
    return out


def parse(src, doc: dict) -> tuple:
    """(members, seed, (Draw, ...)) of a sweep file's ``members``, ``seed`` and
    ``[random]`` (members 0 and no draws without them).

    Raises
    ------
    InputError
        ``[random]`` without ``members`` or the reverse, an unknown distribution, a missing
        or unknown parameter, a negative standard deviation, low >= high, an empty choice.
    """
    table = doc.get("random", {})
    if not isinstance(table, dict):
        raise InputError(src, "random", "must be a table [random]")
    members = doc.get("members")
    if members is None:
        if table:
            raise InputError(src, "members", "missing: [random] draws each of `members` runs "
                             "(e.g. members = 32)")
        return 0, 0, ()
    if isinstance(members, bool) or not isinstance(members, int) or not \
            1 <= members <= MAX_MEMBERS:
        raise InputError(src, "members", f"must be an integer from 1 to {MAX_MEMBERS}, "
                         f"got {members!r}")
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < MAX_SEED:
        shown = f"an integer of {len(str(seed))} digits" if isinstance(seed, int) and \
            abs(seed) >= 10 ** 24 else repr(seed)
        raise InputError(src, "seed", f"must be an integer from 0 to 2^63 - 1 (it is "
                         f"stored as a 64-bit integer), got {shown}")
    if not table:
        raise InputError(src, "random", "missing: the keys the members draw (e.g. "
                         "\"tip_mass.mass\" = {dist = \"normal\", mean = 10.0, std = 0.5})")
    draws = []
    for key, spec in flatten_random(table).items():
        where = f"random.{key}"
        if not isinstance(spec, dict):
            raise InputError(src, where, "must be a distribution table such as {dist = "
                             "\"uniform\", low = 0.0, high = 1.0}")
        dist = spec.get("dist")
        if dist not in DISTRIBUTIONS:
            raise InputError(src, f"{where}.dist", f"unknown distribution {dist!r} (valid: "
                             f"{', '.join(DISTRIBUTIONS)})")
        need, optional = DISTRIBUTIONS[dist]
        params = {k: v for k, v in spec.items() if k != "dist"}
        for k in params:
            if k not in need + optional:
                raise InputError(src, f"{where}.{k}", f"not a parameter of {dist} (valid: "
                                 f"{', '.join(need + optional)})")
        for k in need:
            if k not in params:
                raise InputError(src, f"{where}.{k}", f"missing: {dist} needs "
                                 f"{', '.join(need)}")
        if dist == "choice":
            if not isinstance(params["values"], list) or not params["values"]:
                raise InputError(src, f"{where}.values", "must be a non-empty list")
        else:
            for k, v in params.items():
                if not _number(v):
                    raise InputError(src, f"{where}.{k}", f"must be a finite number, got "
                                     f"{show(v)}")
            if dist == "normal" and params["std"] < 0:
                raise InputError(src, f"{where}.std", f"must be >= 0, got {params['std']}")
            low, high = params.get("low", -math.inf), params.get("high", math.inf)
            if not low < high:
                raise InputError(src, f"{where}.low", f"must be below high, got low "
                                 f"{low} and high {high}")
        draws.append(Draw(key, dist, params))
    return members, seed, tuple(draws)


def member_values(draws, seed: int, member: int) -> dict:
    """{key: value} of member ``member``: its own generator (seed, member)."""
    rng = np.random.default_rng((seed, member))
    return {d.key: d.sample(rng) for d in draws}


def wilson(passes: int, n: int, confidence: float = CONFIDENCE) -> tuple:
    """(low, high) Wilson score interval of a pass rate passes / n (n = 0: (0, 1)); it
    keeps inside [0, 1] and stays meaningful at 0 and n passes, where the normal
    approximation's interval collapses to a point (scipy.stats.binomtest's
    proportion_ci, method 'wilson')."""
    if n == 0:
        return 0.0, 1.0
    from scipy.stats import binomtest

    ci = binomtest(passes, n).proportion_ci(confidence, method="wilson")
    return max(0.0, float(ci.low)), min(1.0, float(ci.high))
