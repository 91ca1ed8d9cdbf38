"""Interactive API docs (Swagger UI, ReDoc) served with their assets from the package.

FastAPI's own /docs and /redoc load their JavaScript from a CDN and stay blank without internet;
these pages load the same tools from the pinned fastapi-offline package's files (MIT licence),
mounted by app.main at ASSETS_PATH.  ReDoc's bundle draws its "API docs by Redocly" logo from
its CDN whatever the options say; this router serves the bundle with that one address pointed
at the package's own favicon, so no page asks the internet for anything.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import fastapi_offline
from fastapi import APIRouter, Request, Response
from fastapi.openapi.docs import (
    get_redoc_html,
    get_swagger_ui_html,
    get_swagger_ui_oauth2_redirect_html,
)
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

ASSETS_PATH = "/docs-assets"
ASSETS_NAME = "docs-assets"
OAUTH2_REDIRECT = "/docs/oauth2-redirect"

REDOC_LOGO_URL = "https://cdn.redoc.ly/redoc/logo-mini.svg"
# Relative to the page (/redoc), so it holds under a root path too.
_LOCAL_LOGO = "docs-assets/favicon.png"
_ASSETS_DIR = Path(fastapi_offline.__file__).parent / "static"

router = APIRouter(include_in_schema=False)


def assets() -> StaticFiles:
    return StaticFiles(directory=_ASSETS_DIR)


@lru_cache(maxsize=1)
def _redoc_bundle() -> bytes:
    """ReDoc's bundle with its CDN logo replaced by the local favicon.  Raises RuntimeError when
    the pinned bundle no longer holds that address (a new ReDoc: check it asks for nothing)."""
    text = (_ASSETS_DIR / "redoc.standalone.js").read_text(encoding="utf-8")
    if REDOC_LOGO_URL not in text:
        raise RuntimeError(f"redoc.standalone.js no longer names {REDOC_LOGO_URL}")
    return text.replace(REDOC_LOGO_URL, _LOCAL_LOGO).encode()


# Routed before the assets mount (app.main includes routers first), so it shadows the file.
@router.get(f"{ASSETS_PATH}/redoc.standalone.js")
def redoc_bundle() -> Response:
    return Response(
        _redoc_bundle(),
        media_type="text/javascript",
        headers={"cache-control": "public, max-age=86400"},
    )


def _root(request: Request) -> str:
    return str(request.scope.get("root_path", ""))


@router.get("/docs")
def swagger_ui(request: Request) -> HTMLResponse:
    """Swagger UI over /openapi.json."""
    root = _root(request)
    return get_swagger_ui_html(
        openapi_url=f"{root}{request.app.openapi_url}",
        title=f"{request.app.title} - Swagger UI",
        oauth2_redirect_url=f"{root}{OAUTH2_REDIRECT}",
        swagger_js_url=f"{root}{ASSETS_PATH}/swagger-ui-bundle.js",
        swagger_css_url=f"{root}{ASSETS_PATH}/swagger-ui.css",
        swagger_favicon_url=f"{root}{ASSETS_PATH}/favicon.png",
    )


@router.get(OAUTH2_REDIRECT)
def swagger_ui_redirect() -> HTMLResponse:
    return get_swagger_ui_oauth2_redirect_html()


@router.get("/redoc")
def redoc(request: Request) -> HTMLResponse:
    """ReDoc over /openapi.json, without web fonts."""
    root = _root(request)
    return get_redoc_html(
        openapi_url=f"{root}{request.app.openapi_url}",
        title=f"{request.app.title} - ReDoc",
        redoc_js_url=f"{root}{ASSETS_PATH}/redoc.standalone.js",
        redoc_favicon_url=f"{root}{ASSETS_PATH}/favicon.png",
        with_google_fonts=False,
    )
