"""Payout devices: how a held coil lets its arm's line out (``[stowage] payout``), one
registry entry each, and the kernels of the two that act on the line (docs/solver.md):

- ``free``: the front level goes when the free part pulls it off the hub (fe.coil.levels);
- ``gate``: as free, but never ahead of a law L(t): a latch that frees stowed levels no
  faster than the law (a burn-wire release of folded segments, say); it does no work;
- ``rate``: a reel at each arm's departure point D that holds the line and lets it out at
  the law (control by the arm length);
- ``brake``: a brake at D that lets the line slip while the line's tension there exceeds
  the brake force and holds it while it is below (control by the force that resists the
  deployment).

The reel and the brake hold the line at D with the front level's free elements: each has
the free fraction phi of its material out (the rest of its rest length is still in the
device), so its rest length is phi L0 and the free length follows the device to round-off,
not to a level. Such an element acts as a spring of stiffness E A / L0 (that of the whole
element: the time step stays that of the mesh) on its stretch d - phi L0. The held front
level sits at D, which moves along the coil between the front level's place and the next
outer one's as the line goes out. Mass passes D with the line: the outer end of each of
these elements carries phi of its half of the element's mass, the device the rest; what
passes in a step joins the outer node with the velocity the line has at D (D's own and the
line speed along the element), from the hub's velocity there: the device's impulse, whose
reaction acts on the hub (its moment too, so that momentum and angular momentum are
conserved to round-off). The device's work is what its update changes in the energy:
kinetic energy of the nodes it touches and of the hub, strain energy of its elements.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.choice import Choice, Param, registry
from spinweb_fe.fe.coil.levels import level_masses
from spinweb_fe.fe.law import length_strain, rate

#: the last time of a constant law's table [s]: value v from 0 up to here
HORIZON = 1e9
FREE, GATE, REEL, BRAKE = 0, 1, 2, 3


def rate_table(rate: float):
    """The paid-out length table of a constant payout rate [m/s]: L(t) = rate t."""
    return np.array([0.0, HORIZON]), np.array([0.0, rate * HORIZON])


def payout_table(st: dict):
    """((P,) times [s], (P,) values) of a [stowage] table's device law (resolved values):
    paid-out lengths [m] (gate, rate) or brake forces [N] (brake); None without one."""
    if st.get("payout_rate") is not None:
        return rate_table(st["payout_rate"])
    if st.get("brake_force") is not None:
        return np.array([0.0, HORIZON]), np.full(2, float(st["brake_force"]))
    for key in ("payout_length", "brake_force_table"):
        if st.get(key) is not None:
            times, values = zip(*st[key])
            return np.array(times, np.float64), np.array(values, np.float64)
    return None


def _table_rule(key, what, increasing):
    def check(tables):
        table = tables["stowage"].get(key)
        if table is None:
            return None
        times, values = zip(*table)
        if any(b <= a for a, b in zip(times, times[1:])) or times[0] < 0:
            return f"stowage.{key}", f"the times must be >= 0 and increase, got {list(times)} s"
        if min(values) < 0 or (increasing and any(b < a for a, b in zip(values, values[1:]))):
            rule = "be >= 0 and never decrease" if increasing else "be >= 0"
            return f"stowage.{key}", f"the {what} must {rule}, got {list(values)}"
        return None
    return check


def _device(name, rule, what=""):
    def check(tables):
        st = tables["stowage"]
        if st["coil"] != "held":
            return "stowage.payout", f"a {name} payout needs stowage.coil = 'held'"
        if what and st["bundle"] != "none":
            return "stowage.bundle", (f"a {what} holds each arm's line at its departure "
                                      "point: bundles are not modelled with it (bundle = "
                                      "'none')")
        return rule(tables)
    return check


_LENGTH = (Param("payout_rate", "m/s", "pos", "payout = gate or rate: paid-out length "
                 "rate t"),
           Param("payout_length", "s, m", None, "payout = gate or rate: [[t, L], ...] "
                 "paid-out length L at time t, linear between the points", kind="table"))
@dataclass(frozen=True)
class Payout(Choice):
    """A payout law: ``device``, a reel or brake at each arm's departure point D (it holds
    the line there, its tension turns the hub, its work is an energy term: fe.coil.payout's
    phases, the ``devices`` feature); ``length_law``, a law of the paid-out length limits
    the payout (``payout_allowed``). The kernels read them as ``Coil.device`` and
    ``Coil.length_law``."""

    device: bool = False
    length_law: bool = False

    @property
    def anchors(self) -> bool:
        """The arm hangs from its front (or its device), not from a free peel front."""
        return self.device or self.length_law


PAYOUTS = registry(
    Payout("free", FREE, "the front advances when the free part pulls it off the hub",
           analytic="the coiled regime: the arm leaves the hub tangentially"),
    Payout("gate", GATE, "as free, but never ahead of the law (payout_rate or "
                         "payout_length): a latch that does no work",
           keys=_LENGTH, need=(("payout_rate", "payout_length"),),
           check=_device("gate", _table_rule("payout_length", "lengths", True)),
           length_law=True),
    Payout("rate", REEL, "a reel at each arm's departure point: the free length follows the "
                         "law (payout_rate or payout_length)",
           keys=_LENGTH, need=(("payout_rate", "payout_length"),),
           check=_device("rate", _table_rule("payout_length", "lengths", True), "reel"),
           analytic="the paying regime: the arm hangs from its departure point, which the "
                    "law moves back along the coil", device=True, length_law=True),
    Payout("brake", BRAKE, "a brake at each arm's departure point: the line slips while "
                           "its tension there exceeds brake_force (or brake_force_table)",
           keys=(Param("brake_force", "N", "nonneg", "payout = brake: the brake force"),
                 Param("brake_force_table", "s, N", None, "payout = brake: [[t, N], ...] "
                       "brake force N at time t, linear between the points", kind="table")),
           need=(("brake_force", "brake_force_table"),),
           check=_device("brake", _table_rule("brake_force_table", "forces", False), "brake"),
           analytic="the braking regime: stick (the arm pivots about its departure point) "
                    "and slip (the tension there equals the brake force)", device=True),
)
#: the entries by code (the solver's view)
BY_CODE = {c.code: c for c in PAYOUTS.values()}


def payout_of(coil) -> Payout:
    """The payout law of a coil (fe.coil.levels.Coil), its registry entry."""
    return BY_CODE[int(coil.payout_code)]


@njit(inline="always")
def _frac(s_to, s_f, s):
    """The share of a front-level element (from arm coordinate s_f to s_to) out of the
    device when the line at D has arm coordinate s."""
    return min(max((s_to - s) / (s_to - s_f), 0.0), 1.0)


@njit(cache=True)
def device_forces(coil, cs, elems, pos, vel, work, record, broken):
    """The front level's free elements of each arm as its device holds them: the free part
    of each runs from D (``cs.dev_x``) to its outer node; its force vector goes into
    ``work.ef`` (replacing the element pass's), its tension into ``work.tension`` on record
    steps, the arm's line tension at D into ``cs.dev_tension``. The held front node takes
    the force in the node sums; ``cs.dev_moment`` receives the moment that moves it to D
    ((x_D - x_a) x f, summed: the hub's loads add it). Returns the corrections of the
    element pass's (strain energy [J], damping power [W]) and the largest device tension
    [N] (``coil`` None: nothing, at compile time)."""
    if coil is None:
        return 0.0, 0.0, 0.0
    ea, inv_rest, rest, cdamp, damped = elems.ea, elems.inv_rest, elems.rest_len, \
        elems.cdamp, elems.damped
    first = elems.nodes
    ef, tension = work.ef, work.tension
    dse, dpow, tmax = 0.0, 0.0, 0.0
    cs.dev_moment[:] = 0.0
    for k in range(coil.arm_ptr.shape[0] - 1):
        lev = coil.arm_ptr[k] + cs.front[k]
        cs.dev_tension[k] = 0.0
        if lev >= coil.arm_ptr[k + 1] or cs.front[k] == 0:
            continue
        s_f = coil.level_coord[lev]
        xd = cs.dev_x[k]
        total = 0.0
        for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
            e, a, b = coil.test_elem[q], coil.test_from[q], coil.test_to[q]
            if broken.shape[0] > 0 and broken[e]:
                continue
            dx, dy, dz = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
            inv, strain = length_strain(dx, dy, dz, inv_rest[e])  # the pass's element
            if record:
                dse -= 0.5 * ea[e] * strain * strain / inv_rest[e]
            if damped:
                ldot = rate(dx, dy, dz, inv, vel[b, 0] - vel[a, 0], vel[b, 1] - vel[a, 1],
                            vel[b, 2] - vel[a, 2])
                n_el = ea[e] * strain
                n_tot = max(n_el + (cdamp[e] * ldot if strain > 0.0 else 0.0), 0.0)
                dpow -= (n_tot - n_el) * ldot
            ux, uy, uz = pos[b, 0] - xd[0], pos[b, 1] - xd[1], pos[b, 2] - xd[2]
            d = np.sqrt(ux * ux + uy * uy + uz * uz + 1e-300)
            stretch = max(d - rest[e] * _frac(coil.test_to_coord[q], s_f, cs.s_dev[k]), 0.0)
            n = ea[e] * inv_rest[e] * stretch  # E A / L0 (d - phi L0)
            c = n / d
            fx, fy, fz = c * ux, c * uy, c * uz  # the force on the held end a
            sign = 1.0 if first[e, 0] == a else -1.0  # ef: the force on the first end
            ef[0, e] = sign * fx
            ef[1, e] = sign * fy
            ef[2, e] = sign * fz
            rx, ry, rz = xd[0] - pos[a, 0], xd[1] - pos[a, 1], xd[2] - pos[a, 2]
            cs.dev_moment[0] += ry * fz - rz * fy
            cs.dev_moment[1] += rz * fx - rx * fz
            cs.dev_moment[2] += rx * fy - ry * fx
            if record:
                tension[e] = n
                dse += 0.5 * n * stretch
                tmax = max(tmax, n)
            total += n
        cs.dev_tension[k] = total
    return dse, dpow, tmax


@njit(inline="always")
def device_point(coil, k, lev, s):
    """(3,) hub-frame position of arm k's departure point D when its front level is
    ``lev`` and the line at D has arm coordinate s: between the front level's place on the
    coil and the next outer level's, interpolated in polar coordinates about the hub axis."""
    pf = coil.level_ref[coil.level_ptr[lev]]
    if lev == coil.arm_ptr[k]:
        return pf.copy()
    po = coil.level_ref[coil.level_ptr[lev - 1]]
    s_f, s_o = coil.level_coord[lev], coil.level_coord[lev - 1]
    a = min(max((s - s_f) / (s_o - s_f), 0.0), 1.0)
    rf, ro = np.hypot(pf[0], pf[1]), np.hypot(po[0], po[1])
    tf = np.arctan2(pf[1], pf[0])
    dth = np.arctan2(po[1], po[0]) - tf
    dth -= 2.0 * np.pi * np.floor(dth / (2.0 * np.pi) + 0.5)
    r, th = rf + a * (ro - rf), tf + a * dth
    return np.array([r * np.cos(th), r * np.sin(th), pf[2] + a * (po[2] - pf[2])])


class Pose(NamedTuple):
    """The hub's pose and motion as the devices see it (fe.hub.axis.axis_pose, fe.hub.body.body_pose):
    ``rot`` (3, 3) the attitude R (hub frame to world), ``centre`` (3,) [m] the hub centre o,
    ``com`` (3,) [m] the body's centre of mass X, ``velocity`` (3,) [m/s] its V, ``omega``
    (3,) [rad/s] its angular velocity (a fixed axis: o = X = V = 0, omega = w e_z)."""

    rot: np.ndarray
    centre: np.ndarray
    com: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray


class LineReaction(NamedTuple):
    """What an arm's line update gives the hub (:func:`move_line`, summed): ``impulse`` (3,)
    [N s], the impulse J given to the line (its reaction -J acts on the hub at D);
    ``moment`` (3,) [N m s], the angular impulse on the hub about the origin that conserves
    angular momentum; ``inertia`` (1,) [kg m^2], the released nodes' model m (x^2 + y^2) at
    their hub-frame places."""

    impulse: np.ndarray
    moment: np.ndarray
    inertia: np.ndarray


@njit(cache=True)
def no_reaction():
    """A :class:`LineReaction` of zeros."""
    return LineReaction(np.zeros(3), np.zeros(3), np.zeros(1))


@njit(cache=True)
def locate_devices(coil, cs, pose):
    """Every active device's D in the world, ``cs.dev_x`` = o + R r_D (``pose``: the hub's
    :class:`Pose`)."""
    for k in range(coil.arm_ptr.shape[0] - 1):
        cs.dev_x[k] = _world(pose, cs.dev_ref[k])


@njit(inline="always")
def _world(pose, r):
    R = pose.rot
    return pose.centre + np.array([R[0, 0] * r[0] + R[0, 1] * r[1] + R[0, 2] * r[2],
                                   R[1, 0] * r[0] + R[1, 1] * r[1] + R[1, 2] * r[2],
                                   R[2, 0] * r[0] + R[2, 1] * r[1] + R[2, 2] * r[2]])


@njit(inline="always")
def _hub_velocity3(pose, x0, x1, x2):
    """The velocity of the hub's material point at (x0, x1, x2), V + omega x (x - X), as
    three floats (no array: the device's inner loops run every step)."""
    w, X, V = pose.omega, pose.com, pose.velocity
    d0, d1, d2 = x0 - X[0], x1 - X[1], x2 - X[2]
    return (V[0] + (w[1] * d2 - w[2] * d1), V[1] + (w[2] * d0 - w[0] * d2),
            V[2] + (w[0] * d1 - w[1] * d0))


@njit(inline="always")
def _hub_velocity(pose, x):
    """:func:`_hub_velocity3` at x as a (3,) array."""
    v0, v1, v2 = _hub_velocity3(pose, x[0], x[1], x[2])
    return np.array([v0, v1, v2])


@njit(inline="always")
def rest_ref(coil, k, lev):
    """(3,) hub-frame place of the mass arm k's device holds while ``lev`` is its front: the
    next outer level's place on the coil (where the outer halves it holds came from; the
    place does not move while the line passes D, so no mass moves without its momentum)."""
    return coil.level_ref[coil.level_ptr[lev - 1]]


@njit(cache=True)
def start_devices(coil, cs, nodes, mass, inv_mass):
    """A reel's or brake's start: every arm's line at its tip (nothing out: s_dev the tip's
    coordinate), the front level's free elements wholly in the device (their outer halves
    off the released nodes' masses, held at D: ``dev_rest``), D at the tip level's place.
    Returns the held mass's sum m (x^2 + y^2) [kg m^2]."""
    j = 0.0
    for k in range(coil.arm_ptr.shape[0] - 1):
        cs.s_dev[k] = coil.arm_end[k]
        lev = coil.arm_ptr[k] + cs.front[k]
        if cs.front[k] > 0 and lev < coil.arm_ptr[k + 1]:
            j += _open_level(coil, cs, k, lev, mass, inv_mass)
    return j


@njit(cache=True)
def _open_level(coil, cs, k, lev, mass, inv_mass):
    """Level ``lev`` becomes arm k's front with its free elements wholly in the device:
    their outer halves leave the outer nodes' masses and are held by the device (at
    :func:`rest_ref`), D at the next outer level's place. Returns the held mass's
    m (x^2 + y^2) [kg m^2]."""
    rest = 0.0
    for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
        b = coil.test_to[q]
        mass[b] -= coil.test_half[q]
        inv_mass[b] = 1.0 / mass[b] if mass[b] > 0.0 else 0.0
        rest += coil.test_half[q]
    cs.dev_rest[k] = rest
    cs.dev_ref[k] = device_point(coil, k, lev, coil.level_coord[lev - 1])
    r = rest_ref(coil, k, lev)
    return rest * (r[0] ** 2 + r[1] ** 2)


@njit(cache=True)
def _release(coil, cs, k, nodes, mass, inv_mass, lev):
    """Level ``lev`` of arm k goes free (its nodes' own masses; their velocities are the
    hub's where they are). Returns their model m (x^2 + y^2) at their hub-frame places."""
    j = 0.0
    for p in range(coil.level_ptr[lev], coil.level_ptr[lev + 1]):
        i = coil.level_nodes[p]
        j += nodes.mass[i] * (coil.level_ref[p, 0] ** 2 + coil.level_ref[p, 1] ** 2)
    level_masses(coil.level_ptr, coil.level_nodes, coil.level_mass, nodes.mass, nodes.inv_mass,
                 mass, inv_mass, lev, lev + 1, False)
    cs.front[k] += 1
    return j


@njit(cache=True)
def move_line(coil, cs, k, elems, nodes, mv, pose, s_new, dt, out):
    """Arm k's line at D from ``cs.s_dev[k]`` to ``s_new`` (a delayed arm's whole coil, not
    yet free, first frees its tip level): the material that passes D joins the outer nodes
    of the front level's elements with the line's velocity there (D's own, ``pose`` at the
    old and the new place over ``dt``, and the line speed along the element); a front
    level the line passes is released (its nodes free with the hub's velocity at D, their
    masses their own less the next front's outer halves). ``out``: a :class:`LineReaction`
    the update adds its reaction to."""
    pos, vel, mass, inv_mass = mv.pos, mv.vel, mv.mass, mv.inv_mass
    first, end = coil.arm_ptr[k], coil.arm_ptr[k + 1]
    lev = first + cs.front[k]
    s_old = cs.s_dev[k]
    if cs.front[k] == 0:  # a delayed arm's tip level goes free
        out.inertia[0] += _release(coil, cs, k, nodes, mass, inv_mass, lev)
        if lev + 1 < end:
            _open_level(coil, cs, k, lev + 1, mass, inv_mass)
            cs.dev_x[k] = _world(pose, cs.dev_ref[k])
        return
    x_d = cs.dev_x[k].copy()
    v_h = _hub_velocity(pose, x_d)
    lf = lev
    while lf < end and s_new <= coil.level_coord[lf]:
        lf += 1
    x_n = _world(pose, device_point(coil, k, lf, s_new)) if lf < end else x_d
    v_d = v_h + (x_n - x_d) / dt  # D slides along the coil as the line goes out
    s = s_old
    while lev < end:
        s_f = coil.level_coord[lev]
        s_stop = max(s_new, s_f)
        x_m = _world(pose, rest_ref(coil, k, lev))  # where the device's mass is held
        vm0, vm1, vm2 = _hub_velocity3(pose, x_m[0], x_m[1], x_m[2])
        for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
            f0 = _frac(coil.test_to_coord[q], s_f, s)
            f1 = _frac(coil.test_to_coord[q], s_f, s_stop)
            dm = (f1 - f0) * coil.test_half[q]
            if dm <= 0.0:
                continue
            b = coil.test_to[q]
            r0, r1, r2 = pos[b, 0] - x_d[0], pos[b, 1] - x_d[1], pos[b, 2] - x_d[2]
            size = np.sqrt(r0 ** 2 + r1 ** 2 + r2 ** 2)
            u = (f1 - f0) * elems.rest_len[coil.test_elem[q]] / dt  # line speed through D
            c = u / size if size > 0.0 else 0.0
            v0, v1, v2 = v_d[0] + c * r0, v_d[1] + c * r1, v_d[2] + c * r2  # the line's at D
            m1 = mass[b] + dm
            vel[b, 0] = (mass[b] * vel[b, 0] + dm * v0) / m1
            vel[b, 1] = (mass[b] * vel[b, 1] + dm * v1) / m1
            vel[b, 2] = (mass[b] * vel[b, 2] + dm * v2) / m1
            mass[b] = m1
            inv_mass[b] = 1.0 / m1
            # the impulse J on the line and the angular impulse that keeps K on the hub:
            # -(x_m x J + (x_b - x_m) x dm v_in)
            j0, j1, j2 = dm * (v0 - vm0), dm * (v1 - vm1), dm * (v2 - vm2)
            J, H = out.impulse, out.moment
            J[0] += j0
            J[1] += j1
            J[2] += j2
            p0, p1, p2 = pos[b, 0] - x_m[0], pos[b, 1] - x_m[1], pos[b, 2] - x_m[2]
            g0, g1, g2 = dm * v0, dm * v1, dm * v2
            H[0] -= (x_m[1] * j2 - x_m[2] * j1) + (p1 * g2 - p2 * g1)
            H[1] -= (x_m[2] * j0 - x_m[0] * j2) + (p2 * g0 - p0 * g2)
            H[2] -= (x_m[0] * j1 - x_m[1] * j0) + (p0 * g1 - p1 * g0)
            cs.dev_rest[k] -= dm
        s = s_stop
        if s > s_f:
            break
        out.inertia[0] += _release(coil, cs, k, nodes, mass, inv_mass, lev)
        lev += 1
        if lev >= end:
            cs.dev_rest[k] = 0.0
            break
        _open_level(coil, cs, k, lev, mass, inv_mass)
    cs.s_dev[k] = s
    if lev < end:
        cs.dev_ref[k] = device_point(coil, k, lev, s)
        cs.dev_x[k] = _world(pose, cs.dev_ref[k])
    cs.dev_speed[k] = (s_old - s) / dt
