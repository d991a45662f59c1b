"""The steady spinning state of a cable web or tethers: equilibrium in the co-rotating frame.

A web spinning steadily at ``omega`` about +z is at rest in the frame that turns with the
hub. There each node carries the centrifugal load ``m_i omega^2 (x_i, y_i)`` and the pulls
of its tension-only cables, ``N = EA max(l / L0 - 1, 0)``; the hub-tied nodes are fixed.
The flat state stays flat (the load has no z component), so the equilibrium is an in-plane
problem, solved here with its finite strains by Newton's method on the sparse tangent

    K_T = K_mat + K_geo - omega^2 M,
    K_mat = sum (EA / L0) e e^T (taut cables),  K_geo = sum (N / l) (I - e e^T),

starting from the flat reference state (every cable at its rest length), with a backtracking
line search and, if Newton fails at the full load, continuation in omega^2.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix, diags
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu

from spinweb_fe.errors import InputError, RunError

log = logging.getLogger(__name__)

RTOL = 1e-10  # relative residual ||R|| / ||m omega^2 x|| of a converged steady state
MAX_ITER = 40  # Newton iterations per load step
MIN_LOAD_STEP = 1.0 / 1024  # smallest fraction of omega^2 the continuation may take
TAUT = -1e-9  # strain from which a cable counts as taut (the flat web holds L = L0 to 1e-9)


class Structure(NamedTuple):
    """The deployed web or tethers as the linear analyses see it (SI units).

    Attributes
    ----------
    node_ref : (n, 3) float64 [m]
        Flat reference positions (z = 0), in the hub frame; the hub axis is +z at the origin.
    node_mass : (n,) float64 [kg]
        Lumped cable mass plus point masses (tied nodes included, the hub not).
    elem_nodes : (m, 2) int64
    elem_rest_len : (m,) float64 [m]
        Rest lengths L0 (from the flat web).
    elem_ea : (m,) float64 [N]
        Axial stiffness EA.
    tied_idx : (k,) int64
        Nodes tied to the hub (fixed in the rotating frame).
    hub_inertia : float [kg m^2]
        J_hub about the axis (the tied nodes not included).
    """

    node_ref: np.ndarray
    node_mass: np.ndarray
    elem_nodes: np.ndarray
    elem_rest_len: np.ndarray
    elem_ea: np.ndarray
    tied_idx: np.ndarray
    hub_inertia: float

    @property
    def free_nodes(self) -> np.ndarray:
        """(n_f,) int64: the nodes that are not tied, in increasing order."""
        free = np.ones(len(self.node_mass), bool)
        free[self.tied_idx] = False
        return np.flatnonzero(free)


@dataclass(frozen=True)
class SteadyState:
    """Result of :func:`solve_steady`.

    Attributes
    ----------
    omega : float [rad/s]
    position : (n, 3) float64 [m]
        Equilibrium positions in the rotating (hub) frame, z = 0.
    tension : (m,) float64 [N]
    strain : (m,) float64
        l / L0 - 1 (negative: slack).
    residual : float
        ||R|| / ||m omega^2 x|| over the free dof at the end.
    residual_force : float [N]
        Largest nodal out-of-balance force.
    iterations : int
        Newton iterations, all load steps together.
    load_steps : int
        Load steps of the continuation in omega^2 (1: the full load at once).
    slack : (s,) int64
        Elements carrying no tension (cables between two tied nodes, part of the rigid hub,
        are not counted).
    """

    omega: float
    position: np.ndarray
    tension: np.ndarray
    strain: np.ndarray
    residual: float
    residual_force: float
    iterations: int
    load_steps: int
    slack: np.ndarray

    @property
    def max_strain(self) -> float:
        return float(self.strain.max(initial=0.0))


def structure_from_model(model) -> Structure:
    """The :class:`Structure` of a :class:`spinweb_fe.fe.model.Model` built on a flat mesh."""
    el = model.elements
    return Structure(np.array(model.mesh.node_ref, np.float64), model.nodes.mass.copy(),
                     np.array(el.nodes), np.array(el.rest_len), np.array(el.ea),
                     np.array(model.hub.tied_idx), float(model.hub.inertia))


def element_state(s: Structure, xy):
    """Unit vectors, lengths, strains and tensions of the elements at in-plane positions.

    Parameters
    ----------
    s : Structure
    xy : (n, 2) float64 [m]

    Returns
    -------
    e : (m, 2) float64
        Unit vector from node i to node j.
    length : (m,) float64 [m]
    strain : (m,) float64
        l / L0 - 1.
    tension : (m,) float64 [N]
        EA max(strain, 0).
    """
    d = xy[s.elem_nodes[:, 1]] - xy[s.elem_nodes[:, 0]]
    length = np.hypot(d[:, 0], d[:, 1])
    e = d / np.where(length > 0, length, 1.0)[:, None]
    strain = length / s.elem_rest_len - 1.0
    return e, length, strain, s.elem_ea * np.maximum(strain, 0.0)


def block_stiffness(s: Structure, coef_ee, coef_perp, e, dim=2) -> csr_matrix:
    """Assembled (dim n, dim n) stiffness of bars whose 2x2 block is
    ``coef_ee e e^T + coef_perp (I - e e^T)`` [N/m] (dim = 2: in-plane; dim = 1 takes the
    scalar ``coef_perp`` per bar, the out-of-plane Laplacian)."""
    n = len(s.node_mass)
    i, j = s.elem_nodes[:, 0], s.elem_nodes[:, 1]
    if dim == 1:
        blocks = coef_perp[:, None, None] * np.ones((1, 1, 1))
    else:
        eet = e[:, :, None] * e[:, None, :]
        blocks = coef_ee[:, None, None] * eet + coef_perp[:, None, None] * (np.eye(2) - eet)
    rows, cols, vals = [], [], []
    for a, b, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
        for p in range(dim):
            for q in range(dim):
                rows.append(dim * a + p)
                cols.append(dim * b + q)
                vals.append(sign * blocks[:, p, q])
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(dim * n, dim * n)).tocsr()


def tangent_parts(s: Structure, xy):
    """Material and geometric in-plane stiffness (2n, 2n) [N/m] at ``xy`` (n, 2) [m].

    A cable at or above its rest length (to :data:`TAUT`) is taut: its material stiffness
    EA / L0 counts, so that the flat reference state is loaded along the cables; a slack
    one contributes nothing.
    """
    e, length, strain, tension = element_state(s, xy)
    taut = strain >= TAUT
    k_mat = np.where(taut, s.elem_ea / s.elem_rest_len, 0.0)
    k_geo = tension / np.where(length > 0, length, 1.0)
    zero = np.zeros_like(k_mat)
    return block_stiffness(s, k_mat, zero, e), block_stiffness(s, zero, k_geo, e)


def internal_force(s: Structure, xy, tension, e) -> np.ndarray:
    """(n, 2) [N] cable forces on the nodes: +N e on node i, -N e on node j."""
    f = np.zeros((len(s.node_mass), 2))
    pull = tension[:, None] * e
    np.add.at(f, s.elem_nodes[:, 0], pull)
    np.add.at(f, s.elem_nodes[:, 1], -pull)
    return f


def _residual(s, xy, w2):
    e, _, _, tension = element_state(s, xy)
    load = w2 * s.node_mass[:, None] * xy
    return internal_force(s, xy, tension, e) + load, load


def roundoff_floor(s: Structure, xy, load) -> float:
    """The relative residual that round-off alone leaves: a tension EA (l / L0 - 1) from
    positions of size |x| is uncertain by about 4 eps EA |x| / L0."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    dN = 4.0 * np.finfo(float).eps * s.elem_ea * r[s.elem_nodes].max(axis=1) / s.elem_rest_len
    node = np.zeros(len(r))
    np.add.at(node, s.elem_nodes[:, 0], dN)
    np.add.at(node, s.elem_nodes[:, 1], dN)
    node = node[s.free_nodes]
    return float(np.linalg.norm(node) / max(np.linalg.norm(load[s.free_nodes]), 1e-300))


