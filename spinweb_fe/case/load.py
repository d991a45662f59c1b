"""Case files: TOML -> validated, frozen dataclasses.

All defaults live in :data:`spinweb_fe.case.schema.SCHEMA` and nowhere else. Every physical
value is in SI units. Unknown keys and missing required keys raise :class:`InputError`
naming the file, the dotted key and the reason (the CLI turns that into exit code 2).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from spinweb_fe.case.rules import cross_check
from spinweb_fe.case.schema import REQUIRED, SCHEMA, TOP_KEYS, Field
from spinweb_fe.case.text import (MAX_DEPTH, check_text, depth, dumps_toml, parse_toml,
                                  read_toml, show)
from spinweb_fe.errors import InputError

def _table_class(name, fields):
    cls = dataclasses.make_dataclass(
        name.capitalize() + "Config",
        [(k, Any, dataclasses.field(default=None)) for k in fields],
        frozen=True)
    cls.__doc__ = f"The [{name}] table (SI units)."
    return cls


TABLE_CLASSES = {name: _table_class(name, fields) for name, fields in SCHEMA.items()}


@dataclass(frozen=True)
class Case:
    """A validated case. ``web`` or ``tethers`` is None (exactly one is set).

    ``source`` is the case file path (or '<string>'); ``raw`` is the resolved nested dict.
    """

    title: str
    web: Any
    tethers: Any
    cable: Any
    tip_mass: Any
    hub: Any
    fold: Any
    stowage: Any
    initial: Any
    control: Any
    time: Any
    output: Any
    source: str = "<string>"
    perturbation: Any = None
    environment: Any = None
    verdict: Any = None
    audit: Any = None
    contact: Any = None

    @property
    def scene(self) -> str:
        """'web' or 'tethers'."""
        return "web" if self.web is not None else "tethers"

    @property
    def folder(self) -> Path:
        return Path(self.source).parent if self.source != "<string>" else Path.cwd()

    def resolve_path(self, p) -> Path:
        """A path from the case, relative to the case file's folder."""
        p = Path(p)
        return p if p.is_absolute() else self.folder / p

    def to_dict(self) -> dict:
        out = {"title": self.title}
        for name in SCHEMA:
            tbl = getattr(self, name)
            values = {} if tbl is None else {k: v for k, v in dataclasses.asdict(tbl).items()
                                             if v is not None}
            if values:
                out[name] = values
        return out

    def to_toml(self) -> str:
        return dumps_toml(self.to_dict())


MAX_INT = 2 ** 53  # integers beyond are not exact as floats (sizes are checked as floats)
MAX_TEXT = 4096  # characters of a string


def _suggest(key, valid):
    near = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.5)
    return f" (did you mean '{near[0]}'?)" if near else f" (valid: {', '.join(sorted(valid))})"


def _coerce(src, dotted, field: Field, value):
    kind = field.kind
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(src, dotted, f"expected a number, got {type(value).__name__} "
                             f"{show(value)}")
        try:
            value = float(value)
        except OverflowError:  # an integer beyond the floats (10^309 and up)
            raise InputError(src, dotted, f"must be finite, got {show(value)} (beyond the "
                             "largest float, 1.8e308)") from None
        if not math.isfinite(value):
            raise InputError(src, dotted, f"must be finite, got {value}")
    elif kind == "int":
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(src, dotted, f"expected an integer, got {show(value)}")
        if abs(value) > MAX_INT:
            raise InputError(src, dotted, f"{show(value)} is beyond the integers a run can "
                             f"hold (|n| < 2^53)")
    elif kind == "str":
        if not isinstance(value, str):
            raise InputError(src, dotted, f"expected a string, got {show(value)}")
        if not isinstance(field.check, tuple):  # free text (a choice names its values)
            check_text(src, dotted, value, MAX_TEXT)
    elif kind == "bool":
        if not isinstance(value, bool):
            raise InputError(src, dotted, f"expected true or false, got {show(value)}")
    elif kind == "table":
        return _table(src, dotted, value)
    elif kind == "vector":
        return _vector(src, dotted, field, value)
    elif kind == "names":
        if not (isinstance(value, list) and value and all(isinstance(x, str) for x in value)):
            raise InputError(src, dotted, f"expected a non-empty list of names, got {value!r}")
        one = Field("str", check=field.check)
        return tuple(_coerce(src, dotted, one, x) for x in value)
    chk = field.check
    if isinstance(chk, tuple):
        if value not in chk:
            raise InputError(src, dotted, f"unknown value {show(value)}{_suggest(value, chk)}")
    elif chk == "pos" and not value > 0:
        raise InputError(src, dotted, f"must be > 0 ({field.unit or 'dimensionless'}), got {value}")
    elif chk == "nonneg" and not value >= 0:
        raise InputError(src, dotted, f"must be >= 0, got {value}")
    elif chk == "frac" and not 0 < value <= 1:
        raise InputError(src, dotted, f"must be in (0, 1], got {value}")
    elif chk == "nonzero" and value == 0:
        raise InputError(src, dotted, "must not be zero")
    return value


