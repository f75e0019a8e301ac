"""python -m server.lti try: the whole LTI flow against a pretend LMS on loopback, before any real LMS is touched
(docs/lti.md, "Try it without an LMS").

It plays the platform (server/lti/platform.py, on 127.0.0.1) and talks to the tool as an LMS and its users' browsers
would, over HTTP only: the tool is `python -m server` started for the try (a temporary data directory, one render
worker, a random admin token), or a running one given by `--url` (on this machine: it must reach the pretend LMS on
127.0.0.1) with its admin token (`--token`, or TRACER_INSTRUCTOR_TOKEN). The steps, each printed with what happened:

1. registration: the LMS registered with the tool (POST /api/lti/platforms, loopback URLs allowed);
2. an instructor's launch (OIDC login, the LMS's signed id_token, the launch): the tool makes the course of the LMS
   course and answers its picker, with the instructor's course page;
3. the instructor publishes the example assignment (scenes/grading) in that course with their own token;
4. deep linking: the instructor's deep-linking launch, the pick, the tool's signed answer verified by the LMS,
   which places the link and its gradebook column;
5. a student's launch of that link: their assignment page, with their token; the course's roster read from the LMS
   (NRPS, as the instructor's launches also do) lists her, active;
6. the student hands in an example submission, and it is graded;
7. the grade is received by the LMS (Assignment and Grade Services) and shown in its gradebook, and the tool's
   dashboard counts it sent.

Then the links an admin can open in a browser. Exit 0 when every step worked; 1 with the step that failed and why.
`--keep` keeps the pretend LMS (and the tool it started) running until Ctrl-C, so that the links can be followed:
the LMS's page launches the tool as the instructor or the student in a browser, through the real OIDC flow.
With `--url`, the platform's registration is removed at the end (the course and the assignment stay).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TypeVar

import httpx

from server.core.paths import ROOT, SCENES
from server.lti.loopback import free_port
from server.lti.platform import Platform
from server.lti.platform_services import AGS_CLAIM, DL, INSTRUCTOR, LEARNER

T = TypeVar("T")  # what a wait gives back

EXAMPLE = SCENES / "grading"  # the example assignment, and its class's submissions
SUBMISSION = EXAMPLE / "class" / "alice.json"
CONTEXT = {"id": "course-1", "label": "LTI-TRY", "title": "LTI try"}
TEACHER = {"sub": "teacher-1", "roles": [INSTRUCTOR], "context": CONTEXT,
           "overrides": {"name": "Grace Hopper", "given_name": "Grace", "family_name": "Hopper",
                         "email": "grace@example.edu"}}  # fmt: skip
STUDENT = {"sub": "student-1", "roles": [LEARNER], "context": CONTEXT,
           "overrides": {"name": "Ada Lovelace", "given_name": "Ada", "family_name": "Lovelace",
                         "email": "ada@example.edu"}}  # fmt: skip
# the LMS course's members as its roster (NRPS) lists them: the two who launch (a sync keeps Ada active)
ROSTER = [
    {"status": "Active", "user_id": who["sub"], "roles": who["roles"], **who["overrides"]} for who in (TEACHER, STUDENT)
]
NAV_LINK = {"id": "nav-1", "title": "Ray tracing (course navigation)"}
START_SECONDS = 300.0  # the tool started here: a first start compiles the render kernels (minutes)
TIMEOUT = 900.0  # the whole try, at most (the grading renders the reference and the submission on CPU)


class StepFailed(Exception):
    def __init__(self, step: str, why: str):
        super().__init__(f"{step}: {why}")
        self.step, self.why = step, why


class Trial:
    """The flow, step by step; `say` prints (a test collects the lines)."""

    def __init__(self, url: str, token: str | None, say: Callable[[str], None] = print, timeout: float = TIMEOUT):
        self.url, self.say = url.rstrip("/"), say
        self.deadline = time.monotonic() + timeout
        self.admin = {"Authorization": f"Bearer {token}"} if token else {}
        self.http = httpx.Client(base_url=self.url, timeout=60, follow_redirects=False)
        self.platform: Platform | None = None
        self.pid: str | None = None
        self.n = 0
        self.found: dict = {}

    # -- the frame of a step -------------------------------------------------------------------------------

    @contextmanager
    def step(self, title: str) -> Iterator[None]:
        self.n += 1
        name = f"{self.n}. {title}"
        self.say(f"{name} ...")
        try:
            yield
        except StepFailed:
            raise
        except httpx.HTTPError as e:
            raise StepFailed(name, f"no answer over HTTP ({type(e).__name__}: {e})") from None
        except (AssertionError, KeyError, ValueError, TypeError) as e:
            raise StepFailed(name, str(e) or type(e).__name__) from None

    def done(self, text: str) -> None:
        self.say(f"   ok: {text}")

    def left(self) -> float:
        return self.deadline - time.monotonic()

    @staticmethod
    def answered(r: httpx.Response, *want: int) -> None:
        if r.status_code not in want:
            raise AssertionError(f"{r.request.method} {r.request.url.path} answered {r.status_code}: {r.text[:300]}")

    def wait(self, what: str, check: Callable[[], T | None], most: float, every: float = 0.5) -> T:
        """`check()`'s first true answer, asked every `every` s for at most `most` s (and the try's time left)."""
        until = time.monotonic() + max(0.0, min(most, self.left()))
        while True:
            got = check()
            if got:
                return got
            if time.monotonic() >= until:
                raise AssertionError(f"{what}: not within {most:.0f} s")
            time.sleep(every)

    # -- the flow --------------------------------------------------------------------------------------------

    def run(self) -> dict:
        p = self.platform
        assert p is not None
        p.members[CONTEXT["id"]] = [dict(m) for m in ROSTER]
        with self.step("Registration"):
            body = p.registration(name="Pretend LMS (python -m server.lti try)")
            r = self.http.post("/api/lti/platforms", json=body, headers=self.admin)
            if r.status_code in (401, 403):
                raise AssertionError(f"the tool refused the admin token ({r.status_code}): give the server's "
                                     "TRACER_INSTRUCTOR_TOKEN with --token")  # fmt: skip
            self.answered(r, 201)
            self.pid = r.json()["id"]
            self.done(f"the LMS {p.issuer} is registered with the tool as platform {self.pid} (client id "
                      f"{p.client_id}, deployment {p.deployment_id}; its URLs on loopback allowed)")  # fmt: skip

        with self.step("An instructor's launch"):
            r = p.do_launch(self.http, self.url, **launch(TEACHER, {"resource_link": NAV_LINK}))
            self.answered(r, 200)
            assert "Pick an assignment" in r.text, f"expected the tool's picker, got: {r.text[:300]}"
            token = re.search(r'href="/course#token=([^"]+)"', r.text)
            assert token, "the picker has no link to the course page"
            teacher = self.found["teacher"] = token[1]
            courses = self.http.get("/api/courses", headers=bearer(teacher)).json()["courses"]
            cid = self.found["course"] = courses[0]["id"]
            self.done(
                f"Grace Hopper (an LMS instructor) opened the tool: it made course {cid} for the LMS course "
                f"{CONTEXT['title']!r}, made her its instructor and showed its picker (nothing to pick yet)"
            )

        with self.step("The instructor publishes an assignment"):
            spec = json.loads((EXAMPLE / "assignment.json").read_text())
            spec["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
            deadline = (datetime.now(UTC) + timedelta(days=7)).isoformat()
            r = self.http.post(f"/api/courses/{cid}/assignments", json={"spec": spec, "deadline": deadline},
                               headers=bearer(teacher))  # fmt: skip
            self.answered(r, 201)
            aid = self.found["assignment"] = r.json()["id"]
            self.done(f"{spec['name']!r} published in {cid} with her token (assignment {aid}); its reference renders")

        with self.step("Deep linking"):
            r = p.do_launch(self.http, self.url, **launch(TEACHER, {"message_type": "LtiDeepLinkingRequest"}))
            self.answered(r, 200)
            pick = re.search(r'name="pick" value="([^"]+)"', r.text)
            assert pick and aid in r.text, f"the picker does not offer the assignment: {r.text[:300]}"
            r = self.http.post("/lti/pick", data={"pick": pick[1], "assignment": aid})
            self.answered(r, 200)
            form = re.search(r'action="([^"]+)"', r.text)
            jwt = re.search(r'name="JWT" value="([^"]+)"', r.text)
            assert form and jwt, f"the tool's answer has no form back to the LMS: {r.text[:300]}"
            back = httpx.post(form[1].replace("&amp;", "&"), data={"JWT": jwt[1]}, timeout=30)
            self.answered(back, 200)  # the LMS verified the tool's signed answer with the tool's key set
            (item,) = p.deep_links[-1][DL + "content_items"]
            link = self.found["link"] = p.place(item)
            p.person("student", **launch(STUDENT, link))
            p.person("instructor", **launch(TEACHER, link))
            p.person("instructor-adds-an-assignment", **launch(TEACHER, {"message_type": "LtiDeepLinkingRequest"}))
            column = item.get("lineItem", {})
            self.done(f"she picked it; the LMS verified the tool's signed answer and placed the link "
                      f"{item['title']!r} (custom assignment={item['custom']['assignment']}) with a gradebook "
                      f"column of {column.get('scoreMaximum', 0):g} points")  # fmt: skip

        with self.step("A student's launch"):
            r = p.do_launch(self.http, self.url, **launch(STUDENT, link))
            self.answered(r, 303)
            where, _, student = r.headers["location"].partition("#token=")
            assert where == f"/assignments/{aid}" and student, f"the launch went to {r.headers['location']}"
            self.found["student"] = student
            brief = self.http.get(f"/api/assignments/{aid}", headers=bearer(student)).json()
            r = self.http.post(f"/api/courses/{cid}/lms/sync", headers=bearer(teacher))
            self.answered(r, 200)
            synced = r.json()
            assert synced["members"] == 1 and synced["left"] == 0, f"the roster read from the LMS: {synced}"
            self.done(
                f"Ada Lovelace (an LMS learner) launched the link: the tool enrolled her as "
                f"{brief['student']['id']!r} and opened her assignment page, her token in the address; the roster "
                f"read from the LMS (NRPS) lists her, active"
            )

        with self.step("A submission graded"):
            scene = SUBMISSION.read_text()
            r = self.http.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(student))
            self.answered(r, 202)
            sub = r.headers["location"]

            def graded_now() -> dict | None:
                s = self.http.get(sub, headers=bearer(student)).json()
                if s["status"] in ("failed", "rejected"):
                    raise AssertionError(f"the submission ended {s['status']}: {s.get('error')}")
                return s if s["status"] == "graded" else None

            graded = self.wait("the submission's grade (the workers render the reference, then it)", graded_now, 600)
            self.found["score"] = graded["score"]
            self.done(f"she handed in {SUBMISSION.relative_to(ROOT)}; graded {graded['score']:g} of "
                      f"{graded['max_score']:g}")  # fmt: skip

        with self.step("The grade at the LMS"):
            lid = link["overrides"][AGS_CLAIM]["lineitem"].rsplit("/", 1)[1]
            got = self.wait("the score at the LMS (the tool's poster sends it)",
                            lambda: [s for s in p.scores if s["lineitem"] == lid], 90)  # fmt: skip
            score = got[-1]
            assert score["userId"] == STUDENT["sub"], score
            assert abs(score["scoreGiven"] - graded["score"]) < 1e-6, (score, graded["score"])
            book = httpx.get(p.url + "/gradebook", timeout=30).text
            assert f"{score['scoreGiven']} / {score['scoreMaximum']}" in book, "the gradebook does not show it"
            board = self.http.get(f"/api/assignments/{aid}/dashboard", headers=bearer(teacher)).json()
            sent = board["lms"]["grades"]["sent"]
            assert sent >= 1, f"the tool's dashboard counts {sent} sent"
            self.done(f"the LMS received {score['scoreGiven']:g} / {score['scoreMaximum']:g} for "
                      f"{score['userId']} ({score['activityProgress']}, {score['gradingProgress']}) and shows it in "
                      f"its gradebook; the tool's dashboard counts {sent} grade sent")  # fmt: skip
        return self.found

    def links(self) -> list[str]:
        p, f = self.platform, self.found
        assert p is not None  # links are asked for after the try, which sets it
        out = [f"  the pretend LMS's course page (launch the tool in a browser): {p.url}/"]
        if "link" in f:
            out += [f"  ... as the student, through the real OIDC flow:     {p.start_url('student')}",
                    f"  ... as the instructor:                              {p.start_url('instructor')}",
                    f"  ... adding an assignment (deep linking):            "
                    f"{p.start_url('instructor-adds-an-assignment')}"]  # fmt: skip
        out.append(f"  the LMS's gradebook (the grades received):          {p.url}/gradebook")
        if "student" in f:
            out.append(f"  the student's assignment page:                      "
                       f"{self.url}/assignments/{f['assignment']}#token={f['student']}")  # fmt: skip
        if "teacher" in f:
            opened = f"&open={f['assignment']}" if "assignment" in f else ""
            out.append(f"  the instructor's course page and dashboard:         {self.url}/course#token={f['teacher']}"
                       f"{opened}")  # fmt: skip
        out.append(f"  the server's status page (the admin's token):       {self.url}/status")
        return out

    def close(self, remove: bool) -> None:
        if remove and self.pid:
            try:
                self.http.delete(f"/api/lti/platforms/{self.pid}", headers=self.admin)
            except httpx.HTTPError:
                pass
        self.http.close()


def launch(*parts: dict) -> dict:
    """launch_token's arguments of `parts` together (their `overrides` merged)."""
    out: dict = {}
    for part in parts:
        out = {**out, **part, "overrides": {**out.get("overrides", {}), **part.get("overrides", {})}}
    return out


