"""The `fleetpinn` command line (console entry point app.cli:main).

app.cli.registry holds the machinery (COMMANDS, @command, build_parser, main); importing this
package registers the offline subcommands (app.cli.offline: fit, predict; app.cli.demo: demo) and the service
subcommands (app.cli.service: serve, migrate, worker, retrain, forecast-batch, seed-demo;
app.cli.keys: keys).  The service subcommands import the service (FastAPI, SQLAlchemy) only
when they run, so the offline ones start without it.
"""

from app.cli import client, demo, keys, offline, service
from app.cli.registry import COMMANDS, USAGE_ERROR, CommandError, build_parser, command, main

__all__ = [
    "COMMANDS",
    "USAGE_ERROR",
    "CommandError",
    "build_parser",
    "client",
    "command",
    "demo",
    "keys",
    "main",
    "offline",
    "service",
]
