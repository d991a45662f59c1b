"""The shape of an optional part of a run (a feature): cable contact, the crossing audit and
its linking check, payout devices, strength and rupture, the gravity field, bundles.

The event loop (:func:`spinweb_fe.run.loop.simulate`) names no feature: it iterates over the
run's features (their registry is :data:`spinweb_fe.run.features.FEATURES`) and asks each,
at event boundaries only,

- ``prepare(state, rows)``: before the first call of the step loop (the state already
  started; a restored feature takes its memory instead);
- ``kernel(hooks)``: the data it hands ``fe.step.advance`` through its hook argument
  (:attr:`Feature.hook`, one of :data:`HOOKS`; the kernels of the features before it in
  ``hooks``), or None when it has none (its data is then in the Model's kernel view, where
  numba prunes it by type, as the strength check, the devices and the bundles are);
- ``trial(kernel, hooks)``: a copy of that kernel for a step run on a copy of the state (the
  loop's first compile call, the last row at t_end): what such a step changes must not
  reach the run (the estimate's timed steps, which must also serve the loop's stops, run
  on deep copies of the features instead: run.loop.time_steps);
- ``columns(kernel, rec, nrec)``: its history columns of the rows the call recorded, named by
  a table of :mod:`spinweb_fe.fe.layout` (:attr:`Feature.layout`);
- ``service(state)``: after every call of the step loop, which stops early (status
  fe.contact.touch.SERVICE) for a feature that needs Python (a stale candidate list);
- ``memory()`` / ``restore(memory)``: what it carries from step to step beyond the State,
  for the checkpoint (a restart continues it bit for bit); :attr:`Feature.state_fields`
  names the State arrays that hold the rest (the checkpoint's ``/state``);
- ``write(h5)``: its part of the result file at the end (a group, attributes);

and, as every recorder, ``start``, ``rows``, ``frame``, ``checkpoint`` and ``end``. Every
hook defaults to doing nothing. A feature that cannot be continued from a checkpoint says so
with :attr:`Feature.checkpointable` False (``--checkpoint-dt`` is then refused).
"""

from __future__ import annotations

from spinweb_fe.record.recorders import Recorder

#: the hook arguments of fe.step.advance, in their order there (None: the feature is absent)
HOOKS = ("audit", "contact", "tidal")


class Feature(Recorder):
    """An optional part of a run (see the module's text).

    Attributes
    ----------
    name : str
        Its registry name and the key of its memory in a checkpoint.
    hook : str or None
        The argument of fe.step.advance it fills (:data:`HOOKS`), None if its data rides in
        the Model's kernel view.
    layout : tuple of fe.layout.Col
        Its history columns (empty: none, or columns of the step's own tables).
    state_fields : tuple of str
        The State arrays (fe.state.to_arrays names) that hold its state between steps.
    checkpointable : bool
        A checkpoint continues it bit for bit.
    """

    name = ""
    hook = None
    layout = ()
    state_fields = ()
    checkpointable = True

    def prepare(self, state, rows: int) -> None:
        pass

    def kernel(self, hooks: dict):
        return None

    def trial(self, kernel, hooks: dict):
        return kernel

    def columns(self, kernel, rec, nrec: int) -> dict:
        return {}

    def service(self, state) -> None:
        pass

    def write(self, h5) -> None:
        pass


def copied(kernel):
    """A NamedTuple of arrays (and of such tuples) with every array copied (a feature's
    kernel for a trial step)."""
    import numpy as np

    def copy(v):
        if isinstance(v, np.ndarray):
            return v.copy()
        if isinstance(v, tuple) and hasattr(v, "_fields"):
            return copied(v)
        return v

    return type(kernel)(*(copy(v) for v in kernel))
