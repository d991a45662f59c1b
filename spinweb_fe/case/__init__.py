"""Case files: the schema, loading and validation (TOML -> Case), and the scene of a run."""

from spinweb_fe.case.load import Case, apply_overrides, dumps_toml, load, loads, parse_set, validate

__all__ = ["Case", "apply_overrides", "dumps_toml", "load", "loads", "parse_set", "validate"]
