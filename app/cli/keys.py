"""`fleetpinn keys create|list|revoke`: the service's API keys (app.services.keys).

Whoever can run these holds the database's credentials, the root of trust: they need no key.
`create` prints the new key once on stdout (nothing else there, so `KEY=$(fleetpinn keys create
...)` works) and can also write it to a file readable only by its owner.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from app.cli.registry import CommandError, command

ROLES = ("read", "write", "admin")


def _arguments(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    create = actions.add_parser("create", help="create a key and print it (shown only once)")
    create.add_argument("--role", choices=ROLES, required=True)
    create.add_argument("--name", default=None, help="who or what uses it (default: <role>-key)")
    create.add_argument(
        "--replace", action="store_true", help="revoke the live key of the same name first"
    )
    create.add_argument("--out", type=Path, default=None, help="also write the key to this file")
    actions.add_parser("list", help="every key: id, name, role, created, revoked (no secrets)")
    revoke = actions.add_parser("revoke", help="revoke a key by its key id or name")
    revoke.add_argument("key", help="key id (the 8 hex digits after fpk_) or name")


@command(
    "keys",
    "create, list or revoke API keys (roles read, write, admin)",
    _arguments,
    uses_model=False,
)
def run_keys(args: argparse.Namespace) -> int:
    from app import key_admin
    from app.errors import ConflictError, NotFoundError

    try:
        if args.action == "create":
            new = key_admin.create_key(
                args.role, args.name or f"{args.role}-key", replace=args.replace
            )
            if args.out is not None:
                _write_secret(args.out, new.key)
            print(new.key)
            print(
                f"created {new.role} key {new.key_id} named {new.name!r}: store it now, it is "
                "not shown again",
                file=sys.stderr,
            )
        elif args.action == "list":
            print(json.dumps(key_admin.list_keys(), indent=2))
        else:
            print(json.dumps(key_admin.revoke_key(args.key), indent=2))
    except (ConflictError, NotFoundError, ValueError) as exc:
        raise CommandError(str(exc.args[0]) if exc.args else str(exc)) from exc
    return 0


def _write_secret(path: Path, key: str) -> None:
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, "w") as out:
        out.write(key + "\n")
    path.chmod(0o600)
