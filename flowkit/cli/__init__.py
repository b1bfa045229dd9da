"""The ``flowkit`` command.  Each subcommand lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a function taking the args;
modules are found automatically (a module whose name starts with "_" is a helper, not a command)."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import warnings


class CLIError(Exception):
    """An error to print as one line (no traceback) with exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="flowkit", description=__import__("flowkit").__doc__)
    p.add_argument("--version", action="version", version=f"flowkit {__import__('flowkit').__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for m in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not m.name.startswith("_"):
            importlib.import_module(f"flowkit.cli.{m.name}").register(sub)
    return p


def _show_compile_notices() -> None:
    """The compile notices (flowkit.compile_notice) on stderr, once per kernel."""
    import logging

    log = logging.getLogger("flowkit.compile")
    ours = [h for h in log.handlers if getattr(h, "flowkit_cli", False)]
    if not ours:
        handler = logging.StreamHandler(sys.stderr)
        handler.flowkit_cli = True
        handler.setFormatter(logging.Formatter("flowkit: %(message)s"))
        log.addHandler(handler)
        log.setLevel(logging.INFO)
        log.propagate = False
    for handler in ours:  # this call's stderr (main may run again with another one)
        handler.stream = sys.stderr  # (not setStream: it flushes the old one, maybe closed)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """A warning as one line on stderr, "flowkit: warning: ...", not Python's file, line number
    and source line."""
    print(f"flowkit: warning: {message}", file=sys.stderr)


def _join_views(argv: list[str]) -> list[str]:
    """``--view -x`` as ``--view=-x``: argparse takes a value starting with '-' for an option."""
    from ..render.camera import VIEWS

    out = []
    for a in argv:
        if out and out[-1] == "--view" and a in VIEWS:
            out[-1] = f"--view={a}"
        else:
            out.append(a)
    return out


def main(argv=None) -> int:
    args = build_parser().parse_args(_join_views(sys.argv[1:] if argv is None else list(argv)))
    _show_compile_notices()
    try:
        with warnings.catch_warnings():  # (restores Python's own display after the command)
            warnings.showwarning = _show_warning
            return int(args.func(args) or 0)
    # (MemoryError: a field that does not fit, FieldMemoryError, says so in one line)
    except (CLIError, FileNotFoundError, ValueError, KeyError, OSError, MemoryError) as e:
        msg = e.args[0] if isinstance(e, KeyError) and e.args else e
        print(f"flowkit {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
