"""Impact zones (fe.contact.zones): the pairs the fail-safe's rounds leave crossing move as rigid
zones. A column of five stacked bars through which the top bar drops in one step: with
one round of pair impulses crossings are left; the zones leave none, keep the linear and
angular momentum, and a zone with a node held on the hub is left alone and counted."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from spinweb_fe.fe.contact.failsafe import resolve_crossings
from spinweb_fe.fe.contact.penalty import MARGIN
from spinweb_fe.fe.contact.zones import ZONE_ROUNDS, impact_zones, pair_adjacency
from support import loop_crossings

DT = 1e-3
LAYERS = 5


def column():
    """Five bars 2 m long stacked 10 mm apart, each turned 0.3 rad from the one below;
    the top bar drops at 60 m/s (60 mm in the step: through every layer), the others
    rest. Returns (pairs, elem_nodes, x_n, x_{n+1}, v_{n+1/2}, inverse masses)."""
    pos = np.empty((2 * LAYERS, 3))
    for k in range(LAYERS):
        a = 0.3 * k
        c, s = np.cos(a), np.sin(a)
        pos[2 * k] = (-c, -s, 0.01 * k)
        pos[2 * k + 1] = (c, s, 0.01 * k)
    vel = np.zeros_like(pos)
    vel[-2:, 2] = -60.0
    vel[-2:, 0] = (3.0, -1.0)  # and slides and turns
    elems = np.arange(2 * LAYERS, dtype=np.int64).reshape(LAYERS, 2)
    pairs = np.array(list(itertools.combinations(range(LAYERS), 2)), np.int64)
    inv_mass = np.linspace(0.5, 1.5, 2 * LAYERS)
    return pairs, elems, pos, pos + DT * vel, vel, inv_mass


def crossings(pairs, elems, pos0, pos1):
    times, signs = np.empty(3), np.empty(3, np.int64)
    n = 0
    for e, g in pairs:
        a, b = elems[e]
        c, d = elems[g]
        n += loop_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c], pos0[d],
                            pos1[d], times, signs)
    return n


def momenta(pos1, vel, inv_mass):
    """(P, L): sum m v and sum m (x_{n+1} - dt v) x v of the free nodes."""
    m = np.where(inv_mass > 0, 1.0 / np.where(inv_mass > 0, inv_mass, 1.0), 0.0)[:, None]
    return (m * vel).sum(0), (m * np.cross(pos1 - DT * vel, vel)).sum(0)


def rigid(vel, pos0):
    """Whether the velocities are one rigid motion (to 1e-12 of the drop speed)."""
    n = len(vel)
    return all(abs(np.dot(vel[i] - vel[j], pos0[i] - pos0[j])) < 1e-12 * 60.0
               for i, j in itertools.combinations(range(n), 2))


def test_the_pair_rounds_can_run_out():
    """The premise: free bars squeezed between two bars of the hub that do not move as one
    body (the top one drops through the column, the bottom one stays) cannot be parted by
    pair impulses: the twenty rounds run out with crossings left; no zone can part them
    either (no rigid motion of the hub carries both), and they are counted."""
    pairs, elems, pos0, pos1, vel, inv_mass = column()
    inv_mass[[0, 1, -2, -1]] = 0.0
    _, impulses, left = resolve_crossings(pairs, elems, pos0, pos1, vel, inv_mass, DT, 1e-4,
                                          (20, 0), None)
    assert impulses > 20 and left > 0
    pairs, elems, pos0, pos1, vel, inv_mass = column()
    inv_mass[[0, 1, -2, -1]] = 0.0
    _, _, left = resolve_crossings(pairs, elems, pos0, pos1, vel, inv_mass, DT, 1e-4,
                                   (20, ZONE_ROUNDS), None)
    # (left: the crossings of pairs the fail-safe can act on; the two held bars' own
    # crossing, which no impulse can change, only the audit counts)
    assert left > 0 and crossings(pairs, elems, pos0, pos1) == left + 1


def squeeze():
    """The column's outer bars (1 t each) close on the three between them from both sides,
    to 0.2 mm apart at the step's end; with a margin of 2 mm (:data:`WIDE_MARGIN`) the
    light bars cannot end that far from both."""
    pairs, elems, pos0, _, vel, inv_mass = column()
    vel[:] = 0.0
    u = (0.01 * (LAYERS - 1) - 2e-4) / 2 / DT
    vel[:2, 2], vel[-2:, 2] = u, -u
    inv_mass[[0, 1, -2, -1]] = 1e-3
    return pairs, elems, pos0, pos0 + DT * vel, vel, inv_mass


#: the fail-safe's margin [m] of :func:`squeeze`
WIDE_MARGIN = 2e-3


def test_a_squeeze_the_pair_rounds_cannot_part_is_parted_by_a_zone():
    """The squeeze: the pair impulses ping-pong the light bars between the heavy ones and
    their twenty rounds leave crossings (the zones held back); with the zones the five bars
    leave the step as one rigid zone, no pair crossing, the linear momentum kept to
    1e-12."""
    pairs, elems, pos0, pos1, vel, inv_mass = squeeze()
    _, _, left = resolve_crossings(pairs, elems, pos0, pos1, vel, inv_mass, DT, WIDE_MARGIN,
                                   (20, 0), None)
    assert left > 0 and crossings(pairs, elems, pos0, pos1) > 0
    pairs, elems, pos0, pos1, vel, inv_mass = squeeze()
    P0, _ = momenta(pos1, vel, inv_mass)
    scale = (np.abs(vel[:, 2]) / inv_mass).max()  # the heavy bars' momentum [N s]
    _, _, left = resolve_crossings(pairs, elems, pos0, pos1, vel, inv_mass, DT, WIDE_MARGIN,
                                   (20, ZONE_ROUNDS), None)
    assert left == 0 and crossings(pairs, elems, pos0, pos1) == 0
    assert rigid(vel, pos0)
    P1, _ = momenta(pos1, vel, inv_mass)
    assert np.abs(P1 - P0).max() < 1e-12 * scale


def test_after_the_zones_no_pair_crosses():
    """After the fail-safe with a single round of pair impulses (so that the zones do the
    rest) no pair crosses over the step, the linear momentum of the free nodes is the
    start's to 1e-12 (round-off), and x_{n+1} = x_n + dt v_{n+1/2} still holds. (The pair
    impulses act at points that are apart at x_n, so they change the angular momentum by
    their couple; the hub takes it in a run, fe.contact.impulses.)"""
    pairs, elems, pos0, pos1, vel, inv_mass = column()
    P0, _ = momenta(pos1, vel, inv_mass)
    _, _, left = resolve_crossings(pairs, elems, pos0, pos1, vel, inv_mass, DT, 1e-4,
                                   (1, ZONE_ROUNDS), None)
    assert left == 0
    assert crossings(pairs, elems, pos0, pos1) == 0
    P1, _ = momenta(pos1, vel, inv_mass)
    assert np.abs(P1 - P0).max() < 1e-12 * np.abs(P0).max()
    assert np.allclose(pos1, pos0 + DT * vel, rtol=0, atol=1e-15)


def zones_as_the_fail_safe_calls_them(pairs, elems, pos0, pos1, vel, inv_mass, hub=None):
    """fe.contact.zones.impact_zones with the arguments in the forms the fail-safe passes
    them (the rounds an int64, every node moved, the list's adjacency, the marks of the
    nodes that follow the hub), the same as their defaults: the tests share the
    fail-safe's compile of it instead of one of their own for each form."""
    n = len(pos0)
    follow = None if hub is None else np.zeros(n, np.bool_)
    return impact_zones(pairs, elems, pos0, pos1, vel, inv_mass, DT, np.int64(ZONE_ROUNDS),
                        hub, np.ones(n, np.bool_), pair_adjacency(pairs, elems, n), follow)


