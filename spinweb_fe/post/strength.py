"""Strength of a finished run: the worst utilisation, when and where, a verdict, the pieces a
torn web came apart into, and a top view of the web coloured by utilisation.

Reads what a run with ``cable.failure_strain`` writes (docs/strength.md): the history columns
``utilisation``, ``max_strain``, ``max_strain_element``, ``max_strain_arm`` (and with rupture
``broken_elements``, ``rupture_dissipation``), ``/frames/broken`` and ``/mesh``.
"""

from __future__ import annotations

import tomllib

import numpy as np


def failure_strain_of(h5) -> float | None:
    """cable.failure_strain of the case stored in a result file (None: no strength check)."""
    try:
        case = tomllib.loads(str(h5.attrs.get("case", "")))
    except tomllib.TOMLDecodeError:
        return None
    return case.get("cable", {}).get("failure_strain")


def where(h5, elem: int) -> str:
    """Where element ``elem`` lies: its arm and arm coordinate (of the arm length), and
    'web edge' when it is on the web's boundary."""
    m = h5["mesh"]
    nodes = m["elements"][elem]
    arm = m["node_arm"][()][nodes]
    coord = m["node_arm_coord"][()][nodes]
    k = int(arm[0] if arm[0] >= 0 else arm[1])
    if k < 0:
        return f"element {elem} (in the cross at the hub, on no arm)"
    length = float(m.attrs.get("arm_length", np.nan))
    text = f"element {elem} (arm {k}, l = {np.nanmean(coord):.1f} m of {length:.1f} m"
    boundary = m.get("elem_sets/boundary")
    if boundary is not None and elem in set(boundary[()].tolist()):
        text += ", web edge"
    return text + ")"


def pieces(elem_nodes, broken, tied, n_nodes) -> int:
    """Pieces a web is in: connected parts of the nodes through its intact elements, the
    nodes tied to the hub joined through the hub (a node with no intact element, a tip mass
    torn off, is a piece of its own)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    keep = ~np.asarray(broken, dtype=bool)
    a, b = elem_nodes[keep, 0], elem_nodes[keep, 1]
    tied = np.asarray(tied, dtype=np.int64)
    if len(tied) > 1:  # the hub joins its tied nodes
        a = np.concatenate([a, np.full(len(tied) - 1, tied[0])])
        b = np.concatenate([b, tied[1:]])
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(n_nodes, n_nodes))
    return int(connected_components(g, directed=False)[0])


def summary_lines(h5) -> list[str]:
    """The strength lines of ``spinweb info`` (none for a run without a failure strain)."""
    hist = h5.get("history")
    if hist is None or "utilisation" not in hist or hist["utilisation"].shape[0] == 0:
        return []
    # a live file (a run still writing) may hold one more row in a column read first: every
    # column is read to the shortest one's length
    names = [c for c in ("time", "utilisation", "max_strain", "max_strain_element",
                         "broken_elements", "rupture_dissipation") if c in hist]
    rows = min(hist[c].shape[0] for c in names)
    hist = {c: hist[c][:rows] for c in names}
    t, u = hist["time"], hist["utilisation"]
    k = int(np.argmax(u))
    eps_f = failure_strain_of(h5)
    head = f"failure strain {eps_f:.4g}; " if eps_f is not None else ""
    if "max_strain_element" not in hist:  # the analytical tethers: their root tension
        return [f"strength: {head}worst utilisation {u[k]:.3g} (strain "
                f"{hist['max_strain'][k]:.4g}, the arm's root tension over E A) at "
                f"t = {t[k]:.6g} s"]
    elem = int(hist["max_strain_element"][k])
    lines = [f"strength: {head}worst utilisation {u[k]:.3g} (strain "
             f"{hist['max_strain'][k]:.4g}) at t = {t[k]:.6g} s, {where(h5, elem)}"]
    over = np.flatnonzero(u > 1.0)
    if "broken_elements" in hist:
        n = hist["broken_elements"][()]
        if n[-1] == 0:
            lines.append(f"verdict: no element broke (worst utilisation {u[k]:.3g})")
            return lines
        first = int(np.argmax(n > 0))
        text = (f"verdict: the web tore: {int(n[-1])} elements broke from t = {t[first]:.6g} s "
                f"(first {where(h5, int(hist['max_strain_element'][first]))}), "
                f"{hist['rupture_dissipation'][-1]:.4g} J dissipated")
        frames = h5.get("frames")
        if frames is not None and "broken" in frames and frames["broken"].shape[0]:
            m = h5["mesh"]
            n_pieces = pieces(m["elements"][()], frames["broken"][-1] > 0,
                              m["node_sets/hub_tied"][()], m["points"].shape[0])
            text += f"; {n_pieces} pieces at t = {frames['time'][-1]:.6g} s"
        lines.append(text)
    elif len(over):
        first = int(over[0])
        lines.append(f"verdict: the cables would break: utilisation above 1 from t = "
                     f"{t[first]:.6g} s ({where(h5, int(hist['max_strain_element'][first]))}); "
                     "cable.rupture = true lets them")
    else:
        lines.append(f"verdict: within strength: the worst utilisation is {u[k]:.3g}, a margin "
                     f"of {1.0 / max(u[k], 1e-300):.3g} on the failure strain")
    return lines


def draw_web(ax, position, elem_nodes, utilisation, broken=None, hub_radius=0.0, vmax=None):
    """Top view of a web on a matplotlib axis: intact elements coloured by utilisation (capped
    at ``vmax``), broken ones left out, the hub as a grey disc. Returns the line collection
    (for a colour bar)."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Circle

    keep = np.ones(len(elem_nodes), bool) if broken is None else ~np.asarray(broken, bool)
    segs = position[elem_nodes[keep]][:, :, :2]
    util = np.nan_to_num(np.asarray(utilisation, float)[keep])
    vmax = vmax or max(float(util.max()) if util.size else 1.0, 1.0)
    lc = LineCollection(segs, cmap="turbo", linewidths=0.8)
    lc.set_array(np.minimum(util, vmax))
    lc.set_clim(0.0, vmax)
    ax.add_collection(lc)
    if hub_radius > 0:
        ax.add_patch(Circle((0, 0), hub_radius, color="0.6", zorder=3))
    ax.set_aspect("equal")
    ax.autoscale_view()
    return lc
