"""The instructor's command line (docs/assignments.md, "From the command line"): a client of a running server's
HTTP API, standard library only (urllib), so it runs wherever the repository is checked out.

    python -m server.course publish SPEC.json --deadline ISO [--late-until ISO] [--late-penalty F]
        [--max-submissions N] [--counts last|best] [--starter FILE] [--show-reference] [--feedback JSON]
        [--open] [--server URL] [--token T]
        [--course C]
    python -m server.course roster ID roster.csv [--out links.csv]
    python -m server.course grades ID [--out grades.csv]
    python -m server.course courses
    python -m server.course course-create ID [--name NAME]
    python -m server.course course-roster COURSE roster.csv [--out links.csv]
    python -m server.course links COURSE [--assignment ID] [--out links.csv]
    python -m server.course staff-add COURSE ID --role instructor|ta [--name N] [--email E]

`publish` sends the spec as a multipart part, and its reference scene file beside it when the spec names
one (`"reference": {"scene": "reference.json"}`, looked for next to the spec, as scenes/grading/ has it);
it prints the assignment's id on the first line (`A=$(python -m server.course publish ... | head -1)`),
then the brief's main facts and, last, the address of its page (/assignments/{id}). `roster` uploads the
roster CSV and writes the links to mail out (`links` writes them again); `grades` writes grades.csv.

Courses (docs/assignments.md, "Courses and staff"): `course-create` (the server admin's token) makes a course,
`staff-add` adds an instructor or a TA and prints their link, `course-roster` enrols a course's roster once
(every assignment of the course, those published later too), `links` writes every student's link again
(links are derived, so they are the same until one is replaced), `publish --course` publishes into a course.

The server is `--server` or TRACER_SERVER (default http://127.0.0.1:8000), the instructor's token
`--token` or TRACER_INSTRUCTOR_TOKEN. What the server refuses is printed as its `path: message` lines
(exit 1); a local file that is missing or unreadable is named (exit 2); a server that cannot be reached
is one line (exit 3).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
import urllib.error
import urllib.request
import uuid
from pathlib import Path

from server.core.roles import STAFF, Role

DEFAULT_SERVER = "http://127.0.0.1:8000"
TIMEOUT = 120  # seconds: publishing validates the spec and its reference scene in the request


class Refused(Exception):
    """The server answered with an error: its `errors` as (path, message) pairs."""

    def __init__(self, status: int, errors: list[tuple[str, str]]):
        super().__init__(f"HTTP {status}")
        self.status, self.errors = status, errors


class Unreachable(Exception):
    """No answer from the server at all (refused, unknown host, timed out)."""


class LocalFile(Exception):
    """A file named on the command line that cannot be read (the message names it)."""


class Client:
    """The server's API with the instructor's bearer token."""

    def __init__(self, server: str, token: str | None):
        self.server, self.token = server.rstrip("/"), token

    def call(self, method: str, path: str, body: bytes | None = None, content_type: str | None = None,
             accept: str = "application/json") -> bytes:  # fmt: skip
        headers = {"Accept": accept}
        if content_type:
            headers["Content-Type"] = content_type
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        request = urllib.request.Request(self.server + path, data=body, method=method, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=TIMEOUT) as r:
                return r.read()
        except urllib.error.HTTPError as e:
            raise Refused(e.code, _errors(e.code, e.read())) from None
        except (urllib.error.URLError, OSError) as e:
            reason = getattr(e, "reason", e)
            raise Unreachable(f"cannot reach the server at {self.server}: {reason}") from None

    def json(self, method: str, path: str, body: bytes | None = None, content_type: str | None = None) -> dict:
        return json.loads(self.call(method, path, body, content_type))


def _errors(status: int, data: bytes) -> list[tuple[str, str]]:
    """The service's one error shape, {"errors": [{"path", "message"}]}; anything else as its text."""
    try:
        errors = json.loads(data)["errors"]
        return [(str(e.get("path", "")), str(e.get("message", ""))) for e in errors]
    except (ValueError, KeyError, TypeError, AttributeError):
        text = data.decode("utf-8", errors="replace").strip()[:300]
        return [("", f"HTTP {status}: {text or 'no details'}")]