def test_a_zone_moves_rigidly_and_keeps_the_momenta():
    """The zones called directly on the column: one zone of every bar, whose velocities
    are one rigid motion V + w x (x - X) (the difference of any two nodes' velocities is
    perpendicular to their separation, to 1e-12 of the speeds), with the linear and the
    angular momentum of the start to 1e-12, and no crossing left."""
    pairs, elems, pos0, pos1, vel, inv_mass = column()
    P0, L0 = momenta(pos1, vel, inv_mass)
    zones, left = zones_as_the_fail_safe_calls_them(pairs, elems, pos0, pos1, vel, inv_mass)
    assert (zones, left) == (1, 0)
    assert crossings(pairs, elems, pos0, pos1) == 0
    for i, j in itertools.combinations(range(2 * LAYERS), 2):
        assert abs(np.dot(vel[i] - vel[j], pos0[i] - pos0[j])) < 1e-12 * 60.0
    P1, L1 = momenta(pos1, vel, inv_mass)
    scale = np.abs(P0).max()
    assert np.abs(P1 - P0).max() < 1e-12 * scale
    assert np.abs(L1 - L0).max() < 1e-12 * scale


def test_a_zone_with_a_held_node_is_left_without_the_hubs_motion():
    """A node of the bottom bar held on the hub (inverse mass 0) and no hub motion given:
    the zone that holds it is not moved, its crossings are returned as left (the audit
    counts them)."""
    pairs, elems, pos0, pos1, vel, inv_mass = column()
    inv_mass[0] = 0.0
    before = vel.copy()
    zones, left = zones_as_the_fail_safe_calls_them(pairs, elems, pos0, pos1, vel, inv_mass)
    assert zones <= 0 and left > 0
    assert np.array_equal(vel, before)


