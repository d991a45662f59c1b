"""Per-arm measures of the FE state, defined as in the analytical model.

Each arm (tether) has a root point R on the hub rim (hub-frame angle theta_R, the mesh's
``arm_root_angle``) and a tip node. As in the analytical model the arm is a straight free
part of length L hanging from an anchor A on the rim, either pivoting about A or leaving the
hub tangentially at a departure point D after winding on from A; phi is the arm's angle
from the outward radial at R, counter-clockwise positive, with |phi| = pi/2 + alpha while
wound over alpha. At each history row, per arm:

- the anchor is R, except where a held coil's front F on the rim holds the arm: under a
  rate payout (its restraint holds F), or once the arm swung over its own coil (the
  measure from R no longer finds it wound in the coil's direction, and the tip lies on the
  leading side of F's radial; a front that merely lags the tangent point leaves the anchor
  at R). The arm then hangs from F, wound over alpha_F = (s_F - arm_root_coord) / r0 from
  R (the step loop records F and the law);
- **pivoting** about A: phi = -w alpha_A + beta, beta the angle of (tip - A) from the
  outward radial at A, continued in time (no jump at +-pi); L = |tip - A|. w is the coil's
  wrap sign (+1 trailing: clockwise), alpha_A = 0 for A = R;
- **wrapped** once the line A -> tip would cross the hub (|beta| > pi/2): the arm winds on
  the hub in the direction it swung, c = -sign(beta); D is the tangent point from the tip
  on that side, wound over rel from A (continued in time over several turns),
  phi = -w alpha_A - c (pi/2 + rel), L the tangent length; back to pivoting when rel = 0.

A coiled arm starts wrapped over its whole coil. Under a free payout the held coil is thus
measured from R by its tangent point, whatever the discrete front: the chain kinks over about
one element at the front, so the front lags the straight arm's departure by up to one level
while the tip, hub and tension follow the continuum (docs/validation.md). Every branch meets
the next continuously for a straight arm (D = A at rel = 0, phi the same on both sides);
the anchor moves by one level (and the measure steps by at most that) when a rate payout
releases the front the arm hangs from, or when the arm swings over its coil.
omega_tip = (p x v)_z / |p|^2, the rate of the tip's polar angle about the hub axis.
The same rows give a held coil's front coordinate and the payout speed, the rate of
its paid-out length H_coord - s_D (H_coord: the tip's arm coordinate, s_D the departure
point's arm coordinate), and log when a rate payout waits for its arm.
"""

from __future__ import annotations

import logging
import math

import numpy as np

log = logging.getLogger(__name__)

PIVOT, WRAPPED = 0, 1


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


def _near(x, ref):
    """x shifted by whole turns to lie within pi of ref."""
    return x + 2 * math.pi * round((ref - x) / (2 * math.pi))


