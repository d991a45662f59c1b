"""``spinweb analytic CASE``: the paper's rigid-arm model (Eqs. 4-8) -> DIR/analytic.h5."""

from __future__ import annotations

import argparse

from spinweb_fe.cli.common import add_case_args, load_case, out_dir
from spinweb_fe.errors import InputError

MODEL_CHOICES = ("printed", "consistent")


def add_parser(sub):
    p = sub.add_parser("analytic", help="run the analytical deployment model",
                       description=__doc__ + " See docs/analytic.md.",
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    add_case_args(p, out=True)
    p.add_argument("--model", choices=MODEL_CHOICES, default="consistent",
                   help="printed: paper's equations as printed; consistent: conserves K and E")
    p.add_argument("--rtol", type=float, default=1e-10, help="solve_ivp relative tolerance")
    p.add_argument("--atol", type=float, default=1e-10,
                   help="solve_ivp absolute tolerance on angles [rad] and rates [rad/s]")
    p.add_argument("--start-length", type=float, default=None, metavar="L0",
                   help="start-up free length of a coiled arm [m] (default 1e-4 H)")
    p.add_argument("--massless-tethers", action="store_true",
                   help="tether scenes: ignore the tether mass (pure Eqs. 5-6 point mass)")
    return p


def run(args) -> int:
    import numpy as np

    from spinweb_fe.analytic import solve as analytic

    case = load_case(args)
    model = getattr(args, "model", "consistent")
    rtol, atol = getattr(args, "rtol", 1e-10), getattr(args, "atol", 1e-10)
    L0 = getattr(args, "start_length", None)
    if model not in MODEL_CHOICES:
        raise InputError("--model", "", f"unknown model '{model}' (valid: printed, consistent)")
    if not (0 < rtol < 1 and atol > 0):
        raise InputError("--rtol/--atol", "", "tolerances must be positive (rtol < 1)")
    try:
        result = analytic.solve_case(case, model=model, rtol=rtol, atol=atol, L0=L0,
                                   tether_mass=not getattr(args, "massless_tethers", False))
    except ValueError as exc:
        raise InputError(args.case, "", str(exc)) from None
    folder = out_dir(args, case)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "analytic.h5"
    analytic.write(path, case, result, rtol=rtol, atol=atol)
    h = result.history
    dk, de = analytic.drifts(result)
    e_text = (f"device work {h['brake_work'][-1].sum():.4g} J (its energy balance)"
              if "brake_work" in h else f"max|E drift|={np.max(np.abs(de)):.3e}")
    print(f"{path}: model={model} t={h['time'][-1]:.6g} s  L={h['arm_length'][-1, 0]:.6g} m  "
          f"omega={h['hub_omega'][-1]:.6g} rad/s  max|K drift|={np.max(np.abs(dk)):.3e}  "
          + e_text
          + (f"  STOPPED: {result.stopped}" if result.stopped else ""))
    if result.stopped:
        from spinweb_fe.errors import RunError
        raise RunError(result.stopped, time=float(h["time"][-1]))
    return 0
