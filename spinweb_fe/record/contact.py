"""The cable-cable contact of a run (``[contact] cables = true``) as a feature: its radius
and stiffness, each listed pair's contact distance, what its fail-safe and friction did so
far, and the step loop's view of it (hook ``contact``; the kernels are
:mod:`spinweb_fe.fe.contact.penalty`). It works on the crossing audit's candidate list
(record.crossings, the feature before it), whose x_n and certificates it shares.
"""

from __future__ import annotations

import logging

import numpy as np

from spinweb_fe.fe.contact.penalty import (AGAIN, DEEPEST_RUN, ENERGY, FRICTION, IMPULSES, KAPPA,
                                         LEFT, MARGIN, ROUNDS, TAKEN, ContactKernel)
from spinweb_fe.fe.contact.bounds import Certified, contact_profile
from spinweb_fe.fe.contact.broad import carried
from spinweb_fe.fe.contact.clock import CONTACT_CLOCK, CONTACT_TALLY
from spinweb_fe.fe.contact.impulses import hub_start
from spinweb_fe.fe.contact.zones import no_adjacency
from spinweb_fe.fe.layout import CONTACT, named
from spinweb_fe.record.feature import Feature, copied
from spinweb_fe.record.profile import Profile

log = logging.getLogger(__name__)

#: the contact's skin, as a share of the audit's default (record.crossings.default_skin):
#: its passes read every listed pair each step, and since the rebuilds cost half as much a
#: thinner list built twice as often is cheaper (the feedback web's first 0.6 s: 34.5 s at
#: 0.2 m, 36.9 s at 0.3 m, 47.2 s at 0.5 m; the tilted free hub's first second 46.1 s at
#: 0.25 m, 55.8 s at 0.5 m; the same impulses; docs/performance.md)
CONTACT_SKIN = 0.5


def cable_radius(case, model) -> float:
    """The contact radius of a case [m]: contact.cable_radius, else the cable's own
    sqrt(A / pi) (A from the largest element's E A and the cable's modulus)."""
    given = case.contact.cable_radius
    if given is not None:
        return float(given)
    area = float(np.max(model.elements.ea)) / case.cable.youngs_modulus
    return float(np.sqrt(area / np.pi))


