"""Helpers shared by the subcommands."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_case_args(p: argparse.ArgumentParser, out=True):
    p.add_argument("case", help="case file (TOML, SI units)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a case key, TOML value syntax, e.g. --set time.end=0.5")
    if out:
        p.add_argument("-o", "--output", default=None, metavar="DIR",
                       help="result folder (default: output.directory or out/<case stem>)")


def load_case(args):
    from spinweb_fe import case as case_mod  # numba and the solver: not for the parser

    return case_mod.load(args.case, args.sets)


def out_dir(args, case) -> Path:
    """-o DIR, else output.directory (relative to the case file), else out/<stem>."""
    if getattr(args, "output", None):
        return Path(args.output)
    if case.output.directory:
        return case.resolve_path(case.output.directory)
    return Path("out") / Path(args.case).stem
