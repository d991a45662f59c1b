"""Figures and numbers of docs/modes.md: the paper's 100 m QuadQuad web spinning at pi/2,
2 pi and 8 pi rad/s with 0, 10 and 50 kg corners, its lowest mode shapes, design sweeps, and
the convergence of the spinning string.

Run from the project root: ``.venv/bin/python -m studies.make_modes_figs`` (about 30 s on one
core). Writes docs/img/modes_shapes.png, modes_sweep_omega.png, modes_sweep_tip_mass.png and
modes_string.png and prints the tables quoted in docs/modes.md.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from spinweb_fe import case as case_mod  # noqa: E402
from spinweb_fe.linear.modes import compute_modes  # noqa: E402
from spinweb_fe.linear.steady import Structure, solve_steady  # noqa: E402
from spinweb_fe.run.modal import analyse, sweep  # noqa: E402
from spinweb_fe.post.modes_plot import plot_sweep  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
CASE = ROOT / "cases" / "paper_free_web.toml"
OMEGAS = (("pi/2", math.pi / 2), ("2 pi", 2 * math.pi), ("8 pi", 8 * math.pi))
CORNERS = (0.0, 10.0, 50.0)
COUNT = 14  # enough to hold the three lowest of each kind


def paper_case(corner=10.0, *sets):
    return case_mod.load(CASE, [f"tip_mass.mass={corner!r}", *sets])


def lowest(md, kind, n=3):
    sel = np.flatnonzero(md.kind == kind)[:n]
    return md.frequency[sel], md.ratio[sel], md.material_share[sel]


def study_table():
    """The frequency table: (omega, corner mass) -> steady state and the lowest modes."""
    print("| omega [rad/s] | corners [kg] | max strain | max tension [kN] | Newton it. | "
          "in-plane omega_k / omega (material share) | out-of-plane omega_k / omega | "
          "lowest in / out [Hz] |")
    print("|---|---|---|---|---|---|---|---|")
    results = {}
    for label, w in OMEGAS:
        for mc in CORNERS:
            res = analyse(paper_case(mc), w, COUNT, "driven")
            results[label, mc] = res
            md, st = res.modes, res.steady
            f_in, r_in, s_in = lowest(md, "in_plane")
            f_out, r_out, _ = lowest(md, "out_of_plane")
            ins = ", ".join(f"{r:.4f} ({s:.2f})" for r, s in zip(r_in, s_in))
            outs = ", ".join(f"{r:.4f}" for r in r_out)
            print(f"| {label} | {mc:g} | {100 * st.max_strain:.3g} % | "
                  f"{st.tension.max() / 1e3:.4g} | {st.iterations} | {ins} "
                  f"| {outs} | {f_in[0] / (2 * math.pi):.4g} / {f_out[0] / (2 * math.pi):.4g} |")
    return results


def draw_mesh(ax, pos, elems, values, cmap, lw=0.8):
    """The elements as lines coloured by ``values`` (E,) in [-1, 1]."""
    lc = LineCollection(pos[elems][:, :, :2], cmap=cmap, linewidths=lw)
    lc.set_array(values)
    lc.set_clim(-1.0, 1.0)
    ax.add_collection(lc)
    return lc


def save_small(fig, path, dpi=80, colors=128):
    """Save a figure as a palette PNG (``colors`` colours): a third of the RGB size."""
    from io import BytesIO

    from PIL import Image

    buf = BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    buf.seek(0)
    Image.open(buf).convert("RGB").quantize(colors).save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} kB)")


def shapes_figure(res, title, path, per_kind=3, arrows=5.0):
    """The lowest in-plane shapes (arrows of u at the nodes of an ``arrows`` m grid over the
    steady web) and out-of-plane shapes (elements coloured by w)."""
    md, st, s = res.modes, res.steady, res.structure
    fig, axes = plt.subplots(2, per_kind, figsize=(3.6 * per_kind + 1.0, 7.4),
                             layout="constrained")
    lim = np.abs(st.position[:, :2]).max() * 1.06
    ref = s.node_ref[:, :2]
    grid = np.all(np.abs(ref / arrows - np.round(ref / arrows)) < 1e-6, axis=1)
    seg = st.position[s.elem_nodes][:, :, :2]
    for row, kind in enumerate(("in_plane", "out_of_plane")):
        idx = np.flatnonzero(md.kind == kind)[:per_kind]
        for ax, k in zip(axes[row], idx):
            shape = md.shape[k]
            if kind == "in_plane":
                ax.add_collection(LineCollection(seg, colors="0.8", linewidths=0.4))
                p, u = st.position[grid], shape[grid]
                q = ax.quiver(p[:, 0], p[:, 1], u[:, 0], u[:, 1], np.hypot(u[:, 0], u[:, 1]),
                              cmap="viridis", clim=(0, 1), angles="xy", scale_units="xy",
                              scale=1.0 / (0.9 * arrows), width=0.005)
            else:
                w = shape[:, 2][s.elem_nodes].mean(axis=1)
                q = draw_mesh(ax, st.position, s.elem_nodes, values=w, cmap="RdBu_r")
            ax.set_title(f"mode {k + 1}, {kind.replace('_', '-')}: "
                         f"{md.frequency[k]:.3g} rad/s = {md.ratio[k]:.3f} omega", fontsize=9)
            ax.set_xlim(-lim, lim)
            ax.set_ylim(-lim, lim)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
        label = "in-plane |u| (arrows)" if kind == "in_plane" else "out-of-plane w"
        fig.colorbar(q, ax=axes[row].tolist(), shrink=0.85, label=label + ", max |u| = 1")
    fig.suptitle(title, fontsize=10)
    save_small(fig, path)


def string_structure(m, length=50.0, area=1.025e-5, rho=1540.0, E=180e12):
    x = np.linspace(0.0, length, m + 1)
    pos = np.column_stack([x, np.zeros(m + 1), np.zeros(m + 1)])
    elems = np.column_stack([np.arange(m), np.arange(1, m + 1)])
    mass = np.zeros(m + 1)
    np.add.at(mass, elems.ravel(), 0.5 * rho * area * length / m)
    return Structure(pos, mass, elems, np.full(m, length / m), np.full(m, E * area),
                     np.array([0]), 1.0)


def string_figure(path):
    """Relative error of the spinning string's modes against Legendre's, vs element count."""
    ms = np.array([10, 20, 40, 80, 160])
    l_odd = np.array([3, 5])
    ref = {"out_of_plane": np.sqrt(l_odd * (l_odd + 1) / 2),
           "in_plane": np.sqrt(l_odd * (l_odd + 1) / 2 - 1)}
    err = {k: [] for k in ref}
    for m in ms:
        s = string_structure(int(m))
        md = compute_modes(s, solve_steady(s, 2.0), 8)
        for kind in ref:
            got = md.ratio[md.kind == kind][1:3]  # l = 1 (a rigid motion) left out
            err[kind].append(np.abs(got - ref[kind]) / ref[kind])
    fig, ax = plt.subplots(figsize=(5.5, 4))
    print("string: relative errors and observed orders (fit over m = 20..160)")
    for kind, marker in (("out_of_plane", "o"), ("in_plane", "^")):
        e = np.array(err[kind])
        for j, l in enumerate(l_odd):
            order = -np.polyfit(np.log(ms[1:]), np.log(e[1:, j]), 1)[0]
            errs = ", ".join(f"{v:.2e}" for v in e[:, j])
            print(f"  {kind} l = {l}: {errs}, order {order:.3f}")
            ax.loglog(ms, e[:, j], marker + "-", label=f"{kind.replace('_', '-')}, l = {l} "
                      f"(order {order:.2f})")
    ax.loglog(ms, err["in_plane"][0][1] * (ms / ms[0]) ** -2.0, "k:", lw=0.8, label="slope -2")
    ax.set_xlabel("elements")
    ax.set_ylabel("relative frequency error")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title("spinning string rooted on the axis vs Legendre modes", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} kB)")


def stiff_comparison():
    """The same web with the 1000x stiffer cable: which ratios move with Zylon's stretch."""
    print("| cable | omega | lowest in-plane omega_k / omega | lowest out-of-plane |")
    print("|---|---|---|---|")
    for name, E in (("Zylon", 180e9), ("1000x", 180e12)):
        for label, w in OMEGAS:
            res = analyse(paper_case(10.0, f"cable.youngs_modulus={E!r}"), w, COUNT)
            _, r_in, _ = lowest(res.modes, "in_plane")
            _, r_out, _ = lowest(res.modes, "out_of_plane")
            print(f"| {name} | {label} | {', '.join(f'{r:.4f}' for r in r_in)} | "
                  f"{', '.join(f'{r:.4f}' for r in r_out)} |")


