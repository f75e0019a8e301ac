"""A course's assignment through the API: published, a roster, submissions and their grades
(tests/server/course/test_api_assignments.py and the tests built on it)."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

from tests.support.api import INSTRUCTOR, bearer, wait_for
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"


CLASS = EXAMPLE / "class"


T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)  # the tests' "now" (the app's clock is set to it)


DEADLINE = T0 + timedelta(days=2)


def spec(inline: bool = True) -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    if inline:
        a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def scene_text(name: str) -> str:
    return (CLASS / f"{name}.json").read_text()


def publish(client, **policy) -> dict:
    body = {"spec": spec(), "deadline": DEADLINE.isoformat(), **policy}
    r = client.post("/api/assignments", json=body)
    assert r.status_code == 201, r.text
    assert r.headers["location"] == f"/api/assignments/{r.json()['id']}"
    return r.json()


def roster(client, aid: str, rows: list[tuple[str, str, str]]) -> dict[str, dict]:
    text = "id,name,email\n" + "".join(f"{i},{n},{e}\n" for i, n, e in rows)
    r = client.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv"})
    assert r.status_code == 200, r.text
    return {s["id"]: s for s in r.json()["students"]}


def submit(client, aid: str, token: str, body: dict, status: int = 202) -> dict:
    r = client.post(f"/api/assignments/{aid}/submissions", json=body, headers=bearer(token))
    assert r.status_code == status, r.text
    return r.json()


def finished(client, aid: str, sid: str, token: str = INSTRUCTOR, timeout: float = 240) -> dict:
    url = f"/api/assignments/{aid}/submissions/{sid}"

    def done():
        s = client.get(url, headers=bearer(token)).json()
        return s["status"] in ("graded", "invalid", "failed") and s

    return wait_for(done, timeout, f"submission {sid} graded", interval=0.1)
