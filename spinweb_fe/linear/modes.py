"""Small vibrations of the steady spinning web in the co-rotating frame (docs/modes.md).

About the planar steady state of :mod:`spinweb_fe.linear.steady` the in-plane and the
out-of-plane motions decouple. Out of the plane (displacement w, tied nodes fixed)

    M w'' + K_z w = 0,    K_z = sum_taut (N / l) [[1, -1], [-1, 1]]      (geometric only),

a symmetric problem solved with ``eigsh`` in shift-invert mode. In the plane (u)

    M u'' + G u' + K u = 0,   G = 2 omega M J,   K = K_mat + K_geo - omega^2 M,

gyroscopic: solved as the first-order problem A z = lambda B z, z = (u, lambda u),
A = [[0, I], [-K, -G]], B = diag(I, M), by ``eigs`` on (A - sigma B)^-1 B, which needs only
the sparse LU of K + sigma G + sigma^2 M (sigma a small negative real shift: the closest
eigenvalues, +-i omega_k, are the lowest). With the hub ``driven`` the tied nodes are fixed;
with the hub ``coasting`` (turning freely on its fixed axis) the rigid rotation theta of the hub and its tied nodes (u_i = theta J
p_i) is one more degree of freedom, with the hub's inertia J_hub, and the prestress of the
tied nodes adds sum_i F_i . p_i to its stiffness, so that a rigid rotation of everything is
exactly a zero mode.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh
from scipy.sparse import coo_matrix, csr_matrix, diags
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs, eigsh, splu

from spinweb_fe.errors import InputError, RunError
from spinweb_fe.linear.steady import (Structure, SteadyState, block_stiffness,
                                      describe_elements, element_state, hub_forces,
                                      tangent_parts)

log = logging.getLogger(__name__)

HUBS = ("driven", "coasting")
DENSE_MAX = 400  # up to this many (first-order) unknowns, dense eigensolvers
SHIFT = 1e-2  # the shift sigma, as a fraction of omega (in-plane) or omega^2 (out of plane)
ZERO = 1e-4  # |lambda| below ZERO |omega| is a zero mode (a drift, or a mechanism)
UNSTABLE = 1e-4  # |Re lambda| below UNSTABLE |omega| is round-off (near-double eigenvalues)


@dataclass(frozen=True)
class Modes:
    """The lowest modes of the spinning web, lowest first.

    Attributes
    ----------
    omega : float [rad/s]
        Spin rate.
    hub : str
        'driven' or 'coasting'.
    frequency : (k,) float64 [rad/s]
        Imaginary part of the eigenvalue (>= 0).
    growth : (k,) float64 [1/s]
        Real part of the eigenvalue: nonzero for a growing (or decaying) mode of an unstable
        steady state; below ``UNSTABLE |omega|`` it is round-off and set to 0.
    kind : (k,) str
        'in_plane' or 'out_of_plane'.
    shape : (k, n, 3) float64 [m]
        Real mode shapes (at the phase of largest displacement), max node |u| = 1 m.
    material_share : (k,) float64
        u^H K_mat u / u^H (K_mat + K_geo) u: the part of the modal stiffness that is cable
        stretch (1: set by EA) rather than tension (0: scales with omega^2).
    """

    omega: float
    hub: str
    frequency: np.ndarray
    growth: np.ndarray
    kind: np.ndarray
    shape: np.ndarray
    material_share: np.ndarray

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.frequency / (2.0 * math.pi)

    @property
    def ratio(self) -> np.ndarray:
        """frequency / |omega|."""
        return self.frequency / abs(self.omega)


class InPlane:
    """Sparse in-plane matrices about a steady state (reduced to the free dof).

    Attributes
    ----------
    M, G, K : csr_matrix (d, d)
        Mass [kg] (and kg m^2 for the hub angle), gyroscopic [kg/s], stiffness [N/m].
    K_mat, K_geo : csr_matrix (d, d) [N/m]
        The material and geometric parts of K (K = K_mat + K_geo - omega^2 M_nodes).
    T : csr_matrix (2n, d)
        Full in-plane displacement (x, y per node) of a reduced vector.
    """

    def __init__(self, s: Structure, st: SteadyState, hub: str = "driven"):
        if hub not in HUBS:
            raise InputError("hub", "", f"must be one of {', '.join(HUBS)}, got '{hub}'")
        n, w = len(s.node_mass), st.omega
        xy = st.position[:, :2]
        k_mat, k_geo = tangent_parts(s, xy)
        m2 = np.repeat(s.node_mass, 2)
        J = _rotation(n)
        free = s.free_nodes
        cols = np.column_stack([2 * free, 2 * free + 1]).ravel()
        d = len(cols) + (hub == "coasting")
        T = coo_matrix((np.ones(len(cols)), (cols, np.arange(len(cols)))), shape=(2 * n, d))
        extra = 0.0
        if hub == "coasting":  # theta moves the tied nodes by theta J p
            p = xy[s.tied_idx]
            rows = np.column_stack([2 * s.tied_idx, 2 * s.tied_idx + 1]).ravel()
            vals = np.column_stack([-p[:, 1], p[:, 0]]).ravel()
            T = T + coo_matrix((vals, (rows, np.full(len(rows), d - 1))), shape=(2 * n, d))
            extra = float(np.sum(hub_forces(s, st) * p))  # sum F . p of the prestress
        T = T.tocsr()
        hub_m = np.zeros(d)
        hub_k = np.zeros(d)
        if hub == "coasting":
            hub_m[-1], hub_k[-1] = s.hub_inertia, extra
        proj = lambda A: (T.T @ A @ T).tocsr()  # noqa: E731
        self.T = T
        self.M = proj(diags(m2)) + diags(hub_m)
        self.G = proj(2.0 * w * diags(m2) @ J)
        self.K_mat = proj(k_mat)
        self.K_geo = proj(k_geo) + diags(hub_k)
        self.K = (self.K_mat + self.K_geo - w * w * proj(diags(m2))).tocsr()

    def full(self, q) -> np.ndarray:
        """(n, 2) displacement of a reduced vector q (d,) (complex allowed)."""
        return (self.T @ q).reshape(-1, 2)


def out_of_plane_matrices(s: Structure, st: SteadyState):
    """(M_z [kg], K_z [N/m]) on the free nodes: lumped masses, geometric stiffness N / l."""
    _, length, _, tension = element_state(s, st.position[:, :2])
    K = block_stiffness(s, None, tension / np.where(length > 0, length, 1.0), None, dim=1)
    free = s.free_nodes
    return diags(s.node_mass[free]).tocsr(), K[free][:, free].tocsr()


def _rotation(n):
    """(2n, 2n) block diagonal J = [[0, -1], [1, 0]]."""
    i = np.arange(n)
    rows = np.concatenate([2 * i, 2 * i + 1])
    cols = np.concatenate([2 * i + 1, 2 * i])
    vals = np.concatenate([-np.ones(n), np.ones(n)])
    return csr_matrix((vals, (rows, cols)), shape=(2 * n, 2 * n))


def in_plane_eigen(mats: InPlane, omega: float, count: int):
    """The ``count`` lowest in-plane eigenpairs: (lambda (c,) complex [1/s], u (d, c)).

    Shift-invert about sigma = -SHIFT |omega| (dense for small problems, ARPACK otherwise:
    either way the inverted operator, whose largest eigenvalues are the lowest modes, so
    that stiff cables do not spoil them). Eigenvalues come as +-i omega_k; one of each pair
    is kept (Im >= 0), lowest |lambda| first.
    """
    d = mats.M.shape[0]
    sigma = -SHIFT * abs(omega)
    lu = _lu((mats.K + sigma * mats.G + sigma * sigma * mats.M).tocsc(), "in-plane")
    GM = (mats.G + sigma * mats.M).tocsr()

    def apply(z):  # (A - sigma B)^-1 B z, z = (a, b)
        a, b = z[:d], z[d:]
        x = lu.solve(np.asarray(-(mats.M @ b + GM @ a)))
        return np.concatenate([x, a + sigma * x])

    if 2 * d <= DENSE_MAX:
        nu, vec = np.linalg.eig(apply(np.eye(2 * d)))
    else:
        op = LinearOperator((2 * d, 2 * d), matvec=apply, dtype=np.float64)
        try:
            nu, vec = eigs(op, k=min(2 * count + 4, 2 * d - 2), which="LM", tol=1e-12)
        except ArpackNoConvergence as exc:
            raise RunError(f"the in-plane eigensolver did not converge ({exc})") from None
    ok = np.abs(nu) > 0
    lam, vec = sigma + 1.0 / nu[ok], vec[:, ok]
    keep = (lam.imag > 0) | ((lam.imag == 0) & (lam.real >= 0))
    lam, vec = lam[keep], vec[:d, keep]
    order = np.argsort(np.abs(lam))[:count]
    return lam[order], vec[:, order]


def out_of_plane_eigen(M, K, omega: float, count: int):
    """The ``count`` lowest out-of-plane eigenpairs: (omega_k^2 (c,) [1/s^2], w (n_f, c)),
    by shift-invert about sigma = -(SHIFT omega)^2 (K - sigma M is positive definite)."""
    n = M.shape[0]
    k = min(count, n)
    sigma = -(SHIFT * omega) ** 2
    if n <= DENSE_MAX or k >= n - 1:
        nu, vec = eigh(M.toarray(), (K - sigma * M).toarray())  # nu = 1 / (lambda - sigma)
        val = sigma + 1.0 / nu
    else:
        try:
            val, vec = eigsh(K.tocsc(), k=k, M=M.tocsc(), sigma=sigma, which="LM", tol=1e-12)
        except ArpackNoConvergence as exc:
            raise RunError(f"the out-of-plane eigensolver did not converge ({exc})") from None
    order = np.argsort(val)[:k]
    return val[order], vec[:, order]


def _lu(Q, what):
    try:
        return splu(Q)
    except RuntimeError as exc:
        raise RunError(f"the {what} stiffness is singular at the shift ({exc}): the "
                       "steady state is a mechanism") from None


def real_shape(u) -> np.ndarray:
    """Real part of a complex displacement (n, c) at the phase of largest norm, scaled to
    max node |u| = 1 and signed so that its largest component is positive."""
    u = np.asarray(u)
    if np.iscomplexobj(u):
        a, b = u.real.ravel(), u.imag.ravel()
        alpha = 0.5 * math.atan2(-2.0 * a @ b, a @ a - b @ b)
        u = (u * np.exp(1j * alpha)).real
    peak = np.sqrt((u * u).sum(axis=1)).max(initial=0.0)
    if peak > 0:
        u = u / peak
    flat = u.ravel()
    big = np.argmax(np.abs(flat)) if flat.size else 0
    return u if flat.size == 0 or flat[big] >= 0 else -u


def _share(u, Kmat, Kgeo):
    """u^H K_mat u / u^H (K_mat + K_geo) u (real parts)."""
    m = float(np.real(np.vdot(u, Kmat @ u)))
    g = float(np.real(np.vdot(u, Kgeo @ u)))
    return m / (m + g) if m + g > 0 else float("nan")


def compute_modes(s: Structure, st: SteadyState, count: int, hub: str = "driven") -> Modes:
    """The ``count`` lowest modes (in-plane and out-of-plane together) about a steady state.

    Parameters
    ----------
    s : Structure
    st : SteadyState
        From :func:`spinweb_fe.linear.steady.solve_steady` at the spin rate wanted.
    count : int
        Number of modes (>= 1).
    hub : {'driven', 'coasting'}
        Hub rate prescribed (tied nodes fixed in the rotating frame) or the hub turning with
        no torque on its fixed axis (its inertia J_hub one more in-plane degree of freedom).

    Returns
    -------
    Modes

    Raises
    ------
    InputError
        count < 1, an unknown hub option.
    RunError
        Slack elements make the in-plane steady state a mechanism (zero modes).
    """
    if int(count) < 1:
        raise InputError("count", "", f"must be >= 1, got {count}")
    n, omega = len(s.node_mass), st.omega
    mats = InPlane(s, st, hub)
    lam, vec = in_plane_eigen(mats, omega, count)
    Mz, Kz = out_of_plane_matrices(s, st)
    w2, wz = out_of_plane_eigen(Mz, Kz, omega, count)
    rows = []
    for k in range(len(lam)):
        u = vec[:, k]
        full = np.zeros((n, 3))
        full[:, :2] = real_shape(mats.full(u))
        grow = float(lam[k].real) if abs(lam[k].real) > UNSTABLE * abs(omega) else 0.0
        rows.append((float(abs(lam[k].imag)), grow, "in_plane", full,
                     _share(u, mats.K_mat, mats.K_geo)))
    free = s.free_nodes
    for k in range(len(w2)):
        full = np.zeros((n, 3))
        full[free, 2] = wz[:, k]
        full = real_shape(full)
        freq = math.sqrt(w2[k]) if w2[k] >= 0 else 0.0
        grow = 0.0 if w2[k] >= 0 else math.sqrt(-w2[k])
        rows.append((freq, grow, "out_of_plane", full, 0.0))
    rows.sort(key=lambda r: math.hypot(r[0], r[1]))
    rows = rows[:count]
    _check_zero_modes(s, st, rows, hub)
    return Modes(omega, hub, np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                 np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
                 np.array([r[4] for r in rows]))


def _check_zero_modes(s, st, rows, hub):
    """Slack elements and more zero modes than the coasting hub's rigid rotation: a mechanism."""
    scale = abs(st.omega)
    zero = [r for r in rows if math.hypot(r[0], r[1]) < ZERO * scale]
    for r in (r for r in rows if r[1] != 0.0):
        log.warning("unstable %s mode: growth rate %.4g 1/s (frequency %.4g rad/s)",
                    r[2], r[1], r[0])
    if len(st.slack) and len(zero) > (hub == "coasting"):
        raise RunError(f"the steady state is a mechanism: {len(zero)} zero-frequency modes, "
                       f"{len(st.slack)} slack elements ({describe_elements(s, st.slack)})")