def test_the_margin_of_the_pair_impulses_is_unchanged():
    """The zones only run when the rounds are used up: a single crossing pair is parted by
    its pair impulse to the fail-safe's margin, as before the zones existed."""
    pairs, elems, pos0, pos1, vel, inv_mass = column()
    sub = np.array([[0, 1]], np.int64)  # the drop through the bottom bar alone
    e2 = np.array([[0, 1], [2, 3]], np.int64)
    idx = np.array([0, 1, 8, 9])
    p0, p1, v, im = pos0[idx].copy(), pos1[idx].copy(), vel[idx].copy(), inv_mass[idx].copy()
    _, impulses, left = resolve_crossings(sub, e2, p0, p1, v, im, DT, MARGIN * 1e-3,
                                            (20, ZONE_ROUNDS), None)
    assert impulses == 1 and left == 0
    assert crossings(sub, e2, p0, p1) == 0


def test_a_zone_with_a_held_node_moves_with_the_hub():
    """The bottom bar held on a hub that turns by 0.05 rad about the z axis over the step
    (the column 2 m from it): the zone of the dropping bar takes the hub's motion, its free
    nodes end where the turn takes them (to 1e-12 m), and no pair crosses."""
    from spinweb_fe.fe.contact.zones import axis_map

    pairs, elems, pos0, pos1, vel, inv_mass = column()
    pos0 += (2.0, 0.0, 0.0)
    hub = axis_map(0.05)
    pos1 = pos0 + DT * vel
    inv_mass[[0, 1]] = 0.0
    pos1[[0, 1]] = pos0[[0, 1]] @ hub[:3].T
    vel[[0, 1]] = (pos1[[0, 1]] - pos0[[0, 1]]) / DT
    zones, left = zones_as_the_fail_safe_calls_them(pairs, elems, pos0, pos1, vel, inv_mass,
                                                    hub)
    assert zones >= 1 and left == 0
    assert crossings(pairs, elems, pos0, pos1) == 0
    moved = np.abs(vel).sum(1) > 0  # the zone's nodes (the others rest)
    assert moved[-2:].all()
    assert np.abs(pos1[moved] - pos0[moved] @ hub[:3].T).max() < 1e-12