def multipart(fields: dict[str, str], files: dict[str, tuple[str, bytes]]) -> tuple[bytes, str]:
    """A multipart/form-data body of text fields and JSON files; (the body, its Content-Type)."""
    boundary = "tracer-" + uuid.uuid4().hex
    out = []
    for name, value in fields.items():
        out.append(f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n{value}\r\n'.encode())
    for name, (filename, data) in files.items():
        head = (f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"; filename="{filename}"\r\n'
                "Content-Type: application/json\r\n\r\n")  # fmt: skip
        out.append(head.encode() + data + b"\r\n")
    out.append(f"--{boundary}--\r\n".encode())
    return b"".join(out), f"multipart/form-data; boundary={boundary}"


def read(path: Path, what: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise LocalFile(f"{path}: no such file ({what})") from None
    except OSError as e:
        raise LocalFile(f"{path}: cannot read it ({what}): {e.strerror}") from None


def publish_parts(args) -> tuple[dict[str, str], dict[str, tuple[str, bytes]]]:
    """The spec (and its reference scene file, when it names one) and the policy, as multipart parts."""
    spec_path = Path(args.spec)
    spec_bytes = read(spec_path, "the grading spec")
    files = {"spec": (spec_path.name, spec_bytes)}
    try:
        spec = json.loads(spec_bytes)
    except (ValueError, UnicodeDecodeError):
        spec = None  # sent as it is: the server names what is wrong with it (`spec: invalid JSON at line ...`)
    ref = spec.get("reference") if isinstance(spec, dict) else None
    if isinstance(ref, dict) and isinstance(ref.get("scene"), str):
        ref_path = spec_path.parent / ref["scene"]
        what = f"the spec's reference.scene, looked for next to {spec_path.name}"
        files["reference"] = (ref_path.name, read(ref_path, what))
    if args.starter:
        files["starter"] = (Path(args.starter).name, read(Path(args.starter), "--starter"))
    fields = {"deadline": args.deadline}
    optional = {"late_until": args.late_until, "late_penalty": args.late_penalty,
                "max_submissions": args.max_submissions, "counts": args.counts, "feedback": args.feedback}  # fmt: skip
    fields.update({k: str(v) for k, v in optional.items() if v is not None})
    if args.show_reference:
        fields["show_reference"] = "true"
    if args.open:
        fields["open"] = "true"
    return fields, files


def describe(a: dict, server: str) -> list[str]:
    """The brief's main facts, a line each, after the id; the brief's page (not its API) last."""
    p = a.get("policy", {})
    lines = [a["id"], f"  {a['name']} (version {a['version']})", f"  deadline: {a['deadline']}"]
    if a.get("late_until"):
        lines[-1] += f"; late until {a['late_until']}, {100 * (a.get('late_penalty') or 0):g} % off"
    requirements = ", ".join(f"{r['name']} {r['points']:g}" for r in a.get("requirements", []))
    images = ", ".join(f"{t['name']} {t['points']:g}" for t in a.get("image_tests", []))
    lines.append(f"  {a['max_score']:g} points: validity {a['validity']['points']:g}; requirements: "
                 f"{requirements or 'none'}; image tests: {images or 'none'}")  # fmt: skip
    most = a.get("max_submissions")
    lines.append(f"  submissions: {'at most ' + str(most) if most else 'no limit'}, the {a['counts']} counts; "
                 f"reference image shown: {'yes' if p.get('show_reference') else 'no'}; "
                 f"open: {'yes, ' + a['join'] if a.get('open') else 'no'}")  # fmt: skip
    ref = a.get("reference_grade")
    if ref:
        score = f" {ref['score']:g} / {ref['max_score']:g}" if ref.get("score") is not None else ""
        lines.append(f"  the reference scene's grade: {ref['status']}{score}")
    lines.append(f"  the brief's page: {server.rstrip('/')}/assignments/{a['id']}")  # what students open
    return lines


def publish(client: Client, args) -> int:
    fields, files = publish_parts(args)
    body, ctype = multipart(fields, files)
    path = f"/api/courses/{args.course}/assignments" if args.course else "/api/assignments"
    a = client.json("POST", path, body, ctype)
    print("\n".join(describe(a, client.server)))
    return 0


def roster(client: Client, args) -> int:
    text = read(Path(args.roster), "the roster, a CSV with the header id,name,email")
    links = client.call("POST", f"/api/assignments/{args.id}/roster", text, "text/csv", accept="text/csv")
    rows = list(csv.DictReader(io.StringIO(links.decode("utf-8"))))
    write(args.out, links)
    print(f"{len(rows)} student(s) on the roster: their links {'in ' + args.out if args.out else 'above'} (the "
          "same as before for those already on it)", file=sys.stderr)  # fmt: skip
    return 0


def course_roster(client: Client, args) -> int:
    text = read(Path(args.roster), "the roster, a CSV with the header id,name,email")
    links = client.call("POST", f"/api/courses/{args.course}/roster", text, "text/csv", accept="text/csv")
    rows = list(csv.DictReader(io.StringIO(links.decode("utf-8"))))
    write(args.out, links)
    print(f"{len(rows)} student(s) enrolled in {args.course} (every assignment): their links "
          f"{'in ' + args.out if args.out else 'above'}", file=sys.stderr)  # fmt: skip
    return 0


def links(client: Client, args) -> int:
    query = f"?assignment={args.assignment}" if args.assignment else ""
    write(args.out, client.call("GET", f"/api/courses/{args.course}/links{query}", accept="text/csv"))
    return 0


def courses(client: Client, args) -> int:
    for c in client.json("GET", "/api/courses")["courses"]:
        print(f"{c['id']}\t{c['name']}\t{c['assignments']} assignment(s)\t{c['students']} student(s)")
    return 0


def course_create(client: Client, args) -> int:
    body = json.dumps({"id": args.id, "name": args.name or args.id}).encode()
    c = client.json("POST", "/api/courses", body, "application/json")
    print(c["id"])
    return 0


def staff_add(client: Client, args) -> int:
    body = json.dumps({"id": args.id, "name": args.name or args.id, "email": args.email or "", "role": args.role})
    s = client.json("POST", f"/api/courses/{args.course}/staff", body.encode(), "application/json")
    print(s["link"])
    print(f"{s['name']} is a{'n' if s['role'] == Role.INSTRUCTOR else ''} {s['role']} of {args.course}: send them the "
          "link above (it carries their token)", file=sys.stderr)  # fmt: skip
    return 0


def grades(client: Client, args) -> int:
    data = client.call("GET", f"/api/assignments/{args.id}/grades.csv", accept="text/csv")
    rows = list(csv.DictReader(io.StringIO(data.decode("utf-8"))))
    graded = sum(1 for row in rows if row.get("score"))
    write(args.out, data)
    print(f"{len(rows)} student(s), {graded} with a grade{': ' + args.out if args.out else ''}", file=sys.stderr)
    return 0


def write(out: str | None, data: bytes) -> None:
    if out is None:
        sys.stdout.write(data.decode("utf-8"))
        return
    try:
        Path(out).write_bytes(data)
    except OSError as e:
        raise LocalFile(f"{out}: cannot write it: {e.strerror}") from None


def parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)  # after the command, as in the module's doc
    common.add_argument("--server", help=f"the server's URL (default: TRACER_SERVER, else {DEFAULT_SERVER})")
    common.add_argument("--token", help="the instructor's token (default: TRACER_INSTRUCTOR_TOKEN)")
    p = argparse.ArgumentParser(prog="python -m server.course", description=(__doc__ or "").split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    pub = sub.add_parser(
        "publish", parents=[common], help="publish an assignment from a grading spec (docs/grading.md)"
    )
    pub.add_argument("spec", help="the spec's JSON file; a reference scene it names as a file is sent beside it")
    pub.add_argument("--deadline", required=True, help="ISO 8601 with a zone: 2026-12-08T23:59:00-05:00")
    pub.add_argument("--late-until", help="late submissions are taken until then (ISO 8601 with a zone)")
    pub.add_argument("--late-penalty", type=float, help="the fraction of a late submission's points taken off")
    pub.add_argument("--max-submissions", type=int, help="attempts per student (an invalid one costs none)")
    pub.add_argument("--counts", choices=("last", "best"), help="which graded submission is the grade")
    pub.add_argument("--starter", help="a scene file the students start from")
    pub.add_argument("--show-reference", action="store_true", help="students may see the reference image")
    pub.add_argument("--feedback", help='when each test is shown, as JSON: \'{"tests": {"pixels": "never"}}\'')
    pub.add_argument("--open", action="store_true", help="anyone with the link may join by a name")
    pub.add_argument("--course", help="the course to publish into (default: your staff token's, else 'default')")
    ros = sub.add_parser(
        "roster", parents=[common], help="upload the roster (id,name,email) and write the links to mail out"
    )
    ros.add_argument("id", help="the assignment's id")
    ros.add_argument("roster", help="the roster's CSV file")
    ros.add_argument("--out", help="the links' CSV (id,name,email,link); default: standard output")
    gra = sub.add_parser("grades", parents=[common], help="write the grades (one row per roster student)")
    gra.add_argument("id", help="the assignment's id")
    gra.add_argument("--out", help="the grades' CSV; default: standard output")
    sub.add_parser("courses", parents=[common], help="list the courses (the admin: all; staff: their own)")
    cc = sub.add_parser("course-create", parents=[common], help="create a course (the server admin's token)")
    cc.add_argument("id", help="1 to 40 letters, digits, '-' or '_'")
    cc.add_argument("--name", help="its name, as students see it")
    cr = sub.add_parser("course-roster", parents=[common], help="enrol a course's roster once (every assignment)")
    cr.add_argument("course", help="the course's id")
    cr.add_argument("roster", help="the roster's CSV file (id,name,email)")
    cr.add_argument("--out", help="the links' CSV (id,name,email,link); default: standard output")
    li = sub.add_parser("links", parents=[common], help="every student's link again (the same until replaced)")
    li.add_argument("course", help="the course's id")
    li.add_argument("--assignment", help="links to this assignment's page (default: the course's page)")
    li.add_argument("--out", help="the links' CSV; default: standard output")
    st = sub.add_parser("staff-add", parents=[common], help="add an instructor or a TA to a course; prints their link")
    st.add_argument("course", help="the course's id")
    st.add_argument("id", help="their id (letters, digits, . _ -)")
    st.add_argument("--role", required=True, choices=[str(r) for r in STAFF])
    st.add_argument("--name")
    st.add_argument("--email")
    return p


def token_joined(argv: list[str]) -> list[str]:
    """`--token T` as `--token=T`: a token is URL-safe base64, and one in 64 starts with "-", which argparse would
    read as an option ("expected one argument")."""
    out: list[str] = []
    it = iter(argv)
    for arg in it:
        value = next(it, None) if arg == "--token" else None
        out.append(arg if value is None else f"--token={value}")  # a bare last --token: argparse says so
    return out


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(token_joined(sys.argv[1:] if argv is None else argv))
    server = args.server or os.environ.get("TRACER_SERVER") or DEFAULT_SERVER
    client = Client(server, args.token or os.environ.get("TRACER_INSTRUCTOR_TOKEN") or None)
    run = {"publish": publish, "roster": roster, "grades": grades, "courses": courses, "course-create": course_create,
           "course-roster": course_roster, "links": links, "staff-add": staff_add}[args.command]  # fmt: skip
    try:
        return run(client, args)
    except Refused as e:
        for path, message in e.errors:
            print(f"{path}: {message}" if path else message, file=sys.stderr)
        return 1
    except LocalFile as e:
        print(e, file=sys.stderr)
        return 2
    except Unreachable as e:
        print(e, file=sys.stderr)
        return 3
