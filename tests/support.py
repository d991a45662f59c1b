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
