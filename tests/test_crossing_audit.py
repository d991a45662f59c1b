"""The crossing audit of a run (record.crossings, ``[audit] crossings``): the bookkeeping of
the broad phase around the exact per-step test of fe.contact.crossing, on scripted motions, and in
the step loop, where it must not change the run."""

from __future__ import annotations

import math
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.fe.contact.touch import REBUILD
from spinweb_fe.record.crossings import CrossingAudit
from spinweb_fe.run.driver import run_case
from spinweb_fe.run.loop import Schedule, simulate


def scripted(elems, n_nodes, held=(), tied=()):
    """A model the audit can read: elements, the nodes ``held`` on a coil of one arm and one
    level (not released while the state's front is 0), the nodes ``tied`` to the hub."""
    coil = SimpleNamespace(arm_ptr=np.array([0, 1 if len(held) else 0], np.int64),
                           level_ptr=np.array([0, len(held)], np.int64),
                           level_nodes=np.asarray(held, np.int64))
    return SimpleNamespace(elements=SimpleNamespace(nodes=np.asarray(elems, np.int64)),
                           coil=coil, n_nodes=n_nodes,
                           hub=SimpleNamespace(tied_idx=np.asarray(tied, np.int64)))


def state_at(pos, angle=0.0):
    return SimpleNamespace(node_pos=np.array(pos, float), hub=SimpleNamespace(
        angle=np.array([angle])), coil=SimpleNamespace(front=np.zeros(1, np.int64)),
        step=np.zeros(1, np.int64))


def bar_through(speed, dt, steps, spin=0.0, skin=0.05):
    """Element 0 fixed along x at z = 0 (about the origin, turned by the spin), element 1
    along y moving in z from -0.3 m at ``speed``; the whole scene turned at ``spin`` rad/s
    about z (a rigid motion: the crossing stays one). Returns the audit after ``steps``."""
    def place(k):
        th = spin * k * dt
        c, s = math.cos(th), math.sin(th)
        p = np.array([[-1.0, 0.1, 0.0], [1.0, 0.1, 0.0],
                      [0.3, -1.0, -0.3 + speed * k * dt], [0.3, 1.0, -0.3 + speed * k * dt]])
        return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1],
                                p[:, 2]]), th
    audit = CrossingAudit(scripted([[0, 1], [2, 3]], 4), skin=skin)
    pos, th = place(0)
    state = state_at(pos, th)
    audit.build(state)
    for k in range(steps):
        pos0 = state.node_pos.copy()
        state.node_pos[:], state.hub.angle[0] = place(k + 1)
        audit.step(pos0, state, k * dt, dt)
    return audit


def test_a_cable_through_the_held_coil_and_the_hub_frame_is_counted():
    """A free bar (element 1) rises through a cable held on the coil (element 0: both ends
    on a level not yet released) and through one tied to the hub (element 2, 2 cm above
    it), the scene spinning with the hub: both crossings counted, at their times to
    round-off; the pair of the two elements that move with the hub is never listed (they
    cannot cross while held). (A list of released material alone saw neither crossing
    with element 0: the paper web's cables passed through the coil unseen.)"""
    speed, dt, spin = 20.0, 1e-4, 8 * math.pi

    def place(k):
        th = spin * k * dt
        c, s = math.cos(th), math.sin(th)
        z = -0.3 + speed * k * dt
        p = np.array([[-1.0, 0.1, 0.0], [1.0, 0.1, 0.0], [0.3, -1.0, z], [0.3, 1.0, z],
                      [-1.0, 0.2, 0.02], [1.0, 0.2, 0.02]])
        return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1],
                                p[:, 2]]), th
    audit = CrossingAudit(scripted([[0, 1], [2, 3], [4, 5]], 6, held=[0, 1], tied=[4, 5]),
                          skin=0.05)
    pos, th = place(0)
    state = state_at(pos, th)
    audit.build(state)
    listed = set()
    for k in range(300):
        listed |= set(map(tuple, audit.pairs.tolist()))
        pos0 = state.node_pos.copy()
        state.node_pos[:], state.hub.angle[0] = place(k + 1)
        audit.step(pos0, state, k * dt, dt)
    assert audit.count == 2
    table = audit.table()
    assert sorted(zip(table["element_a"], table["element_b"])) == [(0, 1), (1, 2)]
    assert np.sort(table["time"]) == pytest.approx([0.3 / speed, 0.32 / speed], abs=1e-12)
    assert (0, 2) not in listed and (0, 1) in listed and (1, 2) in listed


