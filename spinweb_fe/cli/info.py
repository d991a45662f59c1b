"""``spinweb info RESULT.h5``: summary of a result file."""

from pathlib import Path


def add_parser(sub):
    p = sub.add_parser("info", help="summary of a result file", description=__doc__)
    p.add_argument("result", help="results.h5 or analytic.h5")
    return p


def summary(path) -> str:
    """Multi-line text summary of a result file."""
    import numpy as np

    from spinweb_fe.io.h5 import open_h5
    from spinweb_fe.record.energy import energy_balance

    path = Path(path)
    with open_h5(path) as h5:
        a = h5.attrs
        lines = [f"file: {path}"]
        for k in ("format_version", "spinweb_version", "model", "status", "dt", "steps",
                  "wall_time_s"):
            if k in a:
                lines.append(f"{k}: {a[k]}")
        if "mesh" in h5:
            m = h5["mesh"]
            lines.append(f"mesh: {m['points'].shape[0]} nodes, {m['elements'].shape[0]} elements, "
                         f"mass {m['node_mass'][()].sum():.4g} kg (without hub)")
        if "history" in h5:
            h = {k: h5["history"][k][()] for k in h5["history"]}
            t = h["time"]
            lines.append(f"history: {len(t)} rows, t = {t[0]:g} .. {t[-1]:g} s")
            if len(t):
                lines.append(f"hub_omega: {h['hub_omega'][0]:.6g} -> {h['hub_omega'][-1]:.6g} rad/s")
                if "arm_length" in h:
                    lines.append(f"arm_length (final, per arm): "
                                 f"{np.array2string(h['arm_length'][-1], precision=4)} m")
                if "angular_momentum" in h:
                    K = h["angular_momentum"]
                    lines.append(f"angular_momentum: {K[0]:.6g} -> {K[-1]:.6g} N m s")
                if "contact_dissipation" in h:
                    e = energy_balance(h)
                    scale = max(abs(h["kinetic_energy"][0]) + abs(h["strain_energy"][0]), 1e-30)
                    lines.append(f"energy balance drift: {np.max(np.abs(e - e[0])) / scale:.3e} "
                                 "(relative to the initial energy)")
                lines.append(f"max_tension: {np.max(h['max_tension']):.6g} N")
        if "frames" in h5:
            lines.append(f"frames: {h5['frames']['time'].shape[0]}")
    return "\n".join(lines)


def run(args) -> int:
    print(summary(args.result))
    return 0
