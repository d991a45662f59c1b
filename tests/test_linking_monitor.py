"""The linking check of a run (record/linking.py's LinkingMonitor, ``[audit] crossings``):
on scripted frames of two two-cell webs, one element pushed through the other web (the
cell pairs it changes, by the crossing's sign rule of test_linking.py), a frame caught
mid-crossing, cells lost to rupture, the memory of a checkpoint; in a run, the /linking
group of results.h5, a restart that continues it, and ``spinweb info``."""

from __future__ import annotations

import math
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from test_linking import along, two_strips

from spinweb_fe import case as case_mod
from spinweb_fe.cli import main
from spinweb_fe.cli.info import summary
from spinweb_fe.record.linking_check import LinkingMonitor
from spinweb_fe.record.recorders import Frame, RunInfo
from spinweb_fe.run.driver import run_case
from spinweb_fe.run.restart import restart_case
from support import loop_crossings

DT = 0.01
E, F = (2, 3), (7, 10)  # two_strips: e of the upright web W1, f of the flat W2


def watched(mesh, frames, state=None, n_total=100, broken=None):
    """A monitor told of the start and of ``frames`` (positions, one a step)."""
    mon = LinkingMonitor(mesh, state)
    mon.start(RunInfo(None, DT, n_total, 0, 1))
    for k, pos in enumerate(frames):
        mon.frame(Frame(k * DT, pos, None, None, None if broken is None else broken[k]))
    return mon


def predicted(mesh, pos0, pos1):
    """{(P, Q): change of Lk} of the cell pairs when e passes through f from pos0 to pos1:
    s eps_e(P) eps_f(Q), s the detector's sign for e and f as stored (test_linking.py)."""
    times, signs = np.empty(3), np.empty(3, np.int64)
    (a, b), (c, d) = E, F
    assert loop_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c], pos0[d],
                          pos1[d], times, signs) == 1
    mon = LinkingMonitor(mesh)
    loops = mon.loops
    w1 = [i for i in range(loops.n_loops) if loops.loop(i).max() < 6]
    w2 = [i for i in range(loops.n_loops) if loops.loop(i).min() >= 6]
    return {(min(P, Q), max(P, Q)): int(signs[0]) * along(loops.loop(P), *E)
            * along(loops.loop(Q), *F) for P in w1 for Q in w2}


def as_dict(rows):
    return {(int(i), int(j)): int(v) for i, j, v in rows}


def test_a_crossing_changes_the_cell_pairs_its_sign_rule_predicts():
    """Frames: the start, e through f, the same, e back: 4 pairs change at the crossing
    (each by the sign rule's +-1), none while nothing moves, 4 back; the first change at
    the second frame, none net."""
    mesh, pos1 = two_strips()
    pos0 = mesh.node_pos.copy()  # (writable, as a run's frames: the kernels' compile shared)
    want = predicted(mesh, pos0, pos1)
    assert sorted(want.values()) == [-1, -1, 1, 1]
    mon = watched(mesh, [pos0, pos1, pos1, pos0])
    t = mon.table()
    assert t["time"].tolist() == pytest.approx([0, DT, 2 * DT, 3 * DT])
    assert t["changed"].tolist() == [0, 4, 0, 4]
    assert np.all(t["suspect"] == 0) and np.all(t["worst"] < 1e-12)
    assert as_dict(mon.current) == as_dict(mon.reference)
    s = mon.summary()
    assert s["changed_total"] == 8 and s["net_changed"] == 0
    assert s["first_change_time"] == pytest.approx(DT)
    once = watched(mesh, [pos0, pos1])
    before, after = as_dict(once.reference), as_dict(once.current)
    for key, dlk in want.items():
        assert after.get(key, 0) - before.get(key, 0) == dlk
    assert once.table()["linked"].tolist() == [len(before), len(after)]
    assert once.summary()["net_changed"] == 4