def test_the_passes_after_the_first_see_every_pair_of_the_moved_nodes():
    """fe.contact.zones.pairs_of, on the column's pairs: for any set of moved nodes it gives exactly
    the pairs with an element that has one of them, each once, sorted (the later passes of
    the fail-safe and the zones test these instead of the whole list). Both of its ways:
    a few pairs sorted, and many (more than a 32nd of the list) read off the stamps in the
    list's order; a column of the column's pairs repeated 40 times (other elements) gives
    the few."""
    from spinweb_fe.fe.contact.zones import pair_adjacency, pairs_of

    pairs, elems, *_ = column()
    n_el, n = len(elems), 2 * LAYERS
    elems = np.concatenate([elems + n * k for k in range(40)])  # 40 columns side by side
    pairs = np.concatenate([pairs + n_el * k for k in range(40)])
    adj = pair_adjacency(pairs, elems, 40 * n)
    rng = np.random.default_rng(1)
    ways = set()
    for tick in range(40):
        moved = rng.random(40 * n) < (0.2 if tick % 2 else 0.002)
        want = [p for p, (e, g) in enumerate(pairs)
                if moved[elems[e]].any() or moved[elems[g]].any()]
        assert list(pairs_of(adj, moved)) == want
        ways.add(32 * len(want) < len(pairs))
    assert ways == {True, False}


def _body(rng):
    """A free hub of 100 kg with an anisotropic inertia, turned and moving, and eight free
    nodes of 0.5-2 kg about it: (RigidState, x_{n+1}, v before, v after the impulses,
    inverse masses, V and angular velocity at the step's start)."""
    from spinweb_fe.fe.hub.rigid import RigidState, jacobi3

    inertia = np.diag([4000.0, 2500.0, 3000.0])
    inertia[0, 1] = inertia[1, 0] = 300.0
    moments, axes = jacobi3(inertia)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    rs = RigidState(rng.normal(size=3), rng.normal(size=3), q, 500.0 * rng.normal(size=3),
                    np.array([100.0]), np.array([0.1, 0.0, -0.2]), inertia, axes, moments)
    n = 8
    pos = 6.0 * rng.normal(size=(n, 3))
    before = 30.0 * rng.normal(size=(n, 3))
    after = before + rng.normal(size=(n, 3))  # the impulses
    pos += DT * (after - before)
    inv_mass = 1.0 / rng.uniform(0.5, 2.0, n)
    return rs, pos, before, after, inv_mass, np.concatenate([rs.velocity, rng.normal(size=3)])


def _body_momenta(rs, x, vel, inv_mass):
    """(P, L) of body and free nodes: M V + sum m v, M X x V + Pi + sum m x x v (``x``:
    the nodes' x_{n+1}, the leapfrog's x_{n+1} x v_{n+1/2} = x_n x v_{n+1/2})."""
    m = (1.0 / inv_mass)[:, None]
    M = rs.mass[0]
    return (M * rs.velocity + (m * vel).sum(0),
            M * np.cross(rs.position, rs.velocity) + rs.momentum + (m * np.cross(x, vel)).sum(0))


