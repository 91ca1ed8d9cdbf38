"""`fleetpinn client`: the running service from the command line, over HTTP (httpx).

    fleetpinn client upload FILE | inspect ... | retrain [--wait] | forecast TAIL | ranking
                     | jobs [JOB_ID] | export   [--url URL] [--timeout S]  (options anywhere)

The service's address comes from --url, else FLEETPINN_URL, else http://127.0.0.1:8000; an API
key in FLEETPINN_API_KEY is sent as `Authorization: Bearer <key>`.  Answers print as tables for
people, or with --json (the server's answer) / --csv (rows for tools).  Long steps show a
progress bar on stderr: the upload's bytes, then the server storing them; a retrain's job with
its stage.  A bad file or argument, or a request the server rejects as invalid (4xx), stops with
exit status 2 and one line naming it; a server that cannot be reached or fails, or a job that
fails, with status 1.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import IO, Any

from app.cli import client_fleet, client_jobs
from app.cli import output as out
from app.cli.api import Api
from app.cli.progress import Bar
from app.cli.registry import CommandError, command

URL_ENV = "FLEETPINN_URL"
KEY_ENV = "FLEETPINN_API_KEY"
DEFAULT_URL = "http://127.0.0.1:8000"

Action = Callable[["Api", argparse.Namespace], int]


class _Reader:
    """A file whose reads advance a progress bar (httpx streams multipart bodies by read())."""

    def __init__(self, file: IO[bytes], size: int, bar: Bar) -> None:
        self.file, self.size, self.bar = file, size, bar

    def read(self, size: int = -1) -> bytes:
        chunk = self.file.read(size)
        self.bar.advance(len(chunk))
        if not chunk:  # all sent: the server validates and stores the rows now
            self.bar.update(self.size, "server storing the rows")
        return chunk


# --- upload, inspect ------------------------------------------------------------------------


def upload(api: Api, args: argparse.Namespace) -> int:
    path: Path = args.file
    if not path.is_file():
        raise CommandError(f"{path}: no such file")
    if path.suffix.lower() not in (".csv", ".parquet"):
        raise CommandError(f"{path.name}: must end in .csv or .parquet")
    size = path.stat().st_size
    with path.open("rb") as file, Bar(f"upload {path.name}", total=size, bytes=True) as bar:
        bar.update(0, "sending")
        reader = _Reader(file, size, bar)
        answer = api.call("POST", "/flights/upload", files={"file": (path.name, reader)})
        bar.update(size, "stored")
    body = answer.json()
    out.facts(
        out.mode_of(args),
        body,
        [(key, key.replace("_", " "), body[key], f"{body[key]:,}") for key in body],
        title=f"{path.name}: flights stored",
    )
    return 0


def _when_inspected(text: str) -> str:
    """--at as the API takes it; a value that is no ISO 8601 date or time is named as the
    option it came from (the server could only say its body was invalid)."""
    try:
        datetime.fromisoformat(text)
    except ValueError:
        raise CommandError(
            f"--at: not an ISO 8601 date or time: {text!r} (e.g. 2026-11-20 or "
            "2026-11-20T14:30:00Z; naive times are UTC)"
        ) from None
    return text


def _inspection(args: argparse.Namespace) -> dict[str, Any]:
    if args.id is None or args.at is None:
        raise CommandError("--id and --at are needed (or --file)")
    if args.crack_m is None and not args.not_found:
        raise CommandError("--crack-m is needed (or --not-found)")
    body: dict[str, Any] = {"inspection_id": args.id, "inspected_at": _when_inspected(args.at)}
    if args.not_found:
        body.update(detected=False, detection_threshold_m=args.threshold_m)
        body.update(pod_a50_m=args.pod_a50_m, pod_a90_m=args.pod_a90_m)
    else:
        body["crack_length_m"] = args.crack_m
    if args.repaired_to_m is not None:
        body.update(repaired=True, crack_after_repair_m=args.repaired_to_m)
    body["location"] = args.location
    return {k: v for k, v in body.items() if v is not None}


def _file_inspections(
    api: Api, path: Path
) -> tuple[dict[str, list[dict[str, Any]]], dict[str, list[int]]]:
    """Each tail's inspections from a validated file (bad rows: RecordError naming them), and
    the file's 1-based data row of each (what an error of the server's names), each
    where its optional `location` column says (blank: the default one).  A non-detection that
    gives no detection threshold nor PoD takes its location's catalogue PoD, as the JSON route
    gives it (app.services.records.locations.with_method_pod); where the location has none, the file's
    own check names the missing field."""
    if not path.is_file():
        raise CommandError(f"{path}: no such file")
    # the file contract's own checks; imported here: the other actions need no pandas
    from model.record_validation import validate_inspections
    from model.records import RecordError, read_table

    table = read_table(path)
    named: list[str | None] = [None] * len(table)
    if "location" in table.columns:
        cells = table.pop("location").astype(object).tolist()
        named = [None if c is None or c != c or str(c).strip() == "" else str(c) for c in cells]
    catalogue = {e["name"]: e for e in api.json("GET", "/locations")} if any(named) else {}
    for k, name in enumerate(named):
        if name is not None and name not in catalogue:
            reason = f"unknown location {name!r} (GET /locations lists the catalogue)"
            raise RecordError(path.name, k + 1, "location", reason)
    if "detected" in table.columns:
        if not catalogue:
            catalogue = {e["name"]: e for e in api.json("GET", "/locations")}
        table = _with_catalogue_pod(table, [catalogue.get(n or "default") for n in named])
    frame = validate_inspections(table, path.name)
    by_tail: dict[str, list[dict[str, Any]]] = {}
    file_rows: dict[str, list[int]] = {}
    for row, values in zip(frame.index, frame.to_dict(orient="records"), strict=True):
        body = {
            str(k): v
            for k, v in values.items()
            if k != "tail" and v is not None and v == v  # NaN: not given
        }
        body["inspected_at"] = values["inspected_at"].strftime("%Y-%m-%dT%H:%M:%SZ")
        if named[int(row) - 1] is not None:
            body["location"] = named[int(row) - 1]
        by_tail.setdefault(str(values["tail"]), []).append(body)
        file_rows.setdefault(str(values["tail"]), []).append(int(row))
    return by_tail, file_rows


def _stored(
    api: Api, tail: str, bodies: list[dict[str, Any]], rows: list[int] | None, source: str
) -> Any:
    """POST one tail's inspections; a refusal naming the request's row names the file's row
    (rows: the file row of each body; None: not from a file)."""
    try:
        return api.json("POST", f"/aircraft/{tail}/inspections", json=bodies)
    except CommandError as exc:
        if rows is None:
            raise
        found = re.search(r"\bbody row (\d+)\b", str(exc))
        if found is None or not 1 <= int(found[1]) <= len(rows):
            raise
        where = f"{source} row {rows[int(found[1]) - 1]}"
        raise CommandError(str(exc).replace(found[0], where, 1)) from exc


def _with_catalogue_pod(table: Any, entries: list[dict[str, Any] | None]) -> Any:
    """table's non-detections that give neither a detection threshold nor a PoD, with their
    location's catalogue PoD (entries: each row's catalogue entry; None: unknown)."""
    given = [c for c in ("detection_threshold_m", "pod_a50_m", "pod_a90_m") if c in table.columns]

    def blank(value: Any) -> bool:
        return value is None or value != value or str(value).strip() == ""

    out = table.copy()
    a50 = list(out["pod_a50_m"]) if "pod_a50_m" in out.columns else [None] * len(out)
    a90 = list(out["pod_a90_m"]) if "pod_a90_m" in out.columns else [None] * len(out)
    for k, (detected, entry) in enumerate(zip(out["detected"], entries, strict=True)):
        missed = str(detected).strip().lower() in ("false", "0", "no", "f", "n", "0.0")
        if not missed or entry is None or entry.get("pod_a50_m") is None:
            continue
        if all(blank(out[c].iloc[k]) for c in given):
            a50[k], a90[k] = entry["pod_a50_m"], entry["pod_a90_m"]
    out["pod_a50_m"], out["pod_a90_m"] = a50, a90
    return out


def inspect(api: Api, args: argparse.Namespace) -> int:
    rows: dict[str, list[int]] = {}
    if args.file is not None:
        batches, rows = _file_inspections(api, args.file)
    elif args.tail is not None:
        batches = {args.tail: [_inspection(args)]}
    else:
        raise CommandError("give a TAIL with --id, --at and the finding, or --file")
    totals = {"inserted": 0, "duplicates": 0}
    assessments: list[dict[str, Any]] = []
    with Bar("inspections", total=len(batches)) as bar:
        done: list[str] = []
        for i, (tail, bodies) in enumerate(sorted(batches.items())):
            bar.update(i, tail)
            source = args.file.name if args.file is not None else "body"
            try:
                answer = _stored(api, tail, bodies, rows.get(tail), source)
            except CommandError as exc:
                if not done:
                    raise
                # each tail is one request: those before stay stored, which a user must know
                stored = f"stored already: the inspections of {', '.join(done)}"
                again = "re-sending the file counts them as duplicates"
                raise CommandError(f"{exc} ({stored}; {again})") from exc
            done.append(tail)
            for key in totals:
                totals[key] += answer[key]
            assessments += [{"tail": tail, **a} for a in answer["assessments"]]
        bar.update(len(batches), "stored")
    flagged = [a for a in assessments if a["flagged"]]
    mode = out.mode_of(args)
    counts = {**totals, "flagged": len(flagged)}
    out.facts(
        mode,
        {**totals, "assessments": assessments},
        [(k, k, v, f"{v:,}") for k, v in counts.items()],
        title=f"inspections of {len(batches)} tail(s)",
    )
    if mode == "table":
        for a in flagged:
            print(_flag_line(a))
    return 0


def _flag_line(assessment: dict[str, Any]) -> str:
    """A flagged inspection in one line: stored, but far from its tail's forecast."""
    z = assessment["forecast_z"]
    return (
        f"FLAGGED {assessment['tail']} {assessment['inspection_id']}: z = {z:+.1f} against the "
        f"forecast of {out.mm(assessment['forecast_crack_m'])} mm (|z| above the flag "
        "threshold): stored, but check the measurement"
    )


