"""The threaded step loop: same physics as the serial one, deterministic per thread count."""

import math

import numpy as np
import pytest

from meshgen.flat import flat_quadquad
from meshgen.tethers import tethers
from spinweb_fe.fe.control import LAWS, Control, free
from spinweb_fe.fe.model import build_model, choose_dt
from spinweb_fe.fe.state import initial_state
from spinweb_fe.run.loop import Schedule, simulate

FREE = free()


def run(mesh, threads, t_end=0.05, **kw):
    model = build_model(mesh, 180e9, 1540.0, 1.025e-5, **kw)
    state = initial_state(model, 8 * math.pi, "all")
    dt = choose_dt(model, 0.3, history_dt=1e-3)
    return simulate(model, FREE, state, dt, Schedule(t_end, 1e-3), threads=threads).history


@pytest.mark.parametrize("friction", [0.0, 0.2])
def test_two_threads_agree_with_one_and_repeat_bit_for_bit(friction):
    """Coiled tethers on a hub (ties, contact, and friction which runs the node pass serially):
    2 threads match 1 thread to round-off over 0.05 s (summation order differs, 1e-9 relative),
    and two 2-thread runs are bit-identical."""
    mesh = tethers(4, 50.0, 50, 6.3, 10.0, "coiled", "trailing")
    kw = dict(hub_radius=6.3, hub_inertia=3969.0, hub_friction=friction)
    h1, h2, h2b = run(mesh, 1, **kw), run(mesh, 2, **kw), run(mesh, 2, **kw)
    for key in ("hub_omega", "kinetic_energy", "arm_length", "angular_momentum"):
        np.testing.assert_allclose(h2[key], h1[key], rtol=1e-9, atol=1e-9 * np.abs(h1[key]).max())
        assert np.array_equal(h2[key], h2b[key])
    K = h2["angular_momentum"]
    assert np.max(np.abs(K - K[0])) / abs(K[0]) < 1e-12


def test_threaded_flat_web_conserves_angular_momentum():
    mesh = flat_quadquad(20.0, 1.0, 1, 1.0, 0.0)
    h = run(mesh, 2, t_end=0.02, hub_radius=0.0, hub_inertia=1.0, contact=False)
    K = h["angular_momentum"]
    assert np.max(np.abs(K - K[0])) / abs(K[0]) < 1e-12
