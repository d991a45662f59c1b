"""Prestressability of a flat web by spin: the force method (Pellegrino & Calladine).

For a pin-jointed web in its flat, deployed shape the in-plane equilibrium equations of
the free nodes read ``A t = f`` with ``A`` (dof x b) the equilibrium matrix, ``t`` (b,)
the bar tensions [N] and ``f`` the nodal loads [N]. The singular value decomposition of
``A`` gives its rank r, s = b - r independent states of self-stress (the null space of
``A``) and m = dof - r inextensional mechanisms (the null space of ``A^T``).

The spin load is the centrifugal force ``f_i = m_i omega^2 r_i`` (lumped cable mass plus
point masses, about the hub axis at the origin). The web carries it in its flat shape
only if ``f`` has no component on the mechanisms (relative residual ``||A t0 - f|| / ||f||``
of the least-squares particular solution ``t0 = A^+ f`` is zero); otherwise the web must
change shape ("distort") before it can carry the load. Among all the equilibrium tensions
``t = t0 + S alpha`` (S: self-stress basis) the linear programme

    maximise  tau  subject to  A t = A t0,  t >= tau,  |t| <= cap max|t0|

(scipy's HiGHS) finds the combination with the largest minimum tension. The web is
prestressable by spin if the load is compatible and that minimum is positive. Such a
combination needs tailored rest lengths; the report also gives the elastic solution of a
web cut stress-free to its flat shape (compatibility ``S^T F t = 0``, F = diag(L/EA)) and
the band of spin rates over which the tailored web stays taut.

Supports: if the mesh has at least two ``hub_tied`` nodes they are fixed (a rigid hub: a
rigid body takes any self-balanced set of forces, which is exactly what fixed nodes give,
so the self-stress states are the same), and cables joining two hub nodes are left out
(they are part of the hub). Otherwise the node nearest the centre is pinned and the
tangential motion of the node farthest from it is blocked: a statically determinate
support that only removes the three in-plane rigid-body motions (its reactions vanish for
a balanced load). Either way the counts s and m refer to the web alone.

Use the web without collinear subdivision (``elements_per_segment = 1``): each extra node
on a straight cable adds one trivial transverse mechanism and one dof. The dense SVD costs
O(dof * b * min(dof, b)) time and O(max(dof, b)^2) memory: 5-25 s at ~3000 bars.

A mechanism that the load does not excite may still be stiffened by the tensions. With
``stability = True`` the reduced tangent stiffness on the mechanism space,
``Q = M^T (K_G - omega^2 M_mass) M`` (geometric stiffness of the tensions minus the
centrifugal softening of the rotating frame; the elastic stiffness vanishes on mechanisms),
is computed; positive definite Q means the prestressed spinning web is stable to first
order in its flat shape.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import csr_matrix, hstack, identity

from meshgen.mesh import Mesh, lumped_mass
from spinweb_fe.errors import RunError
from spinweb_fe.linear.assembly import equilibrium_matrix, free_dof_basis, geometric_stiffness

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PrestressReport:
    """Result of :func:`analyse`. Forces in N, stiffness in N/m.

    Attributes
    ----------
    n_nodes, n_bars, n_dof : int
        Nodes, bars taken into account, free in-plane degrees of freedom.
    rank, n_selfstress, n_mechanisms : int
        Rank r of A, s = b - r, m = dof - r.
    supports : str
        How the rigid-body motions were removed.
    load_norm : float [N]
        ||f|| over the free dof.
    load_residual : float
        ||A t0 - f|| / ||f||: the part of the load on the mechanisms (0 = compatible).
        Point masses dominate ||f||; see also ``node_residual_max``.
    node_residual_max : float
        Largest fraction of a node's own load left unbalanced by t0.
    method : str
        'LP (HiGHS)' or 'least squares (unique: s = 0)'.
    min_force, max_force : float [N]
        Extreme bar tensions of the best combination (negative = compression).
    n_compressed : int
        Bars with a negative tension in the best combination.
    capped : bool
        The LP reached the bound on the forces (a tension-only self-stress exists
        somewhere: the minimum is then limited only by the bound).
    elastic_min_force, elastic_max_force : float [N]
        Extreme tensions of the compatible (elastic) solution of a web cut stress-free to
        its flat shape with the same EA in every cable: ``S^T F t = 0``, F = diag(L/EA).
    elastic_n_compressed : int
        Bars in compression in that elastic solution.
    load_compatible, prestressable : bool
        Verdict: compatible load, and min_force > 0.
    stability_min : float [N/m]
        Smallest eigenvalue of Q (NaN if there is no mechanism or it was not computed).
    n_neutral, n_negative : int
        Eigenvalues of Q that are zero (within 1e-9 of the largest diagonal stiffness)
        or negative; Q is positive definite if both are 0 (-1: not computed).
    omega_band : (float, float)
        If prestressable: the spin rates, as fractions of ``omega``, between which a web
        whose rest lengths are tailored to give ``tension`` at ``omega`` stays in tension
        (linear, equal EA: the misfit self-stress t - t_el is fixed, the elastic part
        grows as omega^2). (0, inf) when s = 0. NaN otherwise.
    tension : (b,) float64 [N]
        Bar tensions of the best combination, in the order of ``bars``.
    bars : (b,) int64
        Indices of the mesh elements analysed.
    """

    n_nodes: int
    n_bars: int
    n_dof: int
    rank: int
    n_selfstress: int
    n_mechanisms: int
    supports: str
    load_norm: float
    load_residual: float
    node_residual_max: float
    method: str
    min_force: float
    max_force: float
    n_compressed: int
    capped: bool
    elastic_min_force: float
    elastic_max_force: float
    elastic_n_compressed: int
    load_compatible: bool
    prestressable: bool
    stability_min: float
    n_neutral: int
    n_negative: int
    omega_band: tuple
    tension: np.ndarray
    bars: np.ndarray

    @property
    def mechanisms_stiffened(self) -> bool | None:
        """Q positive definite (None if not computed)."""
        if self.n_neutral < 0:
            return None
        return self.n_neutral == 0 and self.n_negative == 0

    @property
    def maxwell(self) -> int:
        """b - dof, which equals s - m (Maxwell's rule with the supports)."""
        return self.n_bars - self.n_dof

    def verdict(self) -> str:
        """One line: prestressable or why not."""
        if not self.load_compatible:
            return (f"NOT prestressable as is: {self.load_residual:.1%} of the load lies on "
                    f"mechanisms, the web must distort")
        if not self.prestressable:
            return (f"NOT prestressable: the best self-stress combination leaves "
                    f"{self.n_compressed} bars in compression (min {self.min_force:.4g} N)")
        if self.elastic_n_compressed == 0:
            return f"prestressable by spin: all {self.n_bars} bars in tension"
        lo, hi = self.omega_band
        return (f"prestressable only with tailored rest lengths: cut stress-free, "
                f"{self.elastic_n_compressed} of {self.n_bars} bars are compressed; tailored, "
                f"tension holds for {lo:.3g} to {hi:.3g} times this omega")


def _supports(mesh, xy):
    hub = np.asarray(mesh.node_sets.get("hub_tied", []), np.int64)
    if len(hub) >= 2:
        return set(hub.tolist()), None, f"{len(hub)} hub-tied nodes fixed (rigid hub)"
    pin = int(np.argmin(np.hypot(xy[:, 0], xy[:, 1])))
    far = int(np.argmax(np.hypot(*(xy - xy[pin]).T)))
    radial = (xy[far] - xy[pin]) / np.linalg.norm(xy[far] - xy[pin])
    return {pin}, (far, radial), (f"node {pin} pinned, node {far} on a radial roller "
                                  f"(statically determinate)")


def analyse(mesh: Mesh, omega: float, line_density: float, stability: bool = True,
            cap: float = 100.0, rtol: float = 1e-9) -> PrestressReport:
    """Force-method prestressability of a flat web spinning at ``omega``.

    Parameters
    ----------
    mesh : Mesh
        Flat web (uses ``node_ref`` x, y; best without collinear subdivision).
    omega : float [rad/s]
        Spin rate; forces scale with omega^2, the verdict does not depend on it.
    line_density : float [kg/m]
        Cable mass per length rho * A (point masses come from the mesh).
    stability : bool
        Also compute the reduced tangent stiffness on the mechanisms.
    cap : float
        Bound on each bar force in the LP, as a multiple of max(|t0|).
    rtol : float
        Relative tolerance for the rank, the load residual and the sign of the tensions.

    Returns
    -------
    PrestressReport
    """
    xy = np.ascontiguousarray(mesh.node_ref[:, :2], dtype=np.float64)
    fixed, roller, how = _supports(mesh, xy)
    fixed_arr = np.array(sorted(fixed), np.int64)
    both_fixed = np.isin(mesh.elem_nodes, fixed_arr).all(axis=1)
    bar_ids = np.flatnonzero(~both_fixed)
    bars = mesh.elem_nodes[bar_ids]
    P = free_dof_basis(xy, fixed, roller)
    A = P @ equilibrium_matrix(xy, bars)
    mass = lumped_mass(mesh, line_density)
    f = P @ (omega ** 2 * mass[:, None] * xy).ravel()
    dof, b = A.shape
    U, sig, Vt = np.linalg.svd(A, full_matrices=True)
    r = int(np.sum(sig > rtol * sig.max())) if sig.size else 0
    S, M = Vt[r:].T, U[:, r:]
    t0 = Vt[:r].T @ ((U[:, :r].T @ f) / sig[:r])
    fnorm = float(np.linalg.norm(f))
    residual = float(np.linalg.norm(A @ t0 - f) / fnorm) if fnorm > 0 else 0.0
    node_res = np.hypot(*(P.T @ (f - A @ t0)).reshape(-1, 2).T)
    node_load = np.hypot(*(P.T @ f).reshape(-1, 2).T)
    loaded = node_load > 1e-12 * max(float(node_load.max(initial=0.0)), 1e-300)
    node_residual = float((node_res[loaded] / node_load[loaded]).max(initial=0.0))
    capped = False
    if S.shape[1] == 0:
        t, t_el, method = t0, t0, "least squares (unique: s = 0)"
    else:
        t, capped = _best_selfstress(csr_matrix(A), t0, cap)
        method = "LP (HiGHS)"
        flex = np.linalg.norm(xy[bars[:, 1]] - xy[bars[:, 0]], axis=1)  # L / EA, EA uniform
        SF = S.T * flex
        t_el = t0 - S @ np.linalg.solve(SF @ S, SF @ t0)  # compatibility: S^T F t = 0
    scale = max(float(np.abs(t).max()), 1e-300)
    compatible = residual <= 1e-6
    prestressable = compatible and float(t.min()) > rtol * scale
    band = _omega_band(t, t_el) if prestressable else (float("nan"), float("nan"))
    qmin, n_neutral, n_negative = float("nan"), -1, -1
    if stability and compatible and M.shape[1] > 0:
        K = geometric_stiffness(xy, bars, t)
        K -= omega ** 2 * np.diag(np.repeat(mass, 2))  # centrifugal softening
        Kf = P @ (P @ K).T  # P K P^T (K is symmetric)
        w = np.linalg.eigvalsh(M.T @ Kf @ M)
        tol = 1e-9 * float(np.abs(np.diag(Kf)).max())
        qmin, n_neutral, n_negative = float(w.min()), int(np.sum(np.abs(w) <= tol)), int(
            np.sum(w < -tol))
    log.debug("prestress: dof=%d b=%d r=%d residual=%.3g", dof, b, r, residual)
    return PrestressReport(
        n_nodes=mesh.n_nodes, n_bars=b, n_dof=dof, rank=r, n_selfstress=b - r,
        n_mechanisms=dof - r, supports=how, load_norm=fnorm, load_residual=residual,
        node_residual_max=node_residual,
        method=method, min_force=float(t.min()), max_force=float(t.max()),
        n_compressed=int(np.sum(t < -rtol * scale)), capped=capped,
        elastic_min_force=float(t_el.min()), elastic_max_force=float(t_el.max()),
        elastic_n_compressed=int(np.sum(t_el < -rtol * scale)),
        load_compatible=compatible, prestressable=prestressable, stability_min=qmin,
        n_neutral=n_neutral, n_negative=n_negative, omega_band=band,
        tension=t, bars=bar_ids)


def _omega_band(t, t_el):
    """Range of (omega'/omega) keeping x t_el + (t - t_el) > 0, x = (omega'/omega)^2."""
    misfit = t - t_el
    tol = 1e-9 * float(np.abs(t).max())
    up, down = t_el > tol, t_el < -tol
    lo = float(np.max(-misfit[up] / t_el[up], initial=0.0))
    hi = float(np.min(misfit[down] / -t_el[down], initial=np.inf))
    return math.sqrt(max(lo, 0.0)), math.sqrt(hi)


def _best_selfstress(A, t0, cap):
    """max_{t, tau} tau s.t. A t = A t0, t >= tau, |t| <= cap max|t0| (sparse, HiGHS),
    then, keeping min(t) >= tau, the smallest max(t).

    Solved in the bar forces themselves (A is sparse) rather than in the self-stress
    amplitudes (S is dense), scaled so that max|t0| = 1.
    """
    dof, b = A.shape
    scale = max(float(np.abs(t0).max()), 1e-300)
    rhs = A @ (t0 / scale)
    c = np.zeros(b + 1)
    c[-1] = -1.0
    A_eq = hstack([A, csr_matrix((dof, 1))]).tocsr()
    A_ub = hstack([-identity(b), np.ones((b, 1))]).tocsr()
    bounds = [(-cap, cap)] * b + [(None, None)]
    res = linprog(c, A_ub=A_ub, b_ub=np.zeros(b), A_eq=A_eq, b_eq=rhs, bounds=bounds,
                  method="highs")
    if res.status != 0:
        raise RunError(f"prestress LP failed: {res.message}")
    tau = res.x[-1]
    # second stage: keep min(t) >= tau, make max(t) as small as possible (unique spread)
    A_ub2 = hstack([identity(b), -np.ones((b, 1))]).tocsr()
    lower = tau - 1e-9 * abs(tau)
    res2 = linprog(c * -1.0, A_ub=A_ub2, b_ub=np.zeros(b), A_eq=A_eq, b_eq=rhs,
                   bounds=[(lower, cap)] * b + [(None, None)], method="highs")
    t = (res2.x if res2.status == 0 else res.x)[:b]
    return t * scale, bool(np.any(np.abs(res.x[:b]) >= 0.999 * cap))


def format_report(rep: PrestressReport, title: str, omega: float) -> str:
    """The report as the lines ``spinweb prestress`` prints (``title``: what was analysed)."""
    if rep.n_mechanisms == 0:
        stiff = "no mechanism"
    elif rep.mechanisms_stiffened is None:
        stiff = "not computed (load not compatible)"
    else:
        stiff = ("yes" if rep.mechanisms_stiffened else
                 f"NO: {rep.n_neutral} neutral, {rep.n_negative} negative") + (
            f" (smallest eigenvalue {rep.stability_min:.4g} N/m)")
    lo, hi = rep.omega_band
    band = ("-" if not rep.prestressable else "every spin rate (statically determinate "
            "for this load)" if lo == 0 and hi == float("inf") else
            f"{lo * omega:.4g} < omega < {hi * omega:.4g} rad/s if the rest lengths "
            "are tailored at this omega (members go slack outside)")
    note = "" if rep.load_compatible else "  (least squares: not in equilibrium)"
    lines = [
        f"topology            {title}",
        f"supports            {rep.supports}",
        f"nodes               {rep.n_nodes}",
        f"free dof            {rep.n_dof}",
        f"bars                {rep.n_bars}",
        f"rank                {rep.rank}",
        f"self-stress states  {rep.n_selfstress}",
        f"mechanisms          {rep.n_mechanisms}   (b - dof = {rep.maxwell} = s - m)",
        f"load residual       {rep.load_residual:.3e} of |f| = {rep.load_norm:.4g} N "
        f"(worst node {rep.node_residual_max:.3g} of its load)",
        f"method              {rep.method}",
        f"min member force    {rep.min_force:.6g} N{note}",
        f"max member force    {rep.max_force:.6g} N{note}",
        f"compressed members  {rep.n_compressed}",
        f"elastic solution    min {rep.elastic_min_force:.6g} N, max "
        f"{rep.elastic_max_force:.6g} N, {rep.elastic_n_compressed} compressed "
        f"(cables cut stress-free to the flat shape, equal EA)",
        f"mechanisms stiffened {stiff}",
        f"tension holds for   {band}",
        f"verdict             {rep.verdict()}",
    ]
    if rep.capped:
        lines.insert(-1, "note                the LP hit its force bound: a tension-only "
                         "self-stress exists")
    return "\n".join(lines)
