// The HTTP API (docs/service.md) as promises, and the page's one HTTP client: every request of every page
// (the workspace, lessons, grading, the course pages) goes through `request` here, and every event stream
// (a job's, a submission's) is followed by `followEvents`. Every failure becomes an ApiError with a message
// a student can read: the server's `{"errors": [{path, message}]}`, or "the server is not answering".
//
// Every request carries this browser's token (`Authorization: Bearer`): the server issues it with the
// first job (POST /api/jobs answers it in `token`), the page keeps it in localStorage, and only that
// token reads, follows, cancels and downloads the jobs it submitted. The Grading tab's requests carry
// the instructor's token instead (typed there, kept in localStorage too). Images and downloads are
// fetched with the header and shown as blob: URLs (an <img src> or <a href> cannot send it).
// An assignment's link makes its roster token the workspace's (course/working.js); the jobs listed until then
// keep the token that submitted them (`rt.owners`), sent only with the requests about those jobs, to this site.
import { store } from "./util.js";

const TOKEN_KEY = "rt.token"; // the student's token, as POST /api/jobs issued it
const INSTRUCTOR_KEY = "rt.instructor"; // the instructor's token (the Grading tab)
const OWNERS_KEY = "rt.owners"; // job id -> the token that submitted it, where that is no longer the workspace's
const JOBS_KEY = "rt.jobs"; // the ids of "my jobs" (viewer.js)
const kept = { student: null, instructor: null }; // when localStorage is not available (a private window)

/** The tokens this browser holds: `student` (its jobs') and `instructor` (grading). */
export const tokens = {
  student: () => store.get(TOKEN_KEY, null) || kept.student,
  instructor: () => store.get(INSTRUCTOR_KEY, null) || kept.instructor,
  setStudent(token) {
    const before = tokens.student();
    if (before && token && before !== token) keepOwners(before, token);
    kept.student = token || null;
    store.set(TOKEN_KEY, kept.student);
  },
  setInstructor(token) {
    kept.instructor = token || null;
    store.set(INSTRUCTOR_KEY, kept.instructor);
  },
};

/** The workspace's token goes from `before` to `now`: each job listed without an owner kept is `before`'s, and
 * stays openable with it; the owners of jobs no longer listed are forgotten, and `now`'s need no entry. */
function keepOwners(before, now) {
  const had = owners();
  const mine = {};
  for (const id of store.get(JOBS_KEY, [])) {
    const owner = typeof id === "string" ? (Object.hasOwn(had, id) ? had[id] : before) : null;
    if (owner && owner !== now) mine[id] = owner;
  }
  store.set(OWNERS_KEY, mine);
}

function owners() {
  const map = store.get(OWNERS_KEY, {});
  return map && typeof map === "object" ? map : {};
}

const shared = new Map(); // job id -> its read-only share token (a job opened from a shared link)

/** Read job `id` with its share token (a read-only link: `#shared/<id>/<token>`) rather than the student's. */
export function useShareToken(id, token) {
  shared.set(id, token);
}

/** The Authorization header of `as` ("student" or "instructor"), or none without a token; a request about a
 * job opened from a shared link (`url`) carries that job's share token. */
