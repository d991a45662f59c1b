"""Cable-cable contact at rest (issue #26, item 4): a short cable hanging over a taut cable in
a steady spin, and the penalty's forces under a rigid motion.

The scene is solved in the frame that turns with the web, where a steady spin is a body
force m omega^2 (x, y, 0) on every node (no Coriolis force at rest): a chord of N elements
pinned at both ends at radius R, pre-tensioned, and a two-node bar across it on the hub's
side, which the spin presses outward onto the chord. Central differences with a velocity
damping run it to rest; the contact's forces (fe.contact.penalty.contact_forces, the step
loop's kernel) then carry the bar's whole centrifugal load, equal and opposite on the chord,
and the chord's deflection is the taut string's closed form.
"""

from __future__ import annotations

import math

import numpy as np

from spinweb_fe.fe.contact.penalty import KAPPA, contact_forces

OMEGA, R, HALF = 2.0, 10.0, 1.0        # rad/s; chord at radius R [m], half-length [m]
N, RHO, EA, STRAIN0 = 20, 0.01, 1e5, 1e-3   # elements, kg/m, N, pre-strain
BAR_MASS, BAR_LEN, RADIUS = 0.01, 0.2, 0.005  # kg, m, m
DT = 1e-5


def scene():
    """Positions, masses, elements and rest lengths of the chord (nodes 0..N) and the bar
    (nodes N+1, N+2, element N) a little inside it, across it at its middle."""
    x = np.linspace(-HALF, HALF, N + 1)
    chord = np.column_stack([x, np.full(N + 1, R), np.zeros(N + 1)])
    gap = 2 * RADIUS + 0.002  # apart at the start: the spin brings them together
    bar = np.array([[0.0, R - gap, -BAR_LEN / 2], [0.0, R - gap, BAR_LEN / 2]])
    pos = np.vstack([chord, bar])
    h = 2 * HALF / N
    mass = np.r_[np.full(N + 1, RHO * h), [BAR_MASS / 2, BAR_MASS / 2]]
    mass[[0, N]] *= 0.5
    inv_mass = 1.0 / mass
    inv_mass[[0, N]] = 0.0  # pinned
    elems = np.array([[i, i + 1] for i in range(N)] + [[N + 1, N + 2]], np.int64)
    rest = np.r_[np.full(N, h / (1 + STRAIN0)), [BAR_LEN]]
    return pos, mass, inv_mass, elems, rest


def cable_forces(pos, elems, rest):
    """Tension-only axial forces EA (l - l0) / l0 (the bar as stiff as the chord)."""
    d = pos[elems[:, 1]] - pos[elems[:, 0]]
    length = np.linalg.norm(d, axis=1)
    tension = np.maximum(EA * (length - rest) / rest, 0.0)
    fe = (tension / length)[:, None] * d
    f = np.zeros_like(pos)
    np.add.at(f, elems[:, 0], fe)
    np.add.at(f, elems[:, 1], -fe)
    return f, tension, d


def settle(steps=40_000, damping=200.0):
    pos, mass, inv_mass, elems, rest = scene()
    pairs = np.array([[e, N] for e in range(N)], np.int64)
    reach = np.full(len(pairs), 2 * RADIUS)
    vel = np.zeros_like(pos)
    fc = np.zeros_like(pos)
    share = np.zeros(len(pos), np.int64)
    for _ in range(steps):
        f, _, _ = cable_forces(pos, elems, rest)
        body = mass[:, None] * OMEGA ** 2 * pos * np.array([1.0, 1.0, 0.0])
        contact_forces(pairs, elems, pos, inv_mass, reach, RADIUS, KAPPA, DT, fc, share)
        vel += DT * inv_mass[:, None] * (f + body + fc - damping * mass[:, None] * vel)
        pos += DT * vel
    contact_forces(pairs, elems, pos, inv_mass, reach, RADIUS, KAPPA, DT, fc, share)
    return pos, mass, elems, rest, fc, vel


def test_a_cable_hanging_over_a_taut_cable_in_a_steady_spin():
    """At rest (speeds below 1e-7 m/s): the contact's force on the bar balances its
    centrifugal load to 1e-6 (what is left is the damped motion's residue), the chord takes
    the opposite force to round-off (1e-12), the bar sits 2 r from the chord less the
    penalty's static give (F / k: 0.2 N on each of two pairs of k = 1e6 N/m, 2e-7 m), and the chord's deflection at its middle
    is the taut string's (w a^2 + P a) / (2 H) with H the chord's tension across its ends,
    to 5e-4 (8e-5 measured; the spin's pull along the chord changes H by rho omega^2 a^2 / 2 = 2e-4 of it,
    and the string's small-slope form drops (delta / a)^2 = 2e-5)."""
    pos, mass, elems, rest, fc, vel = settle()
    assert np.abs(vel).max() < 1e-7
    bar = [N + 1, N + 2]
    load = (mass[bar, None] * OMEGA ** 2 * pos[bar] * np.array([1.0, 1.0, 0.0])).sum(0)
    on_bar, on_chord = fc[bar].sum(0), fc[:N + 1].sum(0)
    assert np.linalg.norm(on_bar + load) < 1e-6 * np.linalg.norm(load)
    assert np.linalg.norm(on_bar + on_chord) < 1e-12 * np.linalg.norm(load)
    mid = N // 2
    give = 2 * RADIUS - (pos[mid, 1] - pos[bar[0], 1])
    assert 0.0 < give < 1e-6
    # the string's closed form
    _, tension, d = cable_forces(pos, elems, rest)
    h_tension = 0.5 * (tension[0] * d[0, 0] / np.linalg.norm(d[0])
                       + tension[N - 1] * d[N - 1, 0] / np.linalg.norm(d[N - 1]))
    w = (mass[1:N] * OMEGA ** 2 * pos[1:N, 1]).sum() / (2 * HALF - 2 * HALF / N)
    deflection = pos[mid, 1] - R
    expected = (w * HALF ** 2 + load[1] * HALF) / (2 * h_tension)
    assert deflection > 0
    assert abs(deflection - expected) < 5e-4 * expected


def test_the_penalty_turns_and_moves_with_the_pair():
    """contact_forces of a pair turned and shifted rigidly: the same energy and the forces
    turned with it (1e-12 of their size)."""
    pos = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.2, -1.0, 0.006], [0.1, 1.0, 0.004]])
    inv_mass = np.ones(4)
    pairs, elems = np.array([[0, 1]], np.int64), np.array([[0, 1], [2, 3]], np.int64)

    def run(p):
        f = np.zeros_like(p)
        e, n, _ = contact_forces(pairs, elems, p, inv_mass, np.full(1, 0.01), 0.005, KAPPA,
                                 1e-4, f, np.zeros(4, np.int64))
        return f, e, n

    f0, e0, n0 = run(pos)
    a, b = 0.8, -0.4
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    rot = rx @ rz
    f1, e1, n1 = run(pos @ rot.T + np.array([30.0, -7.0, 2.0]))
    assert n0 == n1 == 1 and e0 > 0
    assert abs(e1 - e0) < 1e-9 * e0
    assert np.abs(f1 - f0 @ rot.T).max() < 1e-9 * np.abs(f0).max()
