"""The ``spinweb`` command line: one module per subcommand, ``main(argv) -> int``.

Each subcommand module defines ``add_parser(subparsers)`` (cheap: no heavy imports) and
``run(args) -> int``. Exit codes follow docs/interface.md: 0 success, 2 invalid input (one
line naming file, key and reason), 1 run-time failure (time and cause).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import signal
import sys
import threading
import warnings

import spinweb_fe
from spinweb_fe import __version__
from spinweb_fe.cli import environ
from spinweb_fe.errors import InputError, RunError, RunInterrupted

COMMANDS = ("run", "check", "mesh", "analytic", "plot", "prestress", "modes", "info", "render",
            "sweep", "design", "converge")
log = logging.getLogger(__name__)


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows an option's default unless its help already says it (or it has none)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "default" in text.lower() or action.default in (None, False, [], argparse.SUPPRESS):
            return text
        return super()._get_help_string(action)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors: one line, exit 2
        raise InputError(self.prog, "", message)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="spinweb", description=spinweb_fe.__doc__.strip() + " One "
                     "subcommand per task; docs/interface.md lists them all.",
                     formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"spinweb {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMANDS:
        mod = importlib.import_module(f"spinweb_fe.cli.{name}")
        p = mod.add_parser(sub)
        p.formatter_class = HelpFormatter
        p.set_defaults(_run=mod.run)
    return parser


def _one_line(text) -> str:
    """The message on one line: control characters (newlines from a key or value, and the
    line breaks of str.splitlines: NEL, LS, PS) escaped."""
    return re.sub(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]", lambda m: repr(m.group())[1:-1],
                  str(text))


def _terminated(signum, frame):  # SIGTERM before a run installs its own handler
    raise RunInterrupted("SIGTERM", None)


def main(argv=None) -> int:
    """Run the CLI; returns the exit code instead of exiting."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminated) if main_thread else None
    shown, warnings.showwarning = warnings.showwarning, environ.show_warning
    try:
        return _main(argv)
    finally:
        warnings.showwarning = shown
        if main_thread:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _main(argv) -> int:
    command = "spinweb"
    try:
        args = build_parser().parse_args(argv)
        command = args.command
        logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                            format="%(message)s", stream=sys.stderr, force=True)
        if not args.verbose:  # other libraries' messages: one line each
            for handler in logging.getLogger().handlers:
                handler.addFilter(environ.OneLine())
        environ.check_environment(command)
        return int(args._run(args) or 0)
    except InputError as exc:
        print(f"spinweb: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # --help / --version
        return int(exc.code or 0)
    except RunError as exc:  # RunInterrupted (a signal) carries ``signame``
        what = "" if getattr(exc, "signame", None) else f"{command} failed: "
        print(f"spinweb: {what}{_one_line(exc)}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader of stdout went away (`| head`): nothing to report
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # stdout without a file descriptor (a test's capture)
            pass
        return 1
    except OSError as exc:
        print(f"spinweb: {command} failed: I/O error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # SIGINT outside the step loop (start-up, reading files)
        print("spinweb: interrupted by SIGINT", file=sys.stderr)
        return 1
    except MemoryError:
        print(f"spinweb: {command} failed: out of memory", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - a bug: one line, the traceback with -v
        log.debug("traceback:", exc_info=True)
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        print(f"spinweb: {command} failed: internal error: {type(exc).__name__}"
              f"{': ' if text else ''}{_one_line(text)} (spinweb -v {command} ... shows "
              "where; please report it)", file=sys.stderr)
        return 1


def main_exit():  # console-script entry point
    sys.exit(main())