def bearer(token: str) -> dict:
    return {"Authorization": f"Bearer {token}"}


class Tool:
    """`python -m server` on 127.0.0.1 for the try: a free port, `data_dir`, one render worker, `token`."""

    def __init__(self, data_dir: Path, token: str, say: Callable[[str], None]):
        self.data_dir, self.token, self.say = data_dir, token, say
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log_path = data_dir.parent / f"{data_dir.name}-server.log"
        self.proc: subprocess.Popen | None = None

    def start(self, most: float = START_SECONDS) -> None:
        env = {**os.environ, "TRACER_INSTRUCTOR_TOKEN": self.token, "TRACER_PREVIEWS_AHEAD": "0",
               "TRACER_LESSONS_AHEAD": "0", "TRACER_INTERACTIVE_WORKERS": "0"}  # fmt: skip
        env.pop("TRACER_REDIS_URL", None)
        env.pop("TRACER_SETTINGS_FILE", None)
        cmd = [sys.executable, "-m", "server", "--host", "127.0.0.1", "--port", str(self.port),
               "--data-dir", str(self.data_dir), "--workers", "1"]  # fmt: skip
        self.log = open(self.log_path, "ab")  # noqa: SIM115 (closed in stop)
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=self.log, stderr=subprocess.STDOUT)
        until = time.monotonic() + most
        with httpx.Client(base_url=self.url, timeout=5) as c:
            while True:
                if self.proc.poll() is not None:
                    raise StepFailed("0. The tool", f"python -m server exited ({self.proc.returncode}): "
                                     f"{self.log_path.read_text(errors='replace')[-1500:]}")  # fmt: skip
                try:
                    workers = c.get("/api/health").json()["workers"]
                    if workers and all(w["ready"] for w in workers):
                        return
                except (httpx.HTTPError, ValueError, KeyError):
                    pass
                if time.monotonic() >= until:
                    raise StepFailed("0. The tool", f"not ready within {most:.0f} s (its log: {self.log_path})")
                time.sleep(0.5)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        if self.proc is not None:
            self.log.close()


