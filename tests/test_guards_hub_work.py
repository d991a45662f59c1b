"""Guard of the fail-safe's hub reaction on a fixed axis (issue #47): the energy the
contact's impulses took, with the hub's share paired with the mean of its half-step rates
(omega_{n-1/2} + omega_{n+1/2}) / 2 as the nodes' impulses are with their half-step
velocities. A bar driven through an element tied to the hub, one step, the fail-safe called
through its Python function (contact_resolve has no Python entry)."""

import numpy as np
import pytest

from spinweb_fe.fe.contact.bounds import Certified, contact_profile, no_motion
from spinweb_fe.fe.contact.impulses import hub_start
from spinweb_fe.fe.contact.failsafe import contact_resolve
from spinweb_fe.fe.contact.penalty import (IMPULSES, MARGIN, ROUNDS, TAKEN, ContactKernel)
from spinweb_fe.fe.contact.zones import no_adjacency


def _resolve(ck, pos, vel, inv_mass, dt, rate, inertia, theta):
    """contact_resolve run by Python (it has no Python entry; its helpers are the compiled
    kernels): its own lines, where the hub's work is paired, as written."""
    return contact_resolve.py_func(ck, pos, vel, inv_mass, dt, rate, inertia, None, theta)


def test_the_fixed_hubs_reaction_work_is_paired_with_its_half_step_rates():
    """Element 0 tied to the hub, upright at x = 1.5 m; element 1 (two free 2 kg nodes)
    along x at z = 0.1 moving in +y at 20 m/s, through element 0 within the step (dt = 1e-2
    s). The impulse along y at x = 1.5 m turns the hub (J = 40 kg m^2) by dw, whose sign
    keeps the angular momentum about the axis; the hub's rates omega_{n-1/2} = 1, omega_{n+1/2}
    = 3 rad/s. The energy taken is minus the nodes' impulse work, sum m dv . (v_{n-1/2} +
    v_{n+1/2}) / 2, minus the hub's, J dw (omega_{n-1/2} + omega_{n+1/2} + dw) / 2, to 1e-15
    (a few ulps: measured 6.5e-17 of the 437 J taken; the angular momentum 1.2e-16). The
    hub's pairing with its new rate alone would be off by J dw (3 - 1) / 2 = 61 J."""
    dt, J, w_minus, w_plus = 1e-2, 40.0, 1.0, 3.0
    elems = np.array([[0, 1], [2, 3]], np.int64)
    pos0 = np.array([[1.5, 0.0, -0.5], [1.5, 0.0, 0.5],
                     [1.0, -0.1, 0.1], [2.0, -0.1, 0.1]])
    v = np.zeros((4, 3))
    v[2:, 1] = 20.0
    pos = pos0 + dt * v
    inv_mass = np.array([0.0, 0.0, 0.5, 0.5])
    pairs = np.array([[0, 1]], np.int64)
    h0 = hub_start()
    h0.rate[0] = w_minus
    motion = no_motion(4, 2)
    cert = Certified(np.full(1, -1.0), motion, no_adjacency(4, 1), np.ones(2, np.int8),
                     *contact_profile())
    n = 4
    ck = ContactKernel(elems, pairs, np.zeros(1), np.zeros((1, 3)), v.copy(), np.zeros((n, 3)),
                       np.zeros((n, 3)), h0, np.zeros((n, 3)), np.zeros(n, np.int64),
                       np.zeros(n, np.bool_), pos0.copy(), np.ones(2, np.int8), cert, 0.01,
                       0.25, MARGIN * 0.01, ROUNDS, 0.0, np.zeros(9), np.zeros((1, 2)))
    vel = v.copy()
    rate, inertia = np.array([w_plus]), np.array([J])
    _resolve(ck, pos, vel, inv_mass, dt, rate, inertia, 0.0)
    assert ck.stats[IMPULSES] >= 1
    dv = vel - v
    assert np.abs(dv[2:, 1]).max() > 1.0  # the bar was stopped or turned back
    dw = rate[0] - w_plus
    m = np.array([0.0, 0.0, 2.0, 2.0])[:, None]
    # angular momentum about the axis: the nodes' change (y x m dv, y = x_{n+1} - dt v) and
    # the hub's J dw cancel
    y = pos - dt * vel
    Hz = (m * np.cross(y, dv)).sum(axis=0)[2]
    assert abs(Hz + J * dw) < 1e-15 * abs(J * dw) and abs(dw) > 1e-3
    nodes = (m * dv * (v + vel)).sum() / 2.0
    hub = J * dw * (w_minus + w_plus + dw) / 2.0
    assert ck.stats[TAKEN] == pytest.approx(-nodes - hub, rel=1e-15)
    assert abs(J * dw * (w_plus - w_minus) / 2.0) > 1e-3 * abs(ck.stats[TAKEN])
