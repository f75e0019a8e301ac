"""The server's status for whoever runs it (docs/service.md, "The status page"): GET /api/status (the admin's:
TRACER_INSTRUCTOR_TOKEN) is the JSON, GET /status the page that draws it (web/status.html, which asks for the token
as /course does and keeps it in the browser the same way). The facts each come from where they live: the workers
from the queue's interface, the lanes from the job store, the grades going back from the LMS's rows
(server/course/lms_posts.py), the last backup, the disk, the release and the schema from server/core/status.py."""

from __future__ import annotations

from datetime import UTC, datetime

import anyio
from fastapi import APIRouter
from fastapi.responses import FileResponse

from server.api.deps import CourseDep, InstructorDep, MaybeJanitorDep, MaybeLmsDep, QueueDep, SettingsDep, StoreDep
from server.core import status as facts
from server.core.paths import WEB
from server.course.lms_posts import posts

router = APIRouter(tags=["status"])


def hosts_of(workers: list[dict]) -> list[dict]:
    """The worker hosts: each host's name, its workers, how many of them are alive and ready, its devices."""
    out: dict[str, dict] = {}
    for w in workers:
        h = out.setdefault(str(w.get("host") or "?"), {"host": str(w.get("host") or "?"), "workers": 0, "alive": 0,
                                                         "ready": 0, "busy": 0, "devices": []})  # fmt: skip
        h["workers"] += 1
        h["alive"] += bool(w.get("alive", True))
        h["ready"] += bool(w.get("ready", True))
        h["busy"] += bool(w.get("job"))
        if (device := w.get("device")) and device not in h["devices"]:
            h["devices"].append(device)
    return sorted(out.values(), key=lambda h: h["host"])


@router.get("/api/status", summary="The server's status for its operator (the admin's): workers, queue, LMS, backup")
async def status(
    _: InstructorDep, settings: SettingsDep, store: StoreDep, queue: QueueDep, course: CourseDep,
    lms: MaybeLmsDep, janitor: MaybeJanitorDep,
) -> dict:  # fmt: skip
    """`workers` (as GET /api/health shows them) and `hosts` (grouped), `queue` (queued and running jobs per lane),
    `lms` (grades going back: pending, failed, sent, the latest error), `backup` (the last one's time and age, `old`
    past two days or when there is none), `disk` (the data directory against TRACER_MAX_DATA_BYTES, as the janitor
    last measured it), `version` and `schema`; `time` is the server's clock."""

    def answer() -> dict:  # reads the database and the disk: in one trip to a thread
        now = course.clock().astimezone(UTC)
        workers = queue.workers()
        measured = janitor.measured if janitor is not None else None
        return {
            "time": now.isoformat(),
            "version": facts.version(),
            "schema": facts.schema(settings.data_dir),
            "backend": queue.backend,
            "hosts": hosts_of(workers),
            "workers": workers,
            "queue": store.lanes(),
            "lms": posts(lms.store, now) if lms is not None else None,
            "backup": facts.last_backup(settings.data_dir, now),
            "disk": facts.disk(
                settings.data_dir,
                measured[0] if measured else None,
                datetime.fromtimestamp(measured[1], UTC) if measured else None,
                int(settings.max_data_bytes),
            ),
        }

    return await anyio.to_thread.run_sync(answer)


@router.get("/status", include_in_schema=False)
def status_page() -> FileResponse:  # the page reads /api/status with the admin's token (web/js/status.js)
    return FileResponse(WEB / "status.html", media_type="text/html")
