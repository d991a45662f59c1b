"""Named choices of a case and their registries: one :class:`Choice` entry per name holds
what the name means, the case keys it uses (with units and checks), how they are validated,
the code the solver reads, and the analytical model's counterpart where there is one.

The registries: hub control laws (:data:`spinweb_fe.fe.control.LAWS`, :class:`Law` entries
with their own analytical forms), payout devices (:data:`spinweb_fe.fe.coil.payout.PAYOUTS`), the
coil and its bundles (:data:`spinweb_fe.fe.coil.levels.COILS`, :data:`~spinweb_fe.fe.coil.levels.BUNDLES`),
hub motions (:data:`spinweb_fe.fe.model.MOTIONS`) and perturbation shapes
(:data:`spinweb_fe.case.perturb.SHAPES`). The case schema builds its keys from the entries,
the loader validates a table with :func:`validate_choice`, and the solver reads ``code``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Param:
    """One case key of a named choice: name, SI unit, check ('finite', 'nonzero', 'pos',
    'nonneg', 'frac', or None), doc; ``kind`` as in the case schema ('float', 'int',
    'table'); ``default``: the value it takes when not given (a key at its default counts
    as not given)."""

    name: str
    unit: str
    check: str | None
    doc: str
    kind: str = "float"
    default: object = None


@dataclass(frozen=True)
class Choice:
    """One name of a named choice.

    Attributes
    ----------
    name : str
        The value of the choosing key.
    code : int
        What the solver reads for it (a kernel branch, a builder's switch).
    doc : str
    keys : tuple of Param
        The keys that belong to it (given with another name, they are refused).
    need : tuple of tuple of str
        Groups of its keys of which exactly one must be given.
    check : callable(tables: dict) -> (dotted key, reason) or None
        Further rules on the case's resolved tables ({table: {key: value}}; None: every
        value passes).
    analytic : str
        What the analytical model does with it ('' : it has no counterpart there).
    """

    name: str
    code: int
    doc: str
    keys: tuple = ()
    need: tuple = ()
    check: Callable | None = None
    analytic: str = ""


def registry(*choices) -> dict:
    """{name: Choice} of the entries, in order; codes and names must be unique."""
    out = {c.name: c for c in choices}
    if len(out) != len(choices) or len({c.code for c in choices}) != len(choices):
        raise ValueError("a registry's names and codes must be unique")
    return out


def registry_keys(reg: dict) -> dict:
    """{key name: Param} of every key of a registry's entries (a key several entries use
    with other units gets them joined: '1 or s')."""
    out = {}
    for choice in reg.values():
        for p in choice.keys:
            if p.name not in out:
                out[p.name] = p
            elif p.unit not in out[p.name].unit.split(" or "):
                out[p.name] = dataclasses.replace(out[p.name],
                                                  unit=f"{out[p.name].unit} or {p.unit}")
    return out


def _given(p: Param, values: dict) -> bool:
    v = values.get(p.name)
    return v is not None and v != p.default


def validate_choice(reg: dict, table: str, choosing: str, tables: dict):
    """The first problem of the case's resolved ``tables`` ({table: {key: value}}, None: not
    given) for the entry of ``reg`` that ``tables[table][choosing]`` names, as (dotted key,
    reason), or None: a key of another entry given, a needed key missing or given twice,
    the entry's own check."""
    values = tables[table]
    chosen = reg[values[choosing]]
    mine = {p.name for p in chosen.keys}
    for key, p in registry_keys(reg).items():
        if key not in mine and _given(p, values):
            users = [c.name for c in reg.values() if key in {q.name for q in c.keys}]
            return f"{table}.{key}", (f"used only with {table}.{choosing} = "
                                      + " or ".join(f"'{u}'" for u in users))
    params = {p.name: p for p in chosen.keys}
    for group in chosen.need:
        given = [k for k in group if _given(params[k], values)]
        dotted = [f"{table}.{k}" for k in group]
        if not given:
            alt = f" (or give {' or '.join(dotted[1:])})" if len(group) > 1 else ""
            return dotted[0], f"required by {table}.{choosing} = '{chosen.name}'{alt}"
        if len(given) > 1:
            return f"{table}.{given[-1]}", f"give either {' or '.join(dotted)}, not both"
    return chosen.check(tables) if chosen.check is not None else None
