"""Files and tables of ``spinweb modes``: ``modes.h5``, the ParaView mode shapes, the
printed tables and ``sweep.csv`` (layout in docs/interface.md and docs/modes.md)."""

from __future__ import annotations

import csv
from pathlib import Path

import h5py
import numpy as np

from meshgen.mesh import Mesh
from spinweb_fe.io.h5 import write_dataset, write_root_attrs
from spinweb_fe.io.mesh import write_mesh_group
from spinweb_fe.io.vtk import write_pvd, write_vtu
from spinweb_fe.linear.modes import Modes
from spinweb_fe.linear.steady import SteadyState, Structure, describe_elements

SWEEP_COLUMNS = (  # (column of sweep.csv, units)
    ("omega", "rad/s"), ("tip_mass", "kg"), ("mode", "1"), ("kind", "-"),
    ("frequency", "rad/s"), ("frequency_hz", "Hz"), ("ratio", "1"), ("growth", "1/s"),
    ("material_share", "1"), ("max_strain", "1"))


def write_modes_h5(path, case, mesh: Mesh, s: Structure, st: SteadyState, md: Modes) -> Path:
    """Write ``modes.h5``: root attributes (with ``omega`` [rad/s] and ``hub``), the modes,
    ``/steady`` and the flat ``/mesh``; every dataset has a ``units`` attribute.

    Parameters
    ----------
    path : str or Path
    case : spinweb_fe.case.Case
    mesh : Mesh
        The flat mesh of the analysis.
    s : Structure
    st : SteadyState
    md : Modes
    """
    path = Path(path)
    with h5py.File(path, "w") as h5:
        write_root_attrs(h5, case, omega=md.omega, hub=md.hub, count=len(md.frequency),
                         steady_residual=st.residual, steady_iterations=st.iterations)
        write_dataset(h5, "frequency", md.frequency, "rad/s", "angular frequency of each mode "
                      "in the rotating frame, lowest first")
        write_dataset(h5, "frequency_hz", md.frequency_hz, "Hz", "frequency / 2 pi")
        write_dataset(h5, "ratio", md.ratio, "1", "frequency / |omega|")
        write_dataset(h5, "growth", md.growth, "1/s", "real part of the eigenvalue (0: stable)")
        write_dataset(h5, "kind", np.array(md.kind, dtype=h5py.string_dtype()), "-",
                      "in_plane or out_of_plane")
        write_dataset(h5, "material_share", md.material_share, "1", "part of the modal "
                      "stiffness from cable stretch EA (the rest is tension, ~ omega^2)")
        write_dataset(h5, "shape", md.shape, "m", "real mode shapes, max |u| = 1 m per mode")
        g = h5.create_group("steady")
        g.attrs["residual"] = st.residual
        g.attrs["iterations"] = st.iterations
        g.attrs["load_steps"] = st.load_steps
        write_dataset(g, "position", st.position, "m", "steady positions, rotating frame")
        write_dataset(g, "tension", st.tension, "N", "steady element tensions")
        write_dataset(g, "strain", st.strain, "1", "l / L0 - 1 (negative: slack)")
        write_dataset(g, "slack", st.slack, "1", "slack element indices")
        write_mesh_group(h5.create_group("mesh"), mesh, s.node_mass)
    return path


def write_mode_vtus(folder, s: Structure, st: SteadyState, md: Modes) -> list:
    """``folder/modes/mode_NNN.vtu`` (NNN from 001, lowest first) on the steady state with
    point data ``shape`` [m] and cell data ``tension`` [N], ``strain`` [-]; and
    ``folder/modes.pvd`` listing them (timestep = mode number). Older mode files go."""
    folder = Path(folder)
    sub = folder / "modes"
    sub.mkdir(parents=True, exist_ok=True)
    for old in sub.glob("mode_*.vtu"):
        old.unlink()
    paths, entries = [], []
    for k in range(len(md.frequency)):
        name = f"mode_{k + 1:03d}.vtu"
        write_vtu(sub / name, st.position, s.elem_nodes, {"shape": md.shape[k]},
                  {"tension": st.tension, "strain": st.strain})
        paths.append(sub / name)
        entries.append((k + 1, f"modes/{name}"))
    write_pvd(folder / "modes.pvd", entries)
    return paths


