"""`fleetpinn client forecast | ranking | export`: the fleet's forecasts from a running service.

Tables show cracks in mm, probabilities in percent and dates in UTC; --csv keeps the API's
values (m, fractions, ISO 8601 UTC with Z); --json prints the server's answer.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from app.cli import output as out
from app.cli.api import Api
from app.cli.registry import CommandError
from app.web import format as fmt

EXPORT_FORMATS = ("csv", "parquet", "json")


def _when(args: argparse.Namespace) -> dict[str, Any]:
    """The horizon and as-of query parameters given."""
    params = {"horizon_days": args.horizon_days, "as_of": args.as_of}
    return {k: v for k, v in params.items() if v is not None}


def _band(values: dict[str, Any] | None, critical_m: float, central: str = "p50") -> str:
    """A crack's `central` value with its p05-p95 band in mm; the API's null (at or past
    a_crit) reads as the pages read it (app.web.format.beyond_critical)."""
    if not values:
        return out.text(None)
    band = fmt.crack_band(values["p05"], values["p95"], critical_m)
    return fmt.crack_mm(values[central], critical_m) + (f" ({band})" if band else "")


def _past_critical(body: dict[str, Any]) -> str:
    return f"past critical since {out.day(body['past_critical_since'])}"


def _age(age: dict[str, Any]) -> str:
    """'91 d since the last flight, STALE; 95 d since the last inspection'."""
    flight = f"{age['days_since_last_flight']:,} d since the last flight"
    if age["stale"]:
        flight += ", STALE"
    inspected = age["days_since_last_inspection"]
    return flight + (
        "; never inspected" if inspected is None else f"; {inspected:,} d since the last inspection"
    )


def _dates(values: dict[str, Any]) -> str:
    """'2027-03-01 (2026-12-20–later)': a quantile the horizon does not reach is 'beyond the
    horizon' (p50) or 'later' (p95), as the pages say, never a dash read as missing."""
    if values["p05"] is None:
        return "beyond the horizon"
    p95 = out.day(values["p95"]) if values["p95"] else "later"
    return f"{_critical_day(values['p50'])} ({out.day(values['p05'])}–{p95})"


def _critical_day(value: str | None) -> str:
    return out.day(value) if value else "beyond the horizon"


def _due_day(value: str | None) -> str:
    return out.day(value) if value else "not due"