class CableContact(Feature):
    """The contact of a run (see the module's text): :meth:`kernel` is a
    :class:`~spinweb_fe.fe.contact.penalty.ContactKernel`, whose ``stats`` say what the last
    step found and what the fail-safe did so far.

    Parameters
    ----------
    model : spinweb_fe.fe.model.Model
    radius : float [m]
        The cable's contact radius (two cables touch closer than twice it).
    kappa : float
        The penalty's stiffness factor (k = kappa m / dt^2).
    friction : float
        Coulomb coefficient between touching cables.
    audit : spinweb_fe.record.crossings.CrossingAudit or None
        The crossing audit whose candidate list the contact works on (in a run: the feature
        before it; None: :meth:`on_list` is given the list).
    """

    name = "contact"
    hook = "contact"
    layout = CONTACT

    def __init__(self, model, radius: float, kappa: float = KAPPA, friction: float = 0.0,
                 audit=None):
        self.audit = audit
        if audit is not None:  # a fixed skin: the contact pays per listed pair (issue #42)
            audit.growth = 1.0
            if not audit.skin_given:  # and a thinner one than the audit's, unless set
                audit.skin = audit.base_skin = CONTACT_SKIN * audit.skin
        self.radius, self.kappa, self.mu = float(radius), float(kappa), float(friction)
        self.elem_nodes = np.array(model.elements.nodes, dtype=np.int64)  # (writable: one type)
        self.force = np.zeros((model.n_nodes, 3))
        self.vel0, self.vel1, self.vel2 = (np.zeros((model.n_nodes, 3)) for _ in range(3))
        self.share = np.zeros(model.n_nodes, np.int64)
        self.follow = np.zeros(model.n_nodes, np.bool_)
        self.stats = np.zeros(9)
        self.codes, self.reach = np.zeros(0, np.int64), np.zeros(0)
        self._pairs = self._kernel = None
        self._rows = 1
        #: what the contact's passes cost (record.profile; not checkpointed)
        self.profile = Profile(CONTACT_CLOCK, CONTACT_TALLY)

    def sync(self, codes, dist):
        """A new candidate list (its pairs' sorted ``codes`` and distances at the build
        [m]): a pair that was listed keeps its contact distance, a new one gets twice the
        radius or, if closer, its distance now (an overlap at entry is kept, not pushed
        apart: stacked layers closer than the radius stay as they are until they part)."""
        reach = carried(codes, np.minimum(2.0 * self.radius, dist), self.codes, self.reach)
        self.codes, self.reach = codes, reach

    def on_list(self, audit, rows: int, codes=None, dist=None):
        """The step loop's view on the audit's list (``audit``: fe.contact.touch.AuditKernel, whose
        x_n it shares; ``codes``, ``dist``: its pairs' codes and distances at the build,
        for :meth:`sync` when the list is new), with room for ``rows`` history rows a
        call."""
        if audit.pairs is not self._pairs or self._kernel.rows.shape[0] < rows:
            if codes is not None and codes is not self.codes:
                self.sync(codes, dist)
            self._pairs = audit.pairs
            cert = Certified(audit.level, audit.motion,
                             no_adjacency(len(self.force), len(audit.pairs)), audit.active,
                             self.profile.clock, self.profile.tally)
            self._kernel = ContactKernel(self.elem_nodes, audit.pairs, self.reach,
                                         np.zeros((len(audit.pairs), 3)), self.vel0,
                                         self.vel1, self.vel2, hub_start(), self.force,
                                         self.share, self.follow, audit.pos0, audit.active,
                                         cert, self.radius, self.kappa,
                                         MARGIN * self.radius, ROUNDS, self.mu, self.stats,
                                         np.zeros((rows, 2)))
        return self._kernel

    # -- the feature's hooks (record.feature) --

    def prepare(self, state, rows: int) -> None:
        self._rows = rows
        self.profile.start()

    def kernel(self, hooks: dict):
        """On the list of the crossing audit (:attr:`audit`, the feature before it, whose
        kernel is ``hooks['audit']``)."""
        return self.on_list(hooks["audit"], self._rows, self.audit.pair_codes,
                            self.audit.pair_dist)

    def trial(self, kernel, hooks: dict):
        au = hooks["audit"]  # (the trial's copy of the audit's kernel: x_n, certificates)
        return copied(kernel)._replace(pos0=au.pos0, active=au.active,
                                       cert=Certified(au.level, au.motion,
                                                      copied(kernel.cert.adj),
                                                      au.active, *contact_profile()))

    def columns(self, kernel, rec, nrec: int) -> dict:
        return named(kernel.rows[:nrec], CONTACT)

    def memory(self) -> dict:
        """Each listed pair's contact distance (raised from an overlap at entry as the
        pair parts) and what the contact did so far."""
        return {"codes": self.codes.copy(), "reach": self.reach.copy(),
                "stats": self.stats.copy()}

    def restore(self, memory: dict) -> None:
        self.codes = np.asarray(memory["codes"], np.int64)
        self.reach = np.asarray(memory["reach"], np.float64)
        self.stats[:] = np.asarray(memory["stats"], np.float64)

    def write(self, h5) -> None:
        """The contact's radius [m], deepest penetration [m], its fail-safe's impulses and
        those of the passes after a reaction of the hub, as attributes of /crossings."""
        g = h5.require_group("crossings")
        g.attrs["contact_radius"] = self.radius
        g.attrs["deepest_penetration"] = self.deepest_run
        g.attrs["contact_impulses"] = self.impulses
        g.attrs["impulses_after_reactions"] = self.impulses_after_reactions
        self.profile.write(g.require_group("profile"), "contact")

    @property
    def energy(self) -> float:
        """Stored in the penalty springs at the last step [J]."""
        return float(self.stats[ENERGY])

    @property
    def dissipated(self) -> float:
        """Kinetic energy the fail-safe's and the friction's impulses took so far [J]."""
        return float(self.stats[TAKEN] + self.stats[FRICTION])

    @property
    def friction_dissipated(self) -> float:
        """Kinetic energy the friction's impulses took so far [J]."""
        return float(self.stats[FRICTION])

    @property
    def deepest_run(self) -> float:
        """The deepest penetration of the run so far [m]."""
        return float(self.stats[DEEPEST_RUN])

    @property
    def impulses(self) -> int:
        return int(self.stats[IMPULSES])

    @property
    def impulses_after_reactions(self) -> int:
        """Pair impulses of the passes after the hub placed its nodes again (of
        :attr:`impulses`)."""
        return int(self.stats[AGAIN])

    @property
    def unresolved(self) -> int:
        """Crossings the fail-safe's rounds left (the audit counts them)."""
        return int(self.stats[LEFT])
