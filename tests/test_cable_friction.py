"""Coulomb friction between touching cables (``[contact] friction``, fe.contact.penalty:
tangential impulses at the step's end), against its own law: the impulse is mu F dt while
the pair slides and what stops it when that is more; momentum is kept, the kinetic energy
it takes is what it books, and a frictionless case is bit-identical to one without the key.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from spinweb_fe.fe.contact.penalty import KAPPA, contact_forces
from spinweb_fe.fe.contact.impulses import friction_impulses

PAIR = np.array([[0, 1]], np.int64)
ELEMS = np.array([[0, 1], [2, 3]], np.int64)
RADIUS, DT, MU = 0.05, 1e-4, 0.4


def touching(slide, normal=0.0, angle=0.7):
    """Bar 0 along x, bar 1 turned by ``angle`` about z and 1.6 radii above it (in
    contact), bar 1 moving at ``slide`` [m/s] along x and ``normal`` along z; masses 1, 2,
    3, 4 kg. Returns pos, vel, inv_mass, hold (the push's normal force and s, t)."""
    c, s = math.cos(angle), math.sin(angle)
    pos = np.array([[-1.0, 0.2, 0.0], [1.0, 0.2, 0.0],
                    [-c + 0.3, -s, 1.6 * RADIUS], [c + 0.3, s, 1.6 * RADIUS]])
    vel = np.zeros((4, 3))
    vel[2:, 0] = slide
    vel[2:, 2] = normal
    inv_mass = 1.0 / np.array([1.0, 2.0, 3.0, 4.0])
    hold = np.zeros((1, 3))
    contact_forces(PAIR, ELEMS, pos, inv_mass, np.full(1, 2 * RADIUS), RADIUS, KAPPA, DT,
                   np.zeros_like(pos), np.zeros(4, np.int64), None, hold)
    return pos, vel, inv_mass, hold


def apply(pos, vel, inv_mass, hold, mu=MU):
    v = vel.copy()
    pos1 = pos + DT * v
    taken = friction_impulses(PAIR, ELEMS, hold, pos, pos1, v, inv_mass, DT, mu)
    return v, pos1, taken


def relative(v, inv_mass, hold):
    s, t = hold[0, 1], hold[0, 2]
    return (1 - s) * v[0] + s * v[1] - (1 - t) * v[2] - t * v[3]


@pytest.mark.parametrize("slide", [50.0, 0.01])
def test_friction_slows_the_sliding_by_mu_f_dt_or_stops_it(slide):
    """Sliding fast (50 m/s): the relative sliding speed drops by w mu F dt (w the pair's
    inverse mass at its points), to 1e-12; slowly (1 cm/s, less than that): it stops (1e-14
    m/s left, relative to the speed). The normal relative velocity is not touched (1e-15
    relative). Momentum kept to
    round-off (1e-15 relative), the booked energy the kinetic energy's fall (1e-12) and
    positive; the angular momentum changes by at most the couple's 2 r j (the arm of the
    two points along the normal)."""
    pos, vel, inv_mass, hold = touching(slide, normal=-0.3)
    fn, s, t = hold[0]
    assert fn > 0
    v, pos1, taken = apply(pos, vel, inv_mass, hold)
    w = (1 - s) ** 2 * inv_mass[0] + s * s * inv_mass[1] + (1 - t) ** 2 * inv_mass[2] \
        + t * t * inv_mass[3]
    r0, r1 = relative(vel, inv_mass, hold), relative(v, inv_mass, hold)
    n = np.array([0.0, 0.0, -1.0])  # bar 0 is below: p - q points down
    t0, t1 = r0 - (r0 @ n) * n, r1 - (r1 @ n) * n
    scale = 1.0 + np.linalg.norm(r0)
    assert abs(r1 @ n - r0 @ n) < 1e-15 * scale
    j = MU * fn * DT
    if np.linalg.norm(t0) > w * j:
        assert np.linalg.norm(t0) - np.linalg.norm(t1) == pytest.approx(w * j, rel=1e-12)
    else:
        assert np.linalg.norm(t1) < 1e-14 * scale
        j = np.linalg.norm(t0) / w
    m = 1.0 / inv_mass
    p0, p1 = (m[:, None] * vel).sum(0), (m[:, None] * v).sum(0)
    assert np.abs(p1 - p0).max() < 1e-15 * max(1.0, np.abs(p0).max())
    ke0, ke1 = 0.5 * (m * (vel ** 2).sum(1)).sum(), 0.5 * (m * (v ** 2).sum(1)).sum()
    assert taken > 0 and taken == pytest.approx(ke0 - ke1, rel=1e-12)
    l0 = np.cross(pos, m[:, None] * vel).sum(0)
    l1 = np.cross(pos, m[:, None] * v).sum(0)
    assert np.linalg.norm(l1 - l0) <= 2 * RADIUS * j * (1 + 1e-9)
    assert np.allclose(pos1, pos + DT * v, rtol=0, atol=1e-15)


def test_no_contact_no_friction():
    """A pair apart (no normal force) and a pair at rest relative to each other get no
    impulse."""
    pos, vel, inv_mass, hold = touching(0.0)
    v, _, taken = apply(pos, vel, inv_mass, hold)
    assert taken == 0.0 and np.array_equal(v, vel)
    hold[:] = 0.0
    pos, vel, inv_mass, _ = touching(10.0)
    v, _, taken = apply(pos, vel, inv_mass, hold)
    assert taken == 0.0 and np.array_equal(v, vel)


def test_a_run_with_friction_books_it_and_frictionless_is_unchanged():
    """The paper's feedback web folded with a 5 mm layer gap, with contact, 0.05 s (its
    layers touch as they unfold): friction 0 gives the bits of a case without the key;
    friction 0.5 takes kinetic energy through its impulses (measured 0.42 kJ, against
    0.16 kJ of the fail-safe's without it; 1.21 and 0.06 kJ before the penalty pushed
    against the held coil too, when the layers pressed harder: the penalty held 10 J or
    more, now 1.4 J), booked so that the energy balance closes as without friction
    (6-7e-5; tolerance 1e-3, the contact test's) and no crossing is made."""
    from support import layered_contact_run

    from spinweb_fe.record.energy import balance_error
    plain, c0, _ = layered_contact_run([])
    zero, _, _ = layered_contact_run(["contact.friction=0.0"])
    for k in plain:
        assert np.array_equal(plain[k], zero[k]), k
    assert c0.friction_dissipated == 0.0 and plain["cable_contact_energy"].max() > 1.0
    rough, c1, crossings = layered_contact_run(["contact.friction=0.5"])
    assert c1.friction_dissipated > 100.0
    assert rough["cable_contact_dissipation"][-1] == pytest.approx(c1.dissipated, rel=1e-12)
    assert balance_error(rough) < 1e-3 and balance_error(plain) < 1e-3
    assert crossings == 0


def test_the_impulses_work_is_the_leapfrogs_pairing():
    """fe.contact.penalty.impulse_work: an impulse that changes v_{n+1/2} from b to a does the
    work m (a - b) . (v_{n-1/2} + a) / 2 (the midpoint rule the step books a force with);
    with v_{n-1/2} = b (no other force in the step) that is the kinetic energy's change;
    held nodes (inverse mass 0) count nothing."""
    from spinweb_fe.fe.contact.impulses import impulse_work

    rng = np.random.default_rng(3)
    before, after, start = (rng.standard_normal((5, 3)) for _ in range(3))
    inv_mass = np.array([1.0, 0.5, 0.0, 2.0, 0.25])
    m = np.where(inv_mass > 0, 1.0 / np.where(inv_mass > 0, inv_mass, 1.0), 0.0)
    want = 0.5 * np.sum(m[:, None] * (after - before) * (start + after))
    assert impulse_work(before, after, start, inv_mass) == pytest.approx(want, rel=1e-14)
    ke = 0.5 * np.sum(m[:, None] * (after ** 2 - before ** 2))
    assert impulse_work(before, after, before, inv_mass) == pytest.approx(ke, rel=1e-14)
