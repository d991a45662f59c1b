"""The certificates of a whole list on threads: the audit's (fe.contact.touch.certified_blocks)
and the fail-safe's first pass (fe.contact.failsafe.certified_candidates). The list is cut
into blocks; joined in the list's order, the blocks must give what one thread gives, bit for
bit, whatever their number: the audit's count, log (its order, and where it runs out of
room) and every pair's new level; the fail-safe's pairs left to test and the count looked
at. (The step loop on two threads against one: tests/test_cable_contact.py's layered paper
web, in make validate.)"""

from __future__ import annotations

import numpy as np
import pytest
from test_crossing_audit import scripted, state_at

from spinweb_fe.fe.contact.bounds import step_motion
from spinweb_fe.fe.contact.clock import T_LOOK_SAMPLED
from spinweb_fe.fe.contact.touch import certified_blocks, certified_crossings
from spinweb_fe.record.crossings import CrossingAudit


def grid_through_grid(rng):
    """12 bars along x at z = 0 and 12 along y at z = +8 mm that move to z = -8 mm in one step
    (144 crossings, more than the log holds), below 200 bars at random in a 3 m cube (2 600
    pairs the certificates rule out), all jittered by up to 1 mm. Returns (elements, x_n,
    x_{n+1})."""
    ends = []
    for y in np.linspace(-1.1, 1.1, 12):
        ends += [[-1.2, y, 0.0], [1.2, y, 0.0]]
    for x in np.linspace(-1.1, 1.1, 12):
        ends += [[x, -1.2, 0.008], [x, 1.2, 0.008]]
    centres = rng.uniform(-1.5, 1.5, (200, 3)) + np.array([0.0, 0.0, 3.0])
    dirs = rng.normal(size=(200, 3))
    dirs *= 0.3 / np.linalg.norm(dirs, axis=1)[:, None]
    for c, d in zip(centres, dirs):
        ends += [c - d, c + d]
    pos0 = np.array(ends)
    pos1 = pos0 + rng.uniform(-1e-3, 1e-3, pos0.shape)
    pos1[24:48, 2] -= 0.016  # the y bars (nodes 24-47) go through the x bars
    elems = np.arange(len(pos0)).reshape(-1, 2)
    return elems, pos0, pos1


def audit_on(elems, pos0, pos1):
    audit = CrossingAudit(scripted(elems, len(pos0)), skin=0.3)
    audit.build(state_at(pos0))
    au = audit.kernel_data
    au.pos0[:] = pos0
    step_motion(au.motion, au.elem_nodes, au.active, au.pos0, pos1)
    return au


def certify(au, pos1, blocks, room):
    """One step's certificates and tests on a copy of the levels: (count, log, levels,
    tallies); ``blocks`` None: one thread."""
    level = au.level.copy()
    log = (np.zeros(room), np.zeros(room, np.int64), np.zeros(room, np.int64),
           np.zeros(room, np.int64))
    clock, tally = np.zeros_like(au.clock), np.zeros_like(au.tally)
    if blocks is None:
        n = certified_crossings(au.pairs, au.elem_nodes, au.pos0, pos1, level, au.motion, True,
                                log, clock, tally, np.int64(0), np.int64(-1))
    else:
        n = certified_blocks(au.pairs, au.elem_nodes, au.pos0, pos1, level, au.motion, True,
                             log, clock, tally, blocks)
    tally[T_LOOK_SAMPLED] = 0  # (the timing's sample: one in SAMPLE pairs of each block)
    return n, log, level, tally


@pytest.mark.parametrize("room", [64, 5])
def test_threads_give_one_threads_count_log_and_levels(room):
    elems, pos0, pos1 = grid_through_grid(np.random.default_rng(5))
    au = audit_on(elems, pos0, pos1)
    n1, log1, level1, tally1 = certify(au, pos1, None, room)
    assert n1 == 144 and tally1[1] == len(au.pairs) > 2000
    assert np.count_nonzero(level1 != au.level) == 144  # the looked-at pairs: new levels
    for blocks in (1, 3, 8, 64):
        n, log, level, tally = certify(au, pos1, blocks, room)
        assert n == n1
        for a, b in zip(log, log1):
            assert np.array_equal(a, b)
        assert np.array_equal(level, level1) and np.array_equal(tally, tally1)


def test_the_fail_safes_first_pass_certificates_on_threads_are_one_threads():
    """fe.contact.failsafe.certified_candidates: the pairs the certificates cannot rule out,
    in the list's order, and the count looked at, as the one-thread first pass decides them
    pair by pair (the same inline bounds, run by Python here), whatever the blocks."""
    from spinweb_fe.fe.contact.bounds import bound_after, bound_now, pair_motion
    from spinweb_fe.fe.contact.crossing import SEP
    from spinweb_fe.fe.contact.failsafe import certified_candidates

    elems, pos0, pos1 = grid_through_grid(np.random.default_rng(7))
    au = audit_on(elems, pos0, pos1)
    mo, sep = au.motion, SEP * au.motion.scale[0]
    want, looked = [], 0
    for p, (e, g) in enumerate(au.pairs):
        if bound_after.py_func(au.level, mo, p, e, g) > sep:
            continue
        looked += 1
        (a, b), (c, d) = au.elem_nodes[e], au.elem_nodes[g]
        if bound_now.py_func(au.level, mo, p, e, g) - pair_motion.py_func(mo, a, b, c, d) <= sep:
            want.append(p)
    assert len(want) >= 144 and looked >= len(want)
    for blocks in (1, 3, 8, 64):
        found, n_looked = certified_candidates(au.pairs, au.elem_nodes, au.level, mo, sep,
                                               blocks)
        assert found.tolist() == want and n_looked == looked