@pytest.mark.parametrize("stuck, place", [(0, True), (3, True), (0, False), (3, False)])
def test_nodes_stuck_to_a_free_hub_take_its_reaction_and_the_momenta_stay(stuck, place):
    """fe.contact.impulses.body_reaction: the free body takes the impulses' reaction so that body
    and nodes keep their linear and angular momentum (to 1e-12 of their size); the nodes
    stuck to it this step (an impact zone moved them with the hub, fe.contact.zones) take the
    body's change with it, a rigid motion dV + dw x (x - X) (to 1e-9 of it), their x_{n+1}
    by dt times it; with none stuck the body takes -J / M as before. Without placing (the
    step's last pass, fe.step.settle) the velocities change and no position: the body's
    centre and attitude and the stuck nodes' x_{n+1} stay (bit for bit)."""
    from spinweb_fe.fe.contact.impulses import body_reaction
    from spinweb_fe.fe.hub.rigid import inv_inertia, rotation

    rs, pos, before, after, inv_mass, start = _body(np.random.default_rng(7 + stuck))
    follow = np.zeros(len(pos), np.bool_)
    follow[:stuck] = True
    pos0 = pos - DT * (after - before)  # x_{n+1} before the impulses moved it
    P0, L0 = _body_momenta(rs, pos0, before, inv_mass)
    J = ((after - before) / inv_mass[:, None]).sum(0)
    V0, X0, q0 = rs.velocity.copy(), rs.position.copy(), rs.quaternion.copy()
    R0 = rotation(rs.quaternion)  # (the body's change of rate is taken at this attitude)
    w0 = inv_inertia(rs, R0, rs.momentum)
    pos_in, after_in = pos.copy(), after.copy()
    body_reaction(rs, pos, before, after, inv_mass, start[0:3], start[3:6], DT, follow, place)
    P1, L1 = _body_momenta(rs, pos, after, inv_mass)
    assert np.abs(P1 - P0).max() < 1e-12 * np.abs(P0).max()
    assert np.abs(L1 - L0).max() < 1e-12 * np.abs(L0).max()
    assert np.array_equal(after[stuck:], after_in[stuck:])  # the others keep theirs
    assert np.array_equal(pos[stuck:], pos_in[stuck:])
    if not place:
        assert np.array_equal(pos, pos_in) and np.array_equal(rs.position, X0)
        assert np.array_equal(rs.quaternion, q0)
    dV = rs.velocity - V0
    if stuck == 0:
        assert np.allclose(dV, -J / rs.mass[0], rtol=0, atol=1e-14)
        return
    dw = inv_inertia(rs, R0, rs.momentum) - w0
    assert np.linalg.norm(dw) > 1e-4  # the body turned
    for i in range(stuck):
        dv = after[i] - after_in[i]
        assert np.abs(dv - (dV + np.cross(dw, pos_in[i] - X0))).max() < 1e-9 * np.abs(dv).max()
        assert np.abs(pos[i] - pos_in[i] - (DT * dv if place else 0.0)).max() < 1e-15


@pytest.mark.parametrize("place", [True, False])
def test_nodes_stuck_to_a_fixed_axis_turn_with_it_and_keep_the_axial_momentum(place):
    """fe.contact.impulses.axis_reaction: the rate's change dw keeps the angular momentum about
    the axis of hub and nodes (J dw + sum m (x_{n+1} x v)_z, to 1e-12), the stuck nodes
    turning with the axis, dv = dw z x x_{n+1}, their x_{n+1} by dt dv (without placing,
    the step's last pass: not at all); with none stuck dw = -H_z / J."""
    from spinweb_fe.fe.contact.impulses import axis_reaction

    rs, pos, before, after, inv_mass, _ = _body(np.random.default_rng(3))
    m = (1.0 / inv_mass)[:, None]
    Hz = (m * np.cross(pos - DT * after, after - before)).sum(0)[2]
    follow = np.zeros(len(pos), np.bool_)
    assert axis_reaction(pos, before, after.copy(), inv_mass, DT, 4000.0, follow) \
        == pytest.approx(-Hz / 4000.0, rel=1e-14)
    follow[:4] = True
    pos0 = pos - DT * (after - before)  # x_{n+1} before the impulses moved it
    Lz0 = (m * np.cross(pos0, before)).sum(0)[2]
    pos_in, after_in = pos.copy(), after.copy()
    dw = axis_reaction(pos, before, after, inv_mass, DT, 4000.0, follow, place)
    Lz1 = (m * np.cross(pos, after)).sum(0)[2] + 4000.0 * dw
    assert abs(Lz1 - Lz0) < 1e-12 * abs(Lz0)
    dv = after - after_in
    assert np.abs(dv[:4] - dw * np.cross([0.0, 0.0, 1.0], pos_in[:4])).max() < 1e-14
    assert np.array_equal(dv[4:], np.zeros((4, 3)))
    assert np.abs(pos - pos_in - (DT * dv if place else 0.0)).max() < 1e-15


