"""A student's own ray tracer, explained on the service (POST /api/assignments/{aid}/submissions/{sid}/trees, and
`trees` in the check; docs/own-tracer.md): each tree of their tree log against the reference's tree through the
same pixel's centre, and the first difference named (tracer/grading/explain.py).

**Who and when.** The student who owns the submission, or the course's staff. The reference's trees show the
reference scene's structure, so they are shown when the error map is (compare.allowed: every image test's
feedback shown now); the 403 says when. No student code ever runs here: the log is data, checked before use
(tracer/grading/treelog.py), within TRACER_MAX_TREE_LOG_BYTES and TRACER_MAX_TREE_LOG_TREES.

**The reference's trees** are traced by workers, each a ray-tree job of the interactive lane as the reference's,
from the version's reference scene with its settings (Whitted, its max_depth and min_weight, the `center`
sampler), and kept per assignment version and pixel (TreeCache): a student who sends the same probes again waits
for no worker. The comparison itself is a few milliseconds of Python.

**What the class hits.** The latest answer of each submission is kept beside its pictures (trees.json), and the
dashboard counts the first `what` of each tree over the class (`whats`).
"""

from __future__ import annotations

import json
import threading
from collections import Counter, OrderedDict
from collections.abc import Awaitable, Callable
from pathlib import Path

import anyio
import numpy as np

from server.core.errors import Conflict, Invalid, NotFound, Unavailable
from server.core.files import write_atomic
from server.core.security import Caller
from server.course import compare
from server.course.schema import AssignmentRow
from server.course.service import Course
from server.jobs.service import JobService
from tracer.errors import SceneError
from tracer.grading import tasks
from tracer.grading.explain import Explainer, centre_scene
from tracer.grading.treelog import TreeLog, parse

ANSWER = "trees.json"  # a submission's latest comparison, beside its pictures
CACHED_TREES = 4096  # reference trees kept in memory, over all assignments


class TreeCache:
    """The reference's centre-ray trees by (assignment, version, x, y), the least recently used dropped first."""

    def __init__(self, size: int = CACHED_TREES):
        self.size, self._trees, self._lock = size, OrderedDict(), threading.Lock()

    def get(self, key: tuple) -> dict | None:
        with self._lock:
            tree = self._trees.get(key)
            if tree is not None:
                self._trees.move_to_end(key)
            return tree

    def put(self, key: tuple, tree: dict) -> None:
        with self._lock:
            self._trees[key] = tree
            self._trees.move_to_end(key)
            while len(self._trees) > self.size:
                self._trees.popitem(last=False)


def reference_scene(course: Course, a: AssignmentRow, version: int) -> dict:
    """The version's reference scene with the assignment's settings (as the grader renders it); 409 without one."""
    spec = next(v for v in course.store.versions(a["id"]) if v["version"] == version)["spec"]
    grader = tasks.grader(json.dumps(spec))
    if grader.reference is None:
        raise Conflict.at("sid", "this assignment has no reference scene: there are no reference trees to compare with")
    return grader.reference.scene


def read_log(body: bytes, scene: dict, max_trees: int) -> TreeLog:
    """The tree log, checked against the reference's film: 422 with every error at its path."""
    film = scene.get("film", {})
    width, height = int(film.get("width", 256)), int(film.get("height", 256))
    try:
        log = parse(body, width, height)
    except SceneError as e:
        raise Invalid(e.errors) from None
    if len(log.trees) > max_trees:
        raise Invalid([{"path": "trees", "message": f"at most {max_trees} trees (TRACER_MAX_TREE_LOG_TREES), "
                        f"got {len(log.trees)}"}])  # fmt: skip
    return log


async def reference_trees(
    jobs: JobService, check: compare.Check, cache: TreeCache, a: AssignmentRow, version: int, scene: dict,
    pixels: list[tuple[int, int]], gone: Callable[[], Awaitable[bool]],
) -> dict[tuple[int, int], dict]:  # fmt: skip
    """The reference's tree at each pixel: from the cache, or traced by workers (all at once) and kept."""
    out: dict[tuple[int, int], dict] = {}
    missing = []
    for x, y in pixels:
        tree = cache.get((a["id"], version, x, y))
        if tree is None:
            missing.append((x, y))
        else:
            out[x, y] = tree
    if not missing:
        return out
    centre = centre_scene(scene)

    async def one(x: int, y: int) -> None:
        try:
            tree = await compare.trace(jobs, check, centre, x, y, 0, None, f"reference tree ({x}, {y})", gone)
        except Invalid:
            raise Unavailable.at("", "the reference's tree could not be traced") from None
        cache.put((a["id"], version, x, y), tree)
        out[x, y] = tree

    async with anyio.create_task_group() as tg:
        for x, y in missing:
            tg.start_soon(one, x, y)
    return out


