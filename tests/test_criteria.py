"""The registries of verdict criteria (record/criteria.py) and run metrics
(record/metrics.py) are the only place either is defined: the judge, the case schema,
``spinweb info``, the sweeps and design read them, the docs' tables are copies of them, and
no other module spells their lists out again."""

import ast
import math
from pathlib import Path

import numpy as np

from spinweb_fe.case.schema import SCHEMA
from spinweb_fe.cli import main
from spinweb_fe.record import criteria, metrics, verdict
from spinweb_fe.sweep import design, run

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "spinweb_fe"


def test_docs_tables_are_the_registries():
    text = (ROOT / "docs" / "design.md").read_text()
    assert criteria.markdown() in text
    assert metrics.markdown() in text


def test_the_schema_judge_sweep_and_design_read_the_registries():
    assert set(SCHEMA["verdict"]) == set(criteria.LIMITS)
    for key, lim in criteria.LIMITS.items():
        f = SCHEMA["verdict"][key]
        assert (f.kind, f.default, f.unit) == (lim.kind, lim.default, lim.unit)
    assert verdict.DEFAULTS is criteria.DEFAULTS and verdict.CRITERIA is criteria.CRITERIA
    every = {c.limit for c in criteria.CRITERIA.values() if c.limit}
    assert every <= set(criteria.LIMITS)
    cols = [c for c, _, _ in run.METRICS]
    assert cols[:len(metrics.METRICS)] == [m.column for m in metrics.METRICS.values()]
    assert design.OBJECTIVES is metrics.OBJECTIVES and design.BOUNDS is metrics.BOUNDS
    # the judge reports every criterion of the registry, in its order
    t = np.linspace(0.0, 1.0, 11)
    h = {"time": t, "arm_length": np.full((11, 2), 5.0), "arm_angle": np.zeros((11, 2)),
         "hub_torque": np.zeros(11), "hub_omega": np.ones(11), "hub_angle": t,
         "angular_momentum": np.ones(11), "kinetic_energy": np.ones(11),
         "strain_energy": np.zeros(11), "torque_work": np.zeros(11),
         "damping_dissipation": np.zeros(11), "contact_dissipation": np.zeros(11)}
    crits = verdict.judge(h, 6.0, 1.0)
    assert [c.name for c in crits] == list(criteria.CRITERIA)


def _literal_names(node):
    """The string constants of a list, tuple, set or dict-keys literal."""
    if isinstance(node, (ast.List, ast.Tuple, ast.Set)):
        items = node.elts
    elif isinstance(node, ast.Dict):
        items = [k for k in node.keys if k is not None]
    else:
        return set()
    return {e.value for e in items if isinstance(e, ast.Constant) and isinstance(e.value, str)}


def test_no_module_spells_the_registries_out_again():
    """A literal collection naming three or more criteria, limit keys or metrics outside the
    registries would be a second definition (the three tables and two deployment times of
    issue #41)."""
    groups = {"criteria": set(criteria.CRITERIA), "limits": set(criteria.DEFAULTS),
              "metrics": set(metrics.METRICS),
              "columns": {m.column for m in metrics.METRICS.values()}}
    own = {PACKAGE / "record" / "criteria.py", PACKAGE / "record" / "metrics.py"}
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path in own:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = _literal_names(node)
            for what, reg in groups.items():
                if len(names & reg) >= 3:
                    found.append((path.relative_to(ROOT), node.lineno, what))
    assert not found, found


def test_required_criteria_decide_the_overall_verdict():
    """[verdict] require: a criterion not asked for is judged and reported, but does not
    fail the run; the result file keeps which were required."""
    t = np.linspace(0.0, 1.0, 11)
    h = {"time": t, "arm_length": np.full((11, 2), 1.0), "arm_angle": np.zeros((11, 2)),
         "hub_torque": np.zeros(11), "hub_omega": np.ones(11), "hub_angle": t,
         "angular_momentum": np.ones(11), "kinetic_energy": np.ones(11),
         "strain_energy": np.zeros(11), "torque_work": np.zeros(11),
         "damping_dissipation": np.zeros(11), "contact_dissipation": np.zeros(11)}
    every = verdict.judge(h, 6.0, 1.0)
    assert not verdict.passed(every) and verdict.failed_names(every) == ["deployed"]
    some = verdict.judge(h, 6.0, 1.0, require=("completed", "recoil", "energy"))
    assert verdict.passed(some) and verdict.failed_names(some) == []
    assert "not required: deployed" in verdict.report(some)[0]
    stopped = verdict.judge(h, 6.0, 1.0, status="stopped: x", t_end=4.0)
    assert stopped[0].value == 0.25  # the share of the run done: a design's margin -0.75
    assert math.isclose(design._margin(stopped[0]), -0.75)


def test_info_lists_the_registries(capsys):
    assert main(["info", "--criteria"]) == 0
    out = capsys.readouterr().out
    for name in [*criteria.CRITERIA, *metrics.METRICS]:
        assert f"  {name}" in out
