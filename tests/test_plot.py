"""spinweb plot: every arm as the spread across the arms, the verdict panels, the sweep
summary's panels, colours and tick labels, checked on the pixels of the figures (the data
placed through each panel's own transform)."""

import math
from pathlib import Path

import h5py
import numpy as np
import pytest
from PIL import Image

from spinweb_fe.cli import main
from spinweb_fe.post.axes import untangle_ticks
from spinweb_fe.post.judged import Judged
from spinweb_fe.post.plot import history_figure
from spinweb_fe.post.verdict_plot import draw, panel_names
from spinweb_fe.record import verdict

ROOT = Path(__file__).resolve().parent.parent
C0 = (0.122, 0.467, 0.706)  # matplotlib's first colour


def rgb(fig):
    """The figure's pixels (H, W, 3) in [0, 1]."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0


def at(fig, ax, x, y):
    """(row, column) of the data point (x, y) of ``ax``."""
    px, py = ax.transData.transform((x, y))
    return int(round(fig.bbox.height - py)), int(round(px))


def near(img, row, col, r=1):
    return img[row - r:row + r + 1, col - r:col + r + 1].reshape(-1, 3)


def bluish(p):
    return p[..., 2] - p[..., 0]


def redness(p):
    return p[..., 0] - np.maximum(p[..., 1], p[..., 2])


def greenness(p):
    return p[..., 1] - np.maximum(p[..., 0], p[..., 2])


def arms_history():
    """Four arms, L_k = 10 (k + 1) t [m] over 1 s; phi, the rates constant."""
    t = np.linspace(0.0, 1.0, 201)
    L = 10.0 * t[:, None] * np.arange(1, 5)[None, :]
    one = np.ones((len(t), 4))
    return {"time": t, "arm_length": L, "arm_angle": 0.0 * one, "hub_omega": np.ones_like(t),
            "tip_omega": one}


def test_every_arm_is_drawn_as_its_spread():
    """At t = 0.8 s the arms span L = 8 .. 32 m: the band covers 14 m and not 36 m, the mean
    line lies at 20 m; with --arm 2 the one line lies at 24 m and no band is drawn."""
    fig = history_figure([(arms_history(), "four arms", None)])
    img, ax = rgb(fig), fig.axes[0]
    assert bluish(near(img, *at(fig, ax, 0.8, 14.0))).min() > 0.05  # inside the band
    assert abs(bluish(near(img, *at(fig, ax, 0.8, 36.0)))).max() < 0.03  # above it
    assert (np.abs(near(img, *at(fig, ax, 0.8, 20.0)) - C0).sum(axis=1) < 0.15).any()
    assert "mean of 4 arms" in ax.get_legend().get_texts()[0].get_text()
    one = history_figure([(arms_history(), "arm 2", None)], arm=2)
    img, ax = rgb(one), one.axes[0]
    assert (np.abs(near(img, *at(one, ax, 0.8, 24.0)) - C0).sum(axis=1) < 0.15).any()
    assert abs(bluish(near(img, *at(one, ax, 0.8, 14.0)))).max() < 0.03  # no band


def judged_run():
    """A closed-form run, reach 10 m on a 1 m hub: arms 0-2 reach 1.0 of their reach by
    0.5 s and stay; arm 3 reaches it, then falls back to 0.3 by 1 s (re-coil: fails, first
    when it is half its arm length back; not deployed at the end); the utilisation passes 1
    at t = 0.7 s; energy and momentum constant."""
    t = np.linspace(0.0, 1.0, 1001)
    ratio = np.minimum(0.1 + 1.8 * t, 1.0)[:, None].repeat(4, axis=1)
    ratio[:, 3] = np.where(t <= 0.5, ratio[:, 3], 1.0 - 1.4 * (t - 0.5))
    pos = np.zeros((len(t), 4, 3))
    ang = np.arange(4) * 0.5 * math.pi
    pos[..., 0], pos[..., 1] = 10.0 * ratio * np.cos(ang), 10.0 * ratio * np.sin(ang)
    zero, one = np.zeros_like(t), np.ones_like(t)
    h = {"time": t, "tip_position": pos, "arm_angle": np.zeros((len(t), 4)),
         "arm_length": 9.0 * ratio, "hub_torque": zero, "hub_omega": one, "hub_angle": t,
         "angular_momentum": 50.0 * one, "kinetic_energy": 100.0 * one, "strain_energy": zero,
         "torque_work": zero, "utilisation": 1.2 * np.sin(math.pi * t) ** 8,
         "max_strain_arm": zero}
    reach = np.full(4, 10.0)
    crits = verdict.judge(h, reach, 1.0, slack_share=0.5, failure_strain=0.03)
    floors = {"energy_floor": 0.0, "momentum_floor": 0.0}
    return Judged(h, crits, reach, 1.0, {"title": "synthetic"}, None, floors)


def test_the_verdict_panels_show_limits_and_first_failures():
    j = judged_run()
    by = {c.name: c for c in j.criteria}
    assert by["recoil"].passed is False and by["deployed"].passed is False
    assert by["overstrain"].passed is False and by["energy"].passed
    # the first times, closed form: u = 1.2 sin^8(pi t) passes 1 at asin(1.2^(-1/8)) / pi;
    # arm 3 is half its 9 m back at 0.5 + 4.5 / 14 s (rows every 1 ms)
    assert by["overstrain"].time == pytest.approx(math.asin(1.2 ** -0.125) / math.pi, abs=1e-3)
    assert by["recoil"].time == pytest.approx(0.5 + 4.5 / 14.0, abs=1e-3)
    names = panel_names(j)
    assert names == ["reach", "fallback", "utilisation", "audits"]  # no slack frames, no swing
    fig = draw([j], names, ["synthetic"])
    img = rgb(fig)
    dep, rec, over, aud = fig.axes[:4]
    # the deployed line at 0.8 of the reach: dashed dark across the panel
    row, _ = at(fig, dep, 0.5, 0.8)
    x0, x1 = (int(v) for v in dep.bbox.intervalx)
    line = img[row - 1:row + 2, x0 + 5:x1 - 5].min(axis=0)
    assert np.mean(line.max(axis=1) < 0.4) > 0.3
    # the re-coil limit line at 0.5 and its first failure, a red vertical line
    _, col = at(fig, rec, by["recoil"].time, 0.25)
    y0, y1 = (int(fig.bbox.height - v) for v in rec.bbox.intervaly[::-1])
    assert np.mean(redness(img[y0 + 5:y1 - 5, col - 1:col + 2]).max(axis=1) > 0.3) > 0.25
    # the strength panel: the first time the utilisation passes 1, red, none elsewhere
    _, col = at(fig, over, by["overstrain"].time, 0.0)
    y0, y1 = (int(fig.bbox.height - v) for v in over.bbox.intervaly[::-1])
    assert np.mean(redness(img[y0 + 5:y1 - 5, col - 1:col + 2]).max(axis=1) > 0.3) > 0.25
    _, away = at(fig, over, by["overstrain"].time - 0.2, 0.0)
    assert np.mean(redness(img[y0 + 5:y1 - 5, away]) > 0.3) < 0.05
    # titles: failing criteria red, the audits green, the figure's red; every panel drawn
    for ax, colour in ((dep, redness), (rec, redness), (over, redness), (aud, greenness)):
        b = ax.title.get_window_extent()
        title = img[int(fig.bbox.height - b.y1):int(fig.bbox.height - b.y0),
                    int(b.x0):int(b.x1)]
        assert (colour(title.reshape(-1, 3)) > 0.3).mean() > 0.01, ax.get_title()
        inside = img[int(fig.bbox.height - ax.bbox.y1) + 3:int(fig.bbox.height - ax.bbox.y0) - 3,
                     int(ax.bbox.x0) + 3:int(ax.bbox.x1) - 3].reshape(-1, 3)
        assert (bluish(inside) > 0.2).mean() > 0.002  # the run's curves
    assert "FAIL" in rec.get_title() and f"first at t = {by['recoil'].time:.3g} s" in \
        rec.get_title()
    assert fig._suptitle.get_text().startswith("synthetic\nverdict: FAILS")


def test_plot_verdict_of_a_run(tmp_path):
    """spinweb plot --panels verdict of a short demo run: the slack panel's last frame is
    the verdict's slack share, the title is the case's, the figure has the verdict's
    colours; the arms plot's title is the case's too."""
    out = tmp_path / "demo"
    assert main(["run", str(ROOT / "cases" / "demo.toml"), "-o", str(out), "--set",
                 "time.end=0.2", "--set", "output.frame_dt=0.05", "--no-progress"]) == 0
    from spinweb_fe.post.verdict_plot import load_judged

    j = load_judged(out / "results.h5")
    assert j.slack is not None and len(j.slack[0]) == 5
    assert j.slack[1][-1] == pytest.approx(j.criterion("slack").value, abs=1e-12)
    assert "slack_share" in panel_names(j) and "utilisation" in panel_names(j)
    png = tmp_path / "v.png"
    assert main(["plot", str(out / "results.h5"), "-o", str(png), "--panels", "verdict"]) == 0
    img = np.asarray(Image.open(png).convert("RGB"), dtype=float) / 255.0
    assert (redness(img.reshape(-1, 3)) > 0.3).mean() > 1e-4  # not deployed at 0.2 s
    assert (greenness(img.reshape(-1, 3)) > 0.3).mean() > 1e-4  # energy, momentum pass
    from spinweb_fe.post.plot import cases_title

    with h5py.File(out / "results.h5") as h5:
        assert "title = \"demo:" in h5.attrs["case"]
    assert cases_title([out / "results.h5"]).startswith("demo: ")


def test_tick_labels_do_not_overlap():
    """Eight swept values close together on a narrow panel overlap as drawn; after
    untangle_ticks the labels left do not, level or slanted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for rotation in (0.0, 30.0):
        fig, ax = plt.subplots(figsize=(3, 2))
        xs = [1.0e5 + 5e3 * k for k in range(8)]
        ax.plot(xs, xs, "o")
        ax.set_xticks(xs, [f"{v:.4g}" for v in xs])
        k = untangle_ticks(fig, ax, rotation)
        assert k > 1  # they did overlap
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        shown = [lb for lb in ax.get_xticklabels() if lb.get_text()]
        assert len(shown) >= 2
        if rotation:
            x = [ax.transData.transform((lb.get_position()[0], 0))[0] for lb in shown]
            gap = min(np.diff(x)) * math.sin(math.radians(rotation))
            assert gap >= 1.2 * shown[0].get_fontsize() * fig.dpi / 72 * 0.99
        else:
            boxes = [lb.get_window_extent(r) for lb in shown]
            assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:]))
        plt.close(fig)


