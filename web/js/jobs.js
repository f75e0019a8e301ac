// Following a render job: its Server-Sent Events (GET /api/jobs/{id}/events, docs/service.md), shared by
// the viewer and the lessons. `progress` and `preview` come while the job runs; `end` brings the finished
// job (job.finished is true) and closes the stream. A dropped connection is retried by the browser
// (EventSource); after MAX_FAILURES drops in a row without news the job is given up as lost.
import { api } from "./api.js";

export const MAX_FAILURES = 8;

/** Follow job `id` until it ends. Handlers (each optional): onProgress(p), onPreview({pass, spp, url}),
 * onEnd(job), onDrop(failures) when the connection drops (the browser reconnects), onLost() after
 * MAX_FAILURES drops. Returns {close(), done}: `done` resolves once the job ended, was lost, or close()
 * was called. */
export function followJob(id, { onProgress, onPreview, onEnd, onDrop, onLost } = {}) {
  const es = new EventSource(api.eventsUrl(id));
  let failures = 0;
  let open = true;
  let finish;
  const done = new Promise((resolve) => (finish = resolve));
  const close = () => {
    if (!open) return;
    open = false;
    es.close();
    finish();
  };
  es.addEventListener("progress", (e) => {
    failures = 0;
    if (open) onProgress?.(JSON.parse(e.data));
  });
  es.addEventListener("preview", (e) => {
    if (open) onPreview?.(JSON.parse(e.data));
  });
  es.addEventListener("end", (e) => {
    if (!open) return;
    close();
    onEnd?.(JSON.parse(e.data));
  });
  es.addEventListener("error", () => {
    if (!open) return;
    failures++;
    if (failures >= MAX_FAILURES) {
      close();
      onLost?.();
    } else onDrop?.(failures);
  });
  return { close, done };
}
