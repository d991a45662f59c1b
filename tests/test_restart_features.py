"""A restart is the run, whatever its features: every feature of record.feature alone and in
the combinations the cases use, stopped at a checkpoint and continued with ``--restart``,
equals the straight run bit for bit in every history, table, group and frame.

The stop is that of SIGKILL right after a checkpoint: the straight run's folder, which holds
rows and frames written after the checkpoint, gets the checkpoint as it was written then,
and the restart cuts back and goes on (test_restart.py does the same for the plain web).
One scene is killed for real (SIGKILL in a child process, right after the checkpoint's
rename), to show that the emulation is what a kill leaves."""

import os
import shutil
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest

from spinweb_fe.cli import main
from spinweb_fe.run.features import FEATURES

CASES = Path(__file__).parent.parent / "cases"
FREE = ("hub.motion='free'",)
LAYERED_CONTACT = ("fold.layer_gap=0.005", "contact.cables=true", "audit.crossings=true")
#: (name, case, overrides, end [s], checkpoint interval [s], the features it must have)
SCENES = (
    ("contact_friction_feedback", "paper_feedback_web",
     LAYERED_CONTACT + ("contact.friction=0.3",), 0.06, 0.03,
     {"crossings", "contact", "linking"}),
    ("contact_free_hub_perturbed", "paper_free_web",
     FREE + LAYERED_CONTACT + ("perturbation.vz_amplitude=0.1",
                               "perturbation.hub_tilt_rate=0.01",
                               "cable.failure_strain=0.035"), 0.04, 0.02,
     {"crossings", "contact", "linking", "strength"}),
    ("audit_layers", "paper_free_web", ("fold.layer_gap=0.005", "audit.crossings=true"),
     0.04, 0.02, {"crossings", "linking"}),
    ("brake_held_coil", "paper_brake_arms", (), 0.05, 0.02, {"devices"}),
    ("reel_eq7_tethers", "paper_reel_arms", (), 0.05, 0.02, {"devices"}),
    ("rupture", "paper_free_web", ("cable.failure_strain=0.002", "cable.rupture=true"),
     0.05, 0.02, {"strength"}),
    ("gravity_free_hub", "paper_free_arms",
     FREE + ("environment.gravity_gradient=true", "environment.orbit_radius=6.771e6",
             "perturbation.hub_tilt_rate=0.05"), 0.05, 0.02, {"gravity"}),
    ("gravity_fixed_axis", "paper_free_arms",
     ("environment.gravity_gradient=true", "environment.orbit_radius=6.771e6"), 0.05, 0.02,
     {"gravity"}),
    ("bundles", "paper_two_stage_web", (), 0.05, 0.02, {"bundles"}),
)
GROUPS = ("history", "frames", "crossings", "linking", "verdict")


def args(case, sets, end, out, *extra):
    argv = ["run", str(CASES / f"{case}.toml"), "-o", str(out), "--no-progress",
            "--set", f"time.end={end}", "--set", "output.frame_dt=0.005"]
    for s in sets:
        argv += ["--set", s]
    return argv + list(extra)


def datasets(h5) -> dict:
    found = {}
    for g in GROUPS:
        if g in h5:
            h5[g].visititems(lambda n, o, g=g: found.__setitem__(f"{g}/{n}", o[()])
                             if isinstance(o, h5py.Dataset) else None)
            found.update({f"{g}@{k}": v for k, v in h5[g].attrs.items()})
    return found


def assert_same_run(a: Path, b: Path):
    """Every dataset and attribute of the groups, the run's status, the ParaView files."""
    with h5py.File(a / "results.h5", "r") as ha, h5py.File(b / "results.h5", "r") as hb:
        da, db = datasets(ha), datasets(hb)
        assert set(da) == set(db)
        for name in da:
            x, y = np.asarray(da[name]), np.asarray(db[name])
            same = (np.array_equal(x, y, equal_nan=True) if x.dtype.kind == "f"
                    else np.array_equal(x, y))
            assert same, name
        for key in ("steps", "status"):
            assert ha.attrs[key] == hb.attrs[key], key
    assert (a / "web.pvd").read_text() == (b / "web.pvd").read_text()
    for d in ET.parse(a / "web.pvd").getroot().iter("DataSet"):
        assert (a / d.get("file")).read_bytes() == (b / d.get("file")).read_bytes()


@pytest.fixture
def keep_checkpoint(monkeypatch, tmp_path):
    """The checkpoint of the first interval, kept aside as the run writes it."""
    from spinweb_fe.io import checkpoint as ckmod

    real, kept = ckmod.write_checkpoint, tmp_path / "first_checkpoint.h5"

    def keep(path, ck, **kw):
        real(path, ck, **kw)
        if not kept.exists():
            shutil.copy(path, kept)
            kept.with_suffix(".time").write_text(repr(ck.time))

    monkeypatch.setattr("spinweb_fe.run.driver.write_checkpoint", keep)
    return kept


@pytest.mark.parametrize("name, case, sets, end, every, wanted", SCENES,
                         ids=[s[0] for s in SCENES])
def test_restart_is_the_run(name, case, sets, end, every, wanted, tmp_path, keep_checkpoint):
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    assert main(args(case, sets, end, straight, "--checkpoint-dt", str(every))) == 0
    with h5py.File(straight / "results.h5", "r") as h5:
        features = set(h5.attrs["features"].split())
    assert wanted <= features, features
    assert float(keep_checkpoint.with_suffix(".time").read_text()) == pytest.approx(every)
    shutil.copytree(straight, killed)  # as if killed after the first checkpoint
    shutil.copy(keep_checkpoint, killed / "checkpoint.h5")
    assert main(["run", "--restart", str(killed), "--no-progress"]) == 0
    assert_same_run(straight, killed)


def test_every_feature_is_in_the_matrix():
    """Each registered feature has a scene above that restarts it."""
    covered = set().union(*(s[5] for s in SCENES))
    assert covered == {e.name for e in FEATURES}


KILLER = """
import os, signal, sys
from spinweb_fe.io import checkpoint
from spinweb_fe.run import driver
from spinweb_fe.cli import main

def write_and_die(path, ck, **kw):
    checkpoint.write_checkpoint(path, ck, **kw)
    os.kill(os.getpid(), signal.SIGKILL)

driver.write_checkpoint = write_and_die
sys.exit(main(sys.argv[1:]))
"""


def test_sigkill_at_a_checkpoint_then_restart(tmp_path):
    """The contact run on a free, tilted hub killed by SIGKILL right after its first
    checkpoint, in a process of its own, then continued: the straight run bit for bit."""
    name, case, sets, end, every, _ = SCENES[1]
    straight, killed = tmp_path / "straight", tmp_path / "killed"
    assert main(args(case, sets, end, straight, "--checkpoint-dt", str(every))) == 0
    env = dict(os.environ, SPINWEB_COMPILE_HELPER="0")
    proc = subprocess.run([sys.executable, "-c", KILLER,
                           *args(case, sets, end, killed, "--checkpoint-dt", str(every))],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-2000:]
    assert main(["run", "--restart", str(killed), "--no-progress"]) == 0
    assert_same_run(straight, killed)
