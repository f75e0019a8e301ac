// Following a render job: its Server-Sent Events (GET /api/jobs/{id}/events, docs/service.md), shared by
// the viewer and the lessons. `progress` and `preview` come while the job runs; `end` brings the finished
// job (job.finished is true) and closes the stream. The stream is read with fetch, not EventSource: only
// fetch sends the job's token (Authorization). A dropped connection is retried after the server's `retry`
// time, as EventSource would; after MAX_FAILURES drops in a row without news the job is given up as lost.
import { api, authHeaders } from "./api.js";

export const MAX_FAILURES = 8;
const RETRY_MS = 1000; // until the stream says otherwise (`retry:`)

/** Follow job `id` until it ends. Handlers (each optional): onProgress(p), onPreview({pass, spp, url}),
 * onEnd(job), onDrop(failures) when the connection drops (it is tried again), onLost() after
 * MAX_FAILURES drops, or at once when the server says there is no such job (404). Returns {close(), done}:
 * `done` resolves once the job ended, was lost, or close() was called. */
export function followJob(id, { onProgress, onPreview, onEnd, onDrop, onLost } = {}) {
  let failures = 0;
  let open = true;
  let retry = RETRY_MS;
  let abort = null;
  let timer = null;
  let finish;
  const done = new Promise((resolve) => (finish = resolve));
  const close = () => {
    if (!open) return;
    open = false;
    clearTimeout(timer);
    abort?.abort();
    finish();
  };
  const lost = () => {
    if (!open) return;
    close();
    onLost?.();
  };
  const dropped = () => {
    if (!open) return;
    failures++;
    if (failures >= MAX_FAILURES) lost();
    else {
      onDrop?.(failures);
      timer = setTimeout(connect, retry);
    }
  };
  const dispatch = (event, text) => {
    if (!open) return;
    const data = JSON.parse(text);
    if (event === "progress") {
      failures = 0;
      onProgress?.(data);
    } else if (event === "preview") onPreview?.(data);
    else if (event === "end") {
      close();
      onEnd?.(data);
    }
  };

  async function connect() {
    if (!open) return;
    abort = new AbortController();
    let res;
    try {
      res = await fetch(api.eventsUrl(id), { headers: { accept: "text/event-stream", ...authHeaders("student", api.eventsUrl(id)) }, cache: "no-store", signal: abort.signal });
    } catch {
      dropped();
      return;
    }
    if (res.status === 404) {
      lost(); // not a job of this browser's token (or gone): no retry can bring it back
      return;
    }
    if (!res.ok || !res.body) {
      dropped();
      return;
    }
    try {
      await readEvents(res.body, dispatch, (ms) => (retry = ms));
    } catch {
      // the connection broke in the middle of the stream
    }
    dropped(); // the stream ended without `end` (nothing happens once the job has ended: close() ran)
  }

  connect();
  return { close, done };
}

/** Read a text/event-stream body: `dispatch(event, data)` for each event, `setRetry(ms)` for `retry:`
 * (comments and ids ignored), as the EventSource specification parses it. (The assignment page reads a
 * submission's events with it too.) */
export async function readEvents(body, dispatch, setRetry) {
  const reader = body.pipeThrough(new TextDecoderStream()).getReader();
  let buffer = "";
  let event = "message";
  let data = [];
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buffer += value;
    const lines = buffer.split("\n");
    buffer = lines.pop(); // an unfinished line waits for the rest
    for (const raw of lines) {
      const line = raw.endsWith("\r") ? raw.slice(0, -1) : raw;
      if (line === "") {
        if (data.length) dispatch(event, data.join("\n"));
        event = "message";
        data = [];
        continue;
      }
      if (line.startsWith(":")) continue;
      const colon = line.indexOf(":");
      const field = colon < 0 ? line : line.slice(0, colon);
      let text = colon < 0 ? "" : line.slice(colon + 1);
      if (text.startsWith(" ")) text = text.slice(1);
      if (field === "event") event = text;
      else if (field === "data") data.push(text);
      else if (field === "retry" && /^\d+$/.test(text)) setRetry(Number(text));
    }
  }
}