def main():
    IMG.mkdir(parents=True, exist_ok=True)
    results = study_table()
    for hub in ("driven", "coasting"):
        md = analyse(paper_case(10.0), 8 * math.pi, 8, hub).modes
        print(f"8 pi, 10 kg, hub {hub}: " + ", ".join(
            f"{f:.4g} {k[0]}" for f, k in zip(md.frequency, md.kind)) + " rad/s")
    stiff_comparison()
    shapes_figure(results["8 pi", 10.0], "paper web (S = 100 m, t = 2.5 m, Zylon), 10 kg "
                  "corners, 8 pi rad/s, hub driven: lowest modes", IMG / "modes_shapes.png")
    case = paper_case(10.0)
    pts = sweep(case, "omega", np.linspace(math.pi / 2, 8 * math.pi, 9), 8 * math.pi, 8)
    plot_sweep(IMG / "modes_sweep_omega.png", "omega", "rad/s", pts,
               "paper web, 10 kg corners: the lowest 8 modes against the spin rate")
    pts = sweep(case, "tip_mass", np.linspace(0.0, 50.0, 11), 8 * math.pi, 8)
    plot_sweep(IMG / "modes_sweep_tip_mass.png", "tip_mass", "kg", pts,
               "paper web at 8 pi rad/s: the lowest 8 modes against the corner mass")
    for name in ("modes_sweep_omega.png", "modes_sweep_tip_mass.png"):
        print(f"wrote {IMG / name} ({(IMG / name).stat().st_size / 1024:.0f} kB)")
    string_figure(IMG / "modes_string.png")


if __name__ == "__main__":
    main()
