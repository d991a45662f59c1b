"""Cable strength: the failure strain of each element, strength margins and rupture.

A scene with a failure strain (``[cable] failure_strain``) runs its element pass through
:func:`strength_pass` instead of the plain one of :mod:`spinweb_fe.fe.step`: the same
tension-only law, operation for operation (so the forces and every other history are bit for
bit those of the same scene without a failure strain), plus

- the peak utilisation u = eps / eps_f over the elements and the steps since the previous
  history row, with its strain and its element (:attr:`StrengthState.peak`);
- with rupture on, the break: an intact element whose strain at x_n exceeds eps_f breaks for
  good at that step. From then on it carries no force (elastic or damper) and its strain is
  no longer checked; the energy it held is added to :attr:`StrengthState.dissipation` (the
  ``rupture_dissipation`` of the energy balance): its strain energy EA eps^2 L0 / 2 at x_n,
  less the half step of work dt N dL/dt / 2 (dL/dt with v_{n-1/2}) that its tension would
  still have done in the central-difference step. That is what the scheme's discrete energy
  (KE of the half-step velocities v_{n-1/2} . v_{n+1/2} plus SE at x_n) loses when the
  element's force is dropped at step n; with the strain energy alone the balance would gain
  dt N dL/dt / 2 per break, an O(dt) error in a snapping web (measured: 9 % of the
  dissipated energy in the free web at cfl 0.2, halving with dt).

A scene without a failure strain has empty arrays here and never calls these kernels: its
element loop is the plain one (no strain check, no broken flag to read).

The break criterion is on the elastic strain (the fibre's), not on the damper's share of the
tension. Elements are visited in index order and chunks are merged in chunk order, so the
peak's element is the first of equal utilisations, for every thread count.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.forces import sum_blocks
from spinweb_fe.fe.law import damped_tension, lengthening, stretch

class Strength(NamedTuple):
    """The strength data of the elements (fixed during a run).

    Attributes
    ----------
    fail : (m,) float64 [-]
        Failure strain eps_f of each element (empty: the scene has no strength check).
    inv_fail : (m,) float64 [-]
        1 / eps_f.
    rupture : bool
        Elements whose strain exceeds eps_f break for good.
    """

    fail: np.ndarray
    inv_fail: np.ndarray
    rupture: bool


class StrengthState(NamedTuple):
    """What changes of the strength check during a run.

    Attributes
    ----------
    broken : (m,) bool
        The element has broken (empty unless rupture is on).
    peak : (3,) float64
        Largest utilisation eps / eps_f since the last history row, its strain [-] and its
        element (-1 and -1 after a row, before the next element pass).
    dissipation : (1,) float64 [J]
        Energy that the broken elements held when they broke, summed (see the module).
    count : (1,) int64
        Broken elements.
    """

    broken: np.ndarray
    peak: np.ndarray
    dissipation: np.ndarray
    count: np.ndarray


def no_strength() -> Strength:
    """Strength data of a scene without a failure strain (no check)."""
    return Strength(np.zeros(0), np.zeros(0), False)


def make_strength(n_elems: int, failure_strain, rupture: bool) -> Strength:
    """Strength data: one failure strain [-] for every element (None: no check)."""
    if failure_strain is None:
        return no_strength()
    fail = np.full(n_elems, float(failure_strain))
    return Strength(fail, 1.0 / fail, bool(rupture))


def strength_start(strength: Strength) -> StrengthState:
    """The strength state at the start of a run: nothing broken, no peak yet."""
    m = strength.fail.shape[0] if strength.rupture else 0
    return StrengthState(np.zeros(m, np.bool_), np.array([-1.0, 0.0, -1.0]), np.zeros(1),
                         np.zeros(1, np.int64))


@njit(cache=True, error_model="numpy")
def accumulate_strength(elems, strength, broken, pos, vel, ef, lo, hi, record, tension, dt):
    """The element law of :mod:`spinweb_fe.fe.forces` (same operations) over elements
    lo..hi-1, with the strength check and the break (``dt`` [s]: the step, for the energy of
    a break): each element's force vector into ``ef`` (3, m + 1) (zero once broken), its
    tension into ``tension`` unless that is empty.

    Returns (strain energy [J] on record steps, max tension [N], damping power [W], peak
    utilisation, its strain, its element, energy of the elements broken now [J], their
    number).
    """
    elem_nodes = elems.nodes
    inv_rest = elems.inv_rest
    ea = elems.ea
    cdamp = elems.cdamp
    damped = elems.damped
    fail = strength.fail
    inv_fail = strength.inv_fail
    rupture = strength.rupture
    se = 0.0
    tmax = 0.0
    pdamp = 0.0
    upeak = -1.0
    speak = 0.0
    epeak = -1
    released = 0.0
    nbreak = 0
    write_tension = tension.shape[0] > 0
    for e in range(lo, hi):
        n_tot = 0.0
        dx = dy = dz = inv = 0.0
        if not (rupture and broken[e]):  # broken for good: no force, no check
            i = elem_nodes[e, 0]
            j = elem_nodes[e, 1]
            dx, dy, dz, inv, strain = stretch(pos, i, j, inv_rest[e])  # N = EA max(eps, 0)
            u = strain * inv_fail[e]  # utilisation eps / eps_f
            if u > upeak:
                upeak = u
                speak = strain
                epeak = e
            n_el = ea[e] * strain
            if rupture and strain > fail[e]:  # the break at x_n: U - dt N dL/dt / 2 dissipated
                broken[e] = True
                nbreak += 1
                ldot = lengthening(vel, i, j, dx, dy, dz, inv)
                released += 0.5 * n_el * strain / inv_rest[e] - 0.5 * dt * n_el * ldot
            else:
                n_tot = n_el
                if damped:  # N_d = c dL/dt while taut, total tension never negative
                    ldot = lengthening(vel, i, j, dx, dy, dz, inv)
                    n_tot = damped_tension(n_el, strain, cdamp[e], ldot)
                    pdamp += (n_tot - n_el) * ldot
                if record:
                    se += 0.5 * n_el * strain / inv_rest[e]  # U = EA eps^2 L0 / 2
                    tmax = max(tmax, n_tot)
        if write_tension:
            tension[e] = n_tot
        c = n_tot * inv
        ef[0, e] = c * dx
        ef[1, e] = c * dy
        ef[2, e] = c * dz
    return se, tmax, pdamp, upeak, speak, epeak, released, nbreak


@njit(cache=True, no_cpython_wrapper=True)
def strength_block(elems, strength, broken, pos, vel, ef, b, size, record, out, dt):
    """:func:`accumulate_strength` of element block b (``size`` elements) into out (8,)."""
    lo = b * size
    hi = min(lo + size, elems.inv_rest.shape[0])
    (out[0], out[1], out[2], out[3], out[4], out[5], out[6],
     out[7]) = accumulate_strength(elems, strength, broken, pos, vel, ef, lo, hi, record,
                                   np.empty(0), dt)


@njit(cache=True, parallel=True)
def strength_threads(elems, strength, broken, pos, vel, work, record, dt):
    """:func:`strength_block` of every block, thread c taking the c-th of ``nc`` equal runs
    of the blocks in ``work.order`` (each element written by its own block only)."""
    nc = work.buf.shape[0]
    nb = work.eout.shape[0]
    order = work.order
    for c in prange(nc):
        for q in range(nb * c // nc, nb * (c + 1) // nc):
            b = order[q]
            strength_block(elems, strength, broken, pos, vel, work.ef, b, work.buf.shape[2],
                           record, work.eout[b], dt)


@njit(cache=True)
def strength_pass(elems, strength, ss, pos, vel, work, record, dt, threads=None):
    """Element force vectors of this step into ``work.ef`` with the strength check; the peak
    since the last row, the broken count and the rupture dissipation go into ``ss``
    (:class:`StrengthState`). Returns (strain energy, max tension, damping power) as the
    plain element pass does (``threads`` None: one thread, and numba compiles no thread
    kernel). Blocks are merged in block order: the first of equal peaks wins, as serially."""
    eout = work.eout
    if threads is None:
        for b in range(eout.shape[0]):
            strength_block(elems, strength, ss.broken, pos, vel, work.ef, b, work.buf.shape[2],
                           record, eout[b], dt)
    else:
        strength_threads(elems, strength, ss.broken, pos, vel, work, record, dt)
    for b in range(eout.shape[0]):
        merge_peak(ss, eout[b, 3], eout[b, 4], int(eout[b, 5]), eout[b, 6], int(eout[b, 7]))
    return sum_blocks(eout)


@njit(cache=True)
def merge_peak(ss, u, strain, elem, released, nbreak):
    """Fold one pass (or chunk) into the strength state: a larger peak replaces the peak;
    broken elements and their energy are added."""
    if u > ss.peak[0]:
        ss.peak[0] = u
        ss.peak[1] = strain
        ss.peak[2] = elem
    ss.dissipation[0] += released
    ss.count[0] += nbreak


@njit(cache=True, no_cpython_wrapper=True)
def record_strength(ss, row, st):
    """One strength row (slots ``st`` of fe.layout.STRENGTH) at a record step, after its
    element pass (utilisation 0 and element -1 once every element is broken); the peak
    starts again for the next row."""
    row[st.utilisation] = max(ss.peak[0], 0.0)
    row[st.max_strain] = ss.peak[1]
    row[st.max_strain_element] = ss.peak[2]
    row[st.broken_elements] = ss.count[0]
    row[st.rupture_dissipation] = ss.dissipation[0]
    ss.peak[0] = -1.0
    ss.peak[1] = 0.0
    ss.peak[2] = -1.0
