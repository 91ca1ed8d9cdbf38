"""The HTTP side of `fleetpinn client`: one service at a base URL, errors as one line.

A 4xx answer (the request was wrong: a bad file, an unknown tail) becomes CommandError (exit
status 2), a 5xx or a service that cannot be reached CommandFailed (status 1), each with the
server's reason in one line.  An API key, when given, goes as `Authorization: Bearer <key>`.
"""

from __future__ import annotations

from typing import Any

import httpx

from app.cli.registry import CommandError, CommandFailed


class Api:
    """The service at `url`; errors become one-line CommandError (4xx) or CommandFailed."""

    def __init__(self, url: str, key: str | None, timeout_s: float) -> None:
        headers = {"authorization": f"Bearer {key}"} if key else {}
        self.url = url.rstrip("/")
        self.http = httpx.Client(base_url=self.url, headers=headers, timeout=timeout_s)

    def call(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        try:
            answer = self.http.request(method, path, **kwargs)
        except httpx.TransportError as exc:
            raise CommandFailed(f"cannot reach the service at {self.url}: {exc}") from exc
        if answer.status_code >= 400:
            message = f"{answer.status_code} from {method} {path}: {_detail(answer)}"
            if answer.status_code >= 500:
                raise CommandFailed(message)
            raise CommandError(message)
        return answer

    def json(self, method: str, path: str, **kwargs: Any) -> Any:
        return self.call(method, path, **kwargs).json()


def _detail(answer: httpx.Response) -> str:
    """The server's reason in one line: its `detail`, the first validation error, or the text."""
    try:
        body = answer.json()
    except ValueError:
        return " ".join(answer.text.split())[:300] or answer.reason_phrase
    detail = body.get("detail") if isinstance(body, dict) else body
    if isinstance(detail, list) and detail:
        first = detail[0]
        where = ".".join(str(part) for part in first.get("loc", []))
        return f"{where}: {first.get('msg')}"
    return str(detail)
