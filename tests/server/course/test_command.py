"""The instructor's command line (server/course/command.py, `python -m server.course`) against a real server on
loopback (`python -m server`): publish the repository's own assignment (scenes/grading/assignment.json, its
reference scene a file beside it), upload a roster and write the links, a student submits with a link's
token, and the grades are written; what the server refuses is printed as its `path: message` lines, a
missing file is named, and a server that is not there is one line."""

from __future__ import annotations

import base64
import csv
import io
import json
import os
import re
import subprocess
import sys

import pytest

from server.course.command import main, token_joined
from tests.support.api import INSTRUCTOR, Server, bearer, free_port, wait_for
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
DEADLINE = "2100-01-01T12:00:00+01:00"


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(
        tmp_path_factory.mktemp("command") / "data", workers=1, env={"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    ) as s:
        yield s


def cli(server: Server, capsys, *argv: str, token: str | None = INSTRUCTOR) -> tuple[int, str, str]:
    """The command run in this process (its HTTP goes to the server): (exit code, stdout, stderr)."""
    extra = ["--server", server.url] + (["--token", token] if token else [])
    code = main([*argv, *extra])
    out = capsys.readouterr()
    return code, out.out, out.err


def published(server: Server, capsys, *policy: str) -> str:
    code, out, err = cli(server, capsys, "publish", str(EXAMPLE / "assignment.json"), "--deadline", DEADLINE, *policy)
    assert code == 0, err
    return out.splitlines()[0]


def test_command_publish_sends_the_spec_with_its_reference_file_and_the_policy(server, tmp_path):
    """As a process of its own (`python -m server.course`), the server and token from the environment."""
    env = {**os.environ, "TRACER_SERVER": server.url, "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    argv = [sys.executable, "-m", "server.course", "publish", str(EXAMPLE / "assignment.json"),
            "--deadline", DEADLINE, "--late-until", "2100-01-02T12:00:00Z", "--late-penalty", "0.25",
            "--max-submissions", "3", "--counts", "best", "--show-reference",
            "--feedback", '{"tests": {"pixels": "after_deadline"}}']  # fmt: skip
    p = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    aid = lines[0]
    assert re.fullmatch(r"[0-9a-f]{32}", aid), p.stdout
    text = "\n".join(lines)
    assert "HW 4: glass, mirrors and soft shadows (version 1)" in text
    assert "deadline: 2100-01-01T11:00:00Z; late until 2100-01-02T12:00:00Z, 25 % off" in text
    assert "13 points: validity 1; requirements: a glass object 2, an area light 1" in text
    assert "image tests: flip 2, ssim 1, psnr 1, pixels 2" in text
    assert "submissions: at most 3, the best counts; reference image shown: yes; open: no" in text
    assert lines[-1] == f"  the brief's page: {server.url}/assignments/{aid}"  # the page a student opens
    page = server.client.get(f"/assignments/{aid}")
    assert page.status_code == 200
    assert "text/html" in page.headers["content-type"]

    a = server.client.get(f"/api/assignments/{aid}", headers=bearer(INSTRUCTOR)).json()
    assert a["spec"]["reference"]["scene"] == json.loads((EXAMPLE / "reference.json").read_text())  # the file, inline
    p = a["policy"]
    assert (p["max_submissions"], p["counts"], p["show_reference"], p["late_penalty"]) == (3, "best", True, 0.25)
    assert p["feedback"]["tests"] == {"pixels": "after_deadline"}
    assert p["open"] is False


def test_command_roster_writes_the_links_and_grades_the_csv(server, capsys, tmp_path):
    """The links' CSV has a working token for each student; a student submits grace's PNG with theirs; the
    grades' CSV has a row per roster student, the graded one with its score. Uploading the roster again
    adds no one: the students keep their links (the same ones in the CSV: tokens are derived)."""
    aid = published(server, capsys, "--starter", str(EXAMPLE / "class" / "alice.json"))
    (tmp_path / "roster.csv").write_text("id,name,email\ng1,Grace Hopper,grace@x.edu\nh2,Heidi,\n")
    links = tmp_path / "links.csv"
    code, out, err = cli(server, capsys, "roster", aid, str(tmp_path / "roster.csv"), "--out", str(links))
    assert code == 0, err
    assert out == ""
    assert "2 student(s) on the roster: their links in" in err
    rows = list(csv.DictReader(io.StringIO(links.read_text())))
    assert [(r["id"], r["name"], r["email"]) for r in rows] == [
        ("g1", "Grace Hopper", "grace@x.edu"),
        ("h2", "Heidi", ""),
    ]
    token = rows[0]["link"].split("#token=")[1]
    assert rows[0]["link"].startswith(f"{server.url}/assignments/{aid}#token=")
    brief = server.client.get(f"/api/assignments/{aid}", headers=bearer(token)).json()
    assert brief["student"]["name"] == "Grace Hopper"
    assert brief["starter"]["name"] == "Alice's glass ball"

    png = base64.b64encode((EXAMPLE / "class" / "grace.png").read_bytes()).decode()
    r = server.client.post(f"/api/assignments/{aid}/submissions", json={"image": png, "format": "png"},
                           headers=bearer(token))  # fmt: skip
    assert r.status_code == 202, r.text
    url = r.headers["location"]
    wait_for(lambda: server.client.get(url, headers=bearer(token)).json()["status"] == "graded", 240, "the grade", 0.2)

    out_csv = tmp_path / "grades.csv"
    code, out, err = cli(server, capsys, "grades", aid, "--out", str(out_csv))
    assert code == 0, err
    assert "2 student(s), 1 with a grade" in err
    header = "id,name,score,max_score,late,submissions"
    assert out_csv.read_text().splitlines() == [header, "g1,Grace Hopper,7,7,false,1", "h2,Heidi,,,,0"]
    code, out, err = cli(server, capsys, "grades", aid)  # to standard output
    assert code == 0
    assert out == out_csv.read_text()

    code, out, err = cli(server, capsys, "roster", aid, str(tmp_path / "roster.csv"))  # again, to standard output
    assert code == 0
    assert "2 student(s) on the roster: their links above" in err
    assert [r["link"] for r in csv.DictReader(io.StringIO(out))] == [r["link"] for r in rows]


def test_command_prints_the_server_s_errors_at_their_paths(server, capsys, tmp_path):
    spec = json.loads((EXAMPLE / "assignment.json").read_text())
    spec["requirements"][1]["check"] = "area_ligth"
    (tmp_path / "reference.json").write_text((EXAMPLE / "reference.json").read_text())
    (tmp_path / "bad.json").write_text(json.dumps(spec))
    code, out, err = cli(server, capsys, "publish", str(tmp_path / "bad.json"), "--deadline", DEADLINE)
    assert code == 1
    assert out == ""
    assert err.startswith("spec.requirements[1].check: unknown preset 'area_ligth'; did you mean 'area_light'?"), err

    good = str(EXAMPLE / "assignment.json")
    code, _, err = cli(server, capsys, "publish", good, "--deadline", "2100-01-01T12:00:00")
    assert code == 1 and err.startswith("deadline: '2100-01-01T12:00:00' has no zone: add one"), err
    code, _, err = cli(
        server, capsys, "publish", good, "--deadline", DEADLINE, "--feedback", '{"tests": {"pixles": "never"}}'
    )
    assert code == 1 and err.startswith("feedback.tests.pixles: no test named 'pixles' in the spec"), err
    code, _, err = cli(server, capsys, "publish", good, "--deadline", DEADLINE, token=None)  # the instructor's route
    assert code == 1 and err.startswith("Authorization: "), err

    (tmp_path / "roster.csv").write_text("name,id,email\nAda,a1,\n")
    aid = published(server, capsys)
    code, _, err = cli(server, capsys, "roster", aid, str(tmp_path / "roster.csv"), "--out", str(tmp_path / "l.csv"))
    assert code == 1
    assert err == "line 1: expected the header 'id,name,email'; got 'name,id,email'\n"
    assert not (tmp_path / "l.csv").exists()
    code, _, err = cli(server, capsys, "grades", "f" * 32)
    assert code == 1
    assert err == f"id: no assignment with id '{'f' * 32}'\n"


def test_command_names_a_missing_file_and_a_server_that_is_not_there(server, capsys, tmp_path):
    spec = json.loads((EXAMPLE / "assignment.json").read_text())
    spec["reference"]["scene"] = "missing.json"
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    code, _, err = cli(server, capsys, "publish", str(tmp_path / "spec.json"), "--deadline", DEADLINE)
    assert code == 2
    assert (
        err == f"{tmp_path / 'missing.json'}: no such file (the spec's reference.scene, looked for next to spec.json)\n"
    )
    code, _, err = cli(server, capsys, "publish", str(tmp_path / "nope.json"), "--deadline", DEADLINE)
    assert code == 2
    assert err == f"{tmp_path / 'nope.json'}: no such file (the grading spec)\n"
    code, _, err = cli(server, capsys, "roster", "f" * 32, str(tmp_path / "roster.csv"))
    assert code == 2
    assert err.startswith(f"{tmp_path / 'roster.csv'}: no such file (the roster")

    nobody = f"http://127.0.0.1:{free_port()}"
    code = main(["grades", "f" * 32, "--server", nobody])
    err = capsys.readouterr().err
    assert code == 3 and err.startswith(f"cannot reach the server at {nobody}: ") and err.count("\n") == 1, err


def test_command_courses_staff_and_a_course_roster(server, capsys, tmp_path):
    """course-create, staff-add (the TA's link opens the course as a TA and cannot publish), course-roster (the
    course's page links), publish --course (the students already enrolled are on it), links (the same again)."""
    code, out, err = cli(server, capsys, "course-create", "gfx", "--name", "Computer Graphics")
    assert (code, out) == (0, "gfx\n"), err
    code, out, err = cli(server, capsys, "staff-add", "gfx", "tina", "--role", "ta", "--name", "Tina")
    assert code == 0 and "Tina is a ta of gfx" in err, err
    ta = out.strip().split("#token=")[1]
    assert out.startswith(f"{server.url}/course#token=")
    code, _, err = cli(server, capsys, "publish", str(EXAMPLE / "assignment.json"), "--deadline", DEADLINE,
                       "--course", "gfx", token=ta)  # fmt: skip
    assert code == 1 and err.startswith("role: a TA may not publish"), err
    (tmp_path / "class.csv").write_text("id,name,email\nkim,Kim,kim@x.edu\n")
    code, out, err = cli(server, capsys, "course-roster", "gfx", str(tmp_path / "class.csv"))
    assert code == 0 and "1 student(s) enrolled in gfx" in err, err
    link = next(csv.DictReader(io.StringIO(out)))["link"]
    assert link.startswith(f"{server.url}/courses/gfx#token=")
    aid = published(server, capsys, "--course", "gfx")
    kim = bearer(link.split("#token=")[1])
    assert server.client.get(f"/api/assignments/{aid}", headers=kim).json()["student"]["id"] == "kim"
    code, out, err = cli(server, capsys, "links", "gfx", "--assignment", aid)
    assert code == 0 and next(csv.DictReader(io.StringIO(out)))["link"] == link.replace(
        "courses/gfx", f"assignments/{aid}"
    )
    code, out, _ = cli(server, capsys, "courses")
    assert code == 0
    assert "gfx\tComputer Graphics\t1 assignment(s)\t1 student(s)" in out


def test_command_takes_a_token_that_starts_with_a_dash(server, capsys):
    """One token in 64 starts with "-" (URL-safe base64): `--token -...` is still the token, not an option (argparse
    said "expected one argument" for such a TA's link; a whole CI run met one). This one is no token of the server's:
    its refusal (not argparse's usage line) shows that the token was sent."""
    code, out, err = cli(server, capsys, "courses", token="-x" + "A" * 41)
    assert code == 1, err
    assert "expected one argument" not in err, err
    assert err.startswith("Authorization: this token is not the instructor's"), err
    assert token_joined(["a", "--token", "-b", "c"]) == ["a", "--token=-b", "c"]
    assert token_joined(["--token"]) == ["--token"]  # a bare one is argparse's to refuse