def test_a_frame_caught_mid_crossing_keeps_the_previous_values():
    """e through f's midpoint, tilted (the cells meet, their boxes overlap): the four pairs
    through e and f are suspects and keep their values (no change, the same linked
    pairs); the change counts at the next frame."""
    mesh, pos1 = two_strips()
    mid = mesh.node_pos.copy()
    mid[[2, 3], 2] = 0.1, -0.1
    mon = watched(mesh, [mesh.node_pos, mid, pos1])
    t = mon.table()
    assert t["suspect"].tolist()[1] == 4 and t["worst"][1] == pytest.approx(0.5, abs=1e-9)
    assert t["changed"].tolist() == [0, 0, 4]
    assert t["linked"][1] == t["linked"][0]


def test_cells_that_lose_an_element_leave_the_check_without_a_change():
    """Element (6, 7) of W2's boundary breaks: its one cell leaves the check, its pairs
    with it (no change counted); e through f then changes only the pairs of W2's other
    cell. e breaking takes both cells of W1 out: nothing is linked."""
    mesh, pos1 = two_strips()
    pos0 = mesh.node_pos.copy()
    gone = np.zeros(len(mesh.elem_nodes), bool)
    gone[7] = True
    mon = LinkingMonitor(mesh)
    cell = [i for i in range(mon.loops.n_loops) if 6 in mon.loops.loop(i)]
    assert len(cell) == 1
    want = {k: v for k, v in predicted(mesh, pos0, pos1).items() if cell[0] not in k}
    mon = watched(mesh, [pos0, pos0, pos1], broken=[None, gone, gone])
    t = mon.table()
    assert t["changed"].tolist() == [0, 0, 2] and t["linked"][1] == t["linked"][0] - 1
    before, after = as_dict(mon.reference), as_dict(mon.current)
    for key, dlk in want.items():
        assert after.get(key, 0) - before.get(key, 0) == dlk
    assert not [key for key in after if cell[0] in key]
    assert mon.alive.sum() == 3 and mon.summary()["net_changed"] == 2
    e_gone = np.zeros(len(mesh.elem_nodes), bool)
    e_gone[1] = True  # e = (2, 3)
    mon = watched(mesh, [pos0, pos1], broken=[None, e_gone])
    assert mon.table()["linked"].tolist()[1] == 0 and mon.table()["changed"][1] == 0
    assert mon.alive.sum() == 2


def test_the_start_the_frames_and_the_end_each_once_and_a_checkpoint_continues(tmp_path):
    """The first state at start(), frames, the last step at the loop's checkpoint event at
    the end (and its frame not again). A monitor stopped at a checkpoint (memory through
    an HDF5 file as the checkpoint writes it) and continued gives the same checks."""
    mesh, pos1 = two_strips()
    pos0 = mesh.node_pos.copy()
    path = [pos0, pos1, pos1, pos0, pos1]

    def state(k):
        return SimpleNamespace(step=np.array([k]), node_pos=path[k].copy(),
                               strength=SimpleNamespace(broken=np.zeros(0, bool)))

    plain = watched(mesh, [], state(0), n_total=4)
    plain.checkpoint(state(4), {})
    plain.frame(Frame(4 * DT, pos1, None, None))  # the last step's frame: checked already
    assert plain.table()["time"].tolist() == pytest.approx([0, 4 * DT])
    assert plain.table()["changed"].tolist() == [0, 4]

    full = watched(mesh, path, state(0), n_total=4)
    assert full.table()["time"].tolist() == pytest.approx([k * DT for k in range(5)])
    first = watched(mesh, path[:2], state(0), n_total=4)
    with h5py.File(tmp_path / "ck.h5", "w") as h5:  # as io/checkpoint.py writes and reads
        for name, value in first.memory().items():
            h5.create_dataset(name, data=np.asarray(value))
    with h5py.File(tmp_path / "ck.h5", "r") as h5:
        memory = {k: v[()] for k, v in h5.items()}
    again = LinkingMonitor(mesh, state(2))
    again.restore(memory)
    again.start(RunInfo(None, DT, 4, 2, 1))  # restored: the state given is not checked
    for k in (2, 3, 4):
        again.frame(Frame(k * DT, path[k], None, None))
    for key, col in full.table().items():
        assert np.array_equal(again.table()[key], col), key
    assert again.summary() == full.summary()
    assert np.array_equal(again.reference, full.reference)


