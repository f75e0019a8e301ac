"""A job's read-only share token (POST /api/jobs/{id}/share): it reads that one job and nothing more."""

from __future__ import annotations

from tests.support.api import INSTRUCTOR, bearer, student_token, submit, tiny_scene, wait_status


def test_api_share_token_reads_one_job_and_changes_nothing(client):
    job = submit(client, tiny_scene())
    other = submit(client, tiny_scene(seed=1))
    wait_status(client, job["id"], {"done"})
    wait_status(client, other["id"], {"done"})
    r = client.post(f"/api/jobs/{job['id']}/share")
    assert r.status_code == 200
    share = r.json()["share_token"]
    assert r.json()["link"] == f"/#shared/{job['id']}/{share}"
    assert client.post(f"/api/jobs/{job['id']}/share").json()["share_token"] == share  # the same each time
    guest = bearer(share)
    assert client.get(f"/api/jobs/{job['id']}", headers=guest).json()["status"] == "done"
    for path in ("image", "image?format=exr", "scene", "aov", "aov/rays", "events"):
        assert client.get(f"/api/jobs/{job['id']}/{path}", headers=guest).status_code == 200, path
    # nothing else: not the owner's other job, not a cancel, not a share of its own, not the owner's list
    assert client.get(f"/api/jobs/{other['id']}", headers=guest).status_code == 404
    assert client.delete(f"/api/jobs/{job['id']}", headers=guest).status_code == 404
    assert client.post(f"/api/jobs/{job['id']}/share", headers=guest).status_code == 404
    assert client.get("/api/jobs", headers=guest).json()["jobs"] == []
    # another student's token, or none, still gets the 404 of an unknown id
    for headers in (bearer(student_token()), {"Authorization": ""}):
        assert client.get(f"/api/jobs/{job['id']}", headers=headers).status_code in (401, 404)
    assert client.get(f"/api/jobs/{job['id']}", headers=bearer(student_token())).status_code == 404
    assert client.post(f"/api/jobs/{job['id']}/share", headers=bearer(student_token())).status_code == 404
    # another job's share token reads nothing of this one
    other_share = client.post(f"/api/jobs/{other['id']}/share").json()["share_token"]
    assert client.get(f"/api/jobs/{job['id']}/image", headers=bearer(other_share)).status_code == 404
    assert other_share != share


def test_api_share_a_job_with_no_owner_is_refused(client):
    job = submit(client, tiny_scene())
    wait_status(client, job["id"], {"done"})
    # the instructor shares a student's job; a job without an owner (grading) has no share token
    assert client.post(f"/api/jobs/{job['id']}/share", headers=bearer(INSTRUCTOR)).status_code == 200
    from server.core.security import share_token

    assert share_token({"id": job["id"], "owner": None}) is None
