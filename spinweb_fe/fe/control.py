"""Hub control laws: the one registry.

A law is one :class:`Law` entry: its name, its case keys (with units and docs), the kernel
code that selects its branch in :func:`eval_control` below (so the law costs one branch per
step inside the numba loop, not a Python call), and its
analytical form (the torque or the prescribed rate as Python functions, used by the
analytical model and by the tests that hold the kernel branch against it). Adding a law
is one entry here plus its branch in ``eval_control``, in this file.

The parameter vector ``params`` holds the law's keys in the order of ``Law.keys``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.choice import Param


@njit(cache=True)
def eval_control(law, t, omega):
    """Control law -> (prescribed, value): torque [N m], or the prescribed hub rate [rad/s].

    ``law`` is a :class:`KernelLaw`; its ``code`` selects the branch of its registry entry.
    """
    p = law.params
    if law.code == 1:  # torque_feedback: M = M0 (1 - omega/omega0)
        return False, p[0] * (1.0 - omega / p[1])
    if law.code == 2:  # spin_ramp: omega = omega_max t / ramp_time, then omega_max
        if t < p[1]:
            return True, p[0] * t / p[1]
        return True, p[0]
    if law.code == 3:  # constant_torque
        return False, p[0]
    return False, 0.0  # free


@dataclass(frozen=True)
class Law:
    """A hub control law.

    Attributes
    ----------
    name : str
        Value of ``control.law``.
    code : int
        Branch of :func:`eval_control`.
    keys : tuple of Param
        The ``[control]`` keys it needs, in parameter-vector order.
    prescribes_rate : bool
        True: the law imposes the hub rate (the torque it takes is reported).
    doc : str
    torque : callable(params, t, omega) -> float [N m], or None
        Analytical form of a torque law.
    rate : callable(params, t) -> (omega [rad/s], omega_dot [rad/s^2]), or None
        Analytical form of a prescribed-rate law.
    breaks : callable(params) -> list of float [s]
        Times at which the law is not smooth (the analytical integrator restarts there).
    """

    name: str
    code: int
    keys: tuple
    prescribes_rate: bool
    doc: str
    torque: Callable | None = None
    rate: Callable | None = None
    breaks: Callable = lambda p: []


def _ramp_rate(p, t):
    if t < p[1]:
        return p[0] * t / p[1], p[0] / p[1]
    return p[0], 0.0


LAWS = {law.name: law for law in (
    Law("free", 0, (), False, "no torque: free deployment", torque=lambda p, t, w: 0.0),
    Law("torque_feedback", 1,
        (Param("M0", "N m", "finite", "torque_feedback: M = M0 (1 - omega/omega0)"),
         Param("omega0", "rad/s", "nonzero", "torque_feedback reference rate")),
        False, "M = M0 (1 - omega/omega0)", torque=lambda p, t, w: p[0] * (1.0 - w / p[1])),
    Law("spin_ramp", 2,
        (Param("omega_max", "rad/s", "finite", "spin_ramp final rate"),
         Param("ramp_time", "s", "pos", "spin_ramp duration")),
        True, "omega = omega_max t / ramp_time, then omega_max; the torque it takes is reported",
        rate=_ramp_rate, breaks=lambda p: [p[1]]),
    Law("constant_torque", 3, (Param("torque", "N m", "finite", "constant_torque value"),),
        False, "M = torque", torque=lambda p, t, w: p[0]),
)}


class KernelLaw(NamedTuple):
    """What the step kernels see of a law: its code and parameter vector."""

    code: int
    params: np.ndarray


@dataclass(frozen=True)
class Control:
    """The chosen law with its parameters (SI units, in ``law.keys`` order)."""

    law: Law
    params: np.ndarray

    @property
    def kernel(self) -> KernelLaw:
        """The law as the step kernels take it."""
        return KernelLaw(self.law.code, self.params)

    def torque_or_rate(self, t: float, omega: float):
        """(prescribed, value) at time t [s] and hub rate omega [rad/s], by the kernel branch."""
        return eval_control(self.kernel, t, omega)


def make_control(name: str, values: dict) -> Control:
    """The Control of law ``name`` with key values ``values`` (name -> float).

    Raises KeyError (unknown law or missing key); the case loader checks both first.
    """
    law = LAWS[name]
    params = np.array([float(values[k.name]) for k in law.keys] + [0.0], dtype=np.float64)
    return Control(law, params)


def free() -> Control:
    """No torque (free deployment)."""
    return make_control("free", {})