@pytest.mark.parametrize("speed", [1.0, 20.0, 200.0])
def test_a_bar_through_another_is_counted_once_with_its_time_and_direction(speed):
    """Element 1 passes element 0 at z = 0, t = 0.3 / speed: counted once (exactly), at that
    time to round-off (1e-12 s), with the direction of the signed volume after it, whatever
    the speed (the list is rebuilt as the bar moves: 3/4 of a skin per rebuild)."""
    dt = 1e-4 if speed < 100 else 1e-5
    steps = int(round(0.6 / speed / dt))
    audit = bar_through(speed, dt, steps)
    assert audit.count == 1
    table = audit.table()
    assert table["time"][0] == pytest.approx(0.3 / speed, abs=1e-12)
    assert set(table["element_a"]) | set(table["element_b"]) == {0, 1}
    assert table["direction"][0] in (-1, 1)
    moved = speed * steps * dt  # 0.6 m: a rebuild at least every REBUILD skins
    assert audit.rebuilds >= int(moved / (REBUILD * audit.skin))


def test_the_spin_alone_never_rebuilds_the_list_and_keeps_the_count():
    """The same crossing in a scene spinning at 8 pi rad/s (the rim moves 2.5 m a step at
    dt = 1e-4 s here): counted once at the same time; the rebuilds are those of the bar's
    own motion (the hub's frame takes the spin out of the skin test)."""
    still = bar_through(20.0, 1e-4, 300)
    spun = bar_through(20.0, 1e-4, 300, spin=8 * math.pi)
    assert spun.count == still.count == 1
    assert spun.table()["time"][0] == pytest.approx(still.table()["time"][0], abs=1e-12)
    assert spun.rebuilds == still.rebuilds


def test_the_count_does_not_depend_on_the_skin():
    """A wider skin lists more pairs and rebuilds less; the crossings are the same."""
    counts = {skin: bar_through(20.0, 1e-4, 300, skin=skin) for skin in (0.01, 0.05, 0.5)}
    assert {a.count for a in counts.values()} == {1}
    assert counts[0.01].rebuilds > counts[0.5].rebuilds


def test_pairs_that_start_touching_are_left_out_until_a_skin_apart():
    """Two coincident elements (a stacked layer) that part and pass through each other
    within the skin: not counted (no side to cross from); once a skin apart, a crossing
    back counts."""
    audit = CrossingAudit(scripted([[0, 1], [2, 3]], 4), skin=0.05)
    base = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    state = state_at(base)
    audit.build(state)
    assert len(audit.pairs) == 0 and len(audit.ignored) == 1
    wobble = [0.01, -0.01, 0.02, 0.0]  # parting within the skin, through each other
    up = list(np.arange(0.02, 0.3, 0.02))
    down = list(np.arange(0.29, -0.3, -0.02))  # through z = 0 between 0.01 and -0.01
    path = wobble + up + down
    for k, z in enumerate(path):
        pos0 = state.node_pos.copy()
        state.node_pos[2:, 2] = z
        audit.step(pos0, state, k * 1e-3, 1e-3)
    assert audit.count == 1  # only the crossing after they were a skin apart
    k = len(wobble) + len(up) + int(np.argmax(np.array(down) < 0))
    assert audit.table()["time"][0] == pytest.approx((k + 0.5) * 1e-3, abs=1e-12)


def test_a_step_longer_than_the_skin_is_still_tested_in_full():
    """A bar that jumps 0.6 m in one step, twelve skins: the list is rebuilt for that step
    with a skin as wide as the jump, and the crossing is counted."""
    audit = bar_through(600.0, 1e-3, 1)
    assert audit.count == 1


def small_web(sets=()):
    return case_mod.loads("[web]\nside = 40.0\nmesh_width = 5.0\n[fold]\npattern = 'flat'\n"
                          "[time]\nend = 0.02\n", list(sets))


def test_an_audited_run_is_the_same_run():
    """The audit only watches: a tilted spinning web run with and without it gives the same
    histories bit for bit (the loop then runs one step per call), and a rigidly tilted web
    makes no crossing."""
    sets = ["perturbation.z_amplitude=1.0", "perturbation.vz_amplitude=2.0"]
    runs = {}
    for on in (False, True):
        scene = prepare(small_web(sets))
        audit = CrossingAudit(scene.model) if on else None
        runs[on] = (simulate(scene.model, scene.control, scene.state, scene.dt,
                             Schedule(0.02, 1e-3), features=[audit] if on else None).history,
                   audit)
    plain, (audited, audit) = runs[False][0], runs[True]
    assert set(audited) == set(plain) | {"crossings"}
    for key in plain:
        assert np.array_equal(plain[key], audited[key]), key
    assert audit.count == 0 and np.all(audited["crossings"] == 0)


