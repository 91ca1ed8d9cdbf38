"""Routes stay thin: a schema in, a service call, a schema out.  No route module imports the
tables' classes or another route module, and none keeps a per-process memo (services do)."""

from __future__ import annotations

import ast
from pathlib import Path

ROUTES = Path(__file__).parents[2] / "app" / "routes"


def _imports(path: Path) -> set[str]:
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


def test_no_route_imports_the_tables_another_route_or_a_memo() -> None:
    modules = sorted(p for p in ROUTES.glob("*.py") if p.name != "__init__.py")
    assert len(modules) > 10
    for path in modules:
        imported = _imports(path)
        assert "app.tables" not in imported, path.name
        assert not any(m.startswith("app.routes") for m in imported), path.name
        assert "app.services.memo" not in imported, path.name
