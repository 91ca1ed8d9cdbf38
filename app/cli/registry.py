"""The subcommand registry of `fleetpinn`: Command, @command, build_parser and main.

Each subcommand is one entry of COMMANDS, added with the @command decorator: a name, a one-line
help, a function that declares its arguments and the function that runs it and returns the exit
status.  A new subcommand is a new decorated function in app.cli.offline or app.cli.service;
main() needs no edit.

Bad input (a record file, a model file, an argument value) stops with exit status 2 and one line
on stderr naming the file, row and column, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from pydantic import ValidationError

USAGE_ERROR = 2
SIGPIPE_STATUS = 141


class CommandError(Exception):
    """A one-line failure a user can fix (bad file, bad value); main() exits with status 2."""


class CommandFailed(Exception):
    """A one-line failure of the work itself (a server that does not answer, a failed job);
    main() exits with status 1."""


@dataclass(frozen=True)
class Command:
    help: str
    configure: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]
    # Whether it runs the model (torch's threads are set first): `keys` and `client` do not,
    # and start without importing it.
    uses_model: bool = True


COMMANDS: dict[str, Command] = {}


def command(
    name: str,
    help: str,
    configure: Callable[[argparse.ArgumentParser], None],
    *,
    uses_model: bool = True,
) -> Callable[[Callable[[argparse.Namespace], int]], Callable[[argparse.Namespace], int]]:
    """Register `run(args) -> exit status` as subcommand `name`; `configure` adds its arguments.

    Raises ValueError when `name` is registered twice or `help` is empty.
    """
    if not help.strip():
        raise ValueError(f"subcommand {name!r} needs a one-line help")

    def register(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        if name in COMMANDS:
            raise ValueError(f"subcommand {name!r} is registered twice")
        COMMANDS[name] = Command(help, configure, run, uses_model)
        return run

    return register


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fleetpinn", description="Fleet fatigue-crack prognosis with hybrid physics-RNNs."
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, cmd in COMMANDS.items():
        sub = subparsers.add_parser(name, help=cmd.help, description=cmd.help)
        cmd.configure(sub)
        sub.set_defaults(run=cmd.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse `argv` (default sys.argv[1:]), run the subcommand and return its exit status."""
    args = build_parser().parse_args(argv)
    try:
        if COMMANDS[args.command].uses_model:
            from model.runtime import configure_threads

            configure_threads()
        status: int = args.run(args)
        sys.stdout.flush()
    except BrokenPipeError:
        return _reader_gone()
    except CommandError as exc:
        return _usage_error(args.command, str(exc))
    except CommandFailed as exc:
        print(f"fleetpinn {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except ValidationError as exc:  # a FLEETPINN_* setting (app.config.Settings)
        first = exc.errors()[0]
        name = "FLEETPINN_" + "_".join(str(part) for part in first["loc"]).upper()
        where = f"setting {name}" if first["loc"] else "settings"  # a check across settings
        return _usage_error(args.command, f"{where}: {first['msg']}")
    except ValueError as exc:  # a bad record file, or FLEETPINN_THREADS (model.runtime)
        if not _usage_value_error(exc):
            raise
        return _usage_error(args.command, str(exc))
    return status


def _usage_value_error(exc: ValueError) -> bool:
    """Whether `exc` is a bad record file (model.records.RecordError) or a bad
    FLEETPINN_THREADS: model/ is imported only by the commands that use it, so it is looked up
    where it was loaded (an exception of a module never imported cannot have been raised)."""
    records, runtime = sys.modules.get("model.records"), sys.modules.get("model.runtime")
    if records is not None and isinstance(exc, records.RecordError):
        return True
    return runtime is not None and runtime.THREADS_ENV in str(exc)


def _reader_gone() -> int:
    """The reader of stdout went away (`fleetpinn client forecast N100 --json | head`): stop
    quietly, as a filter killed by SIGPIPE does, with its status 128 + 13.  What Python still
    has to write at exit goes to /dev/null, so no BrokenPipeError follows either."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return SIGPIPE_STATUS


def _usage_error(command: str, message: str) -> int:
    print(f"fleetpinn {command}: error: {message}", file=sys.stderr)
    return USAGE_ERROR
