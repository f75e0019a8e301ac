// Following a render job: its Server-Sent Events (GET /api/jobs/{id}/events, docs/service.md), shared by
// the viewer and the lessons. `progress` and `preview` come while the job runs; `end` brings the finished
// job (job.finished is true) and closes the stream. The stream is api.js's `followEvents` (read with fetch,
// which sends the job's token; a dropped connection retried after the server's `retry` time); after
// MAX_FAILURES drops in a row without progress the job is given up as lost.
import { MAX_DROPS, api, followEvents } from "./api.js";

export const MAX_FAILURES = MAX_DROPS;

/** Follow job `id` until it ends. Handlers (each optional): onProgress(p), onPreview({pass, spp, url}),
 * onEnd(job), onDrop(failures) when the connection drops (it is tried again), onLost() after
 * MAX_FAILURES drops, or at once when the server says there is no such job (404). Returns {close(), done}:
 * `done` resolves once the job ended, was lost, or close() was called. */
export function followJob(id, { onProgress, onPreview, onEnd, onDrop, onLost } = {}) {
  return followEvents(api.eventsUrl(id), {
    news: ["progress"],
    onEvent(event, data) {
      if (event === "progress") onProgress?.(data);
      else if (event === "preview") onPreview?.(data);
      else if (event === "end") onEnd?.(data);
    },
    onDrop,
    onGiveUp: onLost, // not a job of this browser's token (or gone), or too many drops
  });
}