# --- arguments ------------------------------------------------------------------------------


def _output_options() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    mode = parent.add_mutually_exclusive_group()
    mode.add_argument("--json", action="store_true", help="print the server's JSON answer")
    mode.add_argument("--csv", action="store_true", help="print rows as CSV (SI units, UTC)")
    return parent


def _when_options() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("--horizon-days", type=int, default=None, help="days after the as-of date")
    parent.add_argument(
        "--as-of", default=None, metavar="DATE", help="today for this answer (YYYY-MM-DD, UTC)"
    )
    return parent


def _connection_options(parser: argparse.ArgumentParser, *, defaults: bool) -> None:
    """--url and --timeout, before the action (with their defaults) or after it: there they
    are left out unless given, so as not to overwrite a value given before the action."""
    parser.add_argument(
        "--url",
        default=os.environ.get(URL_ENV, DEFAULT_URL) if defaults else argparse.SUPPRESS,
        help=f"the service (default ${URL_ENV} or {DEFAULT_URL}); ${KEY_ENV} is sent as a "
        "bearer key",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=600.0 if defaults else argparse.SUPPRESS,
        help="seconds per request",
    )


def _client_arguments(parser: argparse.ArgumentParser) -> None:
    _connection_options(parser, defaults=True)
    shown, when = _output_options(), _when_options()
    anywhere = argparse.ArgumentParser(add_help=False)
    _connection_options(anywhere, defaults=False)
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")

    def add(name: str, help: str, action: Action, *parents: argparse.ArgumentParser) -> Any:
        child = sub.add_parser(
            name, help=help, description=help, parents=[shown, anywhere, *parents]
        )
        child.set_defaults(action_run=action)
        return child

    p = add("upload", "upload a flights file (CSV or Parquet) with a progress bar", upload)
    p.add_argument("file", type=Path, metavar="FILE")

    p = add("inspect", "record one inspection of a tail, or a file of them", inspect)
    p.add_argument("tail", nargs="?", metavar="TAIL")
    p.add_argument("--file", type=Path, default=None, help="inspections file (CSV or Parquet)")
    p.add_argument("--id", default=None, help="inspection id")
    p.add_argument("--at", default=None, help="when (ISO 8601; naive: UTC)")
    p.add_argument("--crack-m", type=float, default=None, help="measured crack (m)")
    p.add_argument("--not-found", action="store_true", help="nothing found")
    p.add_argument("--threshold-m", type=float, default=None, help="nothing found: threshold")
    p.add_argument("--pod-a50-m", type=float, default=None, help="nothing found: PoD a50")
    p.add_argument("--pod-a90-m", type=float, default=None, help="nothing found: PoD a90")
    p.add_argument("--repaired-to-m", type=float, default=None, help="repaired to this crack")
    p.add_argument(
        "--location",
        default=None,
        help="where on the aircraft (a catalogue name; default: the default location); a "
        "file names each row's in its optional location column",
    )

    p = add(
        "retrain", "queue a retrain; --wait follows it with a progress bar", client_jobs.retrain
    )
    p.add_argument("--wait", action="store_true", help="follow the job to its end")
    p.add_argument("--kernel", default=None)
    p.add_argument("--lbfgs-iterations", type=int, default=None)
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--no-activate", action="store_true")

    p = add(
        "forecast",
        "one tail's forecast: today, the horizon, risk, inspect-by",
        client_fleet.forecast,
        when,
    )
    p.add_argument("tail", metavar="TAIL")
    p.add_argument(
        "--location", default=None, help="one control point's forecast (default: the aircraft's)"
    )

    p = add("ranking", "who to inspect next", client_fleet.ranking, when)
    p.add_argument("--limit", type=int, default=20)
    p.add_argument("--by", choices=("risk", "crack", "due"), default="risk")

    p = add("jobs", "recent jobs, or one job", client_jobs.jobs)
    p.add_argument("job_id", nargs="?", metavar="JOB_ID")
    p.add_argument("--limit", type=int, default=20)

    p = add(
        "export", "every tail's forecast, ranked (CSV, Parquet or JSON)", client_fleet.export, when
    )
    p.add_argument("--format", choices=client_fleet.EXPORT_FORMATS, default=None)
    p.add_argument("--out", type=Path, default=None, help="file to write (default: stdout)")


@command(
    "client",
    "talk to a running fleetpinn service (upload, retrain, forecast, ...)",
    _client_arguments,
    uses_model=False,
)
def run_client(args: argparse.Namespace) -> int:
    api = Api(args.url, os.environ.get(KEY_ENV) or None, args.timeout)
    try:
        status: int = args.action_run(api, args)
    finally:
        api.http.close()
    sys.stdout.flush()
    return status
