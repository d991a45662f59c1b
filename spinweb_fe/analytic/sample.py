"""The analytical model's history: the integrated segments sampled every ``history_dt`` into
the FE's ``/history`` layout (:mod:`spinweb_fe.record.history`), and its balance errors."""

from __future__ import annotations

import math

import numpy as np

from spinweb_fe.analytic.regimes import REGIMES

#: the observables of :data:`spinweb_fe.analytic.regimes.Observed`, then the integrated ones
_NAMES = ("kinetic_energy", "angular_momentum", "max_tension", "L", "tip", "hub_torque",
          "device", "speed", "hub_angle", "hub_omega", "phi", "torque_work", "impulse", "lost")


def sample(ctx, segments, dt: float, t_end: float) -> dict:
    """The history of the integrated ``segments`` [(t_a, t_b, dense, regime, lost)] on the
    grid k dt up to the last segment's end."""
    n_out = int(math.floor(t_end / dt + 1e-9)) + 1
    times = np.arange(n_out) * dt
    times = times[times <= segments[-1][1] + 1e-12]
    cols = {k: np.empty(len(times)) for k in _NAMES}
    k = 0
    for i, (ta, tb, dense, regime, lost) in enumerate(segments):
        last = i == len(segments) - 1
        observe = REGIMES[regime].observe
        while k < len(times) and (times[k] < tb or (last and times[k] <= tb + 1e-12)):
            tk = min(times[k], tb)
            y = dense(tk)
            vals = (*observe(ctx, tk, y), y[0], y[2], y[1], y[4], y[5], lost)
            for name, v in zip(_NAMES, vals):
                cols[name][k] = v
            k += 1
    n, zeros = ctx.p.n, np.zeros(len(times))

    def per_arm(v):
        return np.repeat(v[:, None], n, axis=1)
    out = {"time": times, "hub_angle": cols["hub_angle"], "hub_omega": cols["hub_omega"],
           "hub_torque": cols["hub_torque"], "kinetic_energy": cols["kinetic_energy"],
           "strain_energy": zeros, "torque_work": cols["torque_work"],
           "damping_dissipation": zeros.copy(), "contact_dissipation": cols["lost"],
           "angular_momentum": cols["angular_momentum"], "max_tension": cols["max_tension"],
           "arm_length": per_arm(cols["L"]), "arm_angle": per_arm(cols["phi"]),
           "tip_omega": per_arm(cols["tip"]), "torque_impulse": (cols["impulse"], "N m s")}
    if ctx.pay is not None or ctx.brake is not None:  # the device's work: E - E0 - W + losses
        out["brake_work"] = per_arm((cols["kinetic_energy"] + cols["lost"]
                                     - cols["kinetic_energy"][0] - cols["torque_work"]) / n)
        out["brake_tension"] = per_arm(cols["device"])
        out["payout_speed"] = per_arm(cols["speed"])
    return out


def drifts(result) -> tuple[np.ndarray, np.ndarray]:
    """Relative balance errors over time: (K - K0 - torque impulse)/|K0| and
    (E - E0 - torque work)/E0 (with K0, E0 replaced by the current scale if they vanish)."""
    h = result.history
    K, E = h["angular_momentum"], h["kinetic_energy"]
    imp = h["torque_impulse"][0]
    K0, E0 = K[0], E[0]
    k_scale = max(abs(K0), np.max(np.abs(K)), 1e-300)
    e_scale = max(E0, np.max(E), 1e-300)
    lost = h["contact_dissipation"]
    return (K - K0 - imp) / k_scale, (E + lost - E0 - h["torque_work"]) / e_scale