export function authHeaders(as = "student", url = "") {
  const id = as === "student" ? /^\/api\/jobs\/([^/?#]+)/.exec(url)?.[1] : null;
  if (id && shared.has(decodeURIComponent(id)))
    return { authorization: `Bearer ${shared.get(decodeURIComponent(id))}` };
  const map = id ? owners() : {};
  const owner = id && Object.hasOwn(map, decodeURIComponent(id)) ? map[decodeURIComponent(id)] : null; // a job of an earlier token
  if (typeof owner === "string" && owner) return { authorization: `Bearer ${owner}` };
  const token = as === "instructor" ? tokens.instructor() : tokens.student();
  return token ? { authorization: `Bearer ${token}` } : {};
}

/** The Authorization header of a request to `url`: `token`'s when one is given (null: none), else `as`'s. */
function authFor(url, as, token) {
  if (token === undefined) return authHeaders(as, url);
  return token ? { authorization: `Bearer ${token}` } : {};
}

export class ApiError extends Error {
  constructor(status, errors, message) {
    super(message || errors.map((e) => (e.path ? `${e.path}: ${e.message}` : e.message)).join("; "));
    this.status = status; // 0 when the server could not be reached
    this.errors = errors; // [{path, message}]
  }
}

/** One request: the parsed JSON answer, or an ApiError (the grading view uses it too, `as: "instructor"`).
 * `raw`: the Response itself when it is OK. `token`: this token instead of `as`'s (an assignment's page
 * sends its own link's token; null sends none). `type`: the content type of a text body (a roster's
 * "text/csv"; JSON otherwise). */
export async function request(
  method,
  url,
  body,
  { raw = false, signal, as = "student", cache, token, type = "application/json" } = {},
) {
  const init = { method, signal, cache, headers: authFor(url, as, token) };
  if (body instanceof FormData) {
    init.body = body; // multipart/form-data: the browser sets the type and its boundary, and streams the files
  } else if (body !== undefined) {
    init.headers["content-type"] = type;
    init.body = typeof body === "string" ? body : JSON.stringify(body);
  }
  let res;
  try {
    res = await fetch(url, init);
  } catch (err) {
    if (err.name === "AbortError") throw err;
    throw new ApiError(0, [{ path: "", message: "the server is not answering (is it running?)" }]);
  }
  if (raw && res.ok) return res;
  let data = null;
  const text = await res.text();
  try {
    data = text ? JSON.parse(text) : null;
  } catch {
    data = null;
  }
  if (!res.ok) {
    const errors =
      data && Array.isArray(data.errors) && data.errors.length
        ? data.errors
        : [{ path: "", message: `the server answered ${res.status} ${res.statusText}`.trim() }];
    throw new ApiError(res.status, errors);
  }
  return data;
}

/** A resource that needs the token (an image, an AOV, a download) as a Blob. */
export async function blob(url, { as = "student", signal, token } = {}) {
  const res = await request("GET", url, undefined, { raw: true, as, signal, cache: "no-store", token });
  return res.blob();
}

/** The load under way in each img (its URL and the promise showImage gave for it). */
const showing = new WeakMap();

/** Show `url` (an image that needs the token) in `img`, as a blob: URL; the one it showed before is
 * released. `img.dataset.src` is the API's URL shown (or being fetched). Resolves to true once `url` is the img's
 * source, false when it could not be loaded or another image was asked for meanwhile; a second call for the URL
 * being fetched gets the first call's promise (it does not answer before the picture is there). */
export function showImage(img, url, { as = "student", token } = {}) {
  const now = showing.get(img);
  if (img.dataset.src === url && now?.url === url) return now.promise;
  img.dataset.src = url;
  const promise = fetchInto(img, url, { as, token });
  showing.set(img, { url, promise });
  return promise;
}

async function fetchInto(img, url, { as, token }) {
  let data;
  try {
    data = await blob(url, { as, token });
  } catch {
    if (img.dataset.src === url) delete img.dataset.src;
    if (showing.get(img)?.url === url) showing.delete(img);
    return false;
  }
  if (img.dataset.src !== url) return false; // another image was asked for meanwhile
  const old = img.dataset.blob;
  img.dataset.blob = URL.createObjectURL(data);
  img.src = img.dataset.blob;
  if (old) setTimeout(() => URL.revokeObjectURL(old), 0);
  return true;
}

/** Offer `url` (a file that needs the token) as a download named `name`. */
export async function downloadFile(url, name, { as = "student" } = {}) {
  const data = await blob(url, { as });
  const href = URL.createObjectURL(data);
  const a = document.createElement("a");
  a.href = href;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(href), 10_000);
}

/** Open `url` (a file that needs the token: a JSON report, a picture) in a new tab, as a blob: URL. */
export async function openFile(url, { as = "student" } = {}) {
  const data = await blob(url, { as });
  const href = URL.createObjectURL(data);
  window.open(href, "_blank", "noopener");
  setTimeout(() => URL.revokeObjectURL(href), 60_000);
}

export const MAX_DROPS = 8; // drops in a row without news, after which a stream is given up
const RETRY_MS = 1000; // until the stream says otherwise (`retry:`)

/** Follow the Server-Sent Events at `url` (a job's, a submission's) until its `end` event or close(). The
 * stream is read with fetch, not EventSource: only fetch sends the token (`as`'s, or `token`'s, as in
 * `request`). Each event calls onEvent(event, data) with its JSON data; `end` closes the stream first. The
 * events named in `news` show the stream alive: each resets the count of drops. A dropped connection (the
 * server not answering, an answer other than 200, a stream that stops without `end`) is tried again after
 * the server's `retry` time, as EventSource would, with onDrop(drops); after MAX_DROPS drops in a row the
 * stream is given up: onGiveUp(). A 404 (not this token's, or gone: no retry brings it back) ends it at
 * once: onMissing() (onGiveUp when not given). Returns {close(), done}: `done` resolves once it ended, was
 * given up, or close() was called. */
export function followEvents(
  url,
  { as = "student", token, news = [], onEvent, onDrop, onGiveUp, onMissing = onGiveUp } = {},
) {
  let drops = 0;
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
  const giveUp = (then) => {
    if (!open) return;
    close();
    then?.();
  };
  const dropped = () => {
    if (!open) return;
    drops++;
    if (drops >= MAX_DROPS) giveUp(onGiveUp);
    else {
      onDrop?.(drops);
      timer = setTimeout(connect, retry);
    }
  };
  const dispatch = (event, text) => {
    if (!open) return;
    const data = JSON.parse(text);
    if (news.includes(event)) drops = 0;
    if (event === "end") close();
    onEvent?.(event, data);
  };

  async function connect() {
    if (!open) return;
    abort = new AbortController();
    let res;
    try {
      res = await fetch(url, {
        headers: { accept: "text/event-stream", ...authFor(url, as, token) },
        cache: "no-store",
        signal: abort.signal,
      });
    } catch {
      dropped();
      return;
    }
    if (res.status === 404) {
      giveUp(onMissing);
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
    dropped(); // the stream ended without `end` (nothing happens once it has ended: close() ran)
  }

  connect();
  return { close, done };
}

/** Read a text/event-stream body: `dispatch(event, data)` for each event, `setRetry(ms)` for `retry:`
 * (comments and ids ignored), as the EventSource specification parses it. */
async function readEvents(body, dispatch, setRetry) {
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

let issuing = null; // the first submission without a token: the others wait for the token it brings

/** POST /api/jobs: the first submission of a browser without a token goes alone and keeps the token the
 * server issues; submissions made at the same time (a lesson's panels) wait for it, so all are one owner's. */
async function submitJob(body) {
  while (!tokens.student() && issuing) await issuing.catch(() => null);
  if (tokens.student()) return request("POST", "/api/jobs", body);
  issuing = request("POST", "/api/jobs", body);
  try {
    const job = await issuing;
    if (job?.token) tokens.setStudent(job.token);
    return job;
  } finally {
    issuing = null;
  }
}

/** A request body with the scene spliced in as the editor's own text (so NaN reaches the validator,
 * and numbers are sent exactly as typed). `sceneText` must already be a parsed, valid JSON value. */
export function withScene(sceneText, fields = {}) {
  const rest = JSON.stringify(fields);
  return `{"scene":${sceneText}${rest === "{}" ? "" : `,${rest.slice(1, -1)}`}}`;
}

export const api = {
  health: () => request("GET", "/api/health"),
  scenes: () => request("GET", "/api/scenes"),
  scene: (name) => request("GET", `/api/scenes/${encodeURIComponent(name)}`),
  askPreview: (name) => request("POST", `/api/scenes/${encodeURIComponent(name)}/preview`),
  previewUrl: (name) => `/api/scenes/${encodeURIComponent(name)}/preview.png`,
  validate: (sceneText, signal) => request("POST", "/api/validate", withScene(sceneText), { signal }),
  submit: (sceneText, priority = 0) => submitJob(withScene(sceneText, priority ? { priority } : {})),
  job: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}`),
  share: (id) => request("POST", `/api/jobs/${encodeURIComponent(id)}/share`),
  jobScene: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}/scene`),
  cancel: (id) => request("DELETE", `/api/jobs/${encodeURIComponent(id)}`),
  aovs: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}/aov`),
  aovUrl: (id, name) => `/api/jobs/${encodeURIComponent(id)}/aov/${encodeURIComponent(name)}`,
  imageUrl: (id, format = "png", pass = 0) =>
    `/api/jobs/${encodeURIComponent(id)}/image?format=${format}${pass ? `&pass=${pass}` : ""}`,
  eventsUrl: (id) => `/api/jobs/${encodeURIComponent(id)}/events`,
  radiosity: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}/radiosity`, undefined, { cache: "no-store" }),
  raytree: (sceneText, x, y, sample, signal) =>
    request("POST", "/api/raytree", withScene(sceneText, { x, y, sample }), { signal }),
  schema: () => request("GET", "/api/schema"),
  samples: (sceneText, x, y) => request("POST", "/api/samples", withScene(sceneText, { x, y })),
};
