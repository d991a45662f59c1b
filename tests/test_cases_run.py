"""Every case in cases/ runs end to end through the CLI with a shortened time.end, and its
outputs follow docs/interface.md (datasets, units, ParaView collection)."""

import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

from spinweb_fe.cli import main
from spinweb_fe.record.history import HISTORY_UNITS, OPTIONAL

CASES = sorted((Path(__file__).parent.parent / "cases").glob("*.toml"))
SHORT = ["--set", "time.end=0.004", "--set", "output.history_dt=0.001",
         "--set", "output.frame_dt=0.002", "--no-progress"]


@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_case_runs_and_writes_contract_outputs(case, tmp_path):
    out = tmp_path / case.stem
    assert main(["run", str(case), "-o", str(out)] + SHORT) == 0
    with h5py.File(out / "results.h5", "r") as h5:
        for key in ("format_version", "spinweb_version", "case", "dt", "steps", "wall_time_s"):
            assert key in h5.attrs
        assert h5.attrs["status"] == "completed"
        hist = h5["history"]
        t = hist["time"][()]
        np.testing.assert_allclose(t, np.arange(5) * 1e-3, atol=1e-12)
        for name, units in HISTORY_UNITS.items():
            if name in OPTIONAL and name not in hist:
                continue
            assert hist[name].attrs["units"] == units, name
            assert np.all(np.isfinite(hist[name][()])), name
        coiled = "coil" in h5["mesh/node_sets"]
        assert ("payout_front" in hist) == coiled  # every coiled case holds its coil
        n_arms = hist["arm_length"].shape[1]
        assert n_arms == len(h5["mesh/node_sets/tips"])
        for name in ("points", "reference_points", "elements", "rest_length", "node_mass"):
            assert "units" in h5["mesh"][name].attrs
        assert len(h5["mesh/node_sets/hub_tied"]) > 0
        n, m = h5["mesh/points"].shape[0], h5["mesh/elements"].shape[0]
        assert h5["frames/position"].shape == (3, n, 3)
        assert h5["frames/tension"].shape == (3, m)
    # the ParaView collection lists every frame, and each frame reads back
    root = ET.parse(out / "web.pvd").getroot()
    files = [d.get("file") for d in root.iter("DataSet")]
    times = [float(d.get("timestep")) for d in root.iter("DataSet")]
    assert times == pytest.approx([0.0, 0.002, 0.004])
    for f in files:
        vtu = meshio.read(out / f)
        assert vtu.points.shape == (n, 3)
        for key in ("velocity", "displacement", "node_mass"):
            assert key in vtu.point_data
        for key in ("tension", "strain", "slack"):
            assert key in vtu.cell_data
    assert main(["info", str(out / "results.h5")]) == 0