def forecast(api: Api, args: argparse.Namespace) -> int:
    where = "" if args.location is None else f"/locations/{args.location}"
    body = api.json("GET", f"/aircraft/{args.tail}{where}/forecast", params=_when(args))
    mode = out.mode_of(args)
    if mode == "json":  # the server's answer as it is
        out.emit(mode, body, [], [])
        return 0
    if mode == "csv":
        columns = [
            out.Column(key, key)
            for key in ("date", "flights", "crack_length_m", "p05", "p50", "p95")
        ]
        out.emit(mode, body, body["trajectory"], columns)
        return 0
    today, later = body["crack_as_of"], body["crack_at_horizon"]
    critical = body["critical_crack_m"]
    inspect_by = out.day(body["inspect_by"]) if body["inspect_by"] else "not due within the horizon"
    if body["overdue"]:
        inspect_by += "  OVERDUE"
    items = [
        (
            "last_flown_at",
            "last recorded flight (UTC)",
            body["last_flown_at"],
            out.stamp(body["last_flown_at"]),
        ),
        ("as_of", "as of", body["as_of"], out.day(body["as_of"])),
        (
            "crack_length_m",
            "crack at last flight, mm (p05–p95)",
            body["crack_length_m"],
            _band(
                {**body["crack_length_band"], "point": body["crack_length_m"]},
                critical,
                central="point",
            ),
        ),
        (
            "crack_as_of_p50_m",
            f"crack on {out.day(today['date'])}, mm p50 (p05–p95)",
            today["p50"],
            _past_critical(body) if body["past_critical"] else _band(today, critical),
        ),
        (
            "past_critical",
            "past critical (p50 at a_crit)",
            body["past_critical"],
            "yes" if body["past_critical"] else "no",
        ),
        (
            "days_since_last_flight",
            "data age",
            body["data_age"]["days_since_last_flight"],
            _age(body["data_age"]),
        ),
        (
            "crack_at_horizon_p50_m",
            f"crack on {out.day(later['date'])}, mm p50 (p05–p95)",
            later["p50"],
            _band(later, critical),
        ),
        (
            "critical_crack_m",
            "a_crit, mm",
            body["critical_crack_m"],
            out.mm(body["critical_crack_m"]),
        ),
        (
            "prob_critical",
            f"P(critical) by {out.day(later['date'])}",
            body["prob_critical"],
            out.percent(body["prob_critical"]),
        ),
        (
            "critical_date_p50",
            "critical date p50 (p05–p95)",
            body["critical_date_quantiles"]["p50"],
            _dates(body["critical_date_quantiles"]),
        ),
        ("inspect_by", "inspect by", body["inspect_by"], inspect_by),
        (
            "flights_per_day",
            "flights per day (projected)",
            body["flights_per_day"],
            f"{body['flights_per_day']:.2f}",
        ),
        ("model_version", "model version", body["model_version"], str(body["model_version"])),
    ]
    strength = _line_strength(body.get("residual_strength"))
    if strength is not None:  # where the location gives a limit stress, after a_crit
        at = [key for key, *_ in items].index("critical_crack_m") + 1
        items.insert(
            at,
            (
                "residual_strength_p50_mpa",
                "residual strength today (p50)",
                strength["residual_strength_mpa"],
                fmt.strength_words(**strength),
            ),
        )
    for line in body.get("locations") or []:  # the aircraft's locations, governing first
        governing = "  GOVERNING" if line["location"] == body["governing_location"] else ""
        due = out.day(line["inspect_by"]) if line["inspect_by"] else "not due"
        shown = f"P(critical) {out.percent(line['prob_critical'])}, inspect by {due}"
        if line.get("residual_strength"):
            shown += f", residual strength {fmt.strength_words(**line['residual_strength'])}"
        items.append(
            (
                f"location_{line['location']}",
                f"location {line['location']}",
                line["prob_critical"],
                shown + governing,
            )
        )
    if body.get("governing_location"):
        governing_name = body["governing_location"]
        items.insert(
            0,
            (
                "governing_location",
                "governing location",
                governing_name,
                f"{governing_name} (the figures below are of {body.get('location') or 'default'})",
            ),
        )
    reasons = {note["location"]: note["reason"] for note in body.get("location_notes") or []}
    for name in body.get("unassessed_locations") or []:  # carried, but no model weighs them
        why = f" ({reasons.pop(name)})" if name in reasons else ""
        items.append((f"location_{name}", f"location {name}", None, f"no model yet: retrain{why}"))
    for name, reason in reasons.items():  # weighed, on the fleet's evidence alone
        items.append((f"note_{name}", f"location {name}", None, reason))
    where = "" if args.location is None else f" at {args.location}"
    if args.location is None and body.get("location"):
        where = f" (governing location {body['governing_location']})"
    out.facts(mode, body, items, title=f"{body['tail']}{where}: forecast")
    return 0


def _line_strength(residual: dict[str, Any] | None) -> dict[str, Any] | None:
    """A forecast's residual_strength at its p50 crack in a line's form (the API's
    LineStrengthOut), None without one (nothing shown)."""
    if residual is None:
        return None
    at = residual["p50"]
    return {
        "residual_strength_mpa": at["residual_strength_mpa"],
        "criterion": at["criterion"],
        "margin": at["margin"],
        "limit_stress_mpa": residual["limit_stress_mpa"],
    }


_RANKING_COLUMNS = [
    out.Column("rank", "#", numeric=True),
    out.Column("tail", "tail"),
    out.Column("crack_today", "crack today, mm p50 (p05–p95)"),
    out.Column("crack_at_horizon", "at horizon end, mm"),
    out.Column("prob_critical", "P(critical)", out.percent, numeric=True),
    out.Column("critical_date_p50", "critical date p50", _critical_day),
    out.Column("inspect_by", "inspect by", _due_day),
    out.Column("overdue", "overdue", out.yes),
    out.Column("data_age", "data age, d"),
    out.Column("last_inspected_at", "last inspection", out.day),
]
_RANKING_CSV = [
    out.Column(key, key)
    for key in (
        "rank",
        "tail",
        "crack_as_of_p05_m",
        "crack_as_of_p50_m",
        "crack_as_of_p95_m",
        "crack_at_horizon_p05_m",
        "crack_at_horizon_p50_m",
        "crack_at_horizon_p95_m",
        "prob_critical",
        "critical_date_p05",
        "critical_date_p50",
        "critical_date_p95",
        "inspect_by",
        "overdue",
        "past_critical",
        "past_critical_since",
        "days_since_last_flight",
        "days_since_last_inspection",
        "stale",
        "last_inspected_at",
    )
]


