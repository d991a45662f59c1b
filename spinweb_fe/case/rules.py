"""The rules of a case that join several keys (the scene and its fold, the stowage and its
devices, layers, the start, the free hub, perturbations, the environment, the run's
size): each an InputError naming the key at fault (spinweb_fe.case.load calls
:func:`cross_check` after every key passed its own check).
"""

from __future__ import annotations

import math

from meshgen.registry import COILED_FOLDS, TETHER_FOLDS, WEB_FOLDS, area_from_areal_density
from spinweb_fe.case.perturb import SHAPES
from spinweb_fe.case.schema import MAX_ELEMENTS, MAX_FRAMES, MAX_HISTORY_ROWS, SCHEMA
from spinweb_fe.errors import InputError
from spinweb_fe.fe.choice import validate_choice
from spinweb_fe.fe.coil.levels import BUNDLES, COILS
from spinweb_fe.fe.control import LAWS
from spinweb_fe.fe.model import MOTIONS
from spinweb_fe.fe.coil.payout import PAYOUTS
from spinweb_fe.fe.tidal import R_EARTH


def cross_check(src, scene, raw, t):
    """The rules between keys of a case's resolved tables ``t`` ({table: {key: value}}; the
    scene 'web' or 'tethers', ``raw`` the file's tables): InputError naming the key."""
    fold = t["fold"]
    if fold["pattern"] is None:
        fold["pattern"] = "star" if scene == "web" else "coiled"
    allowed = WEB_FOLDS if scene == "web" else TETHER_FOLDS
    if fold["pattern"] not in allowed:
        raise InputError(src, "fold.pattern",
                         f"'{fold['pattern']}' is not a {scene} fold (valid: {', '.join(allowed)})")
    _check_stowage(src, scene, raw, t)
    _check_layers(src, scene, t)
    _check_start(src, t)
    _check_free_hub(src, t)
    _check_perturbation(src, scene, t)
    _check_environment(src, t)
    if t["cable"]["rupture"] and t["cable"]["failure_strain"] is None:
        raise InputError(src, "cable.rupture", "needs cable.failure_strain (the strain at "
                         "which an element breaks)")
    hub = t["hub"]
    law = t["control"]["law"]
    for key in LAWS[law].keys:
        if t["control"][key.name] is None:
            raise InputError(src, f"control.{key.name}", f"required by control.law = '{law}'")
    if scene == "web":
        web = t["web"]
        if web["mesh_width"] > web["side"] / 2:
            raise InputError(src, "web.mesh_width",
                             f"{web['mesh_width']} m is more than half the side {web['side']} m")
        if web["hub_cutout"] is not None and web["hub_cutout"] >= web["side"] / 2:
            raise InputError(src, "web.hub_cutout", f"{web['hub_cutout']:g} m leaves no web of "
                             f"side {web['side']:g} m")
        if hub["radius"] >= web["side"] / 2:
            raise InputError(src, "hub.radius",
                             f"hub radius {hub['radius']} m does not fit in a web of side {web['side']} m")
        if web["areal_density"] is not None:
            area = area_from_areal_density(
                web["topology"], web["areal_density"], web["mesh_width"], t["cable"]["density"])
            if not (math.isfinite(area) and area > 0):  # (a tiny density: it overflows)
                raise InputError(src, "web.areal_density", f"gives a cable area of {area:g} "
                                 "m^2 with this cable.density and mesh_width: not a cable")
            given = raw.get("cable", {}).get("area")
            # a resolved case (spinweb check, results.h5) holds both, equal: it reloads
            if given is not None and abs(t["cable"]["area"] - area) > 1e-12 * area:
                raise InputError(src, "cable.area",
                                 "give either cable.area or web.areal_density, not both")
            t["cable"]["area"] = area
    _check_sizes(src, scene, t)
    if t["time"]["end"] < t["output"]["history_dt"]:
        raise InputError(src, "output.history_dt",
                         f"{t['output']['history_dt']} s is longer than time.end {t['time']['end']} s")


