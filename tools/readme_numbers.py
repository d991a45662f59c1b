"""The README's tables of the paper's runs, regenerated: each case run to its end on one
thread, its size, time, balances and verdict written to
benchmarks/results/readme_numbers.json (with the date, the CPU and its ISA, the load) and
the two tables printed, or patched into README.md between their markers.

    python -m tools.readme_numbers [--cases NAME ...] [--patch] [--from-json]

``--from-json`` makes the tables from the JSON without running anything; ``--cases`` runs
some cases again and keeps the others' rows. Run it on a quiet machine (``nice`` on a
shared one: its wall times are then upper bounds, the load is recorded with each row).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import tempfile
import time
from pathlib import Path

import h5py

from benchmarks.common import machine
from benchmarks.paper_runs import errors
from spinweb_fe import case as case_mod
from spinweb_fe.record import verdict
from spinweb_fe.run.driver import run_case

ROOT = Path(__file__).resolve().parent.parent
JSON = ROOT / "benchmarks" / "results" / "readme_numbers.json"
README = ROOT / "README.md"
#: the paper-run table's rows, in order (name -> label)
RUNS = {"paper_free_arms": "paper_free_arms", "paper_free_arms_eq7": "paper_free_arms_eq7",
        "paper_free_web": "paper_free_web", "paper_two_stage_web": "paper_two_stage_web",
        "paper_payout_web": "paper_payout_web (reel)", "paper_reel_arms": "paper_reel_arms",
        "paper_brake_arms": "paper_brake_arms", "paper_brake_web": "paper_brake_web",
        "paper_feedback_web": "paper_feedback_web", "paper_ramp_web": "paper_ramp_web",
        "tri_ramp_web": "tri_ramp_web (3 arms)",
        "paper_free_arms_stiff": "paper_free_arms_stiff",
        "paper_free_arms_eq7_stiff": "paper_free_arms_eq7_stiff",
        "paper_free_web_stiff": "paper_free_web_stiff",
        "paper_feedback_web_stiff": "paper_feedback_web_stiff",
        "paper_ramp_web_stiff": "paper_ramp_web_stiff"}
#: the verdict table's rows (the stiff cases' verdicts are the same questions again)
VERDICTS = [n for n in RUNS if not n.endswith("_stiff")] + ["demo"]
MARK = "<!-- readme_numbers: {} -->"
END = "<!-- /readme_numbers -->"


def run_one(name: str, out: Path) -> dict:
    """Run ``cases/NAME.toml`` to its end on one thread (results and frames written; the
    step loop compiled first by a run of two steps, so the wall time is the run's) and
    return its row."""
    src = ROOT / "cases" / f"{name}.toml"
    case = case_mod.load(src)
    warm = case_mod.load(src, ["time.end=1e-7", "output.history_dt=1e-7", "output.frame_dt=0"])
    run_case(warm, out / f"{name}_warm", progress=False, threads=1)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    res = run_case(case, out / name, progress=False, threads=1)
    wall = time.perf_counter() - t0
    h = res.history
    e_err, k_err = errors(h)
    with h5py.File(out / name / "results.h5") as f:
        crits = verdict.read_group(f)
        elements = int(f["mesh/elements"].shape[0])
    return {"title": case.title, "end_s": case.time.end, "elements": elements,
            "steps": res.steps, "wall_s": wall, "loop_s": res.loop_s,
            "energy_error": e_err, "angular_momentum_error": k_err,
            "controlled": case.control.law != "free",
            "contact_share_of_KE0": float(h["contact_dissipation"][-1]
                                          / max(h["kinetic_energy"][0], 1e-30)),
            "verdict": "pass" if verdict.passed(crits) else "fail",
            "criteria": [{"name": c.name, "passed": c.passed, "value": c.value,
                          "limit": c.limit, "units": c.units, "time": c.time, "arm": c.arm,
                          "detail": c.detail, "required": getattr(c, "required", True)}
                         for c in crits],
            "load_1min": [load0, os.getloadavg()[0]], "date": time.strftime("%Y-%m-%d")}


def _g(x, digits=2) -> str:
    """Two significant digits, kept: '0.30', '1.0', '86', '1.8e-13' (no '+' or leading
    zero in the exponent); from 100 on, whole numbers."""
    if abs(x) >= 100:
        return f"{x:.0f}"
    s = f"{x:#.{digits}g}".rstrip(".")
    s = s.replace(".e", "e")
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m[1] == "-" else "") + m[2], s)


def _e(x) -> str:
    """'3.0e-3', '1.8e-13': two significant digits in scientific notation."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m[1] == "-" else "") + m[2],
                  f"{x:.1e}")


def _pct(x) -> str:
    return "0 %" if x == 0 else f"{_g(100 * x)} %"


def _int(n) -> str:
    """'3 220' for 3220."""
    return f"{n:,}".replace(",", " ")


def _steps(n) -> str:
    return f"{n / 1e6:.3g} M" if n >= 1e6 else _int(n)


