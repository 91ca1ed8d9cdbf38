"""The layering of docs/architecture.md, read from the source: model/ never imports app/; app/
imports no private name and no compiled part (model.fast_march*) of model/; no modules of app/
and model/ import each other in a circle.  Imports inside functions count too: a lazy import
still ties two modules together."""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("app", "model")


@dataclass(frozen=True)
class Import:
    source: str  # importing module, e.g. "app.services.forecasts.risk"
    target: str  # imported module of app/ or model/, e.g. "model.uncertainty"
    names: tuple[str, ...]  # names taken from it ("from target import a, b"); () for "import"
    line: int


def _modules() -> dict[str, Path]:
    modules = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _imports() -> list[Import]:
    """Every import of an app/ or model/ module by one, resolved to the module it loads."""
    modules = _modules()
    found = []
    for source, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found += [
                    Import(source, alias.name, (), node.lineno)
                    for alias in node.names
                    if alias.name in modules
                ]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                for alias in node.names:
                    submodule = f"{node.module}.{alias.name}"
                    if submodule in modules:  # "from model import records"
                        found.append(Import(source, submodule, (), node.lineno))
                    elif node.module in modules:
                        found.append(Import(source, node.module, (alias.name,), node.lineno))
    return found


def _where(imp: Import) -> str:
    names = f" ({', '.join(imp.names)})" if imp.names else ""
    return f"{imp.source} line {imp.line}: {imp.target}{names}"


def test_the_source_is_read() -> None:
    """Guards the checks below against passing on an empty reading."""
    targets = {(imp.source, imp.target) for imp in _imports()}
    assert ("model.hybrid", "model.fast_march") in targets
    assert ("app.services.jobs.retrain", "model.posterior") in targets


def test_model_never_imports_app() -> None:
    wrong = [
        _where(imp)
        for imp in _imports()
        if imp.source.split(".")[0] == "model" and imp.target.split(".")[0] == "app"
    ]
    assert not wrong, wrong


def test_app_imports_no_private_or_compiled_part_of_model() -> None:
    wrong = [
        _where(imp)
        for imp in _imports()
        if imp.source.split(".")[0] == "app"
        and imp.target.split(".")[0] == "model"
        and (
            imp.target.startswith("model.fast_march")
            or any(part.startswith("_") for part in imp.target.split("."))
            or any(name.startswith("_") for name in imp.names)
        )
    ]
    assert not wrong, wrong


# The one door to the statistics (model/posterior.py) and the parts of model/ that are not
# statistics: records and their checks, loads and cycles, the physics, its tables and crack
# cases, the fleet generators, the runtime.  model.forecast is the future loads and the calendar; its marches
# are the door's (FORECAST_MARCHES).
DOOR = "model.posterior"
NOT_STATISTICS = {
    "model.records",
    "model.record_validation",
    "model.cycle_counting",
    "model.spectrum_files",
    "model.integrate",
    "model.growth_laws",
    "model.physics",
    "model.geometry",
    "model.materials",
    "model.materials_file",
    "model.training_data",
    "model.runtime",
    "model.dynamo_import",
    "model.fleet",
    "model.spectra_fleet",
    "model.forecast",
    "model.record_bounds",
}
NOT_STATISTICS_PACKAGES = ("model.crack_cases",)  # fracture mechanics: beta(a), a_crit
FORECAST_MARCHES = {"march_ahead", "flights_to_critical", "first_at_or_above"}


def test_app_reaches_the_statistics_through_the_door_only() -> None:
    """app/ imports of model/ are the door or a part that is not statistics (issue 39: the
    app stores and serves what the door returns)."""
    wrong = [
        _where(imp)
        for imp in _imports()
        if imp.source.split(".")[0] == "app"
        and imp.target.split(".")[0] == "model"
        and imp.target != DOOR
        and imp.target not in NOT_STATISTICS
        and not imp.target.startswith(NOT_STATISTICS_PACKAGES)
    ]
    assert not wrong, wrong


def _forecast_names(path: Path) -> set[str]:
    """Names of model.forecast a module uses: imported from it, or read off its alias."""
    tree = ast.parse(path.read_text(), str(path))
    aliases, used = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "model.forecast":
            used.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module == "model":
            aliases.update(a.asname or a.name for a in node.names if a.name == "forecast")
    for node in ast.walk(tree):
        named = isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
        if named and node.value.id in aliases:  # type: ignore[attr-defined]
            used.add(node.attr)  # type: ignore[attr-defined]
    return used


def test_app_marches_forecasts_through_the_door_only() -> None:
    modules = _modules()
    wrong = {
        name: sorted(_forecast_names(path) & FORECAST_MARCHES)
        for name, path in modules.items()
        if name.split(".")[0] == "app" and _forecast_names(path) & FORECAST_MARCHES
    }
    assert not wrong, wrong
    assert "recent_utilization" in _forecast_names(modules["app.services.forecasts.cache_fill"])


def test_no_import_circle() -> None:
    edges: dict[str, set[str]] = {}
    for imp in _imports():
        if imp.target != imp.source:
            edges.setdefault(imp.source, set()).add(imp.target)
    done: set[str] = set()

    def circle_from(module: str, path: list[str]) -> list[str] | None:
        if module in path:
            return [*path[path.index(module) :], module]
        if module in done:
            return None
        for target in sorted(edges.get(module, ())):
            circle = circle_from(target, [*path, module])
            if circle is not None:
                return circle
        done.add(module)
        return None

    for module in sorted(edges):
        circle = circle_from(module, [])
        assert circle is None, " -> ".join(circle)
