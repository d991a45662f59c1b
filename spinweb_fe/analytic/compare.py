"""FE runs against the analytical model: the mapping of an FE scene to the model's arm, the
FE and analytical twins of a case, and the error norms of docs/validation.md."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from meshgen.mesh import POLYGON_TAN
from meshgen.registry import COILED_FOLDS, cable_length_per_area
from spinweb_fe.analytic.models import HALF_PI, ArmParams, params_from_case
from spinweb_fe.analytic.solve import devices_from_case, integrate
from spinweb_fe.case.scene import control_from_case, prepare
from spinweb_fe.fe.model import build_model, choose_dt
from spinweb_fe.fe.state import initial_state
from spinweb_fe.record.energy import energy_balance
from spinweb_fe.run.loop import Schedule, simulate

#: the four compared quantities: (history name, short name, SI unit)
QUANTITIES = (("arm_length", "L", "m"), ("arm_angle", "phi", "rad"),
              ("hub_omega", "omega_centre", "rad/s"), ("tip_omega", "omega_tip", "rad/s"))


def rigid_root(case, mesh, model):
    """Variant of a web model whose root region and central cross are tied to the hub.

    The star fold gathers the central cross (a slack chain of a - c metres per half) and the
    root legs (slack r0 (1 - pi/4)) between the hub ties and the arm roots, so the hub can turn
    tens of metres relative to the web before any torque passes (docs/validation.md). Tying
    every node with arm coordinate < c (and the cross) to the hub at its folded position makes
    the FE root what the analytical model assumes: the free arm starts at the rim point M_k.
    """
    arm, l = mesh.node_arm, mesh.node_arm_coord
    inner = np.flatnonzero(~((arm >= 0) & (l >= mesh.arm_root_coord - 1e-9)))
    sets = dict(mesh.node_sets)
    sets["hub_tied"] = inner.astype(np.int64)
    mesh2 = dataclasses.replace(mesh, node_sets=sets)
    cab, hub = case.cable, case.hub
    model2 = build_model(mesh2, cab.youngs_modulus, cab.density, cab.area, cab.damping_ratio,
                         hub_radius=hub.radius, hub_inertia=hub.inertia, hub_friction=hub.friction)
    return mesh2, model2


def fe_run(case, variant=None):
    """Run the FE model of a validated case in memory; returns (history, info, mesh, model).

    variant='rigid_root' ties the web's root region to the hub (:func:`rigid_root`).
    """
    mesh, model, control, state, dt = prepare(case)
    if variant == "rigid_root":
        mesh, model = rigid_root(case, mesh, model)
        state = initial_state(model, case.initial.omega, case.initial.spin)
        dt = choose_dt(model, case.time.cfl, case.time.dt, case.output.history_dt)
    t0 = time.perf_counter()
    res = simulate(model, control, state, dt, Schedule(case.time.end, case.output.history_dt))
    wall = time.perf_counter() - t0
    h = res.history
    bal = energy_balance(h)
    e_scale = max(float(np.max(h["kinetic_energy"])), 1e-30)
    info = {"elements": int(model.n_elems), "nodes": int(model.n_nodes), "dt": dt,
            "energy_balance_error": float(np.max(np.abs(bal - bal[0]))) / e_scale,
            "steps": int(res.steps), "wall_s": wall, "loop_s": res.loop_s,
            "element_updates_per_s": model.n_elems * res.steps / max(res.loop_s, 1e-9)}
    return res.history, info, mesh, model


def web_params(case, mesh, model, root="hub"):
    """Map the FE star-folded web to the analytical distributed arm (docs/validation.md).

    The free arm is the part beyond the gathered root region: H = arm_length - arm_root_coord
    (42.5 m for the paper web), its roots at the merge points M_k on the rim. Its mass is
    taken from the FE lumped masses: per arm, the cable mass of the nodes with arm coordinate
    >= l0 (tip node: cable only, the corner mass is m_tip) split into the Eq. 7 profile
    (m_lin = rho_A cot(pi/n) H^2: rho_A H^2 for the square web, rho_A H^2 / sqrt(3) for the
    triangular web) and the rest as a uniform tether (the edge lines' excess). The root
    region and the half-axes (nodes with l < l0 or no arm), gathered between the ties and
    the rim, turn with the hub: with root='hub' their inertia sum m r^2 (folded positions) is
    added to J_hub; root='drop' leaves it out (J_hub alone) to show its weight.
    """
    c, a, r0 = mesh.arm_root_coord, mesh.arm_length, case.hub.radius
    H = a - c
    n = mesh.n_arms
    m = model.nodes.mass - mesh.node_point_mass
    arm, l = mesh.node_arm, mesh.node_arm_coord
    free = (arm == 0) & (l >= c - 1e-9)
    m_free = float(m[free].sum())
    rho_a = case.web.areal_density
    if rho_a is None:
        rho_a = (case.cable.density * case.cable.area
                 * cable_length_per_area(case.web.topology, case.web.mesh_width))
    m_lin = min(rho_a * H * H / POLYGON_TAN[n], m_free)
    m_uni = m_free - m_lin
    inner = ~((arm >= 0) & (l >= c - 1e-9))
    r2 = mesh.node_pos[:, 0] ** 2 + mesh.node_pos[:, 1] ** 2
    J_root = float(np.sum(model.nodes.mass[inner] * r2[inner]))
    J_hub = case.hub.inertia + (J_root if root == "hub" else 0.0)
    p = ArmParams(n=n, H=H, r0=r0, J_hub=J_hub, m_tip=case.tip_mass.mass, m_lin=m_lin,
                  m_uni=m_uni)
    return p, {"H": H, "m_lin": m_lin, "m_uni": m_uni, "J_root_region": J_root,
               "J_hub": J_hub, "root_region_mass": float(model.nodes.mass[inner].sum())}


def analytic_twin(case, params=None, t_end=None, model="consistent"):
    """The analytical model of a case (its own mapping unless ``params`` is given); returns
    (history, AnalyticResult)."""
    p = params or params_from_case(case)
    coiled = case.fold.pattern in COILED_FOLDS
    payout, brake = devices_from_case(case)
    res = integrate(p, control_from_case(case), model=model, t_end=t_end or case.time.end,
                    history_dt=case.output.history_dt, coiled=coiled, wrap=case.fold.wrap,
                    omega_init=case.initial.omega, spin=case.initial.spin,
                    payout=payout, brake=brake)
    return res.history, res


def first_pivot(an_hist):
    """Time the analytical arm first leaves the coil (|phi| <= pi/2): end of the uncoiling."""
    phi = an_hist["arm_angle"][:, 0]
    idx = np.flatnonzero(np.abs(phi) <= HALF_PI + 1e-9)
    return float(an_hist["time"][idx[0]]) if len(idx) else float(an_hist["time"][-1])


def error_table(fe, an, windows):
    """Max and RMS of |FE - analytic| (arm 0 and the max over arms) per quantity and window.

    windows: dict name -> (t_a, t_b). Returns {window: {quantity: {max, rms, max_all_arms}}}.
    """
    n = min(len(fe["time"]), len(an["time"]))
    t = fe["time"][:n]
    out = {}
    for wname, (ta, tb) in windows.items():
        sel = (t >= ta - 1e-12) & (t <= tb + 1e-12)
        out[wname] = {"t": [ta, tb]}
        for key, short, unit in QUANTITIES:
            x, y = fe[key][:n][sel], an[key][:n][sel]
            e = np.abs(x - y)
            if e.ndim == 2:
                e_all, e = e, e[:, 0]
            else:
                e_all = e[:, None]
            out[wname][short] = {"max": float(e.max()) if len(e) else float("nan"),
                                 "rms": float(np.sqrt(np.mean(e ** 2))) if len(e) else float("nan"),
                                 "max_all_arms": float(e_all.max()) if len(e) else float("nan"),
                                 "unit": unit}
    return out
