"""TOML text in and out: every way a file can be unreadable is one InputError, and the
resolved case is written so that it reads back (docs/robustness.md, "Bad input").

:func:`parse_toml` turns what ``tomllib`` raises besides its syntax errors into a reason:
an integer of more than 4300 digits (Python's limit on reading one: ValueError), arrays or
tables nested deeper than Python's recursion (RecursionError), and refuses a document nested
deeper than :data:`MAX_DEPTH` levels (no case, sweep or design file has more than four).
:func:`dumps_toml` escapes control characters, so a stored case always parses again.
:func:`show` keeps a value in a message short.
"""

from __future__ import annotations

import math
import stat
import tomllib
from pathlib import Path

from spinweb_fe.errors import InputError

MAX_DEPTH = 16  # tables and arrays in one another
SHOW = 60  # characters of a value quoted in a message


def show(value, width: int = SHOW) -> str:
    """``repr(value)``, cut to ``width`` characters (a 400-digit number, a long list)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10 ** 24:
        return f"an integer of {len(str(abs(value)))} digits"
    text = repr(value)
    return text if len(text) <= width else text[:width - 4] + " ..."


def check_text(source, key, value: str, limit: int = 4096) -> str:
    """``value`` if it is printable text of at most ``limit`` characters, else InputError
    (control characters would break the one-line messages, the stored case, HDF5's strings
    and file names)."""
    bad = next((ch for ch in value if ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0), None)
    if bad is not None:
        raise InputError(source, key, f"contains the control character {bad!r}: give "
                         "printable text")
    if len(value) > limit:
        raise InputError(source, key, f"is {len(value)} characters long (at most {limit})")
    return value


def base_path(source, doc: dict, what: str) -> Path:
    """The base case of a sweep or design file (``base``, relative to ``source``)."""
    value = doc.get("base")
    if not isinstance(value, str):
        raise InputError(source, "base", f"missing: the base case file, relative to the "
                         f"{what} file")
    try:
        return (Path(source).parent / check_text(source, "base", value)).resolve()
    except (OSError, RuntimeError) as exc:  # a loop of links
        raise InputError(source, "base", f"cannot be resolved ({exc})") from None


def depth(doc) -> int:
    """Levels of tables and arrays in ``doc`` (a scalar: 0), without recursion."""
    deepest, todo = 0, [(doc, 0)]
    while todo:
        node, level = todo.pop()
        if isinstance(node, dict):
            todo += [(v, level + 1) for v in node.values()]
        elif isinstance(node, list):
            todo += [(v, level + 1) for v in node]
        else:
            continue
        deepest = max(deepest, level + 1)
    return deepest


def parse_toml(text: str, source) -> dict:
    """``tomllib.loads(text)``, every failure an InputError of ``source`` (the whole file)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(source, "", f"TOML syntax error: {exc}") from None
    except ValueError as exc:  # int("1" * 5000): Python's limit on reading an integer
        why = "an integer of more than 4300 digits" if "digits" in str(exc) else str(exc)
        raise InputError(source, "", f"not readable: {why}") from None
    except RecursionError:
        raise InputError(source, "", f"arrays or tables nested too deep to read (at most "
                         f"{MAX_DEPTH} levels)") from None
    if (levels := depth(doc)) > MAX_DEPTH:
        raise InputError(source, "", f"arrays or tables nested {levels} levels deep (at most "
                         f"{MAX_DEPTH})")
    return doc


def read_toml(path, what: str = "file", missing: str | None = None) -> dict:
    """Read and parse a TOML file (UTF-8, a byte-order mark accepted); a missing (the
    reason ``missing``, default 'no such WHAT'), empty, unreadable or non-UTF-8 file is an
    InputError."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(path, "", missing or f"no such {what}") from None
    except (OSError, ValueError) as exc:  # a name too long or with a NUL, a loop of links
        raise InputError(path, "", f"cannot be read ({getattr(exc, 'strerror', None) or exc})") \
            from None
    if stat.S_ISDIR(mode):
        raise InputError(path, "", f"is a folder, not a {what}")
    if not stat.S_ISREG(mode):
        raise InputError(path, "", f"is not a regular file (a FIFO or a device), not a {what}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(path, "", f"cannot read the file ({exc.strerror})") from None
    if not data.strip():
        raise InputError(path, "", "the file is empty")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, "", "not UTF-8 text") from None
    return parse_toml(text, path)


def _string(v: str) -> str:
    out = []
    for ch in v:
        if ch in '\\"':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def fmt(v) -> str:
    """One TOML value."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if v != v else ("inf" if v > 0 else "-inf"))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    return repr(v)


def dumps_toml(d: dict) -> str:
    """Serialise a two-level dict of scalars as TOML text."""
    lines = [f"{k} = {fmt(v)}" for k, v in d.items() if not isinstance(v, dict)]
    for k, v in d.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{kk} = {fmt(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"
