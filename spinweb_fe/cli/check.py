"""``spinweb check CASE``: validate a case and print it with every default filled in."""

from spinweb_fe.cli.common import add_case_args, load_case


def add_parser(sub):
    p = sub.add_parser("check", help="validate a case and print the resolved case",
                       description=__doc__)
    add_case_args(p, out=False)
    return p


def run(args) -> int:
    case = load_case(args)
    print(case.to_toml(), end="")
    return 0
