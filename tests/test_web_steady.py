"""Steady spinning web against closed forms: the square grid is statically determinate under
the centrifugal load, so each mesh line carries the centrifugal pull of its own nodes beyond
the element, t = omega^2 sum m_k |x_k| (docs/prestress.md). The FE solver, started
unstretched and damped to rest in the rotating frame, must find the same tensions."""


import numpy as np
from closed_forms import quadquad_line_tensions

from meshgen.flat import flat_quadquad
from spinweb_fe.fe.control import free
from spinweb_fe.fe.model import build_model, choose_dt
from spinweb_fe.fe.state import initial_state
from spinweb_fe.run.loop import Schedule, current_tension, simulate

E, RHO, A = 180e12, 1540.0, 1.025e-5  # 1000x Zylon: strain ~1e-7, elasticity negligible


def test_spinning_flat_web_tensions_match_statics():
    """S = 20 m, t = 2.5 m, 1 kg corners at 2 rad/s, no hub: every element tension within
    1e-3 of the largest (residual damped oscillation) of the closed form after 0.2 s."""
    omega = 2.0
    mesh = flat_quadquad(20.0, 2.5, 1, 1.0, 0.0)
    model = build_model(mesh, E, RHO, A, damping_ratio=1.0, hub_radius=0.0, hub_inertia=1.0,
                        contact=False)
    state = initial_state(model, omega, "all")
    dt = choose_dt(model, 0.3, history_dt=1e-3)
    simulate(model, free(), state, dt, Schedule(0.2, 1e-3))
    fe = current_tension(model, state.node_pos, state.node_vel)
    ref = quadquad_line_tensions(mesh, omega, RHO * A)
    assert np.max(np.abs(fe - ref)) < 1e-3 * ref.max()
    assert ref.min() > 0
