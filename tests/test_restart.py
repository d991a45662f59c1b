"""Checkpoint / restart: a run stopped at a checkpoint and continued with ``--restart`` gives
the same /history, /frames and ParaView files as an uninterrupted run, bit for bit."""

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest

from spinweb_fe.io import checkpoint as ckmod
from spinweb_fe.cli import main
from spinweb_fe.fe.coil.levels import CoilState
from spinweb_fe.fe.hub.rigid import RigidState
from spinweb_fe.fe.rupture import StrengthState
from spinweb_fe.fe.state import HubState, State, to_arrays

CASES = Path(__file__).parent.parent / "cases"
# a star-folded web deploying from rigid rotation: it sits on the slack/taut kink, where any
# difference in the continued state would grow fast (physics-notes section 2)
WEB = [str(CASES / "paper_free_web.toml"), "--no-progress", "--set", "output.frame_dt=0.013"]


def run(out, end, *extra):
    return main(["run", *WEB, "-o", str(out), "--set", f"time.end={end}", *extra])


def assert_same_results(a: Path, b: Path):
    """Identical /history and /frames datasets, web.pvd text and VTU bytes."""
    with h5py.File(a / "results.h5", "r") as ha, h5py.File(b / "results.h5", "r") as hb:
        for group in ("history", "frames"):
            assert set(ha[group]) == set(hb[group])
            for key in ha[group]:
                assert np.array_equal(ha[group][key][()], hb[group][key][()]), (group, key)
        assert ha.attrs["steps"] == hb.attrs["steps"] and hb.attrs["status"] == "completed"
    assert (a / "web.pvd").read_text() == (b / "web.pvd").read_text()
    files = [d.get("file") for d in ET.parse(a / "web.pvd").getroot().iter("DataSet")]
    written = sorted(p.name for p in (b / "frames").glob("*.vtu"))
    assert written == sorted(Path(f).name for f in files)
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes(), f


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Uninterrupted run to 0.2 s, checkpointing every 0.05 s."""
    out = tmp_path_factory.mktemp("ref")
    assert run(out, 0.2, "--checkpoint-dt", "0.05") == 0
    return out


def test_stop_at_time_end_then_continue(reference, tmp_path):
    out = tmp_path / "two_legs"
    assert run(out, 0.1, "--checkpoint-dt", "0.05") == 0
    with h5py.File(out / "checkpoint.h5", "r") as ck:
        assert ck.attrs["time"] == pytest.approx(0.1) and ck.attrs["history_rows"] == 100
    assert main(["run", "--restart", str(out), "--set", "time.end=0.2", "--no-progress"]) == 0
    assert_same_results(reference, out)
    assert not list(out.glob("*.tmp"))


def test_restart_cuts_back_what_was_written_after_the_checkpoint(reference, tmp_path,
                                                                 monkeypatch):
    """As if killed after the checkpoint at 0.1 s: results.h5 already holds rows and frames up
    to 0.2 s; the restart cuts them back to the checkpoint's counts and recomputes them."""
    out = tmp_path / "killed"
    kept = tmp_path / "checkpoint_at_0.1.h5"
    real = ckmod.write_checkpoint

    def keep_a_copy(path, ck, **kw):
        real(path, ck, **kw)
        if ck.steps * ck.dt == pytest.approx(0.1):
            shutil.copy(path, kept)

    monkeypatch.setattr("spinweb_fe.run.driver.write_checkpoint", keep_a_copy)
    assert run(out, 0.2, "--checkpoint-dt", "0.05") == 0
    shutil.copy(kept, out / "checkpoint.h5")
    (out / "frames" / "web_000099.vtu").write_text("stale frame of another run")
    assert main(["run", "--restart", str(out), "--no-progress"]) == 0
    assert_same_results(reference, out)
    assert not (out / "frames" / "web_000099.vtu").exists()