def _free_dofs(s):
    free = s.free_nodes
    return np.column_stack([2 * free, 2 * free + 1]).ravel()


def _newton(s, xy, w2, dofs, rtol, max_iter):
    """Newton with a backtracking line search at the load omega^2 = w2; returns
    (converged, xy, iterations, relative residual)."""
    mass = diags(np.repeat(s.node_mass, 2))
    xy = xy.copy()
    R, load = _residual(s, xy, w2)
    norm = lambda r, f: np.linalg.norm(r.ravel()[dofs]) / max(  # noqa: E731
        np.linalg.norm(f.ravel()[dofs]), 1e-300)
    rel = norm(R, load)
    tol = max(rtol, roundoff_floor(s, xy, load))
    for it in range(1, max_iter + 1):
        k_mat, k_geo = tangent_parts(s, xy)
        K = (k_mat + k_geo - w2 * mass).tocsc()[dofs][:, dofs]
        try:
            dx = splu(K.tocsc()).solve(R.ravel()[dofs])
        except RuntimeError:  # exactly singular tangent
            return False, xy, it, rel
        if not np.all(np.isfinite(dx)):
            return False, xy, it, rel
        step = 1.0
        for _ in range(12):
            trial = xy.copy()
            trial.ravel()[dofs] += step * dx
            R_t, load_t = _residual(s, trial, w2)
            rel_t = norm(R_t, load_t)
            if rel_t < rel or rel_t <= tol:
                break
            step *= 0.5
        xy, R, load, rel = trial, R_t, load_t, rel_t
        log.debug("newton: omega^2 = %.6g, iteration %d, step %.3g, residual %.3e",
                  w2, it, step, rel)
        tol = max(rtol, roundoff_floor(s, xy, load))
        if rel <= tol:
            return True, xy, it, rel
    return False, xy, max_iter, rel