@pytest.mark.parametrize("scene, margin", [("column", 1e-4), ("squeeze", WIDE_MARGIN)])
def test_the_later_passes_certificates_rule_out_only_pairs_that_cannot_meet(scene, margin):
    """The column (or the squeeze, whose light bars rest until an impulse moves them),
    carried 30 mm up in the step as a whole (so that the swept boxes of its 10 mm layers
    overlap, as the stacked layers' of a turning web do), beside fifty bars 5-14 m away
    (every pair listed; the column's ten nodes under an eighth of the 110, so the passes
    after the first take the pairs of the nodes a pass moved), with each pair's exact
    distance at x_n as its certificate: the later passes test exactly only the pairs whose
    swept boxes meet and whose bound at the step's start less their four nodes' motion as
    the impulses left it does not keep them apart (fe.contact.bounds.moved_pair_motion),
    and no pair of the list crosses over the step after the fail-safe (the exact test on
    every pair). In the column the result is bit for bit the one of certificates that rule
    nothing out (the same least separation), with fewer exact tests. (In the squeeze it is
    not: the first pass reads its certificates against the motion at its start, and a light
    bar an impulse moves within that pass has its pairs tested in the next pass instead, a
    different order of the same impulses' kind; the motion as step_motion saw it before the
    impulses, read in the later passes, would rule out the squeezed bars' pairs and leave
    crossings.)"""
    from spinweb_fe.fe.contact.bounds import Certified, contact_profile, no_motion, step_motion
    from spinweb_fe.fe.contact.clock import N_ROUND_LOOKED, N_ROUND_PAIRS, N_ROUNDS
    from spinweb_fe.fe.contact.distance import closest_points
    from spinweb_fe.fe.contact.zones import axis_map, no_adjacency

    _, elems, pos0, pos1, vel, inv_mass = column() if scene == "column" else squeeze()
    rng = np.random.default_rng(5)
    far = []
    for k in range(50):  # bars 2 m long, 5-14 m from the column
        centre = np.array([5.0 + 0.2 * k, rng.uniform(-3, 3), rng.uniform(-1, 1)])
        u = rng.normal(size=3)
        far += [centre - u / np.linalg.norm(u), centre + u / np.linalg.norm(u)]
    far = np.array(far)
    pos0 = np.vstack([pos0, far])
    vel = np.vstack([vel, np.zeros_like(far)])
    vel[:, 2] += 30.0  # the whole scene carried up
    pos1 = pos0 + DT * vel
    inv_mass = np.concatenate([inv_mass, np.full(len(far), 0.8)])
    n, m = len(pos0), len(pos0) // 2
    elems = np.arange(n, dtype=np.int64).reshape(m, 2)
    pairs = np.array(list(itertools.combinations(range(m), 2)), np.int64)
    exact = np.array([closest_points(pos0[a], pos0[b], pos0[c], pos0[d])[2]
                      for (a, b), (c, d) in ((elems[e], elems[g]) for e, g in pairs)])
    out = {}
    for name, level in (("certified", exact * (1 - 1e-12)), ("none", np.full(len(pairs), -1.0))):
        cert = Certified(level.copy(), no_motion(n, m), no_adjacency(n, len(pairs)),
                         np.ones(m, np.int8), *contact_profile())
        p1, v = pos1.copy(), vel.copy()
        step_motion(cert.motion, elems, cert.active, pos0, p1)
        # (the types of the step loop's call: a fixed axis that did not turn, no moved set)
        taken, impulses, left = resolve_crossings(pairs, elems, pos0, p1, v, inv_mass, DT,
                                                  margin, (20, ZONE_ROUNDS), cert,
                                                  axis_map(0.0), None, np.zeros(n, np.bool_),
                                                  None)
        out[name] = (taken, impulses, left, p1, v, cert.tally.copy())
    a, b = out["certified"], out["none"]
    for taken, impulses, left, p1, *_ in (a, b):
        assert impulses > 0 and left == 0 and crossings(pairs, elems, pos0, p1) == 0
    tally, plain = a[5], b[5]
    assert tally[N_ROUNDS] >= 1 and plain[N_ROUNDS] >= 1  # later passes ran
    assert 0 < tally[N_ROUND_PAIRS] < 0.5 * tally[N_ROUND_LOOKED]  # most ruled out
    if scene == "column":
        assert a[:3] == b[:3]
        assert np.array_equal(a[3], b[3]) and np.array_equal(a[4], b[4])
        assert tally[N_ROUND_LOOKED] == plain[N_ROUND_LOOKED]
        assert tally[N_ROUND_PAIRS] < 0.5 * plain[N_ROUND_PAIRS]  # beyond what boxes rule out
