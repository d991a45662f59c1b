"""Hub control laws: a small named registry.

Each law is a name, a numba code (evaluated by ``kernels.eval_control`` inside the step
loop, so the law costs one branch per step, not a Python call) and a function that packs
the case's ``[control]`` keys into the kernel's parameter vector. Adding a law means one
entry here and one branch in ``kernels.eval_control``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from spinweb_fe import kernels
from spinweb_fe.errors import InputError


@dataclass(frozen=True)
class Law:
    """A control law: kernel code, parameter packing, and whether it prescribes the hub rate."""

    name: str
    code: int
    params: Callable  # control config -> list of floats
    prescribes_rate: bool
    doc: str


LAWS = {law.name: law for law in (
    Law("free", kernels.LAW_FREE, lambda c: [], False, "no torque: free deployment"),
    Law("torque_feedback", kernels.LAW_FEEDBACK, lambda c: [c.M0, c.omega0], False,
        "M = M0 (1 - omega/omega0)"),
    Law("spin_ramp", kernels.LAW_RAMP, lambda c: [c.omega_max, c.ramp_time], True,
        "omega = omega_max t / ramp_time, then omega_max; the torque it takes is reported"),
    Law("constant_torque", kernels.LAW_CONSTANT, lambda c: [c.torque], False, "M = torque"),
)}


@dataclass(frozen=True)
class Control:
    """The chosen law with its packed parameters (kernel-ready)."""

    law: Law
    params: np.ndarray

    @property
    def code(self) -> int:
        return self.law.code

    def torque_or_rate(self, t: float, omega: float):
        """(prescribed, value) at time t [s] and hub rate omega [rad/s] (Python-side evaluation)."""
        return kernels.eval_control(self.code, self.params, t, omega)


def make_control(control_cfg, source="<case>") -> Control:
    """Build a Control from the case's [control] table."""
    try:
        law = LAWS[control_cfg.law]
    except KeyError:
        raise InputError(source, "control.law",
                         f"unknown law '{control_cfg.law}' (valid: {', '.join(LAWS)})") from None
    params = np.array(law.params(control_cfg) + [0.0], dtype=np.float64)
    return Control(law, params)