def _check_stowage(src, scene, raw, t):
    """[stowage]: coiled scenes only; each registry's keys and rules (the coil, the payout
    device, the bundles); bundles on webs."""
    st, given = t["stowage"], raw.get("stowage") or {}
    pattern = t["fold"]["pattern"]
    if pattern not in COILED_FOLDS:
        if given:
            key = next(iter(given))
            raise InputError(src, f"stowage.{key}", f"only a coiled scene has a stowage "
                             f"(fold.pattern = '{pattern}')")
        for key in st:
            st[key] = None
        return
    if st["coil"] is None:
        st["coil"] = "held"
    for reg, key in ((COILS, "coil"), (PAYOUTS, "payout"), (BUNDLES, "bundle")):
        _choice_ok(src, reg, "stowage", key, t)
    if st["bundle"] != "none" and scene != "web":
        raise InputError(src, "stowage.bundle", "bundles gather a web's levels: a tether "
                         "scene has none")


def _check_layers(src, scene, t):
    """fold.layer_gap > 0: a coiled scene whose stowage keeps a level's layers apart (the
    mesh generator checks the geometry: meshgen.layers)."""
    st, pattern = t["stowage"], t["fold"]["pattern"]
    if t["fold"]["layer_gap"] == 0:
        return
    if pattern not in COILED_FOLDS:
        raise InputError(src, "fold.layer_gap", f"only a folded scene has layers (fold.pattern "
                         f"= '{pattern}')")
    if st["bundle"] != "none":
        raise InputError(src, "fold.layer_gap", "a bundle (stowage.bundle) moves each level "
                         "as one point, its layers merged: needs layer_gap = 0")
    if scene == "web" and PAYOUTS[st["payout"]].device:
        raise InputError(src, "fold.layer_gap", f"a {st['payout']} device lets each level out "
                         "at one point: needs layer_gap = 0 on a web")


def _check_start(src, t):
    """[initial] state = 'steady': a scene that has a steady spinning state to start from."""
    ini = t["initial"]
    if ini["state"] != "steady":
        return
    if t["fold"]["pattern"] in COILED_FOLDS:
        raise InputError(src, "initial.state", f"'steady' needs a deployed scene (fold.pattern "
                         f"= 'flat' or 'straight'): a coiled scene ('{t['fold']['pattern']}') "
                         "has no steady spinning state")
    if ini["spin"] != "all":
        raise InputError(src, "initial.state", "'steady' spins the whole scene: needs "
                         "initial.spin = 'all'")
    if ini["omega"] == 0:
        raise InputError(src, "initial.omega", "is 0: a steady start needs a spin rate (a "
                         "cable net without spin has no steady state)")


def _choice_ok(src, reg, table, key, t):
    """The chosen entry's keys and rules (fe.choice.validate_choice), or InputError."""
    problem = validate_choice(reg, table, key, t)
    if problem is not None:
        raise InputError(src, *problem)


def _check_free_hub(src, t):
    """[hub]: the inertia triple (positive, triangle inequality), what a free hub needs."""
    hub = t["hub"]
    given = hub["principal_inertia"]
    if given is not None:
        if hub["inertia"] is not None and abs(hub["inertia"] - given[2]) > 1e-12 * given[2]:
            raise InputError(src, "hub.inertia", "give either hub.inertia or "
                             "hub.principal_inertia (whose third value it is), not both")
        if hub["inertia_transverse"] is not None:
            raise InputError(src, "hub.inertia_transverse", "give either "
                             "hub.inertia_transverse or hub.principal_inertia, not both")
        hub["inertia"] = given[2]
    if hub["inertia"] is None:
        hub["inertia"] = hub["mass"] * hub["radius"] * hub["radius"]
        if not 0 < hub["inertia"] < math.inf:
            raise InputError(src, "hub.inertia", f"the default mass * radius^2 = "
                             f"{hub['inertia']:g} kg m^2 is not a usable number; give it")
    if given is None and (hub["motion"] == "free" or hub["inertia_transverse"] is not None):
        if hub["inertia_transverse"] is None:
            hub["inertia_transverse"] = 0.5 * hub["inertia"]
        triple = (hub["inertia_transverse"], hub["inertia_transverse"], hub["inertia"])
        key = "hub.inertia_transverse"
    else:
        triple, key = given, "hub.principal_inertia"
    if triple is not None:
        a, b, c = sorted(triple)
        if a + b < c * (1 - 1e-12):
            raise InputError(src, key, f"{list(triple)} kg m^2 breaks the triangle inequality "
                             f"(each moment at most the sum of the other two): no rigid body "
                             "has these")


