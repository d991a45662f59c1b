"""The registry of a run's features (record.feature): which parts a case and its model
have, how each is built, and the start-up checks each makes. The one place a feature is
named; the event loop (run.loop) and the driver (run.driver) iterate over what
:func:`features_of` returns.

Features that ride in the Model (strength, devices, gravity field, bundles) are wanted by
the model alone, so that a run without a case (a test, a study) gets them too; those of
the case (the crossing audit, the cable contact, the linking check) need the case. Order
matters: a feature's kernel may use those of the features before it (the contact works on
the audit's list).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.record.contact import CableContact, cable_radius
from spinweb_fe.record.crossings import CrossingAudit
from spinweb_fe.record.linking_check import LinkingMonitor
from spinweb_fe.record.parts import Bundles, Devices, GravityField
from spinweb_fe.record.strength import StrengthCheck


class FeatureEntry(NamedTuple):
    """One feature: its class (record.feature.Feature), ``wanted(case, model)`` (case None:
    a run without a case), ``build(case, model, state, built)`` (``built``: the features
    built before it, by name), ``check(case, model, state)``: its start-up checks
    (InputError), or None."""

    name: str
    doc: str
    cls: type
    wanted: Callable
    build: Callable
    check: Callable | None = None


def records_vectors(model, state) -> bool:
    """Whether a run records the vector columns (momentum vectors, the hub's pose, the
    distances from the hub plane): a free hub, the gravity gradient, or a scene not exactly
    in the plane (some node with z or v_z not 0). A fixed-axis scene in the plane without
    the tidal field stays there exactly (its forces have no z part), and its step loop is
    the one without them; its cables cannot cross."""
    return bool(model.free_hub or model.env.n > 0.0 or np.any(state.node_pos[:, 2] != 0.0)
                or np.any(state.node_vel[:, 2] != 0.0))


def _check_crossings(case, model, state) -> None:
    """The audit (and the contact, on its list) needs a scene that can leave the plane."""
    touching = case.contact.cables
    if records_vectors(model, state):
        return
    key = "contact.cables" if touching else "audit.crossings"
    why = ", and the coincident layers of a planar fold have no contact defined" \
        if touching else ""
    raise InputError(case.source, key, "the scene cannot leave the plane (fixed axis, no "
                     "layer gap, no perturbation, no gravity gradient): its cables cannot "
                     f"cross{why}; give fold.layer_gap or a perturbation")


def _check_contact(case, model, state) -> None:
    """A contact radius above half the layer gap (stacked layers would start inside each
    other's reach), and elements that start closer than the audit's touch distance
    (coincident layers, or a displacement perturbation that moved stacked layers through
    each other: contact between them is undefined)."""
    radius, gap = cable_radius(case, model), case.fold.layer_gap
    given = case.contact.cable_radius is not None
    name = "contact.cable_radius" + ("" if given else " (default sqrt(A / pi))")
    if gap > 0.0 and radius > 0.5 * gap:
        raise InputError(case.source, "contact.cable_radius",
                         f"{name} {radius:.6g} m is more than half fold.layer_gap "
                         f"({gap:.6g} m): stacked layers would start in contact")
    start = CrossingAudit(model, case.audit.skin, case.audit.touch)
    start.build(state)
    if not len(start.ignored):
        return
    key, why = "fold.layer_gap", "the layer gap is below audit.touch"
    if gap == 0.0:
        why = "the fold's layers coincide; give fold.layer_gap"
    elif case.perturbation.z_amplitude != 0.0:
        key = "perturbation.z_amplitude"
        why = ("the perturbation moves stacked layers unequally (the tied nodes stay) and "
               "puts them through each other; perturb by velocity "
               "(perturbation.vz_amplitude) instead")
    raise InputError(case.source, key,
                     f"{len(start.ignored)} pairs of elements start closer than audit.touch "
                     f"({start.touch:g} m), where contact is undefined: {why}")


def _audited(case) -> bool:
    return case is not None and (case.audit.crossings or case.contact.cables)


#: every feature, in the order the loop asks them (a kernel may use those before it)
FEATURES = (
    FeatureEntry("strength", "strength check and rupture (cable.failure_strain)",
                 StrengthCheck,
                 lambda case, model: len(model.strength.fail) > 0,
                 lambda case, model, state, built: StrengthCheck(model)),
    FeatureEntry("devices", "reels and brakes at the departure points (stowage.payout)",
                 Devices,
                 lambda case, model: model.kernel.devices is not None,
                 lambda case, model, state, built: Devices()),
    FeatureEntry("gravity", "the gravity gradient of an orbit "
                            "(environment.gravity_gradient)",
                 GravityField,
                 lambda case, model: model.env.n > 0.0,
                 lambda case, model, state, built: GravityField(model)),
    FeatureEntry("bundles", "two-stage deployment (stowage.bundle)",
                 Bundles,
                 lambda case, model: model.kernel.bundles is not None,
                 lambda case, model, state, built: Bundles()),
    FeatureEntry("crossings", "the crossing audit and the contact's candidate list "
                              "(audit.crossings, contact.cables)",
                 CrossingAudit,
                 lambda case, model: _audited(case),
                 lambda case, model, state, built: CrossingAudit(model, case.audit.skin,
                                                                 case.audit.touch),
                 _check_crossings),
    FeatureEntry("contact", "cable-cable contact (contact.cables)",
                 CableContact,
                 lambda case, model: case is not None and case.contact.cables,
                 lambda case, model, state, built: CableContact(
                     model, cable_radius(case, model), case.contact.stiffness,
                     case.contact.friction, audit=built["crossings"]),
                 _check_contact),
    FeatureEntry("linking", "the linking numbers of the web's cells (audit.crossings)",
                 LinkingMonitor,
                 lambda case, model: case is not None and case.audit.crossings,
                 lambda case, model, state, built: LinkingMonitor(model.mesh, state)),
)


def features_of(model, state, case=None) -> list:
    """The features of a run of ``model`` from ``state`` (record.feature.Feature), in the
    registry's order; with ``case``, those the case asks for too."""
    built = {}
    for entry in FEATURES:
        if entry.wanted(case, model):
            built[entry.name] = entry.build(case, model, state, built)
    return list(built.values())


def check_features(case, model, state) -> None:
    """The start-up checks of every feature the case has (InputError, one line)."""
    for entry in FEATURES:
        if entry.check is not None and entry.wanted(case, model):
            entry.check(case, model, state)