def small_web(sets=()):
    """The crossing audit's small web (tests/test_crossing_audit.py), tilted by 1 m (its
    cells' boxes overlap: the check computes pairs), audited, frames every 0.01 s."""
    return case_mod.loads("[web]\nside = 40.0\nmesh_width = 5.0\n[fold]\npattern = 'flat'\n"
                          "[time]\nend = 0.02\n", ["perturbation.z_amplitude=1.0",
                                                   "audit.crossings=true",
                                                   "output.frame_dt=0.01", *sets])


def read_linking(path):
    with h5py.File(path / "results.h5") as f:
        g = f["linking"]
        return ({k: g[k][()] for k in g if k != "cells"}, dict(g.attrs),
                {k: g[k].attrs.get("units") for k in g if k != "cells"})


def test_a_run_writes_the_linking_check_and_info_prints_both_audits(tmp_path, capsys):
    """results.h5 of an audited run: /linking with a check at 0, 0.01 and 0.02 s, nothing
    linked nor changed, its units; without frames the start and the end; ``spinweb info``
    prints the crossing audit and the linking check."""
    run_case(small_web(), tmp_path / "a", progress=False)
    data, attrs, units = read_linking(tmp_path / "a")
    assert data["time"] == pytest.approx([0.0, 0.01, 0.02])
    assert np.all(data["linked"] == 0) and np.all(data["changed"] == 0)
    assert np.all(data["worst"] < 1e-9) and np.all(data["suspect"] == 0)
    assert units["time"] == "s" and units["linked"] == "1" and units["worst"] == "1"
    assert attrs["changed_total"] == 0 and math.isnan(attrs["first_change_time"])
    assert attrs["loops"] == 49 and attrs["dropped"] == 0  # 8 x 8 cells, 4 x 4 cut out, the rim
    assert data["links"].shape == (0, 3)
    text = summary(tmp_path / "a" / "results.h5")
    assert "crossings: 0 (broad phase built" in text
    assert "linking: 49 cells, 3 checks (t = 0 .. 0.02 s); cell pairs linked 0 at the " \
           "start, 0 at the end; 0 changes" in text
    assert main(["info", str(tmp_path / "a" / "results.h5")]) == 0
    assert "linking: 49 cells" in capsys.readouterr().out
    run_case(small_web(["output.frame_dt=0"]), tmp_path / "b", progress=False)
    assert read_linking(tmp_path / "b")[0]["time"] == pytest.approx([0.0, 0.02])
    run_case(small_web(["audit.crossings=false"]), tmp_path / "c", progress=False)
    text = summary(tmp_path / "c" / "results.h5")
    assert "crossings:" not in text and "linking:" not in text


def test_a_restarted_run_continues_the_linking_check(tmp_path):
    """Stopped at 0.01 s (its checkpoint) and continued to 0.02 s: the same /linking as
    the run straight through."""
    run_case(small_web(), tmp_path / "straight", progress=False)
    run_case(small_web(["time.end=0.01"]), tmp_path / "legs", progress=False,
             checkpoint_dt=0.01)
    restart_case(tmp_path / "legs", ["time.end=0.02"], progress=False)
    a, attrs_a, _ = read_linking(tmp_path / "straight")
    b, attrs_b, _ = read_linking(tmp_path / "legs")
    assert set(a) == set(b)
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    assert attrs_a["changed_total"] == attrs_b["changed_total"]