def _png(path: Path) -> np.ndarray | None:
    if not path.is_file():
        return None
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0


async def compare_log(
    course: Course, jobs: JobService, check: compare.Check, cache: TreeCache, caller: Caller, aid: str, sid: str,
    body: bytes, max_trees: int, gone: Callable[[], Awaitable[bool]],
) -> dict:  # fmt: skip
    """The route's answer: {submission, width, height, trees: [{pixel, matches, differences, student,
    reference}], scene} (404 as for any submission; 409 for a scene or an ungraded one; 403 while the error map
    is hidden; 422 for a bad log). `scene` is the reference scene the trees were traced in (the student renders
    it anyway): the page draws both trees over the images and in 3D with its camera and objects."""
    a, who = await anyio.to_thread.run_sync(course.who, aid, caller)
    sub = await anyio.to_thread.run_sync(course.submission, a, sid)
    if sub is None or not (who.student is None or sub["student"] == who.student["student"]):
        raise NotFound.at("sid", f"no submission with id '{sid[:64]}'")
    if sub["kind"] == "scene":
        raise Conflict.at("sid", f"submission '{sid}' is a scene: its ray trees are traced by the service (GET "
                          ".../raytree); a tree log is for an image from your own tracer")  # fmt: skip
    compare.allowed(course, a, sub, who)
    scene = await anyio.to_thread.run_sync(reference_scene, course, a, sub["version"])
    log = read_log(body, scene, max_trees)
    pixels = [t.pixel for t in log.trees]  # (x, y): a tuple once parsed
    trees = await reference_trees(jobs, check, cache, a, sub["version"], scene, pixels, gone)
    folder = course.runs.root / sub["run_id"] / "out" / sid if sub.get("run_id") else None

    def work() -> dict:
        shown = _png(folder / "render.png") if folder else None
        reference = _png(folder / "reference.png") if folder else None
        answers = Explainer(scene, reference, device=None).compare(log, shown, trees)
        film = scene.get("film", {})
        out = {"submission": sid, "width": film.get("width", 256), "height": film.get("height", 256),
               "trees": answers, "scene": scene}  # fmt: skip
        if folder is not None and folder.is_dir():  # the latest answer, for the staff and the dashboard
            write_atomic(folder / ANSWER, lambda tmp: tmp.write_bytes(json.dumps(out).encode()))
        return out

    return await anyio.to_thread.run_sync(work)


async def check_log(
    course: Course, jobs: JobService, check: compare.Check, cache: TreeCache, a: AssignmentRow, who, trees: object,
    max_trees: int, gone: Callable[[], Awaitable[bool]],
) -> list[dict]:  # fmt: skip
    """`trees` of the check: the log compared with the current version's reference (no image: no `encoding`)."""
    body = json.dumps(trees).encode()
    scene = await anyio.to_thread.run_sync(reference_scene, course, a, a["version"])
    log = read_log(body, scene, max_trees)
    pixels = [t.pixel for t in log.trees]  # (x, y): a tuple once parsed
    got = await reference_trees(jobs, check, cache, a, a["version"], scene, pixels, gone)
    return await anyio.to_thread.run_sync(lambda: Explainer(scene, None, device=None).compare(log, None, got))


async def latest(course: Course, caller: Caller, aid: str, sid: str) -> dict:
    """The submission's latest comparison (404 when none was made), to its student or the staff, while the
    policy shows the error map."""
    a, who = await anyio.to_thread.run_sync(course.who, aid, caller)
    sub = await anyio.to_thread.run_sync(course.submission, a, sid)
    if sub is None or not (who.student is None or sub["student"] == who.student["student"]):
        raise NotFound.at("sid", f"no submission with id '{sid[:64]}'")
    compare.allowed(course, a, sub, who)
    path = course.runs.root / sub["run_id"] / "out" / sid / ANSWER if sub.get("run_id") else None
    try:
        return json.loads(path.read_text()) if path else {}
    except (OSError, ValueError):
        raise NotFound.at("sid", f"no tree log was compared for submission '{sid[:64]}' yet") from None


def whats(course: Course, a: AssignmentRow) -> dict[str, int]:
    """The class's first differences by `what`: each submission's latest comparison, each tree's first one."""
    counts: Counter[str] = Counter()
    for sub in course.submissions(a):
        if not sub.get("run_id"):
            continue
        path = course.runs.root / sub["run_id"] / "out" / sub["id"] / ANSWER
        try:
            kept = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        for t in kept.get("trees", []):
            if t.get("differences"):
                counts[t["differences"][0]["what"]] += 1
    return dict(counts.most_common())
