"""Helpers several test files share (not part of the library)."""

from spinweb_fe.fe.forces import internal_forces, make_links, make_work


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
    further case keys). Returns (history, the CableContact, the audit's crossing count)."""
    from pathlib import Path

    from spinweb_fe import case as case_mod
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.fe.cable_contact import CableContact, cable_radius
    from spinweb_fe.record.crossings import CrossingAudit
    from spinweb_fe.run.loop import Schedule, simulate

    web = Path(__file__).resolve().parents[1] / "cases" / "paper_feedback_web.toml"
    case = case_mod.load(web, ["fold.layer_gap=0.005", f"time.end={end}", "output.frame_dt=0",
                               "contact.cables=true", *sets])
    sc = prepare(case)
    audit = CrossingAudit(sc.model, case.audit.skin, case.audit.touch)
    contact = CableContact(sc.model, cable_radius(case, sc.model), case.contact.stiffness,
                           case.contact.friction)
    h = simulate(sc.model, sc.control, sc.state, sc.dt, Schedule(end, 1e-3),
                 crossings=audit, contact=contact).history
    return h, contact, int(audit.kernel.count[0])
