"""The case schema: every key of a case file, with its type, default, check, SI unit and doc,
in one place. The named choices (topologies, folds, wraps, control laws) come from their
registries (:mod:`meshgen.registry`, :mod:`spinweb_fe.fe.control`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from meshgen.registry import TETHER_FOLDS, TIES, TOPOLOGIES, WEB_FOLDS, WRAP_SIGN
from spinweb_fe.case.perturb import SHAPES
from spinweb_fe.fe.choice import registry_keys
from spinweb_fe.fe.coil.levels import BUNDLES, COILS
from spinweb_fe.fe.control import LAWS
from spinweb_fe.fe.model import MOTIONS
from spinweb_fe.fe.coil.payout import PAYOUTS
from spinweb_fe.record.criteria import LIMITS as VERDICT_LIMITS

REQUIRED = object()  # marker: the key has no default

SPINS = ("all", "hub")
STARTS = ("rigid", "steady")
MAX_ELEMENTS = 10_000_000  # cable elements of a scene (memory: about 1 kB per element)
MAX_HISTORY_ROWS = 10_000_000  # time.end / output.history_dt
MAX_FRAMES = 100_000  # time.end / output.frame_dt


@dataclass(frozen=True)
class Field:
    """One case key: its type, default, and check.

    kind: 'float' | 'int' | 'str' | 'bool' (true / false) | 'table' (a list of [t, value]
    pairs of numbers) | 'vector' (a list of three numbers, the check applies to each) |
    'names' (a non-empty list of strings, each one of the check's);
    check: 'pos' (> 0), 'nonneg' (>= 0),
    'frac' (0 < x <= 1), 'finite', 'nonzero', a tuple of allowed strings, or None.
    """

    kind: str
    default: Any = REQUIRED
    check: Any = None
    unit: str = ""
    doc: str = ""


F = Field


def _choice(name, reg, default, doc) -> dict:
    """The key that names a registry's entry and the keys of its entries (each optional
    here; the loader checks them against the chosen entry: fe.choice.validate_choice)."""
    table = {name: F("str", default, tuple(reg), "", doc)}
    for key, p in registry_keys(reg).items():
        table[key] = F(p.kind, p.default, p.check, p.unit, p.doc)
    return table


def _control_table() -> dict:
    """[control]: the law and the keys of every law of the registry (each optional here;
    the loader requires those of the chosen law)."""
    table = {"law": F("str", "free", tuple(LAWS), "", "hub torque law")}
    for law in LAWS.values():
        for key in law.keys:
            table.setdefault(key.name, F("float", None, key.check, key.unit, key.doc))
    return table


SCHEMA: dict[str, dict[str, Field]] = {
    "web": {
        "topology": F("str", "quadquad", tuple(TOPOLOGIES), "", "web/mesh topology"),
        "side": F("float", 100.0, "pos", "m", "web side S"),
        "mesh_width": F("float", 2.5, "pos", "m", "mesh width t (cable spacing)"),
        "elements_per_segment": F("int", 1, "pos", "", "cable elements between two mesh nodes"),
        "areal_density": F("float", None, "pos", "kg/m^2",
                           "if set, the cable area is derived from it (see docs/mesh.md)"),
        "hub_cutout": F("float", None, "nonneg", "m",
                        "half-width of the central square removed for the hub (default: "
                        "smallest mesh line at or outside the hub radius)"),
    },
    "tethers": {
        "count": F("int", 4, "pos", "", "number of radial tethers n"),
        "length": F("float", 50.0, "pos", "m", "tether length H"),
        "elements": F("int", 50, "pos", "", "elements per tether"),
        "arm_mass": F("float", None, "pos", "kg", "cable mass of each tether, distributed as "
                      "the paper's Eq. 7 (linear, zero at the tip); default: rho A H, uniform"),
    },
    "cable": {
        "youngs_modulus": F("float", 180e9, "pos", "Pa", "Young's modulus E"),
        "density": F("float", 1540.0, "pos", "kg/m^3", "cable density rho"),
        "area": F("float", 1.025e-5, "pos", "m^2", "cross-section area A"),
        "damping_ratio": F("float", 0.0, "nonneg", "", "axial damping, fraction of critical"),
        "failure_strain": F("float", None, "pos", "", "strain at which the cable breaks "
                            "(tensile strength / E); absent: no strength check"),
        "rupture": F("bool", False, None, "", "elements whose strain exceeds failure_strain "
                     "break for good (false: only the margins are recorded)"),
    },
    "tip_mass": {
        "mass": F("float", 10.0, "nonneg", "kg", "point mass at each web corner / tether tip"),
    },
    "hub": {
        "radius": F("float", 6.3, "pos", "m", "hub radius r0"),
        "mass": F("float", 100.0, "pos", "kg", "hub mass"),
        "inertia": F("float", None, "pos", "kg m^2", "hub inertia (default mass*radius^2)"),
        "friction": F("float", 0.0, "nonneg", "", "Coulomb coefficient of cable-hub contact"),
        **_choice("motion", MOTIONS, "fixed_axis", "fixed_axis: the hub turns about +z; "
                  "free: a rigid body of six degrees of freedom (docs/solver.md)"),
        "inertia_transverse": F("float", None, "pos", "kg m^2", "free hub: inertia about a "
                                "hub-plane axis of an axisymmetric hub (default inertia / 2, "
                                "a thin ring)"),
        "principal_inertia": F("vector", None, "pos", "kg m^2", "free hub: principal moments "
                               "[I_x, I_y, I_z] about the hub-frame axes (z the spin axis), "
                               "instead of inertia and inertia_transverse"),
    },
    "fold": {
        "pattern": F("str", None, tuple(WEB_FOLDS) + tuple(TETHER_FOLDS), "",
                     "web: star | flat; tethers: straight | coiled (default star / coiled)"),
        "wrap": F("str", "trailing", tuple(WRAP_SIGN), "", "coil direction relative to the spin"),
        "ties": F("str", "frame", tuple(TIES), "", "hub attachment of the star-folded web: the "
                  "whole hole boundary (frame) or the 4 axis nodes (axes)"),
        "layer_gap": F("float", 0.0, "nonneg", "m", "least distance between two cables "
                       "that share no node in the folded and coiled start: the star fold's "
                       "layers stacked along the hub axis, the coil rising pass over pass "
                       "(0: layers and turns coincide; docs/mesh.md 2.9)"),
    },
    "stowage": {
        **_choice("coil", COILS, None, "coiled scenes: held (the coil turns with the hub "
                  "until its arm's peel front releases it) or loose (default held)"),
        **_choice("payout", PAYOUTS, "free", "how a held coil lets its line out: free (the "
                  "arm pulls the coil off) or a device (docs/solver.md)"),
        **_choice("bundle", BUNDLES, "none", "webs: none, or each arm's gathered levels move "
                  "as one until_length / until_time (two-stage deployment)"),
    },
    "initial": {
        "omega": F("float", 8 * math.pi, "finite", "rad/s", "initial spin rate"),
        "spin": F("str", "all", SPINS, "", "all: hub and web spin; hub: only the hub"),
        "state": F("str", "rigid", STARTS, "", "rigid: the mesh's positions turning rigidly at "
                   "omega; steady: the steady spinning equilibrium at omega (straight "
                   "tethers and flat webs: the Newton solve of spinweb modes)"),
    },
    "control": _control_table(),
    "perturbation": {
        **_choice("shape", SHAPES, "tilt", "out-of-plane shape of z_amplitude and "
                  "vz_amplitude: tilt, random or mode"),
        "z_amplitude": F("float", 0.0, "nonneg", "m", "largest out-of-plane displacement of "
                         "the web (tilt: of its deployed tips)"),
        "vz_amplitude": F("float", 0.0, "nonneg", "m/s", "largest out-of-plane velocity of "
                          "the web's free nodes, same shape"),
        "hub_tilt_rate": F("float", 0.0, "finite", "rad/s", "free hub: initial rate about "
                           "its x axis (nutation)"),
        "arm": F("int", 0, "nonneg", "", "the arm of tip_mass_scale and delay"),
        "tip_mass_scale": F("float", 1.0, "nonneg", "", "that arm's tip mass times this"),
        "delay": F("float", 0.0, "nonneg", "s", "held coil: that arm's whole coil stays on "
                   "the hub until t = delay"),
    },
    "environment": {
        "gravity_gradient": F("bool", False, None, "", "the tidal acceleration of a circular "
                              "orbit about the Earth on every node and the hub (free hub)"),
        "orbit_radius": F("float", None, "pos", "m", "gravity gradient: orbit radius from "
                          "the Earth's centre"),
        "altitude": F("float", None, "finite", "m", "gravity gradient: orbit altitude above "
                      "the mean radius 6 371 km (instead of orbit_radius)"),
        "orbit_tilt": F("float", 0.0, "finite", "rad", "gravity gradient: angle of the orbit "
                        "normal from the spin axis +z, about +x"),
    },
    "verdict": {k: F(lim.kind, lim.default, lim.check, lim.unit, lim.doc)
                for k, lim in VERDICT_LIMITS.items()},
    "contact": {
        "cables": F("bool", False, None, "", "cable-cable contact: elements that share no "
                    "node repel closer than twice cable_radius (a penalty as stiff as the "
                    "step allows; docs/solver.md); runs the crossing audit's list, one step "
                    "per call"),
        "cable_radius": F("float", None, "pos", "m", "cables: the contact radius (default: "
                          "the cable's own, sqrt(A / pi)); about 1.5 v dt for cables "
                          "closing at v"),
        "stiffness": F("float", 0.25, "pos", "", "cables: the penalty k = stiffness m / dt^2 "
                       "(m the pair's effective mass; 0.25: the contact spring's critical "
                       "step is 4 dt)"),
        "friction": F("float", 0.0, "nonneg", "", "cables: Coulomb friction coefficient "
                      "between touching cables (impulses at the step's end that slow the "
                      "sliding at most to rest, booked as cable_contact_dissipation); 0: "
                      "frictionless"),
    },
    "audit": {
        "crossings": F("bool", False, None, "", "count every crossing of two cable elements "
                       "(history crossings, table /crossings; tested in the step loop) and "
                       "check the linking numbers of the web's cells at the start, every "
                       "frame and the end (/linking): docs/results.md"),
        "skin": F("float", None, "pos", "m", "crossings: the broad phase's skin (rebuilt "
                  "when a node has moved 3/4 of it in the hub's frame; default the smaller "
                  "of 0.5 m and a fifth of the median element: docs/performance.md)"),
        "touch": F("float", 1e-3, "nonneg", "m", "crossings: pairs closer than this when "
                   "they enter the list (stacked layers) are left out until they separate"),
    },
    "time": {
        "end": F("float", REQUIRED, "pos", "s", "end time"),
        "cfl": F("float", 0.2, "frac", "",
                 "fraction of the critical step L0/c (0.2: see docs/stability.md)"),
        "dt": F("float", None, "pos", "s", "optional cap on the time step"),
    },
    "output": {
        "history_dt": F("float", 1e-3, "pos", "s", "interval of scalar histories"),
        "frame_dt": F("float", 0.05, "nonneg", "s", "interval of VTU frames (0 = none)"),
        "directory": F("str", None, None, "", "result folder, relative to the case file"),
    },
}
TOP_KEYS = {"title": F("str", "", None, "", "free text")}
