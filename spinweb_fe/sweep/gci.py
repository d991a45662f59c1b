"""Grid convergence numerics: observed order, Richardson extrapolation and Roache's grid
convergence index (GCI) from solutions on three or more meshes (docs/converge.md).

The procedure is Celik et al. (2008), "Procedure for estimation and reporting of
uncertainty due to discretization in CFD applications", ASME J. Fluids Eng. 130(7) 078001,
with grid 1 the finest: h1 < h2 < h3, r21 = h2/h1, r32 = h3/h2 (unequal ratios allowed),
eps21 = phi2 - phi1, eps32 = phi3 - phi2, s = sign(eps32/eps21), and the observed order p
the fixed point of

    p = |ln|eps32/eps21| + q(p)| / ln r21,   q(p) = ln((r21^p - s) / (r32^p - s)),

phi_ext = (r21^p phi1 - phi2) / (r21^p - 1), GCI_fine = Fs |eps21 / phi1| / (r21^p - 1) with
the safety factor Fs = 1.25 of a three-grid study.

Classification (Stern et al.'s convergence ratio R = eps21/eps32): R < 0 oscillatory, no
order; 0 < R and a positive order exists monotone; otherwise divergent (the differences do
not shrink). Where there is no order the answer is a range, the values' spread, not an
extrapolation: a solution that has not settled into its asymptotic range has no error bar
that Richardson's model could give.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: Roache's safety factor for a study of three or more grids with an observed order
SAFETY = 1.25
#: the fixed-point iteration's tolerance on p and its iteration cap
P_TOL, P_ITER = 1e-12, 500
#: values that differ by less than this share of their size are equal (round-off)
ROUNDOFF = 1e-10
#: observed orders outside this range get a note: below it the differences barely shrink
#: and the extrapolation reaches far; above it (the scheme is at most second order) they
#: shrink by a coincidence of the three values more likely than by the asymptotic law
ORDER_RANGE = (0.5, 3.0)
#: kinds of convergence
KINDS = ("monotone", "oscillatory", "divergent", "equal", "incomplete")


@dataclass(frozen=True)
class Estimate:
    """The discretisation error of one quantity from its three finest grids.

    ``h`` and ``phi`` (all grids, finest first) are the inputs; ``used`` the indices of the
    three grids of the estimate. ``error_bar`` (per grid, the quantity's units; NaN on the
    grids outside the estimate): monotone, Fs |phi_k - phi_ext| (the finest grid's is
    GCI_fine |phi1|, the next Roache's coarse-grid GCI); without an order, the spread
    max - min of the three values (a range, not a bound). ``low``, ``high``: the finest
    value's band (monotone phi1 -+ its error bar; otherwise the three values' range).
    """

    h: tuple
    phi: tuple
    kind: str
    used: tuple = ()
    order: float = math.nan
    extrapolated: float = math.nan
    gci_fine: float = math.nan  # relative to |phi1|
    approx_error: float = math.nan  # e_a21 = |eps21 / phi1|
    extrap_error: float = math.nan  # e_ext21 = |(phi_ext - phi1) / phi_ext|
    ratios: tuple = ()
    low: float = math.nan
    high: float = math.nan
    error_bar: tuple = ()
    safety: float = SAFETY
    triples: tuple = field(default=())  # (h1, order or nan, kind) of each consecutive triple
    note: str = ""

    def as_dict(self) -> dict:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["triples"] = [list(t) for t in self.triples]
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in out.items()}


def _q(p, r21, r32, s):
    return math.log((r21 ** p - s) / (r32 ** p - s))


def _g(p, r21, r32):
    """eps32/eps21 of phi = phi_ext + C h^p on the three grids (monotone: s = 1)."""
    return r21 ** p * (r32 ** p - 1.0) / (r21 ** p - 1.0)


def observed_order(r21: float, r32: float, eps21: float, eps32: float) -> float:
    """Observed order p of a monotone triple (Celik et al. 2008, Eqs. 3a-3c), by the
    fixed-point iteration started at q = 0; a bisection on eps32/eps21 = g(p) if the
    iteration does not settle. NaN when no positive order fits (divergent)."""
    ratio = eps32 / eps21
    if not ratio > 0:
        return math.nan
    if ratio <= math.log(r32) / math.log(r21):  # g(0+): the differences do not shrink
        return math.nan
    s = 1.0
    p = abs(math.log(ratio)) / math.log(r21)
    for _ in range(P_ITER):
        try:
            new = abs(math.log(ratio) + _q(p, r21, r32, s)) / math.log(r21)
        except (ValueError, ZeroDivisionError, OverflowError):
            break
        if abs(new - p) <= P_TOL * max(1.0, p):
            return new
        p = new
    lo, hi = 1e-9, 1.0  # bisection: g grows with p from g(0+) = ln r32 / ln r21
    while _g(hi, r21, r32) < ratio and hi < 1e3:
        lo, hi = hi, 2.0 * hi
    if _g(hi, r21, r32) < ratio:
        return math.inf
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _g(mid, r21, r32) < ratio else (lo, mid)
    return 0.5 * (lo + hi)


def triple(h, phi, safety: float = SAFETY) -> Estimate:
    """The estimate of three grids (any order; sorted finest first).

    Parameters
    ----------
    h : (3,) [m]
        Representative mesh sizes (here the mesh width, or the tether's element length).
    phi : (3,)
        The quantity on each grid (its own units).
    safety : float
        Roache's factor of safety Fs (1.25 for three grids with an observed order).
    """
    order = np.argsort(np.asarray(h, float))
    h = tuple(float(h[i]) for i in order)
    phi = tuple(float(phi[i]) for i in order)
    return _estimate(h, phi, (0, 1, 2), safety)


def _on(used, n, bar) -> tuple:
    """Error bars on the grids of the estimate, NaN on the others (not estimated)."""
    return tuple(bar(k) if k in used else math.nan for k in range(n))


def _estimate(h, phi, used, safety) -> Estimate:
    (h1, h2, h3), (f1, f2, f3) = (h[i] for i in used), (phi[i] for i in used)
    r21, r32 = h2 / h1, h3 / h2
    base = dict(h=h, phi=phi, used=used, ratios=(r21, r32), safety=safety)
    if not all(map(math.isfinite, (f1, f2, f3))):
        return Estimate(kind="incomplete", error_bar=(math.nan,) * len(h),
                        note="a value is missing (a run failed, or the event never happens)",
                        **base)
    e21, e32 = f2 - f1, f3 - f2
    lo, hi = min(f1, f2, f3), max(f1, f2, f3)
    if hi - lo <= ROUNDOFF * max(abs(lo), abs(hi)):
        return Estimate(kind="equal", extrapolated=f1, gci_fine=0.0, low=lo, high=hi,
                        error_bar=_on(used, len(h), lambda k: hi - lo),
                        note="the same value on every grid (to round-off)", **base)
    kind, p = "divergent", math.nan
    if e21 * e32 < 0.0:
        kind = "oscillatory"
    elif e21 != 0.0:
        p = observed_order(r21, r32, e21, e32)
        kind = "monotone" if math.isfinite(p) and p > 0 else "divergent"
    if kind != "monotone":
        spread = hi - lo
        note = ("the values alternate with refinement: no order, their range" if
                kind == "oscillatory" else "the differences do not shrink with refinement: "
                "no order, their range")
        return Estimate(kind=kind, low=lo, high=hi, error_bar=_on(used, len(h),
                                                                   lambda k: spread),
                        note=note, **base)
    rp = r21 ** p
    ext = (rp * f1 - f2) / (rp - 1.0)
    ea = abs(e21 / f1) if f1 != 0 else math.inf
    eext = abs((ext - f1) / ext) if ext != 0 else math.inf
    bars = _on(used, len(h), lambda k: safety * abs(phi[k] - ext))
    u1 = safety * abs(e21) / (rp - 1.0)
    note = ""
    if p < ORDER_RANGE[0]:
        note = (f"order {p:.2g} below {ORDER_RANGE[0]}: the differences barely shrink, the "
                "extrapolation is not reliable (not in the asymptotic range)")
    elif p > ORDER_RANGE[1]:
        note = (f"order {p:.2g} above {ORDER_RANGE[1]} (the scheme is at most second order): "
                "the agreement of the finer grids may be a coincidence")
    return Estimate(kind="monotone", order=p, extrapolated=ext,
                    gci_fine=u1 / abs(f1) if f1 != 0 else math.inf, approx_error=ea,
                    extrap_error=eext, low=f1 - u1, high=f1 + u1, error_bar=bars, note=note,
                    **base)


def study(h, phi, safety: float = SAFETY) -> Estimate:
    """The estimate of a study of three or more grids: from its three finest grids with a
    value, with the order of every consecutive triple in ``triples`` (does p settle?).

    Parameters
    ----------
    h : (n,) [m], n >= 3
        Mesh sizes, any order.
    phi : (n,)
        The quantity on each grid (NaN: the run failed or the event never happened).
    """
    if len(h) != len(phi) or len(h) < 3:
        raise ValueError(f"a grid study needs three or more grids, got {len(h)}")
    order = np.argsort(np.asarray(h, float))
    h = tuple(float(h[i]) for i in order)
    phi = tuple(float(phi[i]) for i in order)
    have = [i for i in range(len(h)) if math.isfinite(phi[i])]
    used = tuple(have[:3]) if len(have) >= 3 else (0, 1, 2)
    est = _estimate(h, phi, used, safety)
    triples = []
    for k in range(len(h) - 2):
        t = _estimate(h, phi, (k, k + 1, k + 2), safety)
        triples.append((h[k], t.order, t.kind))
    return Estimate(**{**est.__dict__, "triples": tuple(triples)})


def stable_from(h, verdicts) -> float:
    """The coarsest mesh size from which on every finer grid gives the same verdict as the
    finest (NaN when the finest has none).

    Parameters
    ----------
    h : (n,) [m]
    verdicts : (n,) of bool or None
        A criterion's pass / fail on each grid (None: it does not apply, or the run failed).
    """
    order = np.argsort(np.asarray(h, float))
    hs = [float(h[i]) for i in order]
    vs = [verdicts[i] for i in order]
    if vs[0] is None:
        return math.nan
    coarsest = hs[0]
    for hk, v in zip(hs, vs):
        if v != vs[0]:
            break
        coarsest = hk
    return coarsest
