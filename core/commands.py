"""Command tables for the kit's ``python -m`` entry points (handin, kit, autograder).

Each entry point lists its commands explicitly: name -> :class:`Command` (the module, the
function to run, a help line, and the optional packages it needs).  Every command is always
listed in ``--help``; a command whose optional package is missing says which package and how to
install it when it is run, instead of disappearing.  Only the module of the command being run is
imported, so one command's heavy or missing dependency never slows down or breaks another.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from .untrusted import for_terminal

__all__ = ["Command", "missing_packages", "build_parser", "run"]


@dataclass(frozen=True)
class Command:
    """One subcommand.

    module: the module that implements it ("handin.pdf"); function: its function taking the parsed
    ``argparse.Namespace`` and returning the exit code; help: one line for ``--help``; needs: import
    names of optional packages it needs ("nbconvert"); install: how to install them; arguments:
    the module's function that adds the command's arguments to its parser (None: no arguments);
    register: instead of ``arguments`` and ``function``, a module function ``f(subparsers)`` that
    adds the whole subcommand under this name itself (for modules that predate the tables).
    """

    module: str
    function: str = "main"
    help: str = ""
    needs: tuple[str, ...] = ()
    install: str = ""
    arguments: str | None = "add_arguments"
    register: str | None = None


def missing_packages(command: Command) -> list[str]:
    """The optional packages of ``command`` that cannot be imported here."""
    out = []
    for name in command.needs:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            out.append(name)
    return out


def _missing_message(prog: str, name: str, command: Command, missing: list[str]) -> str:
    how = command.install or f"pip install {' '.join(missing)}"
    return (f"`{prog} {name}` needs the package{'s' if len(missing) > 1 else ''} {', '.join(missing)}, "
            f"which {'are' if len(missing) > 1 else 'is'} not installed here. Install with: {how}")


def build_parser(prog: str, description: str, table: Mapping[str, Command],
                 only: str | None = None) -> argparse.ArgumentParser:
    """The parser of an entry point: every command listed, with its arguments when it is ``only``
    (only that command's module is imported) or when ``only`` is None (every module is)."""
    parser = argparse.ArgumentParser(prog=prog, description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, command in table.items():
        missing = missing_packages(command)
        help_text = command.help + (f" (needs {', '.join(missing)}: not installed)" if missing else "")
        if only is not None and name != only:
            sub.add_parser(name, help=help_text, description=help_text)
            continue
        if missing:
            p = sub.add_parser(name, help=help_text, description=help_text)
            message = _missing_message(prog, name, command, missing)

            def report(args, _message=message):
                print(f"error: {_message}", file=sys.stderr)
                return 2

            p.set_defaults(func=report, _any_arguments=True)  # its arguments are unknown without its module
            continue
        module = importlib.import_module(command.module)
        if command.register:
            getattr(module, command.register)(sub)
            continue
        p = sub.add_parser(name, help=help_text, description=help_text)
        if command.arguments:
            getattr(module, command.arguments)(p)
        p.set_defaults(func=getattr(module, command.function))
    return parser


def run(prog: str, description: str, table: Mapping[str, Command], argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` (default: the process's arguments) and run the chosen command; its exit code.

    A FileNotFoundError or ValueError from the command is printed as ``error: ...`` (exit 2).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    chosen = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(prog, description, table, chosen if chosen in table else "")
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "_any_arguments", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return args.func(args)
    except (FileNotFoundError, ValueError) as exc:
        # The message may quote a submission's name: shown, never acted on by the terminal.
        print(f"error: {for_terminal(exc)}", file=sys.stderr)
        return 2
