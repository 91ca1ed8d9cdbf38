"""Identity and roles: API keys (stored hashed), 401/403, the login cookie of the pages, the
OpenAPI security schemes, and the key that every write records."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from app.cli import main
from app.services import keys
from app.tables import ApiKey
from tests.app.conftest import add_tail, bearer, flights, new_key

OPEN = ("/health", "/ready", "/metrics", "/docs", "/redoc", "/openapi.json", "/pages/login")


def test_no_key_is_401_and_the_open_paths_stay_open(client: TestClient) -> None:
    for path in OPEN:
        assert client.get(path, headers={"Authorization": ""}).status_code == 200, path
    anonymous = TestClient(client.app)
    answer = anonymous.get("/aircraft")
    assert answer.status_code == 401
    assert answer.headers["www-authenticate"] == "Bearer"
    assert "Authorization: Bearer" in answer.json()["detail"]
    assert anonymous.put("/aircraft/N1").status_code == 401
    wrong = "fpk_00000000_" + "A" * 43
    for headers in (bearer(wrong), {"X-API-Key": "nonsense"}, bearer("")):
        answer = anonymous.get("/aircraft", headers=headers)
        assert answer.status_code == 401, headers
    assert "invalid or revoked" in anonymous.get("/aircraft", headers=bearer(wrong)).text


def test_roles_read_write_admin(client: TestClient) -> None:
    app = client.app
    reader, writer = new_key(app, "read"), new_key(app, "write")  # type: ignore[arg-type]
    add_tail(client, "N1", 4)
    as_reader = {"Authorization": "", "X-API-Key": reader}  # the other header works too
    assert client.get("/aircraft/N1", headers=as_reader).status_code == 200
    refused = client.post("/aircraft/N1/flights", json=flights(1), headers=as_reader)
    assert refused.status_code == 403
    assert "'read'" in refused.json()["detail"] and "'write'" in refused.json()["detail"]
    assert client.get("/aircraft/N1").json()["flight_count"] == 4  # nothing stored
    assert client.post("/models/retrain", headers=as_reader).status_code == 403
    as_writer = bearer(writer)
    more = flights(6)[4:]
    assert client.post("/aircraft/N1/flights", json=more, headers=as_writer).status_code == 201
    assert client.post("/models/1/activate", headers=as_writer).status_code == 403
    assert client.get("/audit", headers=as_writer).status_code == 403
    assert client.post("/models/1/activate").status_code == 404  # admin passes, no version


def test_keys_are_stored_hashed_revocable_and_named_once(client: TestClient) -> None:
    app = client.app
    with app.state.session_factory() as session:  # type: ignore[attr-defined]
        created = keys.create_key(session, role="read", name="ops")
        stored = session.scalars(select(ApiKey).where(ApiKey.key_id == created.key_id)).one()
        secret = created.key.rsplit("_", 1)[1]
        assert secret not in (stored.key_hash, stored.salt) and len(stored.key_hash) == 64
        with pytest.raises(keys.ConflictError):
            keys.create_key(session, role="read", name="ops")
        with pytest.raises(ValueError, match="name must be"):  # cli:<command> is no key's name
            keys.create_key(session, role="read", name="cli:seed-demo")
        assert client.get("/aircraft", headers=bearer(created.key)).status_code == 200
        keys.revoke_key(session, "ops")
    time.sleep(app.state.settings.key_cache_seconds)  # type: ignore[attr-defined]
    assert client.get("/aircraft", headers=bearer(created.key)).status_code == 401
    # the name is free again once its key is revoked
    assert client.get("/aircraft", headers=bearer(new_key(app, "read", "ops"))).status_code == 200  # type: ignore[arg-type]


def test_every_write_records_its_key(client: TestClient) -> None:
    app = client.app
    writer = bearer(new_key(app, "write", "line-maintenance"))  # type: ignore[arg-type]
    assert client.put("/aircraft/N1", headers=writer).status_code == 201
    assert client.post("/aircraft/N1/flights", json=flights(3), headers=writer).status_code == 201
    body = {"inspection_id": "I1", "inspected_at": "2024-01-02T00:00:00Z", "crack_length_m": 0.005}
    assert client.post("/aircraft/N1/inspections", json=body, headers=writer).status_code == 201
    job = client.post("/models/retrain", headers=writer).json()["job_id"]
    listed = client.get("/aircraft/N1/inspections").json()
    assert listed[0]["recorded_by"] == "line-maintenance"
    assert client.get("/aircraft/N1/flights/F0001").json()["recorded_by"] == "line-maintenance"
    assert client.get(f"/jobs/{job}").json()["requested_by"] == "line-maintenance"
    events = client.get("/audit", params={"limit": 10}).json()["items"]
    by_action = {e["action"]: e for e in events}
    assert {"aircraft.create", "flights.ingest", "inspections.ingest", "retrain"} <= set(by_action)
    assert {e["actor"] for e in events if e["action"] != "key.create"} == {"line-maintenance"}
    assert by_action["flights.ingest"]["detail"]["inserted"] == 3
    assert by_action["retrain"]["subject"] == f"job/{job}"


def test_openapi_declares_both_key_schemes(client: TestClient) -> None:
    document = client.get("/openapi.json").json()
    schemes = document["components"]["securitySchemes"]
    assert schemes["bearer"] == {
        "type": "http",
        "scheme": "bearer",
        "description": schemes["bearer"]["description"],
    }
    assert schemes["apiKey"]["in"] == "header" and schemes["apiKey"]["name"] == "X-API-Key"
    operation = document["paths"]["/aircraft/{tail}/inspections"]["post"]
    assert {"bearer": []} in operation["security"] and {"apiKey": []} in operation["security"]
    assert "security" not in document["paths"]["/health"]["get"]


def test_pages_log_in_with_a_cookie_that_only_reads(client: TestClient) -> None:
    reader = new_key(client.app, "read")  # type: ignore[arg-type]
    browser = TestClient(client.app, follow_redirects=False)
    sent = browser.get("/pages/models")
    assert sent.status_code == 303
    assert sent.headers["location"] == "/pages/login?next=/pages/models"
    refused = browser.post("/pages/login", data={"key": "wrong", "next": "/pages/models"})
    assert refused.status_code == 401 and "unknown or revoked" in refused.text
    logged_in = browser.post("/pages/login", data={"key": reader, "next": "/pages/models"})
    assert logged_in.status_code == 303 and logged_in.headers["location"] == "/pages/models"
    cookie = logged_in.headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=strict" in cookie
    assert browser.get("/pages/models").status_code == 200
    assert browser.get("/aircraft").status_code == 200  # a GET reads with the cookie
    assert browser.put("/aircraft/N9").status_code == 401  # a write never does
    # no open redirect: only paths on this server
    away = browser.post("/pages/login", data={"key": reader, "next": "//evil.example/x"})
    assert away.headers["location"] == "/"
    assert browser.post("/pages/logout").headers["location"] == "/pages/login"


def test_login_and_logout_refuse_forms_of_other_sites(client: TestClient) -> None:
    reader = new_key(client.app, "read")  # type: ignore[arg-type]
    browser = TestClient(client.app, follow_redirects=False)  # base http://testserver
    form = {"key": reader, "next": "/"}
    for sender in (
        {"origin": "https://evil.example"},
        {"origin": "null"},  # a sandboxed or data: page
        {"origin": "http://testserver:8080"},  # another port is another origin
        {"referer": "https://evil.example/login-csrf.html"},
    ):
        refused = browser.post("/pages/login", data=form, headers=sender)
        assert refused.status_code == 403, sender
        assert "set-cookie" not in refused.headers
        assert "sent from another site" in refused.text
        assert browser.post("/pages/logout", headers=sender).status_code == 403
    own = {"origin": "http://testserver", "referer": "http://testserver/pages/login?next=/"}
    logged_in = browser.post("/pages/login", data=form, headers=own)
    assert logged_in.status_code == 303 and "set-cookie" in logged_in.headers
    assert browser.get("/pages/models").status_code == 200
    assert browser.post("/pages/logout", headers=own).status_code == 303


def test_keys_command_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("FLEETPINN_DATABASE_URL", f"sqlite:///{tmp_path / 'keys.db'}")
    from app.config import get_settings

    get_settings.cache_clear()
    try:
        out = tmp_path / "demo-key"
        assert main(["keys", "create", "--role", "admin", "--name", "demo", "--out", str(out)]) == 0
        printed = capsys.readouterr()
        key = printed.out.strip()
        assert key.startswith("fpk_") and out.read_text().strip() == key
        assert out.stat().st_mode & 0o777 == 0o600
        assert "not shown again" in printed.err
        assert main(["keys", "create", "--role", "read", "--name", "demo"]) == 2
        assert "--replace" in capsys.readouterr().err
        assert main(["keys", "create", "--role", "admin", "--name", "demo", "--replace"]) == 0
        capsys.readouterr()
        assert main(["keys", "list"]) == 0
        listed = json.loads(capsys.readouterr().out)
        # oldest first: the replaced key is revoked, the new one live
        assert [(k["name"], k["revoked_at"] is not None) for k in listed] == [
            ("demo", True),
            ("demo", False),
        ]
        assert key not in json.dumps(listed)
        assert main(["keys", "revoke", "nobody"]) == 2
        assert main(["keys", "revoke", "demo"]) == 0
    finally:
        get_settings.cache_clear()
