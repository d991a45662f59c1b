"""Out-of-plane perturbations of the initial state (``[perturbation]``), reproducible from the
case: a displacement and a velocity normal to the hub plane, of one shape.

- ``tilt``: the web (every node not tied to the hub, the held coil included) turned rigidly
  about the hub-frame x axis through the hub centre by alpha, sin alpha = z_amplitude / the
  largest |y| of the deployed tips (so a flat web's tips reach z_amplitude; a coiled web is
  the stowed coil turned by the same angle); vz_amplitude turns it at the rate
  vz_amplitude / that |y|. When the tips have a larger |x| than |y| (one or two tethers
  along x), the turn is about -y instead (lifting +x), with |x| the lever. The tied nodes stay with the hub.
- ``random``: z = z_amplitude w, v_z = vz_amplitude w, w a smooth random field of the flat
  (deployed) web's material points: eight plane waves of wavelengths between half and twice
  the web's radius, random directions, phases and amplitudes (``seed``), tapered to zero at
  the hub ties, scaled to max |w| = 1 over the web's nodes.
- ``mode``: w the lowest out-of-plane mode shape of the deployed web spinning at the case's
  rate (spinweb_fe.linear, the hub driven: zero at the ties), scaled to max |w| = 1. A
  coiled or folded scene maps it by material point (the meshes share their node numbers): each
  node, the held coil's too, carries the displacement of its place in the deployed web.

Displacements move the held coil's hub-frame positions (the coil is stowed that way);
velocities act on the nodes free at the start only (a held node moves with the hub).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from spinweb_fe.fe.choice import Choice, Param, registry

WAVES = 8  # plane waves of the random field

#: [perturbation] shape: what it does, and its keys (``code``: the branch of
#: :func:`perturbed` and ``case.scene``'s field)
SHAPES = registry(
    Choice("tilt", 0, "the web turned rigidly about the hub-frame x axis (its tied nodes "
                      "stay)"),
    Choice("random", 1, "a smooth random field (plane waves, seed), zero at the hub",
           keys=(Param("seed", "", "nonneg", "shape = random: seed of the field", kind="int",
                       default=0),)),
    Choice("mode", 2, "the lowest out-of-plane mode of the deployed web (spinweb modes)"),
)
TILT, RANDOM, MODE = (SHAPES[name].code for name in ("tilt", "random", "mode"))


def normalised(w: np.ndarray, web: np.ndarray) -> np.ndarray:
    """w / max |w| over the nodes ``web`` (bool mask); the sign makes the largest positive."""
    k = int(np.argmax(np.where(web, np.abs(w), -1.0)))
    return w / w[k] if w[k] != 0 else w


def random_field(ref: np.ndarray, tied: np.ndarray, seed: int) -> np.ndarray:
    """(n,) smooth random field of the flat positions ``ref`` (n, 3), zero at and inside the
    radius of the ``tied`` nodes, max |w| = 1 over the others."""
    rng = np.random.default_rng(seed)
    r = np.hypot(ref[:, 0], ref[:, 1])
    web = np.ones(len(ref), bool)
    web[tied] = False
    r_tie = float(r[tied].max()) if len(tied) else 0.0
    r_max = float(r.max())
    lam = rng.uniform(0.5, 2.0, WAVES) * r_max
    ang = rng.uniform(0.0, 2 * math.pi, WAVES)
    phase = rng.uniform(0.0, 2 * math.pi, WAVES)
    amp = rng.standard_normal(WAVES)
    k = (2 * math.pi / lam)[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    w = (amp[:, None] * np.cos(k @ ref[:, :2].T + phase[:, None])).sum(axis=0)
    w *= np.clip((r - r_tie) / max(r_max - r_tie, 1e-300), 0.0, 1.0)
    return normalised(w, web)


def mode_field(structure, omega: float) -> np.ndarray:
    """(n,) the lowest out-of-plane mode of the deployed ``structure``
    (:class:`spinweb_fe.linear.steady.Structure`) spinning at ``omega`` [rad/s] with the hub
    driven, max |w| = 1.

    Raises
    ------
    spinweb_fe.errors.RunError
        No steady state (see :func:`spinweb_fe.linear.steady.solve_steady`).
    """
    from spinweb_fe.linear.modes import out_of_plane_eigen, out_of_plane_matrices
    from spinweb_fe.linear.steady import solve_steady

    st = solve_steady(structure, omega)
    M, K = out_of_plane_matrices(structure, st)
    _, shapes = out_of_plane_eigen(M, K, omega, 1)
    w = np.zeros(len(structure.node_mass))
    w[structure.free_nodes] = shapes[:, 0]
    web = np.zeros(len(w), bool)
    web[structure.free_nodes] = True
    return normalised(w, web)


def tilt_angle(ref: np.ndarray, tips: np.ndarray, z_amplitude: float) -> tuple:
    """(alpha [rad], lever [m], axis): the turn about hub-frame axis ``axis`` (0: x, 1: y)
    that lifts the deployed tips to z_amplitude, and their largest distance from that axis
    in the plane (x unless the tips reach farther along x than along y)."""
    reach = np.max(np.abs(ref[tips, :2]), axis=0)
    axis = 1 if reach[0] > reach[1] * (1 + 1e-9) else 0
    lever = float(reach[1 - axis])
    return math.asin(min(z_amplitude / lever, 1.0)), lever, axis


def perturbed(case, model, make_state, field=None):
    """(model, state) with the case's out-of-plane perturbation.

    Parameters
    ----------
    case : spinweb_fe.case.Case
    model : spinweb_fe.fe.model.Model
    make_state : callable(Model) -> State
        The initial state of a model (its held nodes placed from the coil's positions).
    field : (n,) float64 or None
        The shape w of ``random`` and ``mode`` (max |w| = 1; None for ``tilt``).
    """
    p = case.perturbation
    if p.z_amplitude == 0 and p.vz_amplitude == 0:
        return model, make_state(model)
    mesh = model.mesh
    web = model.nodes.inv_mass > 0  # not tied to the hub
    pos = np.array(mesh.node_pos, np.float64)
    rate = np.zeros(mesh.n_nodes)
    if SHAPES[p.shape].code == TILT:
        alpha, lever, axis = tilt_angle(mesh.node_ref, np.asarray(mesh.node_sets["tips"]),
                                        p.z_amplitude)
        c, s = math.cos(alpha), math.sin(alpha)
        u = 1 - axis  # the coordinate the turn lifts: y (about +x) or x (about -y)
        y, z = pos[web, u].copy(), pos[web, 2].copy()
        pos[web, u], pos[web, 2] = c * y - s * z, s * y + c * z
        tilt_rate = p.vz_amplitude / lever
    else:
        pos[web, 2] += p.z_amplitude * field[web]
        rate[web] = p.vz_amplitude * field[web]
        tilt_rate = 0.0
    coil = model.coil
    if len(coil.level_nodes):
        model = dataclasses.replace(model, coil=coil._replace(
            level_ref=np.ascontiguousarray(pos[coil.level_nodes])))
    state = make_state(model)
    moved = pos[web] - state.node_pos[web]
    state.node_pos[web] = pos[web]
    if case.initial.spin == "all":  # the rigid spin omega e_z x x of the moved positions
        free_web = state.node_inv_mass[web] > 0
        idx = np.flatnonzero(web)[free_web]
        state.node_vel[idx, 0] -= case.initial.omega * moved[free_web, 1]
        state.node_vel[idx, 1] += case.initial.omega * moved[free_web, 0]
    free = state.node_inv_mass > 0
    state.node_vel[free, 2] += rate[free]
    if tilt_rate:  # the same turn, at tilt_rate
        state.node_vel[free, u] -= tilt_rate * state.node_pos[free, 2]
        state.node_vel[free, 2] += tilt_rate * state.node_pos[free, u]
    return model, state