def _check_perturbation(src, scene, t):
    """[perturbation]: amplitudes within the web, what each key needs."""
    p = t["perturbation"]
    size = t["web"]["side"] if scene == "web" else t["tethers"]["length"]
    if p["z_amplitude"] > size:
        raise InputError(src, "perturbation.z_amplitude", f"{p['z_amplitude']:g} m is larger "
                         f"than the web ({size:g} m)")
    _choice_ok(src, MOTIONS, "hub", "motion", t)
    _choice_ok(src, SHAPES, "perturbation", "shape", t)
    if p["delay"] > 0 and t["stowage"]["coil"] != "held":
        raise InputError(src, "perturbation.delay", "holds an arm's coil on the hub: needs a "
                         "held coil (stowage.coil = 'held', a coiled scene)")


def _check_environment(src, t):
    """[environment]: an orbit outside the Earth for the gravity gradient, a free hub."""
    env = t["environment"]
    orbit = [k for k in ("orbit_radius", "altitude") if env[k] is not None]
    if not env["gravity_gradient"]:
        extra = orbit + (["orbit_tilt"] if env["orbit_tilt"] != 0 else [])
        if extra:
            raise InputError(src, f"environment.{extra[0]}", "used only with "
                             "environment.gravity_gradient = true")
        return
    if not orbit:
        raise InputError(src, "environment.orbit_radius", "required by "
                         "environment.gravity_gradient = true (or give environment.altitude)")
    if len(orbit) == 2:
        raise InputError(src, "environment.altitude", "give either environment.orbit_radius "
                         "or environment.altitude, not both")
    radius = env["orbit_radius"] if env["orbit_radius"] is not None else R_EARTH + env["altitude"]
    if not radius > R_EARTH:
        raise InputError(src, f"environment.{orbit[0]}", f"the orbit radius {radius:g} m is "
                         f"inside the Earth (mean radius {R_EARTH:g} m)")


def _check_sizes(src, scene, t):
    """Refuse cases whose mesh or outputs could not be allocated (before meshgen tries)."""
    if scene == "web":
        web = t["web"]
        n = web["side"] / web["mesh_width"]
        n_elems = 2.0 * n * (n + 1.0) * web["elements_per_segment"]
        # the key furthest from its default is the one at fault (web.side = 1e9, say)
        d = SCHEMA["web"]
        side, width = web["side"] / d["side"].default, d["mesh_width"].default / web["mesh_width"]
        far = {"web.side": side * side,  # (products overflow to inf, powers raise)
               "web.mesh_width": width * width,
               "web.elements_per_segment": float(web["elements_per_segment"])}
        key = max(far, key=far.get)
    else:
        n_elems = float(t["tethers"]["count"]) * t["tethers"]["elements"]
        key = "tethers.elements"
    if n_elems > MAX_ELEMENTS:
        raise InputError(src, key, f"gives about {n_elems:.3g} cable elements, more than "
                         f"the limit {MAX_ELEMENTS:.0e}")
    out = t["output"]
    rows = t["time"]["end"] / out["history_dt"]
    if rows > MAX_HISTORY_ROWS:
        raise InputError(src, "output.history_dt", f"gives {rows:.3g} history rows up to "
                         f"time.end, more than the limit {MAX_HISTORY_ROWS:.0e}")
    if out["frame_dt"] > 0 and t["time"]["end"] / out["frame_dt"] > MAX_FRAMES:
        raise InputError(src, "output.frame_dt", f"gives {t['time']['end'] / out['frame_dt']:.3g}"
                         f" frames up to time.end, more than the limit {MAX_FRAMES:.0e}")
