"""Per-arm measures of the FE state, defined as in the analytical model.

Each arm (tether) has a root point R on the hub rim (hub-frame angle theta_R), a tip node,
and a *spine*: for every arm-coordinate level from the root to the tip, the outermost node(s)
of the flat web at that level (a tether: all its nodes; a star-folded web arm: its two
outline edges, the half sides that meet at its corner). At each history row:

- wound length w = arm coordinate (minus the root's) of the last spine level that is still,
  together with every level before it, on the hub (planar radius <= r0 (1 + 1e-3));
  the wrap sense s = +1 (trailing: the coil runs clockwise from its first level) or -1;
- the departure point D is that last wound spine node; the wound angle alpha and L are
  refined with the tangent from the tip to the rim (L = sqrt(|p|^2 - r0^2), exact for a
  straight taut free part, continuous in time) whenever that agrees with D to within two
  spine levels, else alpha = w / r0 and L = |tip - D|;
- phi = -s (pi/2 + alpha) while wound (the analytical model's coiled branch,
  |phi| = pi/2 + alpha); otherwise the angle of (tip - R) from the outward radial at R,
  counter-clockwise positive;
- omega_tip = (p x v)_z / |p|^2: the rate of the tip's polar angle about the hub axis.

Measuring the wound part by contact (not by the tip's angle) stays right when a slack
coil slides over a frictionless hub.
"""

from __future__ import annotations

import math

import numpy as np

from meshgen.fold import half_axes

CONTACT_TOL = 1e-3  # relative radius tolerance for "on the hub"


def arm_probes(mesh):
    """Probe nodes of the arm measures: tips first, then the spine of each arm.

    Returns
    -------
    probes : (p,) int64          node indices (tips are probes[:n_arms])
    spine_arm : (p - n,) int64   arm of each spine probe
    spine_level : (p - n,) int64 level index (0 = root level) of each spine probe
    spine_coord : (p - n,) float arm coordinate of each spine probe, minus the root's [m]
    """
    tips = np.asarray(mesh.node_sets["tips"], dtype=np.int64)
    n_arms = mesh.n_arms
    arm, coord = mesh.node_arm, mesh.node_arm_coord
    ref = mesh.node_ref
    s_idx, s_arm, s_lev, s_coord = [], [], [], []
    if n_arms == len(tips):
        # outermost: largest gauge max_j P.u_j over the half-axes u_j (max(|x|, |y|) for
        # the square web): the web's outline edges that become the arm's edges
        reach = np.max(ref[:, :2] @ half_axes(mesh.arm_root_angle).T, axis=1)
        # a web's spine keeps only the levels that reach its outline: levels of interior
        # nodes alone (a mesh whose lines are not parallel to the half-axes) are slack
        # concertina points that lift off the hub while the taut edges stay wound
        edge = reach.max() - 1e-9 * max(1.0, reach.max()) if "boundary" in mesh.node_sets \
            else -np.inf
        for k in range(n_arms):
            nodes = np.flatnonzero((arm == k) & (coord >= mesh.arm_root_coord - 1e-9))
            groups = [(lev, nodes[np.abs(coord[nodes] - lev) < 1e-9])
                      for lev in np.unique(np.round(coord[nodes], 9))]
            groups = [(lev, g) for lev, g in groups if reach[g].max() >= edge]
            for j, (lev, group) in enumerate(groups):
                outer = group[reach[group] >= reach[group].max() - 1e-9]
                s_idx += list(outer)
                s_arm += [k] * len(outer)
                s_lev += [j] * len(outer)
                s_coord += [lev - mesh.arm_root_coord] * len(outer)
    probes = np.concatenate([tips, np.asarray(s_idx, dtype=np.int64)])
    return (probes, np.asarray(s_arm, np.int64), np.asarray(s_lev, np.int64),
            np.asarray(s_coord, float))


def deployed_length(mesh) -> np.ndarray:
    """(n_arms,) [m] arm length L of the fully deployed (flat, reference) state: the distance
    from each arm's root point on the rim to its tip in ``node_ref`` (a tether: H; a
    star-folded web arm: the flat web's corner distance from the rim, a sqrt(2) - r0 for
    the square web, S / sqrt(3) - r0 for the triangular web)."""
    tips = np.asarray(mesh.node_sets["tips"])
    ang = mesh.arm_root_angle if mesh.n_arms == len(tips) else np.arctan2(
        mesh.node_ref[tips, 1], mesh.node_ref[tips, 0])
    root = mesh.hub_radius * np.column_stack([np.cos(ang), np.sin(ang)])
    return np.hypot(*(mesh.node_ref[tips, :2] - root).T)