@pytest.mark.parametrize("sets,key,reason", [
    (["--set", "hub.mass=50.0"], "hub.mass", "cannot change on --restart"),
    (["--set", "time.end=0.05"], "time.end", "is not after the checkpoint"),
    (["--set", "time.bogus=1"], "time.bogus", "unknown key"),
])
def test_restart_refuses_changes(reference, tmp_path, capsys, sets, key, reason):
    out = tmp_path / "copy"
    shutil.copytree(reference, out)
    before = (out / "results.h5").read_bytes()
    assert main(["run", "--restart", str(out), *sets, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{key}: " in err and reason in err
    assert (out / "results.h5").read_bytes() == before


def test_restart_refuses_a_case_argument(reference, capsys):
    assert main(["run", WEB[0], "--restart", str(reference)]) == 2
    assert "not both" in capsys.readouterr().err


def test_checkpoint_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(0)
    pos = rng.standard_normal((7, 3)) * 1e3
    pos[0, 0], pos[1, 1] = 5e-324, -0.0  # subnormal and negative zero survive
    one = lambda: rng.standard_normal(1)  # noqa: E731
    st = State(pos, rng.standard_normal((7, 3)), rng.random(7), rng.random(7),
               HubState(one(), one(), one()),
               CoilState(np.array([3, 0], np.int64), np.array([True, False]),
                         *(rng.standard_normal(sh) for sh in (2, 2, (2, 3), (2, 3), 2, 2, 2, 3, 2))),
               rng.standard_normal(4), np.array([12345], np.int64), one(),
               StrengthState(np.array([True, False, True]), rng.standard_normal(3), one(),
                             np.array([2], np.int64)),
               RigidState(*(rng.standard_normal(s) for s in (3, 3, 4, 3, 1, 3, (3, 3),
                                                             (3, 3), 3))))
    entries = [(0.0, "frames/web_000000.vtu"), (0.05, "frames/web_000001.vtu")]
    memory = {"arms": {"prev_phi": np.array([np.nan, 1.0]),
                       "prev_wound": np.array([True, False])},
              "energy": {"ref": np.array([1.5, 2.5])}}
    ck = ckmod.Checkpoint(state=st, dt=1.1e-5, history_rows=12, frames=2, pvd_entries=entries,
                          case_toml="[time]\nend = 1.0\n", case_source="a/b.toml",
                          checkpoint_dt=0.5, memory=memory, threads=2)
    path = ckmod.write_checkpoint(tmp_path / "checkpoint.h5", ck)
    back = ckmod.read_checkpoint(path)
    for name, a in to_arrays(st).items():
        b = to_arrays(back.state)[name]
        assert a.dtype == b.dtype and a.dtype in (np.float64, np.int64, np.bool_)
        assert a.tobytes() == b.tobytes(), name
    assert (back.dt, back.history_rows, back.frames, back.threads) == (1.1e-5, 12, 2, 2)
    assert back.steps == 12345
    assert back.pvd_entries == ck.pvd_entries
    assert back.case_toml == ck.case_toml and back.case_source == "a/b.toml"
    assert np.array_equal(back.memory["arms"]["prev_phi"], [np.nan, 1.0], equal_nan=True)
    assert back.memory["arms"]["prev_wound"].tolist() == [True, False]
    assert back.memory["energy"]["ref"].tolist() == [1.5, 2.5]
    assert not (tmp_path / "checkpoint.h5.tmp").exists()


def test_a_checkpoint_never_continues_other_results(reference, tmp_path, capsys):
    """A fresh run into a folder removes the old checkpoint; a checkpoint copied next to the
    results of another run is refused (run_id), and those results stay untouched."""
    out = tmp_path / "other"
    shutil.copytree(reference, out)
    assert run(out, 0.05) == 0
    capsys.readouterr()
    assert not (out / "checkpoint.h5").exists()
    shutil.copy(reference / "checkpoint.h5", out / "checkpoint.h5")
    before = (out / "results.h5").read_bytes()
    assert main(["run", "--restart", str(out), "--set", "time.end=0.3", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "results.h5: run_id: the results are not those of" in err[0]
    assert (out / "results.h5").read_bytes() == before


@pytest.mark.parametrize("path", sorted(CASES.glob("*.toml")), ids=lambda p: p.stem)
def test_resolved_case_loads_again(path):
    """The resolved case (stored in results.h5 and the checkpoint) validates to the same case,
    derived values (cable.area from web.areal_density, hub.inertia) included."""
    from spinweb_fe import case as case_mod

    c = case_mod.load(path)
    again = case_mod.loads(c.to_toml())
    assert again.to_dict() == c.to_dict()
