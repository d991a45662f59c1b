"""The features whose kernel data rides in the Model's kernel view (fe.model.Kernel, where
numba prunes an absent one by type): the payout devices, the gravity field's node forces
and the bundles. Their state between steps is the State's (``state_fields``, saved whole by
a checkpoint); here are their history columns and their hook data.
"""

from __future__ import annotations

import numpy as np

from spinweb_fe.fe.layout import ARM, DEVICE, named
from spinweb_fe.record.feature import Feature


class Devices(Feature):
    """Reels and brakes at the arms' departure points (``payout = 'rate' | 'brake'``): per
    arm, the line tension at D and the device's work so far (fe.layout.DEVICE, recorded in
    the step's arm rows)."""

    name = "devices"
    layout = DEVICE
    state_fields = ("coil/s_dev", "coil/dev_rest", "coil/dev_ref", "coil/dev_x",
                    "coil/dev_work", "coil/dev_tension", "coil/dev_speed", "coil/dev_moment",
                    "coil/dev_friction")

    def columns(self, kernel, rec, nrec: int) -> dict:
        arms = named(rec.arm_table[:nrec], ARM)
        return {c.name: arms[c.name] for c in DEVICE}


class GravityField(Feature):
    """The gravity gradient of a circular orbit (``[environment] gravity_gradient``): on a
    fixed axis, the node forces the step computes at x_n and pairs with the step's motion
    for their work (hook ``tidal``, scratch of a step); a free hub takes the field in its own
    phases. Its work is a step term (``gravity_gradient_work`` in ``State.totals``)."""

    name = "gravity"
    hook = "tidal"
    state_fields = ("totals",)

    def __init__(self, model):
        self.tidal = None if model.free_hub else np.zeros((model.n_nodes, 3))

    def kernel(self, hooks: dict):
        return self.tidal

    def trial(self, kernel, hooks: dict):
        return None if kernel is None else np.zeros_like(kernel)


class Bundles(Feature):
    """Two-stage deployment (``[stowage] bundle``): each arm moves as a bundle until its
    release; which arms are still bundled is the State's ``coil/bundled``."""

    name = "bundles"
    state_fields = ("coil/bundled",)