def test_results_hold_the_crossings_and_the_verdict_judges_them(tmp_path):
    """results.h5 of an audited run: the history column, the /crossings table with its
    units, and the verdict's 'tangled' criterion (n/a without the audit)."""
    run_case(small_web(["audit.crossings=true", "output.frame_dt=0",
                        "perturbation.z_amplitude=1.0"]), tmp_path / "a", progress=False)
    run_case(small_web(["output.frame_dt=0"]), tmp_path / "b", progress=False)
    with h5py.File(tmp_path / "a" / "results.h5") as f:
        assert f["history/crossings"].attrs["units"] == "1"
        g = f["crossings"]
        assert g.attrs["count"] == 0 and g["time"].attrs["units"] == "s"
        assert g.attrs["skin"] == 0.5
        assert f["verdict/tangled"].attrs["passed"] == 1
    with h5py.File(tmp_path / "b" / "results.h5") as f:
        assert "crossings" not in f and "crossings" not in f["history"]
        assert f["verdict/tangled"].attrs["passed"] == -1


def test_the_default_skin_follows_the_mesh():
    """Without audit.skin the broad phase's skin is the smaller of 0.5 m and a fifth of
    the median element (docs/performance.md: on a finer mesh a long skin lists too many
    pairs of a stacked column); a given skin is kept."""
    coarse = prepare(small_web()).model  # 5 m elements
    fine = prepare(small_web(["web.mesh_width=1.0"])).model
    assert CrossingAudit(coarse).skin == 0.5
    assert CrossingAudit(fine).skin == pytest.approx(0.2 * np.median(fine.elements.rest_len))
    assert CrossingAudit(fine).skin < 0.5
    assert CrossingAudit(fine, 0.7).skin == 0.7


@pytest.mark.parametrize("sets, key, words", [
    (["audit.crossings=true"], "audit.crossings", "cannot leave the plane"),
    (["contact.cables=true"], "contact.cables", "no contact defined"),
    (["contact.cables=true", "perturbation.z_amplitude=1.0", "contact.cable_radius=0.0"],
     "contact.cable_radius", "must be > 0"),
])
def test_what_the_audit_and_the_contact_cannot_do_is_refused(tmp_path, sets, key, words):
    """A planar scene (its cables cannot cross; a planar fold's layers coincide) and a
    radius that is not positive are refused with one line naming the key, nothing
    written; a radius above half the layer gap is refused on a layered fold (CLI, exit 2)."""
    from spinweb_fe.errors import InputError

    with pytest.raises(InputError) as err:
        run_case(small_web(sets), tmp_path / "r", progress=False)
    assert err.value.key == key and words in str(err.value)
    assert not (tmp_path / "r").exists()


def test_a_radius_above_half_the_layer_gap_is_refused_at_the_command_line(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    case = Path(__file__).resolve().parents[1] / "cases" / "paper_feedback_web.toml"
    out = subprocess.run([sys.executable, "-m", "spinweb_fe", "run", str(case), "-o",
                          str(tmp_path / "r"), "--set", "contact.cables=true", "--set",
                          "fold.layer_gap=0.003", "--set", "time.end=0.01"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "more than half fold.layer_gap" in out.stderr
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("sets, key", [
    (["fold.layer_gap=0.005", "hub.motion='free'", "perturbation.shape='tilt'",
      "perturbation.z_amplitude=1.0"], "perturbation.z_amplitude"),
    (["perturbation.z_amplitude=1.0"], "fold.layer_gap"),
])
def test_contact_on_elements_that_start_through_each_other_is_refused(tmp_path, sets, key):
    """A displacement perturbation of a layered fold turns or lifts the stacked layers but
    not the nodes tied to the hub, so the layers' columns above the ties start through
    each other (the tilt of 1 m: 563 pairs closer than 1 mm, 150 of them touching); a
    perturbed fold without a layer gap starts with its layers coincident. Contact between
    them is undefined: refused with one line naming the key, nothing written. The same
    tilt by velocity starts clean."""
    from pathlib import Path

    from spinweb_fe.errors import InputError
    from spinweb_fe.run.features import check_features

    web = Path(__file__).resolve().parents[1] / "cases" / "paper_free_web.toml"
    with pytest.raises(InputError) as err:
        run_case(case_mod.load(web, ["contact.cables=true", *sets]), tmp_path / "r",
                 progress=False)
    assert err.value.key == key and "start closer than audit.touch" in str(err.value)
    assert not (tmp_path / "r").exists()
    by_velocity = case_mod.load(web, ["contact.cables=true", "fold.layer_gap=0.005",
                                      "hub.motion='free'", "perturbation.shape='tilt'",
                                      "perturbation.vz_amplitude=5.0"])
    scene = prepare(by_velocity)
    check_features(by_velocity, scene.model, scene.state)
