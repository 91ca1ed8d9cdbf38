"""The Jinja2 environment of the pages (templates shipped in app/web/templates) and the static
files (app/web/static) they link to."""

from __future__ import annotations

from pathlib import Path

from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates

from app.web.format import FILTERS

_HERE = Path(__file__).parent
STATIC_NAME = "web-static"

templates = Jinja2Templates(directory=_HERE / "templates")
templates.env.filters.update(FILTERS)


def static_files() -> StaticFiles:
    """The pages' stylesheet and icon, mounted by app.main under /static as STATIC_NAME."""
    return StaticFiles(directory=_HERE / "static")
