"""The `fleetpinn` command line (console entry point app.cli:main).

app.cli.registry holds the machinery (COMMANDS, @command, build_parser); a subcommand is
registered when its module is imported: app.cli.offline (fit), app.cli.predict (predict), app.cli.spectrum
(spectrum), app.cli.demo (demo),
app.cli.service (serve, migrate, worker, retrain, forecast-batch, seed-demo), app.cli.keys
(keys), app.cli.client (client).  main() imports only the module of the subcommand asked for
(all of them for the overall help), so `fleetpinn keys` and `fleetpinn client` start without
PyTorch and `fleetpinn fit` without FastAPI and SQLAlchemy.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence

from app.cli import registry
from app.cli.registry import COMMANDS, USAGE_ERROR, CommandError, build_parser, command

# subcommand -> the module that registers it
MODULE_OF = {
    "fit": "app.cli.offline",
    "predict": "app.cli.predict",
    "spectrum": "app.cli.spectrum",
    "demo": "app.cli.demo",
    "serve": "app.cli.service",
    "migrate": "app.cli.service",
    "worker": "app.cli.service",
    "retrain": "app.cli.service",
    "forecast-batch": "app.cli.service",
    "seed-demo": "app.cli.service",
    "keys": "app.cli.keys",
    "client": "app.cli.client",
}


def load_commands(name: str | None = None) -> None:
    """Register subcommand `name` (None or an unknown name: all of them)."""
    wanted = [MODULE_OF[name]] if name in MODULE_OF else sorted(set(MODULE_OF.values()))
    for module in wanted:
        importlib.import_module(module)


def main(argv: Sequence[str] | None = None) -> int:
    """Parse `argv` (default sys.argv[1:]), run the subcommand and return its exit status."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    load_commands(arguments[0] if arguments else None)
    return registry.main(arguments)


__all__ = [
    "COMMANDS",
    "MODULE_OF",
    "USAGE_ERROR",
    "CommandError",
    "build_parser",
    "command",
    "load_commands",
    "main",
]
