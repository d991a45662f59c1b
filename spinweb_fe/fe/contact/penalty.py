"""Cable-cable contact (``[contact] cables = true``, issue #26): two elements that share no
node repel where they come closer than twice the cable radius r.

A penalty force between the two closest points p (on element ab, at a + s (b - a)) and q
(on cd, at c + t (d - c)) of the pair, along n = (p - q) / |p - q|:

    F = k delta n,   delta = 2 r - |p - q| > 0,   k = kappa m / dt^2,

on the first element's ends (1 - s) F and s F, on the second's -(1 - t) F and -t F. The
forces are equal and opposite and act along the line of the two points, so the pair
changes neither the linear nor the angular momentum (to round-off). The stiffness is the
stiffest the time step carries: m is the pair's two sides in series, each side the
lighter of its element's two nodes (1 / m = max(1/m_a, 1/m_b) + max(1/m_c, 1/m_d): at
least the effective inverse mass wherever the elements touch, so that the contact spring's
critical step is at least 4 dt with kappa = 0.25: the step does not change; and one k per
pair, so that the force is the gradient of the stored energy). The penalty is a potential:
the energy it stores, sum 1/2 k delta^2, is booked in the balance as ``cable_contact_energy``; the
central-difference update integrates it as it does the cables (energy to O(dt^2)).

What a penalty cannot do: stop two elements that close faster than the spring can push
back within the gap. A pair closing at v penetrates about v / omega, omega = sqrt(k / m_c)
with m_c its effective mass where it touches (omega dt = 0.35 at mid-element, 0.5 at a
node, with kappa = 0.25), so the radius must be about 1.5 v dt for elements closing at v
(tests/test_cable_contact.py: 200 m/s at dt = 1e-4 s passes through at r = 2.5 cm, not at
3 cm): 1.4 mm at 20 m/s and 1.4 cm at 200 m/s on the paper web's step (4.6e-5 s). The
crossing audit, which runs with the contact, counts the crossings that still happen.

Friction (``[contact] friction`` mu, Coulomb): at the step's end every pair that was in
contact at its start gets a tangential impulse at its two closest points (the step's
normal force F from above), opposite to their relative sliding velocity v_t (of
v_{n+1/2}) and at most what stops it there: j = min(mu F dt, |v_t| / w), w the pair's
inverse mass at those points (sum of the squared weights over the nodes' masses), equal
and opposite on the two elements (x_{n+1} = x_n + dt v_{n+1/2} follows). The energy it
takes is booked with the fail-safe's as ``cable_contact_dissipation`` (both paired as the
step pairs a force's work, fe.contact.impulses); the sliding is slowed at most to rest (j <= |v_t|
/ w). The two points are
up to twice the radius apart along the normal, so the pair of impulses makes a couple of
that arm: angular momentum changes by at most 2 r j per contact (linear momentum is kept
to round-off).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.contact.bounds import ROUND, Certified, bound_now
from spinweb_fe.fe.contact.clock import (C_CLOSEST, C_PUSH, C_SELECT, N_NEAR, N_PUSH, N_TOUCH,
                                         cycles, lap)
from spinweb_fe.fe.contact.distance import closest_nodes
from spinweb_fe.fe.contact.impulses import HubStart

#: the penalty stiffness k = KAPPA m / dt^2 (the contact spring's critical step 4 dt)
KAPPA = 0.25
#: the fail-safe's impulses leave a crossing pair this share of the radius apart
MARGIN = 0.1
#: passes of the fail-safe over the candidate pairs per step at most
ROUNDS = 20


@njit(inline="always")
def _box_gap(pos, a, b, c, d):
    """The largest gap [m] along an axis between the boxes of elements ab and cd (a lower
    bound of their distance)."""
    gap = 0.0
    for k in range(3):
        g = max(min(pos[c, k], pos[d, k]) - max(pos[a, k], pos[b, k]),
                min(pos[a, k], pos[b, k]) - max(pos[c, k], pos[d, k]))
        gap = max(gap, g)
    return gap


@njit(cache=True)
def contact_forces(pairs, elem_nodes, pos, inv_mass, reach, radius, kappa, dt, force, share,
                   cert=None, hold=None, slack=0.0):
    """The penalty forces of the candidate ``pairs`` at ``pos`` into ``force`` (n, 3),
    which is zeroed first; ``reach`` (P,) [m]: each pair's contact distance (twice the
    radius, or less for a pair that entered the list closer: it is raised to the largest
    distance the pair has had, up to twice the radius, here). A node that does not move
    freely (inv_mass 0: held on or tied to the hub, inside a bundle) takes its share of
    the force like the others (the step hands it on: :func:`add_penalty`); a pair with no
    free node is left out. A node in contact with
    several elements at once (a column of stacked layers) shares the step's stiffness
    among them: each pair's k is divided by the most contacts one of its nodes has now
    (``share`` (n,) int64 scratch), so that the springs on a node together stay within the
    step. ``cert`` (fe.contact.bounds.Certified), if given: the pairs' certificates, whose
    bound at ``pos`` (the step's start) rules out the pairs farther apart than twice the
    radius (else the pairs' own boxes at ``pos``); a pair it does not rule out gets its
    exact distance less ``slack`` [m] (round-off) as its new bound, and the three loops
    are timed into its profile (fe.contact.clock: C_SELECT, C_CLOSEST, C_PUSH). ``hold``
    (P, 3), if given: each pair's normal force [N] (0: not in contact) and its closest
    points' s and t, for the friction. Returns (stored energy [J], pairs in contact,
    deepest penetration [m])."""
    force[:] = 0.0
    share[:] = 0
    if hold is not None:
        hold[:, 0] = 0.0
    reach_max = 2.0 * radius
    energy, count, deepest = 0.0, 0, 0.0
    # first the near pairs (those their certificate or boxes do not hold farther apart than
    # twice the radius: a far one's contact distance rises to it), their closest points
    # (NaN: no node free) and the contacts per node, then the push
    n_pairs = pairs.shape[0]
    near = np.empty(n_pairs, np.int64)
    n_near = 0
    if cert is not None:
        start = cycles()
    for p in range(n_pairs):
        e, g = pairs[p, 0], pairs[p, 1]
        if cert is None:
            far = _box_gap(pos, elem_nodes[e, 0], elem_nodes[e, 1], elem_nodes[g, 0],
                           elem_nodes[g, 1]) >= reach_max
        else:
            far = bound_now(cert.level, cert.motion, p, e, g) > reach_max
        if far:
            if reach[p] < reach_max:
                reach[p] = reach_max
            continue
        near[n_near] = p
        n_near += 1
    if cert is not None:
        start = lap(cert.clock, C_SELECT, start)
    ps, pt, pd = np.empty(n_near), np.empty(n_near), np.empty(n_near)
    for q in range(n_near):
        p = near[q]
        e, g = pairs[p, 0], pairs[p, 1]
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[g, 0], elem_nodes[g, 1]
        if max(inv_mass[a], inv_mass[b]) + max(inv_mass[c], inv_mass[d]) == 0.0:
            pd[q] = np.nan  # no node moves freely
            continue
        ps[q], pt[q], pd[q] = closest_nodes(pos, a, b, c, d)
        if cert is not None:  # (a level at the step's start: its sums to then)
            mo = cert.motion
            cert.level[p] = max(cert.level[p], pd[q] - slack + mo.cum0[e] + mo.cum0[g])
        if 0.0 < pd[q] < reach[p]:
            share[a] += 1
            share[b] += 1
            share[c] += 1
            share[d] += 1
    if cert is not None:
        start = lap(cert.clock, C_CLOSEST, start)
    for q in range(n_near):
        p = near[q]
        dist = pd[q]
        if np.isnan(dist):
            continue
        if dist >= reach[p] or dist <= 0.0:  # apart: the contact distance rises with it
            reach[p] = min(max(reach[p], dist), reach_max)
            continue
        e, g = pairs[p, 0], pairs[p, 1]
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[g, 0], elem_nodes[g, 1]
        s, t = ps[q], pt[q]
        delta = reach[p] - dist
        # the pair's stiffness from its nodes' masses, not from where it touches: one
        # k per pair (while its nodes' contacts stay) keeps the force the gradient of
        # 1/2 k delta^2
        im = max(inv_mass[a], inv_mass[b]) + max(inv_mass[c], inv_mass[d])
        many = max(max(share[a], share[b]), max(share[c], share[d]))
        k = kappa / (im * dt * dt * many)
        fmag = k * delta / dist
        for j in range(3):
            pj = pos[a, j] + s * (pos[b, j] - pos[a, j])
            qj = pos[c, j] + t * (pos[d, j] - pos[c, j])
            fj = fmag * (pj - qj)
            force[a, j] += (1.0 - s) * fj
            force[b, j] += s * fj
            force[c, j] -= (1.0 - t) * fj
            force[d, j] -= t * fj
        if hold is not None:
            hold[p, 0], hold[p, 1], hold[p, 2] = k * delta, s, t
        energy += 0.5 * k * delta * delta
        count += 1
        deepest = max(deepest, delta)
    if cert is not None:
        lap(cert.clock, C_PUSH, start)
        cert.tally[N_PUSH] += 1
        cert.tally[N_NEAR] += n_near
        cert.tally[N_TOUCH] += count
    return energy, count, deepest


@njit(cache=True)
def add_penalty(ck, force):
    """The penalty's forces at x_n (:func:`contact_push`) into the step's ``force`` (n, 3)
    [N], after the cables': part of f_n, on every node. A node that does not move freely
    hands its share on as it hands on the cables' (the hub's torque, the free body's force
    and moment, a bundle's gathering), so a cable pushed off the held coil or the hub's
    frame pushes the hub back, and the step's momenta stay in balance at every row."""
    if ck.stats[IN_CONTACT] == 0:
        return
    for i in range(force.shape[0]):
        for k in range(3):
            force[i, k] += ck.force[i, k]


class ContactKernel(NamedTuple):
    """The cable-cable contact as the step loop sees it (:meth:`CableContact.kernel`).

    elem_nodes, pairs: as the audit's; reach (P,) [m]: each pair's contact distance; hold
    (P, 3): each pair's normal force [N] and closest points at the step's start; vel0,
    vel1, vel2 (n, 3) [m/s]: v_{n-1/2} at the step's start and scratch for the impulses'
    work; hub0: the hub at the step's start and the reaction the fail-safe gave it
    (fe.contact.impulses.HubStart); force
    (n, 3) [N] and share (n,) int64: scratch; follow (n,) bool: the free nodes that move
    with the hub this step (fe.contact.zones); pos0, active, cert: the audit's (x_n, the
    elements its broad phase takes, the pairs' certificates and the step's motion:
    fe.contact.bounds.Certified); radius [m],
    kappa, margin [m] (the fail-safe's), rounds, mu (the friction coefficient); stats (9,):
    stored energy [J], pairs in contact, deepest penetration [m] now and over the run,
    energy the fail-safe took [J], its impulses, crossings it left, energy the friction
    took [J], impulses of the passes after a reaction of the hub (fe.step.settle); rows
    (R, 2): stored energy and dissipation (fail-safe and friction) at each history row [J].
    """

    elem_nodes: np.ndarray
    pairs: np.ndarray
    reach: np.ndarray
    hold: np.ndarray
    vel0: np.ndarray
    vel1: np.ndarray
    vel2: np.ndarray
    hub0: HubStart
    force: np.ndarray
    share: np.ndarray
    follow: np.ndarray
    pos0: np.ndarray
    active: np.ndarray
    cert: Certified
    radius: float
    kappa: float
    margin: float
    rounds: int
    mu: float
    stats: np.ndarray
    rows: np.ndarray


#: ContactKernel.stats slots
ENERGY, IN_CONTACT, DEEPEST, DEEPEST_RUN, TAKEN, IMPULSES, LEFT, FRICTION, AGAIN = range(9)


@njit(cache=True, no_cpython_wrapper=True)
def contact_push(ck, pos, vel, inv_mass, dt):
    """The penalty forces at x_n into ``ck.force`` (the step adds them to f_n:
    :func:`add_penalty`), and v_{n-1/2} kept (the impulses' work at the step's end is
    paired with it; its copy is timed with the near selection)."""
    start = cycles()
    ck.vel0[:] = vel
    lap(ck.cert.clock, C_SELECT, start)
    st = ck.stats
    st[ENERGY], count, st[DEEPEST] = contact_forces(ck.pairs, ck.elem_nodes, pos, inv_mass,
                                                    ck.reach, ck.radius, ck.kappa, dt,
                                                    ck.force, ck.share, ck.cert,
                                                    ck.hold,
                                                    ROUND * ck.cert.motion.scale[0])
    st[IN_CONTACT] = count
    st[DEEPEST_RUN] = max(st[DEEPEST_RUN], st[DEEPEST])


@njit(cache=True, no_cpython_wrapper=True)
def contact_row(ck, k):
    """Row ``k`` of the call: the stored energy and the fail-safe's dissipation so far."""
    ck.rows[k, 0] = ck.stats[ENERGY]
    ck.rows[k, 1] = ck.stats[TAKEN] + ck.stats[FRICTION]


