#!/usr/bin/env bash
# PostgreSQL 15 from Debian's packages, its cluster started, and a login role for the tests and
# benchmarks (fleetpinn/fleetpinn, CREATEDB: each test run makes and drops its own databases).
# Idempotent: with the server up and the role there it only checks.  Never fails the caller:
# where PostgreSQL cannot be installed or started (no root, no package registry) the PostgreSQL
# tests skip and say why.
set -uo pipefail
VERSION=15
CLUSTER=main
ROLE=fleetpinn
PASSWORD=fleetpinn

say() { echo "install-postgres: $*" >&2; }

SUDO=""
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else
        SUDO="-"
    fi
fi

ready() { pg_isready -q -h 127.0.0.1 -p "$(port)" 2>/dev/null; }
port() { pg_conftool -s "$VERSION" "$CLUSTER" show port 2>/dev/null || echo 5432; }

if ! [ -x "/usr/lib/postgresql/$VERSION/bin/postgres" ]; then
    if [ "$SUDO" = "-" ]; then
        say "not root and PostgreSQL $VERSION is not installed; the PostgreSQL tests will skip"
        exit 0
    fi
    export DEBIAN_FRONTEND=noninteractive
    if ! { $SUDO apt-get update -qq \
        && $SUDO apt-get install -y -qq --no-install-recommends -o DPkg::Lock::Timeout=300 \
            postgresql; }; then
        say "apt-get could not install postgresql; the PostgreSQL tests will skip"
        exit 0
    fi
fi
[ "$SUDO" = "-" ] && SUDO=""

if ! pg_lsclusters -h 2>/dev/null | awk '{print $1, $2}' | grep -qx "$VERSION $CLUSTER"; then
    $SUDO pg_createcluster "$VERSION" "$CLUSTER" >/dev/null || say "pg_createcluster failed"
fi
if ! ready; then
    # Without systemd (containers, CI) pg_ctlcluster starts the server itself; a concurrent
    # start by another run answers "already running", which the wait below absorbs.
    $SUDO pg_ctlcluster "$VERSION" "$CLUSTER" start 2>/dev/null || true
    for _ in $(seq 1 60); do ready && break; sleep 0.5; done
fi
if ! ready; then
    say "PostgreSQL $VERSION did not start; the PostgreSQL tests will skip"
    exit 0
fi

as_postgres() { $SUDO runuser -u postgres -- "$@" 2>/dev/null || su postgres -c "$*" 2>/dev/null; }
exists=$(as_postgres psql -p "$(port)" -tAc "SELECT 1 FROM pg_roles WHERE rolname = '$ROLE'")
if [ "$exists" != "1" ]; then
    as_postgres psql -p "$(port)" -qc "CREATE ROLE $ROLE LOGIN CREATEDB PASSWORD '$PASSWORD'" \
        || say "could not create role $ROLE (a concurrent run may have made it)"
fi
exit 0
