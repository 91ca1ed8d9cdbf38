"""Logging in to the pages: an API key (any role) pasted once into a form becomes an HttpOnly,
SameSite=Strict cookie that lets the browser read pages and images (app.auth: GET and HEAD
only; writes always need the key in a header)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, Query, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from app.auth import COOKIE
from app.services import keys
from app.web.html import templates

router = APIRouter(tags=["pages"], include_in_schema=False)

# A browser session lasts a working day; the key itself stays valid until revoked.
_COOKIE_SECONDS = 12 * 3600


def _local(path: str | None) -> str:
    """Where to go after logging in: a path on this server only (no open redirect)."""
    if path and path.startswith("/") and not path.startswith("//") and "\\" not in path:
        return path
    return "/"


def _form(request: Request, next_path: str, error: str | None, status_code: int) -> HTMLResponse:
    return templates.TemplateResponse(
        request,
        "login.html",
        {"nav": None, "next_path": next_path, "error": error},
        status_code=status_code,
    )


@router.get("/pages/login", name="login_page")
def login_page(
    request: Request, next_path: Annotated[str | None, Query(alias="next")] = None
) -> HTMLResponse:
    """The login form."""
    return _form(request, _local(next_path), None, 200)


@router.post("/pages/login")
def login(
    request: Request,
    key: Annotated[str, Form(max_length=200)],
    next_path: Annotated[str, Form(alias="next")] = "/",
) -> Response:
    """Check the key; on success set the cookie and go on to `next`."""
    with request.app.state.session_factory() as session:
        found = keys.find_key(session, key)
    if found is None:
        return _form(request, _local(next_path), "That key is unknown or revoked.", 401)
    response = RedirectResponse(_local(next_path), status_code=303)
    response.set_cookie(
        COOKIE,
        key.strip(),
        max_age=_COOKIE_SECONDS,
        httponly=True,
        samesite="strict",
        secure=request.url.scheme == "https",
    )
    return response


@router.post("/pages/logout", name="logout")
def logout() -> Response:
    """Forget the cookie."""
    response = RedirectResponse("/pages/login", status_code=303)
    response.delete_cookie(COOKIE)
    return response
