"""The arm measures have no jumps beyond what the motion allows, on every case of cases/.

Bound (docs/results.md): between two history rows the measured arm moves only as its tip
and its anchor do. With rho the tip's distance from the hub axis, theta_tip its polar angle
and l = sqrt(rho^2 - r0^2) its tangent length (|d l| <= sqrt(|d rho^2|), the tangent's
sensitivity to rho is unbounded on the rim):

- L is the tangent length or the distance to an anchor on the rim that turns with the hub
  and moves with the wound angle: |dL| <= |d tip| + sqrt(|d rho^2|) + r0 (|d theta_hub| +
  |d phi|);
- phi is the anchor's wound angle plus the arm's angle about it: the tangent point moves
  with theta_tip and with atan(l / r0) (|d| <= sqrt(|d rho^2|) / r0), a pivot's angle
  with the tip over the arm's length: |d phi| <= |d theta_hub| + |d theta_tip| +
  sqrt(|d rho^2|) / r0 + |d tip| / min(L).

Under a rate payout the restraint anchors the arm at its front F, which moves by a level
spacing at each release: the bounds grow by the front's move g between the rows (L) and g / r0
(phi).
"""

from pathlib import Path

import numpy as np
import pytest

from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.run.loop import Schedule, simulate

CASES = sorted((Path(__file__).resolve().parents[1] / "cases").glob("*.toml"))
#: end times: the uncoiling and the first swing of every tether and Zylon web case, the
#: start of the stiff (slow) ones
END = {"demo": 2.0, "paper_payout_web": 2.0, "paper_two_stage_web": 0.8, "paper_free_arms": 0.8, "paper_free_arms_eq7": 0.8, "paper_free_web": 0.8,
       "paper_feedback_web": 0.8, "paper_ramp_web": 2.0, "tri_ramp_web": 2.0}
#: the stiff cases' 1.5 us step: 55 000 steps to 0.08 s (the feedback web's arms unwound
#: to 10 m, the ramp web's first swing), 4 s a case at 0.15 s
STIFF_END = 0.08


@pytest.mark.parametrize("path", CASES, ids=[c.stem for c in CASES])
def test_no_jumps_in_arm_length_and_angle(path):
    end = END.get(path.stem, STIFF_END if "stiff" in path.stem else 0.8)
    cs = case_mod.load(path, [f"time.end={min(end, 2.0)}", "output.frame_dt=0"])
    mesh, model, control, state, dt = prepare(cs)
    h = simulate(model, control, state, dt, Schedule(cs.time.end, cs.output.history_dt)).history
    r0 = model.hub.radius
    tip = h["tip_position"]
    d_tip = np.linalg.norm(np.diff(tip, axis=0), axis=2)
    d_hub = np.abs(np.diff(h["hub_angle"]))[:, None]
    d_phi = np.abs(np.diff(h["arm_angle"], axis=0))
    d_L = np.abs(np.diff(h["arm_length"], axis=0))
    rho2 = tip[..., 0] ** 2 + tip[..., 1] ** 2
    d_rho = np.sqrt(np.abs(np.diff(rho2, axis=0)))
    theta = np.arctan2(tip[..., 1], tip[..., 0])
    d_theta = np.abs(np.angle(np.exp(1j * np.diff(theta, axis=0))))
    L = h["arm_length"]
    l_min = np.maximum(np.minimum(L[1:], L[:-1]), 1e-3 * max(r0, 1e-3))
    tol = 1e-9 * max(1.0, float(np.abs(L).max()))
    gap = 0.0
    if cs.stowage.payout == "rate":  # the anchor's step: one level spacing at a release
        front = h["payout_front"]
        gap = np.abs(np.diff(front, axis=0))
    over_L = d_L - (d_tip + d_rho + r0 * (d_hub + d_phi) + gap) - tol
    over_phi = d_phi - (d_hub + d_theta + d_rho / max(r0, 1e-9) + d_tip / l_min
                        + gap / max(r0, 1e-9)) - 1e-9
    k = np.unravel_index(np.argmax(over_L), over_L.shape)
    assert over_L.max() <= 0, (f"L jumps by {d_L[k]:.4g} m at t = {h['time'][k[0]]:.4g} s "
                               f"(arm {k[1]}), the motion allows {d_L[k] - over_L[k]:.4g} m")
    k = np.unravel_index(np.argmax(over_phi), over_phi.shape)
    assert over_phi.max() <= 0, (f"phi jumps by {d_phi[k]:.4g} rad at t = "
                                 f"{h['time'][k[0]]:.4g} s (arm {k[1]}), the motion allows "
                                 f"{d_phi[k] - over_phi[k]:.4g} rad")
