"""A seeded generator of hostile input for tests/test_fuzz.py (issue #46, item 6): case,
sweep and design files mutated value by value and byte by byte, and result folders with
entries planted under the names the tool writes.

A file is held as its leaves: {path (tuple of keys; an int for an entry of [[runs]]): TOML
value text}. Mutations replace a leaf by a hostile value, drop one, add an unknown key, or
damage the text (cut it, insert bytes, repeat a line). Every variant is a function of
(seed, index): a failure names both, and ``variant(kind, seed, index)`` rebuilds it.
"""

from __future__ import annotations

import random
import tomllib
from pathlib import Path

from spinweb_fe.case.text import fmt

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "cases"
#: small cases (fast to validate and, for the folder states, to run)
CASE_FILES = ("paper_free_arms.toml", "demo.toml", "paper_brake_arms.toml",
              "paper_feedback_web.toml", "tri_ramp_web.toml", "paper_reel_arms.toml")
DESIGN_FILES = ("fig8_hub.toml", "tethers_feedback.toml", "paper_web_omega.toml")

#: TOML value texts at the edges: numbers huge, tiny, not finite, of the wrong type, strings
#: with control characters, deep arrays, dates, tables where a scalar belongs
HOSTILE = (
    "0", "-1", "0.0", "-0.0", "1e300", "-1e300", "1e-300", "5e-324", "nan", "-nan", "inf",
    "-inf", "1" + "0" * 400, "-1" + "0" * 400, "1" + "0" * 5000, "1" + "0" * 30 + ".5",
    "4.5", "2147483648", "9223372036854775808", "18446744073709551616", "1e9", "1e15",
    '"20"', '""', '"\\u0000"', '"a\\nb"', '"\\u001b[2J"', '"' + "x" * 5000 + '"',
    '"\\u0085"', "true", "false", "[]", "[1.0, 2.0]", "[[0.0, 1.0], [0.5, -1.0]]",
    "[" * 40 + "]" * 40, "[" * 1000 + "]" * 1000, "{}", "{ a = 1 }", "1979-05-27",
    "1979-05-27T07:32:00Z", "07:32:00", '"../../etc/passwd"', '"/dev/null"', "0x7fffffff",
    "1_000_000", "-0x1",
)
#: numbers only: most of them parse, and reach the checks of the values
NUMBERS = tuple(v for v in HOSTILE if v[0] in "-0123456789" and not v.startswith("1979")
                and ":" not in v) + ("1.0", "2.0", "0.5", "1e-6", "100.0", "1e6")
#: entries a result folder may hold that the tool did not make
PLANTS = ("link", "fifo", "folder", "garbage")
NAMES = (".reserve", "run.lock", "checkpoint.h5.tmp", "web.pvd.tmp", "web.pvd", "results.h5",
         "frames", "checkpoint.h5", ".previous", ".previous-dropped",
         "frames/web_000000.vtu", ".previous/MANIFEST", ".previous/results.h5")


def leaves(doc, prefix=()) -> dict:
    """{path: TOML text} of a parsed document (arrays of tables by index)."""
    out = {}
    for key, value in doc.items():
        path = (*prefix, key)
        if isinstance(value, dict):
            out.update(leaves(value, path))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for i, entry in enumerate(value):
                out.update(leaves(entry, (*path, i)))
        else:
            out[path] = fmt(value)
    return out


def _key(parts) -> str:
    return ".".join('"' + str(p).replace("\\", "\\\\").replace('"', '\\"') + '"'
                    for p in parts)


def emit(flat: dict) -> str:
    """TOML text of the leaves: dotted keys, arrays of tables as arrays of inline tables."""
    lines, arrays = [], {}
    for path, text in flat.items():
        at = next((i for i, p in enumerate(path) if isinstance(p, int)), None)
        if at is None:
            lines.append(f"{_key(path)} = {text}")
        else:
            arrays.setdefault(path[:at], {}).setdefault(path[at], []).append(
                f"{_key(path[at + 1:])} = {text}")
    for path, entries in arrays.items():
        body = ", ".join("{ " + ", ".join(items) + " }" for _, items in sorted(entries.items()))
        lines.append(f"{_key(path)} = [{body}]")
    return "\n".join(lines) + "\n"


def mutate(rng: random.Random, flat: dict, extra_paths=()) -> dict:
    """One to three value-level mutations of a file's leaves."""
    flat = dict(flat)
    for _ in range(rng.randint(1, 3)):
        paths = list(flat) or [("title",)]
        op = rng.random()
        path = rng.choice(paths)
        if op < 0.35:  # a number at the edge, where a number is
            flat[path] = rng.choice(NUMBERS)
        elif op < 0.6:
            flat[path] = rng.choice(HOSTILE)
        elif op < 0.72:
            flat.pop(path, None)
        elif op < 0.82:
            flat[(*path[:-1], rng.choice(["radious", "extra", "Side", "é", " ", "a.b"]))] = \
                rng.choice(HOSTILE[:12])
        elif op < 0.9 and extra_paths:
            flat[rng.choice(extra_paths)] = rng.choice(HOSTILE)
        else:  # a value where a table was
            flat = {p: v for p, v in flat.items() if p[:1] != path[:1]}
            flat[path[:1]] = rng.choice(HOSTILE)
    return flat