def _wall(s) -> str:
    return _g(s) if s < 10 else f"{s:.0f}"


def run_table(rows: dict) -> list:
    """The paper-run table's lines."""
    out = ["| case | simulated | elements | steps | wall [s] | energy error | angular "
           "momentum | contact |", "|---|---|---|---|---|---|---|---|"]
    for name, label in RUNS.items():
        r = rows.get(name)
        if r is None:
            continue
        contact = "-" if r["controlled"] else _pct(r["contact_share_of_KE0"])
        out.append(f"| {label} | {r['end_s']:g} s | {_int(r['elements'])} | "
                   f"{_steps(r['steps'])} | {_wall(r['wall_s'])} | {_pct(r['energy_error'])} | "
                   f"{_e(r['angular_momentum_error'])} | {contact} |")
    return out


def _what(r) -> str:
    """The verdict table's last column: each failed criterion with its value against its
    limit and what it says (one the verdict does not require marked so); for a run that
    deploys, when it was out for good, its swing and slack."""
    crits = {c["name"]: c for c in r["criteria"]}
    bad = [c for c in r["criteria"] if c["passed"] is False]
    if not [c for c in bad if c.get("required", True)]:
        dep, swing = crits["deployed"], crits.get("swing", {})
        when = re.search(r"out for good from t = ([0-9.]+) s", dep["detail"])
        text = f"- (out for good from {float(when[1]):.3g} s" if when else "- ("
        if swing.get("passed"):
            text += f"; swing {_g(swing['value'])} rad"
        if crits.get("overstrain", {}).get("passed"):
            text += f"; utilisation {_g(crits['overstrain']['value'])}"
        slack = crits["slack"]
        note = ", not required" if slack["passed"] is False else ""
        return text + f"; slack {_g(slack['value'])}{note})"
    parts = []
    for c in bad:
        unit = "" if c["units"] == "1" else f" {c['units']}"
        extra = "" if c.get("required", True) else ", not required"
        text = f"{c['name']} {_g(c['value'])}{unit} (limit {c['limit']:g}{unit}{extra})"
        back = re.search(r"fell back ([0-9.e+]+) m", c["detail"])
        if c["name"] == "recoil" and back:
            text += f": a tip {float(back[1]):.3g} m back"
        if c["name"] == "overstrain" and c["time"] == c["time"]:
            text += f" from {c['time']:.2g} s"
        parts.append(text)
    return ", ".join(parts)


def verdict_table(rows: dict) -> list:
    out = ["| case | verdict | what fails |", "|---|---|---|"]
    for name in VERDICTS:
        r = rows.get(name)
        if r is not None:
            word = "**deploys**" if r["verdict"] == "pass" else "fails"
            out.append(f"| {RUNS.get(name, name)} | {word} | {_what(r)} |")
    return out


def stamp(doc: dict) -> str:
    """The line that says where and when the tables were measured."""
    m = doc["machine"]
    rows = [r for r in doc["cases"].values()]
    dates = sorted({r["date"] for r in rows})
    loads = [x for r in rows for x in r["load_1min"]]
    return (f"*`python -m tools.readme_numbers`, {' to '.join(dict.fromkeys([dates[0], dates[-1]]))}"
            f": {m['processor']} (family/model {m['cpu_family_model']}, {m['isa'].upper()}), "
            f"{m['cores']} cores, numba {m['numba']}; one thread, results and frames written; "
            f"load {min(loads):.1f}-{max(loads):.1f} (a shared machine: wall times are upper "
            "bounds); benchmarks/results/readme_numbers.json.*")


def patch(text: str, key: str, lines: list) -> str:
    """``text`` with the block between MARK(key) and END replaced by ``lines``."""
    start = text.index(MARK.format(key))
    stop = text.index(END, start)
    return text[:start] + MARK.format(key) + "\n" + "\n".join(lines) + "\n" + text[stop:]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=None, help="run these again (default: all)")
    ap.add_argument("--from-json", action="store_true", help="tables from the JSON only")
    ap.add_argument("--patch", action="store_true", help="write the tables into README.md")
    ap.add_argument("--out", default=None, help="result folders (default: a temporary one)")
    args = ap.parse_args(argv)
    doc = json.loads(JSON.read_text()) if JSON.exists() else {"cases": {}}
    if not args.from_json:
        names = args.cases or list(dict.fromkeys([*RUNS, *VERDICTS]))
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(args.out or tmp)
            doc["machine"] = machine()
            for name in names:
                doc["cases"][name] = row = run_one(name, out)
                print(f"{name}: {row['verdict']}, {row['wall_s']:.3g} s", flush=True)
                JSON.write_text(json.dumps(doc, indent=1))
    tables = {"runs": [stamp(doc), "", *run_table(doc["cases"])],
              "verdicts": [stamp(doc), "", *verdict_table(doc["cases"])]}
    for lines in tables.values():
        print("\n".join(lines) + "\n")
    if args.patch:
        text = README.read_text()
        for key, lines in tables.items():
            text = patch(text, key, lines)
        README.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