def _vector(src, dotted, field, value):
    """A list of three finite numbers, each passing the field's check -> tuple of floats."""
    if not (isinstance(value, list) and len(value) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)):
        raise InputError(src, dotted, f"expected a list of three numbers, got {show(value)}")
    one = Field("float", check=field.check, unit=field.unit)
    return tuple(_coerce(src, dotted, one, x) for x in value)


def _table(src, dotted, value):
    """A list of [t, value] pairs of finite numbers -> tuple of (float, float)."""
    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
    if not (isinstance(value, list) and value and all(
            isinstance(p, list) and len(p) == 2 and all(number(x) for x in p) for p in value)):
        raise InputError(src, dotted, f"expected a list of [t, value] pairs of numbers, "
                         f"got {show(value)}")
    return tuple((float(a), float(b)) for a, b in value)


def validate(raw: dict, source: str = "<string>") -> Case:
    """Check a nested dict against SCHEMA and the cross-key rules; return a Case."""
    src = str(source)
    if not isinstance(raw, dict):
        raise InputError(src, "", "the case must be a TOML table")
    valid_top = set(SCHEMA) | set(TOP_KEYS)
    for key in raw:
        if key not in valid_top:
            raise InputError(src, key, f"unknown key{_suggest(key, valid_top)}")
    scenes = [s for s in ("web", "tethers") if s in raw]
    if len(scenes) != 1:
        why = "both [web] and [tethers] given" if scenes else "neither [web] nor [tethers] given"
        raise InputError(src, "web|tethers", f"exactly one scene table is needed: {why}")
    scene = scenes[0]
    title = _coerce(src, "title", TOP_KEYS["title"], raw.get("title", ""))
    tables = {}
    for name, fields in SCHEMA.items():
        given = raw.get(name)
        if given is None:
            if name in ("web", "tethers"):
                tables[name] = None
                continue
            given = {}
        if not isinstance(given, dict):
            raise InputError(src, name, f"must be a table [{name}], got {show(given)}")
        for key in given:
            if key not in fields:
                raise InputError(src, f"{name}.{key}", f"unknown key{_suggest(key, fields)}")
        values = {}
        for key, field in fields.items():
            dotted = f"{name}.{key}"
            if key in given:
                values[key] = _coerce(src, dotted, field, given[key])
            elif field.default is REQUIRED:
                raise InputError(src, dotted, "missing required key")
            else:
                values[key] = field.default
        tables[name] = values
    cross_check(src, scene, raw, tables)
    kwargs = {n: (None if v is None else TABLE_CLASSES[n](**v)) for n, v in tables.items()}
    return Case(title=title, source=src, **kwargs)


def parse_set(arg: str) -> tuple[list[str], Any]:
    """Parse one ``--set a.b=value`` override; the value uses TOML syntax (bare words are strings)."""
    if "=" not in arg:
        raise InputError("--set", arg, "expected key=value")
    key, text = arg.split("=", 1)
    key = key.strip()
    parts = key.split(".")
    if not key or any(not p for p in parts):
        raise InputError("--set", key, "empty key")
    try:
        value = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = text.strip()
    except (ValueError, RecursionError):  # 5000 digits; arrays nested past the recursion
        raise InputError("--set", key, "not a readable value (an integer of more than 4300 "
                         "digits, or arrays nested too deep)") from None
    if depth(value) > MAX_DEPTH:
        raise InputError("--set", key, f"arrays nested more than {MAX_DEPTH} levels deep")
    return parts, value


def apply_overrides(raw: dict, sets) -> dict:
    for arg in sets or ():
        parts, value = parse_set(arg)
        node = raw
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise InputError("--set", arg, f"'{p}' is not a table")
        node[parts[-1]] = value
    return raw


def load(path, sets=()) -> Case:
    """Read, override and validate a case file.

    Parameters
    ----------
    path : str or Path
        TOML case file.
    sets : iterable of str
        ``key=value`` overrides (TOML value syntax), applied before validation.
    """
    path = Path(path)
    raw = read_toml(path, "case file", missing="no such file")
    raw = apply_overrides(raw, sets)
    return validate(raw, str(path))


def loads(text: str, sets=()) -> Case:
    """Validate a case given as TOML text (tests, notebooks)."""
    return validate(apply_overrides(parse_toml(text, "<string>"), sets))