def solve_steady(s: Structure, omega: float, rtol: float = RTOL,
                 max_iter: int = MAX_ITER) -> SteadyState:
    """Steady spinning state at ``omega`` [rad/s], finite strains, tied nodes fixed.

    Parameters
    ----------
    s : Structure
    omega : float [rad/s]
        Spin rate (nonzero).
    rtol : float
        Converged when ||R|| <= rtol ||m omega^2 x|| over the free dof (or, for very stiff
        cables, when ||R|| is down to the round-off of the tensions, :func:`roundoff_floor`).
    max_iter : int
        Newton iterations per load step.

    Returns
    -------
    SteadyState

    Raises
    ------
    InputError
        If omega is zero or not finite.
    RunError
        If Newton does not converge (no steady state: the load outgrows the cables' EA,
        or the web is a mechanism); the message gives the residual.
    """
    if not (math.isfinite(omega) and omega != 0.0):
        raise InputError("omega", "", f"must be finite and nonzero, got {omega:g} rad/s: a "
                         "cable net without spin has no out-of-plane stiffness")
    w2 = float(omega) ** 2
    dofs = _free_dofs(s)
    xy = np.ascontiguousarray(s.node_ref[:, :2], dtype=np.float64)
    done, inc, iterations, steps, rel = 0.0, 1.0, 0, 0, math.inf
    while done < 1.0:
        frac = min(1.0, done + inc)
        ok, xy_new, it, rel = _newton(s, xy, frac * w2, dofs, rtol, max_iter)
        iterations += it
        if ok:
            xy, done, steps = xy_new, frac, steps + 1
            inc = min(2.0 * inc, 1.0)
            continue
        inc /= 4.0
        if inc < MIN_LOAD_STEP:
            raise RunError(f"no steady state at omega = {omega:.6g} rad/s: Newton did not "
                           f"converge beyond {done:.3g} of omega^2 (relative residual "
                           f"{rel:.3e} after {iterations} iterations); the centrifugal load "
                           "may outgrow the cables' stiffness")
    R, _ = _residual(s, xy, w2)
    _, _, strain, tension = element_state(s, xy)
    R_free = R[s.free_nodes]
    pos = np.zeros((len(xy), 3))
    pos[:, :2] = xy
    log.debug("steady: %d iterations, %d load steps, residual %.3e", iterations, steps, rel)
    hub_elem = np.isin(s.elem_nodes, s.tied_idx).all(axis=1)  # part of the rigid hub
    return SteadyState(float(omega), pos, tension, strain, float(rel),
                       float(np.hypot(R_free[:, 0], R_free[:, 1]).max(initial=0.0)),
                       iterations, steps, np.flatnonzero((tension <= 0.0) & ~hub_elem))


def hub_forces(s: Structure, st: SteadyState) -> np.ndarray:
    """(k, 2) [N] net force on each tied node (cable pulls plus its own centrifugal load),
    which the hub must take: the root tension of a tether is its norm."""
    xy = st.position[:, :2]
    e, _, _, tension = element_state(s, xy)
    f = internal_force(s, xy, tension, e) + st.omega ** 2 * s.node_mass[:, None] * xy
    return f[s.tied_idx]


def check_mechanism(s: Structure, st: SteadyState) -> None:
    """RunError naming the slack elements if they leave nodes without a taut path to the hub.

    The out-of-plane stiffness is the Laplacian of the taut cables weighted by N / l, with
    the tied nodes fixed: it is singular exactly when some free node is not connected to
    a tied node by taut cables; such nodes are a mechanism in and out of the plane.
    """
    if len(st.slack) == 0:
        return
    taut = st.tension > 0.0
    n = len(s.node_mass)
    i, j = s.elem_nodes[taut, 0], s.elem_nodes[taut, 1]
    graph = csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    anchored = np.isin(label, label[s.tied_idx])
    loose = np.flatnonzero(~anchored)
    if len(loose):
        raise RunError(f"the steady state is a mechanism: {len(st.slack)} slack elements "
                       f"({describe_elements(s, st.slack)}) leave {len(loose)} nodes "
                       f"(first {loose[:5].tolist()}) without a taut path to the hub")


def describe_elements(s: Structure, idx, limit: int = 8) -> str:
    """'element k (nodes a-b), ...' for the first ``limit`` of ``idx``."""
    parts = [f"element {k} (nodes {s.elem_nodes[k, 0]}-{s.elem_nodes[k, 1]})"
             for k in np.asarray(idx)[:limit]]
    more = len(idx) - limit
    return ", ".join(parts) + (f" and {more} more" if more > 0 else "")
