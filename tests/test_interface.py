"""docs/interface.md is the project's description of its interface: every command, case key
and history dataset of the code is listed there, and nothing that the code does not have."""

import re
from pathlib import Path

from spinweb_fe.case.schema import SCHEMA, TOP_KEYS
from spinweb_fe.cli import COMMANDS, build_parser
from spinweb_fe.record.history import COLUMNS

DOC = (Path(__file__).resolve().parents[1] / "docs" / "interface.md").read_text()


def section(title):
    start = DOC.index(f"## {title}")
    end = DOC.find("\n## ", start + 1)
    return DOC[start:end if end > 0 else None]


def first_cells(text):
    """The first cell of every table row: `name` or `spinweb cmd ...`."""
    return [m.group(1) for m in re.finditer(r"^\| `([^`]+)`", text, re.M)]


def test_every_case_key_is_documented_and_nothing_else():
    documented = set(first_cells(section("Case file")))
    code = {f"{t}.{k}" for t, fields in SCHEMA.items() for k in fields} | set(TOP_KEYS)
    assert documented == code, (sorted(code - documented), sorted(documented - code))


def test_every_command_is_documented_and_exists():
    rows = first_cells(section("Command line"))
    documented = {r.split()[1] for r in rows}
    assert documented == set(COMMANDS)
    parser = build_parser()  # each documented option exists on its command
    sub = next(a for a in parser._actions if a.dest == "command")
    for r in rows:
        name = r.split()[1]
        options = set(sub.choices[name]._option_string_actions)
        for opt in re.findall(r"(--[a-z-]+|-o)\b", r):
            assert opt in options, (name, opt)


def test_every_history_dataset_is_documented_with_its_units():
    rows = re.findall(r"^\| `(\w+)` \| \((T,?n?,?[34]?)\) \| ([^|]+) \|", section("`results.h5`"),
                      re.M)
    assert {name: units.strip() for name, _, units in rows} == \
        {name: c.units for name, c in COLUMNS.items()}
