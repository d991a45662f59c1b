"""``spinweb info RESULT.h5``: summary of a result file."""

from pathlib import Path


def add_parser(sub):
    p = sub.add_parser("info", help="summary of a result file", description=__doc__)
    p.add_argument("result", nargs="?", help="results.h5 or analytic.h5")
    p.add_argument("--criteria", action="store_true",
                   help="list the verdict criteria and the run metrics (their registries: "
                        "what each measures, its unit, limit key and default)")
    p.add_argument("--verdict", action="store_true",
                   help="only the verdict: the overall line, then one line per criterion")
    return p


def summary(path) -> str:
    """Multi-line text summary of a result file (also of one that a run is writing)."""
    from spinweb_fe.io.h5 import read_result

    return read_result(path, lambda h5: "\n".join(_lines(Path(path), h5)))


def _lines(path, h5) -> list:
    import numpy as np

    from spinweb_fe.io.h5 import history_of
    from spinweb_fe.post.strength import summary_lines
    from spinweb_fe.record.energy import balance_error

    a = h5.attrs
    lines = [f"file: {path}"]
    for k in ("format_version", "spinweb_version", "model", "status", "dt", "steps",
              "wall_time_s"):
        if k in a:
            lines.append(f"{k}: {a[k]}")
    h = history_of(h5)
    if a.get("status") == "running":
        lines.append(_live(path, h))
    if "mesh" in h5:
        m = h5["mesh"]
        lines.append(f"mesh: {m['points'].shape[0]} nodes, {m['elements'].shape[0]} elements, "
                     f"mass {m['node_mass'][()].sum():.4g} kg (without hub)")
    if "history" in h5 and not h:
        lines.append("history: 0 rows (the run stopped before its first rows were written)")
    if h:
        t = h["time"]
        lines.append(f"history: {len(t)} rows, t = {t[0]:g} .. {t[-1]:g} s")
        lines.append(f"hub_omega: {h['hub_omega'][0]:.6g} -> {h['hub_omega'][-1]:.6g} rad/s")
        if "arm_length" in h:
            lines.append(f"arm_length (final, per arm): "
                         f"{np.array2string(h['arm_length'][-1], precision=4)} m")
        if "angular_momentum" in h:
            K = h["angular_momentum"]
            lines.append(f"angular_momentum: {K[0]:.6g} -> {K[-1]:.6g} N m s")
        if "contact_dissipation" in h:
            lines.append(f"energy balance drift: "
                         f"{balance_error(h, floor=float(a.get('energy_floor', 0.0))):.3e} "
                         "(relative to the energy scale of the run's audit: max(initial "
                         "energy, torque work, round-off floor))")
        lines.append(f"max_tension: {np.max(h['max_tension']):.6g} N")
    if "frames" in h5:
        lines.append(f"frames: {h5['frames']['time'].shape[0]}")
    lines += audit_lines(h5)
    lines += summary_lines(h5)
    if h and a.get("status") != "running":
        lines += verdict_lines(h5, h)
    return lines


def audit_lines(h5) -> list:
    """The crossing audit (/crossings) and the linking check (/linking), when the file has
    them."""
    lines = []
    if "crossings" in h5:
        g = h5["crossings"]
        t = g["time"][()]
        first = f", the first at t = {t.min():.6g} s" if len(t) else ""
        lines.append(f"crossings: {int(g.attrs['count'])}{first} (broad phase built "
                     f"{int(g.attrs['rebuilds'])} times)")
        if "contact_impulses" in g.attrs:
            lines.append(f"contact: radius {float(g.attrs['contact_radius']):.6g} m, deepest "
                         f"penetration {float(g.attrs['deepest_penetration']):.6g} m, "
                         f"{int(g.attrs['contact_impulses'])} fail-safe impulses "
                         f"({int(g.attrs['impulses_after_reactions'])} after the hub's "
                         "reactions)")
        if "profile" in g:
            from spinweb_fe.record.profile import report
            lines += report(g["profile"].attrs)
    if "linking" in h5:
        g = h5["linking"]
        t, changed = g["time"][()], int(g.attrs["changed_total"])
        when = (f" (t = {t[0]:.6g} .. {t[-1]:.6g} s)" if len(t) else "")
        first = (f", the first at t = {float(g.attrs['first_change_time']):.6g} s"
                 if changed else "")
        lines.append(f"linking: {int(g.attrs['loops'])} cells, {len(t)} checks{when}; "
                     f"cell pairs linked {g['reference'].shape[0]} at the start, "
                     f"{g['links'].shape[0]} at the end; {changed} changes{first}")
    return lines


def verdict_lines(h5, h) -> list:
    """The verdict a result file holds; judged here from its history for a file written
    before verdicts (its slack is then unknown)."""
    from spinweb_fe.post.judged import criteria_of
    from spinweb_fe.record import verdict

    return verdict.report(criteria_of(h5, h))


def _live(path, h) -> str:
    """Whether a 'running' file is being written by a live run, or its run was killed."""
    from spinweb_fe.io.folder import describe, holder

    folder = path.parent
    info = holder(folder)
    if info is not None:
        return f"live: a run is writing this file ({describe(info)})"
    when = f"after t = {h['time'][-1]:.6g} s" if h else "before its first rows"
    again = (f"continue it with `spinweb run --restart {folder}`"
             if (folder / "checkpoint.h5").is_file() else "run the case again (no checkpoint)")
    return (f"interrupted: no process is running it any more (killed {when}?); {again}")


def verdict_only(path) -> str:
    """The verdict lines of a result file (judged from its history if it has no /verdict)."""
    from spinweb_fe.io.h5 import read_result
    from spinweb_fe.post.judged import history_checked

    return read_result(path, lambda h5: "\n".join(
        verdict_lines(h5, history_checked(Path(path), h5))))


def registries() -> list:
    """Lines of ``--criteria``: the criteria and metrics registries."""
    from spinweb_fe.record import criteria, metrics

    out = criteria.listing() + ["", "metrics (record/metrics.py; sweep column, design use):"]
    for m in metrics.METRICS.values():
        use = "/".join(x for x, ok in (("objective", m.objective), ("bound", m.bound)) if ok)
        out.append(f"  {m.name:<15} {m.column:<22} [{m.unit}] {use or 'sweep only'}: "
                   f"{m.measures}")
    return out


def run(args) -> int:
    from spinweb_fe.errors import InputError

    if args.criteria:
        print("\n".join(registries()))
        if args.result is None:
            return 0
    elif args.result is None:
        raise InputError("RESULT", "", "missing: the result file (or --criteria)")
    print(verdict_only(args.result) if args.verdict else summary(args.result))
    return 0
