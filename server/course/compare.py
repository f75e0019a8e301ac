"""Two ray trees at one pixel of a graded scene submission: the student's scene and the reference's, traced as the
grader rendered them, side by side with the first node where they differ (GET /api/assignments/{aid}/submissions/
{sid}/raytree, docs/assignments.md "Comparing ray trees at a pixel").

**As graded.** The student's scene is the one their render was made from: the scene of their grade's render job
(the assignment's settings applied: film size, samples, seed, integrator, depth), as the grading run kept it.
The reference is the version's reference scene with the same settings, and with the student's sampler, samples
per pixel and light samples, as its noise baseline is rendered; and with the same seed as the student's
render. So the two eye rays of a sample are the same ray, and every difference below them is the scenes'.

**The feedback policy.** The reference's tree shows its structure (its objects, materials and lights at that
pixel), as the error map and the rejected pixels do: a student may ask when they may see those pictures (every
image test's feedback shown now; `Course.files`), and the 403 says when that will be. The instructor always may.

**Traced by workers.** Each tree is a ray-tree job of the interactive lane, like POST /api/raytree: the
student's job is theirs (it counts against their share of the queue), the reference's is the instructor's
(a student never reads the reference scene from its job). The comparison itself is tracer/grading/treediff.py.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable

import anyio

from server.core.errors import Conflict, Forbidden, Invalid, NotFound, Unavailable
from server.core.security import Caller
from server.course.base import iso
from server.course.people import Who
from server.course.policy import Feedback, When
from server.course.schema import AssignmentRow, SubmissionWithGrade
from server.course.service import Course
from server.jobs.lifecycle import RAYTREE_PRIORITY
from server.jobs.service import JobService
from tracer.grading import tasks
from tracer.grading.treediff import first_difference

Check = Callable[[bytes], Awaitable[dict]]  # a scene request's body -> its summary (the checking processes'), or 422


def allowed(course: Course, a: AssignmentRow, sub: SubmissionWithGrade | dict, who: Who) -> None:
    """403 unless the caller may see the reference's structure now: the instructor, or a student who may see
    the image tests' pictures (every image test's feedback shown), with when they will be shown. (`sub` a dict:
    a check's {version} alone, no submission yet.)"""
    if who.instructor:
        return
    feedback = Feedback.model_validate(a["policy"]["feedback"])
    now = course.now()
    hidden = {}
    for key in course.spec(a["id"], sub["version"]).image_tests():
        when = When(feedback.tests.get(key, feedback.default))
        if not course.shown(when, a, who, now):
            hidden[key] = when
    if not hidden:
        return
    names = ", ".join(hidden)
    if When.never in hidden.values():
        message = (
            f"the ray trees at a pixel show the reference's scene, and this assignment never shows its image tests' "
            f"feedback ({names}) to students: they are not shown"
        )
    else:
        cut = course.deadlines(a, who.student)[1]
        message = (
            f"the ray trees at a pixel show the reference's scene: they are shown with the image tests' feedback "
            f"({names}), after your deadline, from {iso(cut)}"
        )
    raise Forbidden.at("sid", message)


def as_graded(course: Course, a: AssignmentRow, sub: SubmissionWithGrade) -> tuple[dict, dict, tuple[int, int]]:
    """(the student's scene, the reference's, (width, height) of the graded image) of a graded scene submission;
    409 for an image, or a submission not graded (yet)."""
    sid = sub["id"]
    if sub["kind"] != "scene":
        raise Conflict.at("sid", f"submission '{sid}' is an image ({sub['kind'].upper()}): there is no scene to trace; "
                  "ray trees are compared for scene submissions")  # fmt: skip
    item = course.runs.item(sub["run_id"], sid)
    stage = (item or {}).get("stage")
    if item is None or stage != "graded":
        state = "queued" if stage in (None, "submitted") else "being graded"
        raise Conflict.at("sid", f"submission '{sid}' is {state}: its ray trees can be compared once it is graded")
    prepared = item.get("prepared") or {}
    job, key, size = prepared.get("job"), prepared.get("key"), prepared.get("size")
    if item["status"] == "invalid":
        raise Conflict.at("sid", f"submission '{sid}' is invalid (its scene has errors): there is no render to compare")
    if job is None or key is None or size is None:
        why = (item.get("report") or {}).get("metrics", {}).get("problem") or "it has no render"
        raise Conflict.at("sid", f"submission '{sid}' was not rendered ({why}): there is no render to compare")
    version = next(v for v in course.store.versions(a["id"]) if v["version"] == sub["version"])
    grader = tasks.grader(json.dumps(version["spec"]))
    if grader.reference is None:
        raise Conflict.at("sid", "this assignment has no reference scene to compare with")
    reference = json.loads(json.dumps(grader.reference.scene))
    reference.setdefault("sampler", {}).update(type=key[0], spp=key[1])  # as its noise baseline is rendered
    reference.setdefault("render", {})["light_samples"] = key[2]  # its seed is the student's: render.seed of both
    return job["scene"], reference, (int(size[0]), int(size[1]))


def in_range(x: int, y: int, sample: int, size: tuple[int, int]) -> None:
    w, h = size
    errors = [
        {"path": k, "message": f"must be a {what} of the graded image in 0..{n - 1} (it is {w}x{h} pixels)"}
        for k, v, n, what in (("x", x, w, "column"), ("y", y, h, "row"))
        if not 0 <= v < n
    ]
    if sample < 0:
        errors.append({"path": "sample", "message": "must be a sample index, 0 or more"})
    if errors:
        raise Invalid(errors)


async def trace(
    jobs: JobService,
    check: Check,
    scene: dict,
    x: int,
    y: int,
    sample: int,
    owner: str | None,
    name: str,
    gone: Callable[[], Awaitable[bool]],
) -> dict:
    """One ray tree, as POST /api/raytree traces it: the scene checked in a checking process, then a short job
    of the interactive lane, waited for; its tree, or the error it ended with."""
    found = await check(json.dumps({"scene": scene}).encode())
    return await jobs.raytree(found, (x, y, sample), priority=RAYTREE_PRIORITY, owner=owner, name=name, gone=gone)


async def raytrees(
    course: Course,
    jobs: JobService,
    check: Check,
    caller: Caller,
    aid: str,
    sid: str,
    x: int,
    y: int,
    sample: int,
    gone: Callable[[], Awaitable[bool]],
) -> dict:
    """The route's answer: {x, y, sample, student: tree, reference: tree, difference: None | {student: path,
    reference: path, what, message, nodes}} (404 as for any submission; 409, 403, 422 as above)."""
    a, who = await anyio.to_thread.run_sync(course.who, aid, caller)
    sub = await anyio.to_thread.run_sync(course.submission, a, sid)
    if sub is None or not (who.student is None or sub["student"] == who.student["student"]):
        raise NotFound.at("sid", f"no submission with id '{sid[:64]}'")
    if sub["kind"] != "scene":
        as_graded(course, a, sub)  # its 409: an image has no scene (before the policy: it never will)
    allowed(course, a, sub, who)
    mine, theirs, size = await anyio.to_thread.run_sync(as_graded, course, a, sub)
    in_range(x, y, sample, size)
    where = f"({x}, {y}) of submission {sid[:8]}"
    student = await trace(jobs, check, mine, x, y, sample, caller.owner, f"ray tree {where}", gone)
    try:
        reference = await trace(jobs, check, theirs, x, y, sample, None, f"reference ray tree {where}", gone)
    except Invalid as e:
        # the reference scene is the instructor's: a student is told what failed, not its paths
        message = "; ".join(err["message"] for err in e.errors) if who.instructor else "it could not be traced"
        raise Unavailable.at("", f"the reference's ray tree could not be traced: {message}") from None
    return {"x": x, "y": y, "sample": sample, "student": student, "reference": reference,
            "difference": first_difference(student, reference)}  # fmt: skip
