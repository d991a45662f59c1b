"""The crossing audit and the cable-cable contact inside the step loop (issue #26): what
``fe.step.advance`` does with them each step, and the arrays it does it on.

``advance`` takes them as two optional arguments (None: numba prunes every line of them, so
a scene without them compiles and runs as before):

    step start   x_n kept (the step's motion is tested from there); the contact's penalty
                 forces at x_n, which the step adds to f_n (fe.contact.penalty.add_penalty)
    row          the audit's count, the contact's stored energy and dissipation so far
    step end     the contact's fail-safe (impulses at the exact crossing time, after the whole
                 step: the hub's placing of tied and held nodes included; when the hub
                 takes a reaction and places its nodes again, the pairs they have are
                 tested again: fe.step.settle); then the audit's exact test of the step
                 (the motion the step ends with), and whether its list is still valid

The loop stops after a step (status :data:`SERVICE`) when the audit's list has gone stale (a
node moved more than :data:`REBUILD` of the skin since the build, in the frame that follows
the web (fe.contact.bounds), or a
held level went free) or its log is nearly full: Python then rebuilds the list
(record.crossings) and goes on. A list is valid while no node has moved more than the skin:
a pair that was not listed was more than twice the skin apart (their boxes, widened by the
skin on each side, did not overlap); a step that takes a node beyond :data:`WIDE` of the skin
is tested on a list built for it, as wide as its motion. Every pair of the list is tested
each step, first by the boxes the two elements swept (computed once per step and element),
then, for the few whose boxes meet, exactly. With the contact, the fail-safe runs that test
first; a step in which it found no crossing (and moved nothing) is not tested again.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.contact.bounds import (BLOCKS_PER_THREAD, ROUND, THREAD_MIN_PAIRS, StepMotion,
                                          bound_now, pair_motion, set_level, step_motion)
from spinweb_fe.fe.contact.clock import (A_CERT, A_EXACT, A_LOOK, A_MOTION, A_WIDE, SAMPLE,
                                         T_CLOSE, T_EXACT, T_LOOK_SAMPLED, T_LOOKED,
                                         T_PAIR_TEST, T_READ, T_STEPS, T_WIDE, T_WIDE_PAIRS,
                                         cycles, lap)
from spinweb_fe.fe.contact.broad import candidate_pairs, moved_since, swept_boxes
from spinweb_fe.fe.contact.crossing import (SEP, apart, boxed_crossings, log_crossings,
                                            pair_crossings)
from spinweb_fe.fe.contact.distance import closest_nodes
from spinweb_fe.fe.contact.impulses import body_snapshot
from spinweb_fe.fe.contact.penalty import contact_push, contact_row

#: status of ``advance``: stopped after a step for Python to rebuild the audit's list
SERVICE = 2
#: crossings logged per step at most (the count has them all)
LOG_PER_STEP = 64
#: the list is rebuilt after a step that left a node this share of the skin from its place
#: at the build (in the frame that follows the web)
REBUILD = 0.75
#: passes of the contact's fail-safe per step at most: the first, and one after each
#: reaction of the hub (its tied and held nodes placed again, fe.step.settle)
REACTIONS = 4
#: a step that takes a node beyond this share of the skin is tested on a list of its own
#: (the rest of the skin covers the chord of a turning frame: a node at radius rho strays
#: from it by at most rho dtheta^2 / 8 + |dtheta| u / 4 over a step that turns the frame by
#: dtheta and moves the node by u in it, microns at 25 rad/s)
WIDE = 0.9


class AuditKernel(NamedTuple):
    """The crossing audit as the step loop sees it (record.crossings.CrossingAudit.kernel).

    elem_nodes (m, 2) int64; pairs (P, 2) int64: the candidate list; ignored (I,) int64:
    sorted codes (e * m + f) of the pairs left out (touching at entry); active (m,) int8:
    the broad phase's (1, or fe.contact.broad.RIGID for an element both of whose ends move
    with the hub); ref (n, 3) [m]: the nodes at the build, in the frame then; fronts
    (k,) int64: the coil's fronts at the build; pos0 (n, 3) [m]: x_n of the step; frame (1,)
    [rad]: the angle of the frame that follows the web (fe.contact.bounds), in which ``ref``
    and the motions are measured; level (P,)
    [m]: each pair's proven least distance at the step's start (fe.contact.bounds); motion:
    what the nodes moved over the step (fe.contact.bounds.StepMotion); skin [m]; count (1,)
    int64: crossings so far; log_time [s], log_a, log_b, log_sign (L,): the log, n_log (1,)
    int64 of it filled; row_count (R,): the count at each history row of the call; moved
    (1,) [m]: the largest motion since the build.
    """

    elem_nodes: np.ndarray
    pairs: np.ndarray
    ignored: np.ndarray
    active: np.ndarray
    ref: np.ndarray
    fronts: np.ndarray
    pos0: np.ndarray
    frame: np.ndarray
    level: np.ndarray
    motion: StepMotion
    skin: float
    count: np.ndarray
    log_time: np.ndarray
    log_a: np.ndarray
    log_b: np.ndarray
    log_sign: np.ndarray
    n_log: np.ndarray
    row_count: np.ndarray
    moved: np.ndarray
    clock: np.ndarray
    tally: np.ndarray


@njit(cache=True)
def wide_pairs(au, pos0, reach):
    """The candidate pairs within ``reach`` [m] at ``pos0``, less the ignored ones."""
    wide = candidate_pairs(pos0, au.elem_nodes, au.active, reach)
    m = np.int64(au.elem_nodes.shape[0])
    keep = np.ones(wide.shape[0], np.bool_)
    if au.ignored.shape[0]:
        for p in range(wide.shape[0]):
            code = wide[p, 0] * m + wide[p, 1]
            i = np.searchsorted(au.ignored, code)
            keep[p] = not (i < au.ignored.shape[0] and au.ignored[i] == code)
    return wide[keep]


@njit(cache=True)
def certified_crossings(pairs, elem_nodes, pos0, pos1, level, mo, test, log, clock, tally,
                        lo=0, hi=-1):
    """The crossings of the listed ``pairs`` (those from ``lo`` to ``hi``, -1: the list's end)
    over the step from ``pos0`` to ``pos1`` (counted, the first written to the ``log``:
    (time, element, element, sign) arrays), tested exactly only where the pair's
    certificate cannot rule them out (fe.contact.bounds: its ``level`` less its elements'
    summed motion, then its bound at the step's start less its own relative motion; ``mo``
    the step's motion); a pair looked at gets a new level (its distance at the step's end
    for one tested). ``test``
    False: the certificates only (the contact's fail-safe tested this step already).
    ``clock``, ``tally``: the profile (fe.contact.clock's A_ and T_ slots), added to only.
    Returns the count."""
    out_t, out_e, out_f, out_s = log
    times = np.empty(3)
    signs = np.empty(3, np.int64)
    w, cuts = np.empty((4, 3)), np.empty(4)
    sep = SEP * mo.scale[0]
    slack = ROUND * mo.scale[0]
    cum = mo.cum
    n = 0
    start = t0 = cycles()
    looked, sampled, close, tested, crossed = 0, 0, 0, 0, 0
    if hi < 0:
        hi = pairs.shape[0]
    for p in range(lo, hi):
        e, f = pairs[p, 0], pairs[p, 1]
        if level[p] - cum[e] - cum[f] > sep:  # (bound_after, read only)
            continue
        timed = looked % SAMPLE == 0
        looked += 1
        if timed:
            t0 = cycles()
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[f, 0], elem_nodes[f, 1]
        bound = bound_now(level, mo, p, e, f) - pair_motion(mo, a, b, c, d)
        if timed:
            t0 = lap(clock, A_LOOK, t0)
            sampled += 1
        if bound > sep:
            set_level(level, mo, p, e, f, bound)
            continue
        t1 = cycles()
        close += 1
        if test:
            tested += 1
            if not apart(pos0, pos1, a, b, c, d, sep):
                crossed += 1
                k = pair_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c],
                                   pos0[d], pos1[d], times, signs, w, cuts, sep)
                n = log_crossings(out_t, out_e, out_f, out_s, n, times, signs, k, e, f)
        set_level(level, mo, p, e, f, closest_nodes(pos1, a, b, c, d)[2] - slack)
        lap(clock, A_EXACT, t1)
    lap(clock, A_CERT, start)
    tally[T_READ] += hi - lo
    tally[T_LOOKED] += looked
    tally[T_LOOK_SAMPLED] += sampled
    tally[T_CLOSE] += close
    tally[T_EXACT] += tested
    tally[T_PAIR_TEST] += crossed
    return n


@njit(cache=True, parallel=True)
def certified_blocks(pairs, elem_nodes, pos0, pos1, level, mo, test, log, clock, tally,
                     blocks):
    """:func:`certified_crossings` on numba's threads: the list cut into ``blocks`` runs of
    pairs, each pair's certificate and test its own (no pair reads another's level), each run
    logging into a log of its own; the logs are then joined in the list's order, so that the
    count, the log and the levels are those of one thread, bit for bit, whatever the threads
    and blocks. The profile's A_CERT holds the wall time, A_LOOK and A_EXACT the threads'
    times summed. Returns the count."""
    out_t, out_e, out_f, out_s = log
    m = pairs.shape[0]
    size = (m + blocks - 1) // blocks
    cap = out_t.shape[0]
    start = cycles()
    bt = np.empty((blocks, cap), out_t.dtype)
    be = np.empty((blocks, cap), out_e.dtype)
    bf = np.empty((blocks, cap), out_f.dtype)
    bs = np.empty((blocks, cap), out_s.dtype)
    counts = np.zeros(blocks, np.int64)
    bclock = np.zeros((blocks, clock.shape[0]), clock.dtype)
    btally = np.zeros((blocks, tally.shape[0]), tally.dtype)
    for c in prange(blocks):
        lo = min(m, c * size)
        counts[c] = certified_crossings(pairs, elem_nodes, pos0, pos1, level, mo, test,
                                        (bt[c], be[c], bf[c], bs[c]), bclock[c], btally[c], lo,
                                        min(m, lo + size))
    n = 0
    for c in range(blocks):
        for i in range(min(counts[c], cap - n)):
            out_t[n + i], out_e[n + i], out_f[n + i], out_s[n + i] = \
                bt[c, i], be[c, i], bf[c, i], bs[c, i]
        n += counts[c]
        for j in range(tally.shape[0]):
            tally[j] += btally[c, j]
        clock[A_LOOK] += bclock[c, A_LOOK]
        clock[A_EXACT] += bclock[c, A_EXACT]
    lap(clock, A_CERT, start)
    return n


@njit(cache=True)
def audit_step(au, pos, t0, dt, fronts, fresh=False, clean=False, threads=None):
    """The crossings of the step from ``au.pos0`` to ``pos`` (starting at ``t0`` [s]),
    counted and logged (``fresh``: ``au.motion`` already holds
    this step's motion; ``clean``: the contact's fail-safe tested this list on this
    motion and found no crossing, so only the certificates are kept up; ``threads``: None,
    one thread (numba compiles no thread kernel), else the list's pairs on that many
    threads, fe.contact.bounds.BLOCKS_PER_THREAD blocks each, when it holds at least
    fe.contact.bounds.THREAD_MIN_PAIRS: the same bits). Returns True if
    the list needs a rebuild (or the log a flush) before the next step."""
    mo = au.motion
    start = cycles()
    if not fresh:
        step_motion(mo, au.elem_nodes, au.active, au.pos0, pos)
    theta = au.frame[0] = mo.theta[1]  # the frame that follows the web, now
    moved = moved_since(au.ref, pos, math.cos(theta), math.sin(theta))
    au.moved[0] = moved
    start = lap(au.clock, A_MOTION, start)
    au.tally[T_STEPS] += 1
    k = au.n_log[0]
    end = k + LOG_PER_STEP
    if moved > WIDE * au.skin:  # a step beyond the list's reach: a list as wide as it
        pairs = wide_pairs(au, au.pos0, au.skin + moved)
        box = np.empty((au.elem_nodes.shape[0], 6))
        swept_boxes(au.elem_nodes, au.active, au.pos0, pos, box)
        n = boxed_crossings(pairs, au.elem_nodes, au.pos0, pos, box, au.log_time[k:end],
                            au.log_a[k:end], au.log_b[k:end], au.log_sign[k:end],
                            SEP * mo.scale[0])
        lap(au.clock, A_WIDE, start)
        au.tally[T_WIDE] += 1
        au.tally[T_WIDE_PAIRS] += pairs.shape[0]
    else:
        n = -1
        log = (au.log_time[k:end], au.log_a[k:end], au.log_b[k:end], au.log_sign[k:end])
        if threads is not None:  # (pruned by numba when None)
            if au.pairs.shape[0] >= THREAD_MIN_PAIRS:
                n = certified_blocks(au.pairs, au.elem_nodes, au.pos0, pos, au.level, mo,
                                     not clean, log, au.clock, au.tally,
                                     BLOCKS_PER_THREAD * threads)
        if n < 0:
            n = certified_crossings(au.pairs, au.elem_nodes, au.pos0, pos, au.level, mo,
                                    not clean, log, au.clock, au.tally, np.int64(0),
                                    np.int64(-1))  # (not literals: one compile)
    mo.cum0[:] = mo.cum  # the sums to the next step's start
    logged = min(n, LOG_PER_STEP)
    for i in range(k, k + logged):
        au.log_time[i] = t0 + au.log_time[i] * dt
    au.n_log[0] = k + logged
    au.count[0] += n
    stale = moved > REBUILD * au.skin or au.n_log[0] + LOG_PER_STEP > au.log_time.shape[0]
    for j in range(fronts.shape[0]):
        stale = stale or fronts[j] != au.fronts[j]
    return stale


@njit(inline="always")
def touch_begin(audit, contact, pos, vel, inv_mass, dt, rate=None, body=None, theta=0.0):
    """Step start: x_n and the frame's angle kept, the contact's penalty forces (``rate``,
    ``theta``: a fixed axis's rate and angle [rad], ``body``: a free hub's state, whose
    velocities and pose are kept for the fail-safe's reaction and its zones)."""
    if audit is not None:
        audit.pos0[:] = pos
        audit.motion.theta[0] = audit.frame[0]
    elif contact is not None:
        contact.pos0[:] = pos
    if contact is not None:
        if rate is not None:
            contact.hub0.rate[0] = rate[0]
            contact.hub0.angle[0] = theta
        if body is not None:
            body_snapshot(body, contact.hub0)
        contact_push(contact, pos, vel, inv_mass, dt)


@njit(inline="always")
def touch_row(audit, contact, k):
    """The row's columns of the audit and the contact."""
    if audit is not None:
        audit.row_count[k] = audit.count[0]
    if contact is not None:
        contact_row(contact, k)


@njit(inline="always")
def touch_end(audit, pos, t0, dt, fronts, fresh=False, clean=False, threads=None):
    """Step end, after the contact's fail-safe (fe.step.settle; ``fresh``, ``clean`` as
    :func:`audit_step` takes them): the audit. True: stop for Python."""
    if audit is not None:
        return audit_step(audit, pos, t0, dt, fronts, fresh, clean, threads)
    return False