def damage(rng: random.Random, text: str) -> bytes:
    """A byte-level damage of a file's text (or none, half the time)."""
    data = text.encode()
    op = rng.random()
    if op < 0.65:
        return data
    if op < 0.72:
        return data[:rng.randrange(len(data) + 1)]
    if op < 0.85:
        at = rng.randrange(len(data) + 1)
        return data[:at] + rng.choice([b"\x00", b"\xff\xfe", b"[[", b"=", b'"', b"\r",
                                       b"\n[web]\n", b"\xef\xbb\xbf", b"\\"]) + data[at:]
    if op < 0.9:
        lines = data.splitlines(keepends=True)
        i = rng.randrange(len(lines)) if lines else 0
        return b"".join(lines[:i + 1] + lines[i:])
    return b"\xef\xbb\xbf" + data.replace(b"\n", b"\r\n")


def case_variant(seed: int, index: int) -> tuple:
    """(file bytes, --set arguments) of hostile case ``index``."""
    rng = random.Random(f"case-{seed}-{index}")
    base = CASES / rng.choice(CASE_FILES)
    flat = leaves(tomllib.loads(base.read_text()))
    extra = [("hub", "mass"), ("time", "end"), ("web", "side"), ("tethers", "count"),
             ("output", "history_dt"), ("title",), ("verdict", "energy"), ("stowage", "coil")]
    data = damage(rng, emit(mutate(rng, flat, extra)))
    sets = []
    if rng.random() < 0.2:
        key = ".".join(str(p) for p in rng.choice(list(flat)))
        sets = ["--set", f"{key}={rng.choice(HOSTILE)}"]
    return data, sets


def sweep_variant(seed: int, index: int) -> tuple:
    """(sweep file bytes, extra arguments) of hostile sweep ``index`` (its base a real case)."""
    rng = random.Random(f"sweep-{seed}-{index}")
    base = CASES / rng.choice(CASE_FILES[:2])
    doc = {"title": "fuzz", "base": str(base), "mode": "fe",
           "set": {"time": {"end": 0.01}}, "grid": {"hub": {"mass": [5.0, 10.0]}}}
    if rng.random() < 0.4:
        doc.update(members=3, seed=7, random={"tip_mass.mass": {"dist": "uniform", "low": 0.5,
                                                                 "high": 1.5}})
    if rng.random() < 0.3:
        doc["runs"] = [{"name": "slow", "initial": {"omega": 1.0}}, {"initial": {"omega": 2.0}}]
    extra = [("seed",), ("members",), ("mode",), ("model",), ("grid", "web", "side"),
             ("grid", "tethers", "count"), ("random", "hub.mass", "dist"), ("set", "x"),
             ("runs", 0, "name"), ("base",)]
    flat = leaves(doc)
    if rng.random() < 0.1:  # a grid of a million runs or more
        for key in ("hub.mass", "tip_mass.mass", "cable.damping_ratio"):
            flat[("grid", key)] = "[" + ", ".join(f"{1 + i * 1e-3:.3f}" for i in range(
                rng.choice([100, 1000]))) + "]"
    data = damage(rng, emit(mutate(rng, flat, extra)))
    args = []
    if rng.random() < 0.15:
        args = ["--workers", rng.choice(["0", "-3", "1000000", "2"])]
    return data, args


def design_variant(seed: int, index: int) -> bytes:
    """The bytes of hostile design file ``index`` (its base made absolute)."""
    rng = random.Random(f"design-{seed}-{index}")
    path = CASES / "design" / rng.choice(DESIGN_FILES)
    doc = tomllib.loads(path.read_text())
    doc["base"] = str((path.parent / doc["base"]).resolve())
    extra = [("scan",), ("rtol",), ("search", "control.M0"), ("bounds", "peak_torque"),
             ("require",), ("minimise",), ("law",), ("chart", "fe"), ("maxiter",)]
    return damage(rng, emit(mutate(rng, leaves(doc), extra)))


def folder_variant(seed: int, index: int) -> tuple:
    """([(name, kind), ...] to plant, the command: 'run', 'restart' or 'info') of hostile
    folder state ``index``."""
    rng = random.Random(f"folder-{seed}-{index}")
    plants = [(rng.choice(NAMES), rng.choice(PLANTS)) for _ in range(rng.randint(1, 2))]
    return plants, rng.choice(["run", "run", "restart", "restart", "info"])
