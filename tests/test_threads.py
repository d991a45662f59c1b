"""The threaded step loop: same physics as the serial one, deterministic per thread count."""

import math

import numpy as np
import pytest

from meshgen.flat import flat_quadquad
from meshgen.tethers import tethers
from spinweb_fe.fe.control import free
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
    2 threads give 1 thread's histories bit for bit over 0.05 s (fixed blocks, fixed
    summation order; a fortiori within 1e-9 relative), and two 2-thread runs are
    bit-identical."""
    mesh = tethers(4, 50.0, 50, 6.3, 10.0, "coiled", "trailing")
    kw = dict(hub_radius=6.3, hub_inertia=3969.0, hub_friction=friction)
    h1, h2, h2b = run(mesh, 1, **kw), run(mesh, 2, **kw), run(mesh, 2, **kw)
    for key in ("hub_omega", "kinetic_energy", "arm_length", "angular_momentum"):
        np.testing.assert_allclose(h2[key], h1[key], rtol=1e-9, atol=1e-9 * np.abs(h1[key]).max())
        assert np.array_equal(h2[key], h1[key])
        assert np.array_equal(h2[key], h2b[key])
    K = h2["angular_momentum"]
    assert np.max(np.abs(K - K[0])) / abs(K[0]) < 1e-12


def test_threads_take_the_element_blocks_of_their_own_nodes():
    """fe.forces.thread_order on a flat web (its x-lines listed before its y-lines): a
    permutation of the blocks, sorted by their mean node; with two threads each takes
    elements whose ends lie in its own half of the nodes (the node passes' ranges), where a
    split of the element order would give each thread ends across all nodes."""
    from spinweb_fe.fe.forces import thread_order

    mesh = flat_quadquad(20.0, 0.25, 1, 1.0, 0.0)
    en, n, block = mesh.elem_nodes, mesh.n_nodes, 64
    order = thread_order(en, block)
    blocks = -(-len(en) // block)
    assert sorted(order.tolist()) == list(range(blocks))
    key = [en[b * block:(b + 1) * block].mean() for b in order]
    assert np.all(np.diff(key) >= 0)

    def own(block_list):  # share of thread 0's element ends below n / 2
        ends = np.concatenate([en[b * block:(b + 1) * block] for b in block_list])
        return np.mean(ends < n // 2)

    assert own(order[:blocks // 2]) > 0.95
    assert own(range(blocks // 2)) < 0.6
    assert thread_order(np.zeros((0, 2), np.int64), block).tolist() == [0]


def test_threaded_flat_web_conserves_angular_momentum():
    mesh = flat_quadquad(20.0, 1.0, 1, 1.0, 0.0)
    h = run(mesh, 2, t_end=0.02, hub_radius=0.0, hub_inertia=1.0, contact=False)
    K = h["angular_momentum"]
    assert np.max(np.abs(K - K[0])) / abs(K[0]) < 1e-12


# (the two-stage web's bundles on two threads are a step loop of their own, compiled for this
# test alone: in make validate; the thread mutants of tests/mutate.py are killed by the
# feedback web here and the tests above)
@pytest.mark.parametrize("case", [pytest.param("paper_two_stage_web", marks=pytest.mark.slow),
                                  "paper_feedback_web"])
def test_every_thread_count_gives_the_same_bits(case):
    """The paper's web (held coil, contact, bundles or torque feedback; 3 220 elements in 7
    blocks): 1 and 2 threads give the same histories bit for bit (the force passes work
    in fixed blocks, each node summed in element order, partial sums added in block
    order)."""
    from pathlib import Path

    from spinweb_fe.case import load
    from spinweb_fe.case.scene import prepare

    case_file = Path(__file__).resolve().parent.parent / "cases" / f"{case}.toml"
    out = []
    for threads in (1, 2):
        scene = prepare(load(case_file))
        out.append(simulate(scene.model, scene.control, scene.state, scene.dt,
                            Schedule(0.02, 1e-3), threads=threads).history)
    assert out[0]["max_tension"].max() > 0.0
    for h in out[1:]:
        for key in out[0]:
            assert np.array_equal(h[key], out[0][key], equal_nan=True), key