def parser(sub=None) -> argparse.ArgumentParser:
    help_ = "the whole LTI flow against a pretend LMS on loopback, before touching a real one"
    ap = (
        sub.add_parser("try", help=help_)
        if sub is not None
        else argparse.ArgumentParser(prog="python -m server.lti try")
    )
    ap.add_argument("--url", help="a running tool on this machine (http://127.0.0.1:8000); default: start one")
    ap.add_argument("--token", help="the running tool's admin token (default: $TRACER_INSTRUCTOR_TOKEN)")
    ap.add_argument("--data-dir", type=Path, help="the started tool's data directory (default: a temporary one, "
                    "removed at the end)")  # fmt: skip
    ap.add_argument("--keep", action="store_true", help="keep the pretend LMS (and the tool it started) running "
                    "until Ctrl-C, for the links")  # fmt: skip
    ap.add_argument("--timeout", type=float, default=TIMEOUT, help=f"seconds for the whole try (default {TIMEOUT:g})")
    return ap


def shout(line: str) -> None:
    print(line, flush=True)  # at once, also into a pipe (a test, a log): a person follows the steps


def stop_on_term(*_) -> None:
    raise KeyboardInterrupt  # SIGTERM ends the try as Ctrl-C does: the tool it started is stopped too


def main(args: argparse.Namespace, say: Callable[[str], None] = shout) -> int:
    if args.timeout <= 0:
        say("--timeout: expected a number of seconds above 0")
        return 2
    tool, temp = None, None
    trial = None
    before = signal.signal(signal.SIGTERM, stop_on_term)
    try:
        with Platform(name="Pretend LMS") as p:
            if args.url:
                url, token = args.url, args.token or os.environ.get("TRACER_INSTRUCTOR_TOKEN")
                try:
                    httpx.get(url.rstrip("/") + "/api/health", timeout=10).raise_for_status()
                except httpx.HTTPError as e:
                    raise StepFailed("0. The tool", f"{url} is not answering ({type(e).__name__}: {e})") from None
                say(f"The tool: {url} (running)")
            else:
                if args.data_dir is None:
                    temp = Path(tempfile.mkdtemp(prefix="lti-try-"))
                    data = temp / "data"
                else:
                    data = args.data_dir
                token = secrets.token_urlsafe(32)
                tool = Tool(data, token, say)
                say(f"Starting the tool: python -m server on 127.0.0.1:{tool.port}, data in {data} (a first start "
                    "compiles the render kernels: minutes)")  # fmt: skip
                tool.start(min(START_SECONDS, args.timeout))
                url = tool.url
                say(f"The tool: {url} (admin token {token})")
            say(f"The pretend LMS: {p.url} (issuer {p.issuer}, its course {CONTEXT['title']!r})")
            p.tool_jwks_url = url.rstrip("/") + "/lti/jwks"
            trial = Trial(url, token, say, args.timeout)
            trial.platform = p
            try:
                trial.run()
            except StepFailed as e:
                say(f"FAILED at step {e.step}: {e.why}")
                say("What was done, to look at:")
                for line in trial.links():
                    say(line)
                return 1
            if args.keep:
                live = ":"
            elif args.url:
                live = " (the LMS's links live while this command runs, --keep keeps it running; the tool's stay):"
            else:
                live = " (they live while this command runs: --keep keeps it running until Ctrl-C):"
            say("The whole flow works. Open in a browser" + live)
            for line in trial.links():
                say(line)
            if args.keep:
                say("Running until Ctrl-C (or SIGTERM) ...")
                try:
                    while True:
                        time.sleep(3600)
                except KeyboardInterrupt:
                    say("stopped")
            return 0
    except StepFailed as e:
        say(f"FAILED at step {e.step}: {e.why}")
        return 1
    finally:
        if trial is not None:
            trial.close(remove=bool(args.url))
        if tool is not None:
            tool.stop()
        if temp is not None:
            shutil.rmtree(temp, ignore_errors=True)
        signal.signal(signal.SIGTERM, before)
