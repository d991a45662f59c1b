"""Helpers several test files share (not part of the library)."""

import numpy as np

from spinweb_fe.fe.contact.crossing import pair_crossings
from spinweb_fe.fe.forces import internal_forces, make_links, make_work


def loop_crossings(a0, a1, b0, b1, c0, c1, d0, d1, times, signs, sep=0.0):
    """fe.contact.crossing.pair_crossings called as the step loop's passes call it (its
    scratch given, ``sep`` [m] a float): the tests share the loop's compile instead of one
    of their own for each other form of the call (3-6 s of CPU each on a cold start)."""
    return pair_crossings(a0, a1, b0, b1, c0, c1, d0, d1, times, signs, np.empty((4, 3)),
                          np.empty(4), float(sep))


def eval_elements(elems, pos, vel, force, tension, want_energy):
    """Tension-only truss forces of every element added into ``force`` (n, 3), tensions into
    ``tension`` (m,) unless it is empty: the step loop's own element and node passes on a
    workspace of their own. Returns (strain energy [J] if ``want_energy`` else 0, max
    tension [N] if ``want_energy`` else 0, damping power [W])."""
    work = make_work(len(pos), len(elems.nodes))
    se, tmax, pdamp = internal_forces(elems, make_links(elems.nodes, len(pos)), pos, vel, work,
                                      True)
    force += work.force
    if len(tension):
        tension[:] = work.tension
    return (se, tmax, pdamp) if want_energy else (0.0, 0.0, pdamp)


def layered_contact_run(sets, end=0.05):
    """The paper's feedback web folded with a 5 mm layer gap, run with the crossing audit
    and the cable contact to ``end`` [s] (history rows every 1 ms, no frames; ``sets``:
    further case keys). Returns (history, the record.contact.CableContact, the audit's
    crossing count)."""
    from pathlib import Path

    from spinweb_fe import case as case_mod
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.run.features import features_of
    from spinweb_fe.run.loop import Schedule, simulate

    web = Path(__file__).resolve().parents[1] / "cases" / "paper_feedback_web.toml"
    case = case_mod.load(web, ["fold.layer_gap=0.005", f"time.end={end}", "output.frame_dt=0",
                               "contact.cables=true", *sets])
    sc = prepare(case)
    features = {f.name: f for f in features_of(sc.model, sc.state, case)}
    h = simulate(sc.model, sc.control, sc.state, sc.dt, Schedule(end, 1e-3),
                 features=features.values()).history
    return h, features["contact"], features["crossings"].count