class ArmTracker:
    """Turns the recorded tip positions / velocities (and a held coil's fronts) into L, phi,
    omega_tip per arm.

    Parameters
    ----------
    mesh : Mesh
    r0 : float [m]
        Hub radius (0: no hub, nothing is ever wound).

    Its memory from row to row (:meth:`memory`, :meth:`restore`: a restarted run continues
    it): per arm the branch (pivot / wrapped), the wrap direction, the last phi and
    departure angle, the last departure coordinate and whether a rate payout waits.
    """

    name = "arms"

    def __init__(self, mesh, r0):
        tips = np.asarray(mesh.node_sets["tips"], dtype=np.int64)
        self.probes = tips
        self.n = len(tips)
        roots = mesh.arm_root_angle
        if len(roots) != self.n:  # no arm data: measure each tip from its own radial
            ref = mesh.node_ref[tips]
            roots = np.arctan2(ref[:, 1], ref[:, 0])
        self.root = np.asarray(roots, float)
        self.r0 = float(r0)
        self.tip_coord = float(mesh.arm_length)
        self.root_coord = float(mesh.arm_root_coord)
        self.wrap = float(mesh.wrap or 1)
        coiled = mesh.wrap != 0 and self.r0 > 0
        self.mode = np.full(self.n, WRAPPED if coiled else PIVOT)
        self.sense = np.full(self.n, self.wrap)  # c: +1 wound clockwise from R
        # angle of the departure point from R along the coil (w), continued in time
        self.prev_ad = np.full(self.n, (self.tip_coord - self.root_coord) / self.r0
                               if coiled else 0.0)
        self.prev_phi = np.full(self.n, np.nan)
        self.prev_sd = np.full(self.n, np.nan)  # departure coordinate of the previous row
        self.prev_front = np.full(self.n, np.nan)  # its front, the front's level spacing,
        self.prev_gap = np.full(self.n, np.nan)  # and whether the departure point was the
        self.prev_tangent = np.zeros(self.n, bool)  # tangent point on the rim
        self.tangent = np.zeros((0, self.n), bool)  # the last rows': the same
        self.waiting = np.zeros(self.n, bool)  # a rate payout's front waits for its arm

    def memory(self) -> dict:
        """What the measure carries from row to row (copies)."""
        return {k: getattr(self, k).copy() for k in
                ("mode", "sense", "prev_ad", "prev_phi", "prev_sd", "prev_front",
                 "prev_gap", "prev_tangent", "waiting")}

    def restore(self, memory: dict) -> None:
        """Continue from :meth:`memory` of an earlier run (same mesh)."""
        for k, v in memory.items():
            if hasattr(self, k):
                setattr(self, k, np.array(v, dtype=getattr(self, k).dtype))

    def columns(self, rows, probe_pos, probe_vel, arm_table=None, row_dt=1.0,
                rate=False, law=None) -> dict:
        """History columns of T rows, each (T, n_arms): ``arm_length``, ``arm_angle``,
        ``tip_omega``, ``tip_position`` (T, n_arms, 3), and with a held coil's arm rows
        ``arm_table`` from the step loop (fe.layout.ARM by name, each (T, n_arms)) also
        ``payout_front`` [m], ``payout_speed`` [m/s] (``row_dt`` [s] apart) and, under a
        payout device (``rate``: the arm hangs from its front) with a length law (``law``,
        default ``rate``), ``payout_allowed`` [m]. ``rows``: the rows' ``time`` and
        ``hub_angle``."""
        L, phi, wtip, sd = self.update(probe_pos, probe_vel, rows["hub_angle"], arm_table, rate)
        out = {"arm_length": L, "arm_angle": phi, "tip_omega": wtip,
               "tip_position": probe_pos[:, :self.n].copy()}
        if arm_table is None:
            return out
        speed = self._speed(sd, arm_table["front"], arm_table["next"], row_dt)
        out.update(payout_front=arm_table["front"].copy(), payout_speed=speed)
        if rate if law is None else law:
            out["payout_allowed"] = arm_table["allowed"].copy()
            self._watch(arm_table, sd, rows["time"])
        return out

    def _speed(self, sd, front, nxt, row_dt):
        """(T, n_arms) [m/s] the rate of the paid-out length between rows, NaN where the
        departure point jumps (no speed is defined across a jump): the measure switches
        between the tangent point on the rim and the front, or the front it measures moves
        by half a level or more between two rows (a level released at once; a device's
        front moves with its line, a level in a row only at 1000 m/s for 2 m levels and 1 ms
        rows)."""
        prev = np.vstack([self.prev_sd[None, :], sd[:-1]])
        speed = np.where(np.isfinite(prev) & np.isfinite(sd), (prev - sd) / row_dt, 0.0)
        gap = np.abs(nxt - front)
        prev_tan = np.vstack([self.prev_tangent[None, :], self.tangent[:-1]])
        prev_front = np.vstack([self.prev_front[None, :], front[:-1]])
        prev_gap = np.vstack([self.prev_gap[None, :], gap[:-1]])
        with np.errstate(invalid="ignore"):
            released = np.abs(front - prev_front) >= 0.5 * prev_gap
        switched = self.tangent != prev_tan
        jump = np.isfinite(prev) & (switched | (released & ~self.tangent & ~prev_tan))
        if len(sd):
            self.prev_sd = sd[-1].copy()
            self.prev_front, self.prev_gap = front[-1].copy(), gap[-1].copy()
            self.prev_tangent = self.tangent[-1].copy()
        return np.where(jump, np.nan, speed)

    def update(self, probe_pos, probe_vel, hub_angle, arm_table=None, rate=False):
        """(T, n_arms, 3) tip positions / velocities, (T,) hub angle and optionally a held
        coil's arm rows (fe.layout.ARM by name; ``rate``: paid out by a rate law) -> (L, phi,
        omega_tip, departure coordinate), each (T, n_arms); the departure is NaN without a
        held coil."""
        T, n = probe_pos.shape[0], self.n
        tip_p, tip_v = probe_pos[:, :n], probe_vel[:, :n]
        L, phi, sd = np.empty((T, n)), np.empty((T, n)), np.full((T, n), np.nan)
        self.tangent = np.zeros((T, n), bool)
        for k in range(n):
            for t in range(T):
                th_r = hub_angle[t] + self.root[k]
                # a held front on the rim anchors the arm under a rate payout (the
                # restraint holds it there) or when the arm swung over its own coil
                # (unwound from R's side and on the front's leading side)
                alpha_a = 0.0
                on_rim = arm_table is not None and arm_table["rim"][t, k] > 0.5
                if on_rim:
                    front = arm_table["front"][t, k]
                    alpha_f = (front - self.root_coord) / self.r0
                    swung = not (self.mode[k] == WRAPPED and self.sense[k] == self.wrap)
                    if rate or arm_table["held_back"][t, k] > 0.5 or (
                            swung and self._leading(alpha_f, th_r, tip_p[t, k])):
                        alpha_a = alpha_f
                L[t, k], phi[t, k], a_d = self._about(k, alpha_a, th_r, tip_p[t, k])
                self.prev_phi[k] = phi[t, k]
                if arm_table is not None:
                    self.tangent[t, k] = on_rim and a_d > 0
                    sd[t, k] = (self.root_coord + self.r0 * a_d if self.tangent[t, k]
                                else arm_table["front"][t, k])
        px, py = tip_p[..., 0], tip_p[..., 1]
        r2 = np.maximum(px * px + py * py, 1e-300)
        omega_tip = (px * tip_v[..., 1] - py * tip_v[..., 0]) / r2
        return L, phi, omega_tip, sd

    def _tangent(self, tip, c):
        """(inertial angle of the tangent point from the tip on the side of a coil wound in
        direction c, tangent length)."""
        rho = math.hypot(tip[0], tip[1])
        l_tan = math.sqrt(max(rho * rho - self.r0 * self.r0, 0.0))
        return math.atan2(tip[1], tip[0]) + c * math.atan2(l_tan, self.r0), l_tan

    def _leading(self, alpha_f, th_r, tip):
        """True if the tip lies on the leading side of the radial through the front F
        (wound over alpha_f from R): the arm cannot be leaving the coil in its direction."""
        th_f = th_r - self.wrap * alpha_f
        cross = math.cos(th_f) * tip[1] - math.sin(th_f) * tip[0]  # > 0: counter-clockwise
        return self.wrap * cross > 0.0

    def _about(self, k, alpha_a, th_r, tip):
        """(L, phi, angle of the departure point from R along the coil) of an arm anchored
        at A, wound over alpha_a from R (A = R: 0): pivoting about A, or wrapped on the hub
        from A in the direction it swung."""
        w, r0 = self.wrap, self.r0
        if self.mode[k] == WRAPPED and r0 > 0:
            c = self.sense[k]
            th_d, l_tan = self._tangent(tip, c)
            a_d = _near(w * (th_r - th_d), self.prev_ad[k])
            rel = w * c * (a_d - alpha_a)
            if rel > 0:
                self.prev_ad[k] = a_d
                return l_tan, -w * alpha_a - c * (0.5 * math.pi + rel), a_d
            self.mode[k] = PIVOT
        th_a = th_r - w * alpha_a
        ex, ey = math.cos(th_a), math.sin(th_a)
        qx, qy = tip[0] - r0 * ex, tip[1] - r0 * ey
        phi = -w * alpha_a + math.atan2(ex * qy - ey * qx, ex * qx + ey * qy)
        prev = self.prev_phi[k]
        if prev == prev:  # continuous in time: the 2 pi branch nearest the previous row
            phi = _near(phi, prev)
        beta = phi + w * alpha_a
        if abs(beta) > 0.5 * math.pi and r0 > 0:  # the line A -> tip would cross the hub
            c = -math.copysign(1.0, beta)
            th_d, l_tan = self._tangent(tip, c)
            rel = max(_near(c * (th_a - th_d), 0.0), 0.0)
            a_d = alpha_a + w * c * rel
            self.mode[k], self.sense[k], self.prev_ad[k] = WRAPPED, c, a_d
            return l_tan, -w * alpha_a - c * (0.5 * math.pi + rel), a_d
        return math.hypot(qx, qy), phi, alpha_a

    def _watch(self, arm_table, sd, times):
        """Log when a rate payout's front waits: the law allows more than two level spacings
        beyond what the arm has paid out (the free part does not pull the coil off)."""
        paid = self.tip_coord - sd
        lag = arm_table["allowed"] - paid
        gap = np.abs(arm_table["next"] - arm_table["front"])
        for k in range(self.n):
            for t in range(lag.shape[0]):
                wait = bool(lag[t, k] > 2.0 * gap[t, k] and np.isfinite(paid[t, k]))
                if wait and not self.waiting[k]:
                    log.info("t = %.4g s, arm %d: the payout waits for its arm (the law "
                             "allows %.4g m, %.4g m are paid out)", times[t], k,
                             arm_table["allowed"][t, k], paid[t, k])
                self.waiting[k] = wait