# after P(critical), where some row's location gives a limit stress
_STRENGTH_COLUMNS = [out.Column("strength_margin", "residual strength today, margin")]
_STRENGTH_CSV = [
    out.Column(key, key)
    for key in (
        "residual_strength_mpa",
        "residual_strength_criterion",
        "residual_strength_margin",
        "limit_stress_mpa",
    )
]


def _ranking_row(item: dict[str, Any], critical_m: float) -> dict[str, Any]:
    today, later = item["crack_as_of_band"], item["crack_at_horizon_band"]
    dates, last = item["critical_date_quantiles"], item["last_inspection"]
    age = item["data_age"]
    return {
        **item,
        "crack_today": _past_critical(item) if item["past_critical"] else _band(today, critical_m),
        "data_age": f"{age['days_since_last_flight']:,}" + (" STALE" if age["stale"] else ""),
        "days_since_last_flight": age["days_since_last_flight"],
        "days_since_last_inspection": age["days_since_last_inspection"],
        "stale": age["stale"],
        "crack_at_horizon": _band(later, critical_m),
        **{f"crack_as_of_{q}_m": today[q] for q in ("p05", "p50", "p95")},
        **{f"crack_at_horizon_{q}_m": later[q] for q in ("p05", "p50", "p95")},
        **{f"critical_date_{q}": dates[q] for q in ("p05", "p50", "p95")},
        "last_inspected_at": None if last is None else last["inspected_at"],
        **_strength_columns(item.get("residual_strength")),
    }


def _strength_columns(strength: dict[str, Any] | None) -> dict[str, Any]:
    """A ranked row's residual strength (the API's LineStrengthOut) as the printout's columns:
    the table's one cell and the CSV's four, empty without one."""
    get = (strength or {}).get
    return {
        "strength_margin": fmt.strength_margin(get("residual_strength_mpa"), get("margin")),
        "residual_strength_mpa": get("residual_strength_mpa"),
        "residual_strength_criterion": get("criterion"),
        "residual_strength_margin": get("margin"),
        "limit_stress_mpa": get("limit_stress_mpa"),
    }


def ranking(api: Api, args: argparse.Namespace) -> int:
    params = {"limit": args.limit, "by": args.by, **_when(args)}
    body = api.json("GET", "/fleet/ranking", params=params)
    mode = out.mode_of(args)
    rows = [
        _ranking_row(item, item.get("critical_crack_m") or body["critical_crack_m"])
        for item in body["items"]
    ]
    title = (
        f"{body['total']} tails by {body['by']}, model v{body['model_version']}, "
        f"horizon {body['horizon_days']} days from {out.day(body['as_of'])}"
    )
    columns = _RANKING_CSV if mode == "csv" else _RANKING_COLUMNS
    if any("residual_strength" in item for item in body["items"]):  # some limit stress
        after = [c.key for c in columns].index("prob_critical") + 1
        strength = _STRENGTH_CSV if mode == "csv" else _STRENGTH_COLUMNS
        columns = [*columns[:after], *strength, *columns[after:]]
    if any("location" in item for item in body["items"]):  # (tail, location) rows
        versions = sorted({(item["location"], item["model_version"]) for item in body["items"]})
        models = ", ".join(f"{name} v{version}" for name, version in versions)
        title = title.replace(" tails ", " (tail, location) rows ").replace(
            f"model v{body['model_version']}", f"models {models}"
        )
        columns = [*columns[:2], out.Column("location", "location"), *columns[2:]]
    out.emit(mode, body, rows, columns, title=title)
    return 0


def export(api: Api, args: argparse.Namespace) -> int:
    export_format = args.format
    if export_format is None:
        export_format = args.out.suffix.lower().lstrip(".") if args.out is not None else "csv"
    if export_format not in EXPORT_FORMATS:
        raise CommandError(f"--out must end in .csv, .parquet or .json, got {args.out.name!r}")
    if export_format == "parquet" and args.out is None:
        raise CommandError("parquet is binary: give --out FILE.parquet")
    params = {"format": export_format, **_when(args)}
    content = api.call("GET", "/forecasts", params=params).content
    if args.out is None:
        sys.stdout.write(content.decode())
        return 0
    args.out.write_bytes(content)
    print(f"wrote {args.out} ({len(content):,} bytes, {export_format})", file=sys.stderr)
    return 0