class ArmTracker:
    """Turns recorded probe positions / velocities into L, phi, omega_tip per arm.

    Parameters
    ----------
    mesh : Mesh
    r0 : float [m]   hub radius (0: no hub, nothing is ever wound)
    contact_tol : float
        Smallest relative radius tolerance of "on the hub" (it grows with the spine spacing).

    The tracker's memory from row to row is the previous arm angle and whether the arm was
    wound (:meth:`memory`, :meth:`restore`: a restarted run continues it).
    """

    name = "arms"

    def __init__(self, mesh, r0, contact_tol=CONTACT_TOL):
        self.probes, self.s_arm, self.s_lev, self.s_coord = arm_probes(mesh)
        tips = mesh.node_sets["tips"]
        self.n = len(tips)
        roots = mesh.arm_root_angle
        if len(roots) != self.n:  # no arm data: measure each tip from its own radial
            ref = mesh.node_ref[tips]
            roots = np.arctan2(ref[:, 1], ref[:, 0])
        self.root = np.asarray(roots, float)
        self.r0 = float(r0)
        self.prev_phi = np.full(self.n, np.nan)  # for a continuous (unwrapped) free-arm angle
        self.prev_wound = np.zeros(self.n, bool)
        gaps = [np.max(np.diff(np.unique(self.s_coord[self.s_arm == k])))
                for k in range(self.n) if np.sum(self.s_arm == k) > 1]
        self.gap = float(max(gaps)) if gaps else 0.0
        # "on the hub": a spinning coil of straight elements of length g lifts off the rim by
        # about r0 (g/r0)^2 / 24, so the tolerance grows with the spine spacing
        self.tol = max(contact_tol, (self.gap / self.r0) ** 2 / 12) if self.r0 > 0 else 0.0

    def memory(self) -> dict:
        """What the measure carries from row to row (copies)."""
        return {"prev_phi": self.prev_phi.copy(), "prev_wound": self.prev_wound.copy()}

    def restore(self, memory: dict) -> None:
        """Continue from :meth:`memory` of an earlier run (same mesh)."""
        self.prev_phi = np.array(memory["prev_phi"], dtype=float)
        self.prev_wound = np.array(memory["prev_wound"], dtype=bool)

    def update(self, probe_pos, probe_vel, hub_angle):
        """(T, p, 3) probe positions / velocities and (T,) hub angle -> (L, phi, omega_tip),
        each (T, n_arms)."""
        T, n = probe_pos.shape[0], self.n
        tip_p, tip_v = probe_pos[:, :n], probe_vel[:, :n]
        L = np.empty((T, n))
        phi = np.empty((T, n))
        r0 = self.r0
        sp = probe_pos[:, n:, :2]
        on_hub = (np.hypot(sp[..., 0], sp[..., 1]) <= r0 * (1 + self.tol) if r0 > 0
                  else np.zeros(sp.shape[:2], bool))
        for k in range(n):
            sel = np.flatnonzero(self.s_arm == k)
            lev = self.s_lev[sel]
            nlev = lev.max() + 1 if len(sel) else 0
            level_on = np.ones((T, nlev), bool)
            for j in range(nlev):
                level_on[:, j] = on_hub[:, sel[lev == j]].all(axis=1)
            run = np.cumprod(level_on, axis=1).sum(axis=1)  # leading levels on the hub
            gap = np.max(np.diff(np.unique(self.s_coord[sel]))) if nlev > 1 else 0.0
            for t in range(T):
                L[t, k], phi[t, k] = self._measure(k, t, hub_angle[t], tip_p[t, k], sp[t], sel,
                                                   lev, int(run[t]), gap)
                self.prev_phi[k] = phi[t, k]
        px, py = tip_p[..., 0], tip_p[..., 1]
        r2 = np.maximum(px * px + py * py, 1e-300)
        omega_tip = (px * tip_v[..., 1] - py * tip_v[..., 0]) / r2
        return L, phi, omega_tip

    def _measure(self, k, t, hub_angle, tip, sp, sel, lev, run, gap):
        r0 = self.r0
        th_root = hub_angle + self.root[k]
        ex, ey = math.cos(th_root), math.sin(th_root)
        if run >= 2:  # something is wound: departure point D = last wound spine node
            d = sp[sel[lev == run - 1][0]]
            q0, q1 = sp[sel[lev == 0][0]], sp[sel[lev == 1][0]]
            sense = 1.0 if q0[0] * q1[1] - q0[1] * q1[0] < 0 else -1.0  # clockwise: trailing
            a_d = self.s_coord[sel[lev == run - 1][0]] / r0
            # refine with the tangent from the tip (exact for a straight, taut free part)
            rho = math.hypot(tip[0], tip[1])
            l_tan = math.sqrt(max(rho * rho - r0 * r0, 0.0))
            th_t = math.atan2(tip[1], tip[0]) + sense * math.atan2(l_tan, r0)
            # angle from D on to the tangent point, along the coil (the coil may slide on a
            # frictionless hub, so measure from D, not from the root)
            delta = sense * (math.atan2(d[1], d[0]) - th_t)
            delta -= 2 * math.pi * round(delta / (2 * math.pi))
            if abs(delta) <= (2 * gap + math.sqrt(2 * self.tol) * r0) / r0:
                alpha, length = a_d + delta, l_tan
            else:
                alpha, length = a_d, math.hypot(tip[0] - d[0], tip[1] - d[1])
            if alpha > 0:
                self.prev_wound[k] = True
                return length, -sense * (0.5 * math.pi + alpha)
        qx, qy = tip[0] - r0 * ex, tip[1] - r0 * ey
        phi = math.atan2(ex * qy - ey * qx, ex * qx + ey * qy)
        prev = self.prev_phi[k]
        if prev == prev and not self.prev_wound[k]:  # continuous in time: the 2 pi branch
            #     nearest the previous row (an arm just off the hub takes the principal value)
            phi += 2 * math.pi * round((prev - phi) / (2 * math.pi))
        self.prev_wound[k] = False
        return math.hypot(qx, qy), phi
