"""Logging in to the pages: an API key (any role) pasted once into a form becomes an HttpOnly,
SameSite=Strict cookie that lets the browser read pages and images (app.auth: GET and HEAD
only; writes always need the key in a header).

Login and logout answer only forms of this site: a browser names the page that sent a form in
`Origin` (or, failing that, `Referer`), and a form from another origin is refused with 403, so
no other site can log a visitor in with its own key (login CSRF) or out.  A client that sends
neither (curl, scripts) is no browser carrying someone's cookies and is served."""

from __future__ import annotations

from typing import Annotated
from urllib.parse import urlsplit

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


def _from_elsewhere(request: Request) -> bool:
    """Whether the form came from a page of another host (Origin, else Referer; "null" is
    another one: a sandboxed or data: page).  Hosts with their ports are compared, not schemes:
    behind a proxy that ends TLS the service sees http where the browser sent https."""
    sender = request.headers.get("origin") or request.headers.get("referer")
    if sender is None:
        return False
    return urlsplit(sender).netloc != request.url.netloc


_ELSEWHERE = "Refused: this form was sent from another site. Log in from this page."


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
    if _from_elsewhere(request):
        return _form(request, _local(next_path), _ELSEWHERE, 403)
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
def logout(request: Request) -> Response:
    """Forget the cookie."""
    if _from_elsewhere(request):
        return _form(request, "/", _ELSEWHERE, 403)
    response = RedirectResponse("/pages/login", status_code=303)
    response.delete_cookie(COOKIE)
    return response
