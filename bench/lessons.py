"""Benchmark of the lessons (issue #25): from opening a lesson to its first picture and to all of them done.

    python -m bench.lessons [--cold] [--workers 1] [--out FILE]
    python -m bench.lessons --write-panels     # server/jobs/lesson_panels.json, from the page's own code

It starts `python -m server` with a fresh data directory and waits until it is warm: the workers ready and
every job it queued at start-up (the examples' previews, the lessons' panels at their first controls) done.
Then headless Chromium opens the page and each lesson in turn, in the lecture's order, one at a time: the
time from the click on its button to the first panel showing a picture (a pass or the final image), to the
first final picture, and to every panel's final picture shown (or its refusal). `--cold` measures the server
as it was before (TRACER_LESSONS_AHEAD=0, TRACER_ANSWER_AGAIN=0: every panel rendered when asked).

`--write-panels` writes the scenes of every lesson's panels at their controls' first values, built in the
browser by web/js/lessons.js's `firstPanels` (the code the page runs), for the server to render ahead.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

from bench.service import Api, start_server
from server.jobs.lesson_panels import PANELS

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--no-first-run"]

FIRST_PANELS = """async () => {
    const { firstPanels } = await import("/js/lessons.js");
    const { api } = await import("/js/api.js");
    return firstPanels((name) => api.scene(name));
}"""

LESSON_IDS = """async () => (await import("/js/lessons.js")).LESSONS.map((l) => l.id)"""

# Click a lesson's button and watch its panels every 5 ms: the times (ms) of the first picture shown, the first
# final one, and all panels ended (a final picture shown, or refused / failed / cancelled).
OPEN_LESSON = """async (id) => {
    const t0 = performance.now();
    document.querySelector(`.lesson-button[data-lesson="${id}"]`).click();
    const final = (p) => {
        const i = p.querySelector("img.lesson-picture");
        return p.dataset.status === "done" && i.dataset.shown === p.dataset.image && i.complete && i.naturalWidth > 0;
    };
    const over = (p) => final(p) || ["refused", "failed", "cancelled"].includes(p.dataset.status);
    let picture = null, first = null;
    for (;;) {
        await new Promise((r) => setTimeout(r, 5));
        const now = performance.now() - t0;
        const ps = document.querySelector("#lesson-stage").dataset.lesson === id
            ? [...document.querySelectorAll(".lesson-panel")] : [];
        if (picture === null && ps.some((p) => p.querySelector("img.lesson-picture")?.dataset.shown)) picture = now;
        if (first === null && ps.some(final)) first = now;
        if (ps.length && ps.every(over)) return { picture, first, all: now, statuses: ps.map((p) => p.dataset.status) };
        if (now > 300000) return { picture, first, all: null, statuses: ps.map((p) => p.dataset.status) };
    }
}"""


def browser_page(url: str):
    """(playwright, browser, page) with the page open at `url` and ready."""
    from playwright.sync_api import sync_playwright

    pw = sync_playwright().start()
    browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
    page = browser.new_context(viewport={"width": 1280, "height": 800}).new_page()
    page.goto(f"{url}/#lessons")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    return pw, browser, page


def first_panels(page) -> list[dict]:
    """Every lesson's panels at their controls' first values, as the page builds them: [{lesson, index, scene}]."""
    return page.evaluate(FIRST_PANELS)


def panels_text(panels: list[dict]) -> str:
    """lesson_panels.json's text: one panel a line, so that a change reads as a change of its lines."""
    return "[\n" + ",\n".join(json.dumps(p, sort_keys=True) for p in panels) + "\n]\n"


def wait_warm(api: Api, timeout: float = 900) -> float:
    """Wait until nothing is queued or running (the start-up's previews and lesson panels); seconds waited."""
    t0 = time.monotonic()
    while True:
        counts = api.json("GET", "/api/health")["jobs"]
        if counts.get("queued", 0) == 0 and counts.get("running", 0) == 0:
            return time.monotonic() - t0
        if time.monotonic() - t0 > timeout:
            raise RuntimeError(f"still busy after {timeout} s: {counts}")
        time.sleep(0.5)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m bench.lessons", description=__doc__.split("\n")[0])
    p.add_argument("--cold", action="store_true", help="no lesson panels ahead, no answers again (as before #25)")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--write-panels", action="store_true", help=f"write {PANELS.name} and exit")
    p.add_argument("--out", help="write the results as JSON")
    args = p.parse_args(argv)
    if args.cold or args.write_panels:
        os.environ["TRACER_LESSONS_AHEAD"] = os.environ["TRACER_ANSWER_AGAIN"] = "0"
    os.environ["TRACER_PREVIEWS_AHEAD"] = "0" if args.write_panels else os.environ.get("TRACER_PREVIEWS_AHEAD", "1")
    with tempfile.TemporaryDirectory(prefix="bench-lessons-") as tmp:
        proc, port = start_server(Path(tmp) / "data", args.workers)
        try:
            api = Api(port)
            warm = 0.0 if args.write_panels else wait_warm(api)
            pw, browser, page = browser_page(f"http://127.0.0.1:{port}")
            try:
                if args.write_panels:
                    panels = first_panels(page)
                    PANELS.write_text(panels_text(panels))
                    print(f"wrote {len(panels)} panels to {PANELS}")
                    return {"panels": len(panels)}
                rows = [{"lesson": i, **page.evaluate(OPEN_LESSON, i)} for i in page.evaluate(LESSON_IDS)]
            finally:
                browser.close()
                pw.stop()
        finally:
            proc.terminate()
            proc.wait(timeout=60)
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "load": os.getloadavg(), "cold": args.cold,
        "workers": args.workers, "warm_up_s": round(warm, 1), "machine": platform.machine(), "lessons": rows,
    }  # fmt: skip
    report(result)
    if args.out:
        Path(args.out).write_text(json.dumps(result, indent=2))
    return result


def seconds(ms: float | None) -> str:
    return "-" if ms is None else f"{ms / 1000:.2f}"


def report(r: dict) -> None:
    load = ", ".join(f"{x:.2f}" for x in r["load"])
    print(f"{r['date']}, load average {load}, {'cold' if r['cold'] else 'warm'}, warm-up {r['warm_up_s']} s")
    print(f"{'lesson':<24} {'picture':>8} {'first':>8} {'all':>8}  panels")
    for row in r["lessons"]:
        times = " ".join(f"{seconds(row[k]):>8}" for k in ("picture", "first", "all"))
        print(f"{row['lesson']:<24} {times}  {','.join(row['statuses'])}")
    alls = sorted(row["all"] for row in r["lessons"] if row["all"] is not None)
    if alls:
        print(f"all done: median {alls[len(alls) // 2] / 1000:.2f} s, max {alls[-1] / 1000:.2f} s")


if __name__ == "__main__":
    main()
