"""app/services' packages follow a request's way: the top-level modules <- records <- forecasts
<- ranking <- jobs (docs/architecture.md).  An import against that order is either one of the
few named here, each with why, or a new back-edge this test names."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SERVICES = ROOT / "app" / "services"
ORDER = ("top", "records", "forecasts", "ranking", "jobs")
# (importing module, imported module): why each goes against the order
BACK_EDGES = {
    # a write of a record keeps the cached answers in step, and a new inspection is compared
    # with its tail's forecast
    ("records.aircraft", "forecasts.forecast_cache"),
    ("records.aircraft_locations", "forecasts.cache_rows"),
    ("records.locations", "forecasts.cache_rows"),
    ("records.corrections", "forecasts.assessment"),
    ("records.corrections", "forecasts.forecast_cache"),
    ("records.ingest", "forecasts.assessment"),
    ("records.ingest", "forecasts.forecast_cache"),
    # the ranking report reads the ranking page's row types
    ("forecasts.reports", "ranking.ranking_page"),
}


def _package(dotted: str) -> str:
    head = dotted.split(".")[0]
    return head if head in ORDER else "top"


def _imports(path: Path) -> set[str]:
    """The app.services modules `path` imports, relative to app.services."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if (
            isinstance(node, ast.ImportFrom)
            and node.module
            and node.module.startswith("app.services")
        ):
            rest = node.module.removeprefix("app.services").lstrip(".")
            if rest in ORDER[1:] or not rest:
                found |= {f"{rest}.{alias.name}".lstrip(".") for alias in node.names}
            else:
                found.add(rest)
        elif isinstance(node, ast.Import):
            found |= {
                a.name.removeprefix("app.services.")
                for a in node.names
                if a.name.startswith("app.services.")
            }
    return found


def test_service_packages_import_along_a_requests_way() -> None:
    against = set()
    for path in SERVICES.rglob("*.py"):
        module = ".".join(path.relative_to(SERVICES).with_suffix("").parts)
        for imported in _imports(path):
            if ORDER.index(_package(imported)) > ORDER.index(_package(module)):
                against.add((module, imported))
    assert against == BACK_EDGES