def format_steady(s: Structure, st: SteadyState, hub: str) -> str:
    """One paragraph on the steady state."""
    slack = ("none" if len(st.slack) == 0 else
             f"{len(st.slack)}: {describe_elements(s, st.slack, 5)}")
    return (f"steady state at omega = {st.omega:.6g} rad/s (hub {hub}): relative residual "
            f"{st.residual:.2e} (largest node force {st.residual_force:.3g} N) after "
            f"{st.iterations} Newton iterations in {st.load_steps} load step(s)\n"
            f"max strain {100 * st.max_strain:.4g} %, max tension {st.tension.max():.6g} N, "
            f"slack elements {slack}")


def format_modes(md: Modes) -> str:
    """The table of modes."""
    lines = [f"{'mode':>4}  {'kind':<12}  {'omega_k [rad/s]':>15}  {'f [Hz]':>10}  "
             f"{'omega_k/omega':>13}  {'material':>8}  {'growth [1/s]':>12}"]
    for k in range(len(md.frequency)):
        lines.append(f"{k + 1:>4}  {md.kind[k]:<12}  {md.frequency[k]:>15.6g}  "
                     f"{md.frequency_hz[k]:>10.5g}  {md.ratio[k]:>13.5g}  "
                     f"{md.material_share[k]:>8.3f}  {md.growth[k]:>12.3g}")
    return "\n".join(lines)


def sweep_rows(name: str, points) -> list:
    """The rows of sweep.csv: one per (value, mode), as dicts of :data:`SWEEP_COLUMNS`."""
    rows = []
    for p in points:
        if p.modes is None:
            rows.append({"omega": p.omega, "tip_mass": p.tip_mass, "mode": 0,
                         "kind": "no_steady_state"})
            continue
        md = p.modes
        for k in range(len(md.frequency)):
            rows.append({"omega": p.omega, "tip_mass": p.tip_mass, "mode": k + 1,
                         "kind": md.kind[k], "frequency": md.frequency[k],
                         "frequency_hz": md.frequency_hz[k], "ratio": md.ratio[k],
                         "growth": md.growth[k], "material_share": md.material_share[k],
                         "max_strain": p.steady.max_strain})
    return rows


def write_sweep_csv(path, name: str, points) -> Path:
    """``sweep.csv``: a header of ``column [units]`` and one row per (value, mode)."""
    path = Path(path)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"{c} [{u}]" for c, u in SWEEP_COLUMNS])
        for r in sweep_rows(name, points):
            w.writerow([_cell(r.get(c, "")) for c, _ in SWEEP_COLUMNS])
    return path


def _cell(v):
    return f"{v:.9g}" if isinstance(v, (float, np.floating)) else v


def format_sweep(name: str, unit: str, points) -> str:
    """The sweep as a table: one line per value, the frequencies [rad/s] lowest first, each
    marked i (in-plane) or o (out-of-plane)."""
    count = max((len(p.modes.frequency) for p in points if p.modes is not None), default=0)
    head = f"{name + ' [' + unit + ']':>16}  {'max strain':>10}  " + "  ".join(
        f"{'mode ' + str(k + 1):>10}" for k in range(count))
    lines = [head]
    for p in points:
        if p.modes is None:
            lines.append(f"{p.value:>16.6g}  no steady state: {p.error}")
            continue
        md = p.modes
        cells = "  ".join(f"{f:>9.4g}{'i' if kind == 'in_plane' else 'o'}"
                          for f, kind in zip(md.frequency, md.kind))
        lines.append(f"{p.value:>16.6g}  {100 * p.steady.max_strain:>9.3g}%  {cells}")
    lines.append("frequencies in rad/s; i: in-plane, o: out-of-plane")
    return "\n".join(lines)