def test_the_sweep_summary_has_no_empty_panel_and_colours_the_verdicts(tmp_path):
    """A grid sweep whose runs never deploy (deploy_time NaN): its panel goes to the
    verdict's severity; passing runs green, failing red."""
    from spinweb_fe.sweep.report import _panels, plot_summary
    from spinweb_fe.sweep.run import PLOTTED, load_sweep

    src = tmp_path / "s.toml"
    src.write_text(f'title = "t"\nbase = "{ROOT / "cases" / "paper_free_arms.toml"}"\n'
                   'mode = "fe"\n[grid]\n"hub.radius" = [1.0, 1.5, 2.0, 2.5]\n')
    sweep = load_sweep(src)
    rows = [{"status": "ok", "deploy_time_s": math.nan, "peak_hub_torque_Nm": 0.0,
             "final_hub_omega_rad_s": 20.0 - i, "max_tension_N": 3e4 + 1e3 * i,
             "recoiled": float(i == 3), "passed": float(i < 2), "severity": 0.6 + 0.3 * i}
            for i in range(4)]
    assert "deploy_time_s" in PLOTTED and len(PLOTTED) == 4
    assert _panels(rows) == [m for m in PLOTTED if m != "deploy_time_s"] + ["severity"]
    png = tmp_path / "summary.png"
    plot_summary(sweep, rows, png)
    img = np.asarray(Image.open(png).convert("RGB"), dtype=float).reshape(-1, 3) / 255.0
    assert (greenness(img) > 0.3).mean() > 2e-4 and (redness(img) > 0.3).mean() > 2e-4
    dead = [dict(r, status="failed: x", peak_hub_torque_Nm=math.nan, max_tension_N=math.nan,
                 final_hub_omega_rad_s=math.nan, severity=math.nan) for r in rows]
    assert _panels(dead) == ["severity"]
