// The HTTP API (docs/service.md) as promises. Every failure becomes an ApiError with a message a
// student can read: the server's `{"errors": [{path, message}]}`, or "the server is not answering".

export class ApiError extends Error {
  constructor(status, errors, message) {
    super(message || errors.map((e) => (e.path ? `${e.path}: ${e.message}` : e.message)).join("; "));
    this.status = status; // 0 when the server could not be reached
    this.errors = errors; // [{path, message}]
  }
}

/** One request: the parsed JSON answer, or an ApiError (the grading view uses it too). */
export async function request(method, url, body, { raw = false, signal } = {}) {
  const init = { method, signal, headers: {} };
  if (body instanceof FormData) {
    init.body = body; // multipart/form-data: the browser sets the type and its boundary, and streams the files
  } else if (body !== undefined) {
    init.headers["content-type"] = "application/json";
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

/** A request body with the scene spliced in as the editor's own text (so NaN reaches the validator,
 * and numbers are sent exactly as typed). `sceneText` must already be a parsed, valid JSON value. */
export function withScene(sceneText, fields = {}) {
  const rest = JSON.stringify(fields);
  return `{"scene":${sceneText}${rest === "{}" ? "" : "," + rest.slice(1, -1)}}`;
}

export const api = {
  health: () => request("GET", "/api/health"),
  scenes: () => request("GET", "/api/scenes"),
  scene: (name) => request("GET", `/api/scenes/${encodeURIComponent(name)}`),
  previewUrl: (name) => `/api/scenes/${encodeURIComponent(name)}/preview.png`,
  validate: (sceneText, signal) => request("POST", "/api/validate", withScene(sceneText), { signal }),
  submit: (sceneText, priority = 0) => request("POST", "/api/jobs", withScene(sceneText, priority ? { priority } : {})),
  job: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}`),
  jobScene: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}/scene`),
  cancel: (id) => request("DELETE", `/api/jobs/${encodeURIComponent(id)}`),
  aovs: (id) => request("GET", `/api/jobs/${encodeURIComponent(id)}/aov`),
  aovUrl: (id, name) => `/api/jobs/${encodeURIComponent(id)}/aov/${encodeURIComponent(name)}`,
  imageUrl: (id, format = "png", pass = 0) =>
    `/api/jobs/${encodeURIComponent(id)}/image?format=${format}${pass ? `&pass=${pass}` : ""}`,
  eventsUrl: (id) => `/api/jobs/${encodeURIComponent(id)}/events`,
  raytree: (sceneText, x, y, sample, signal) => request("POST", "/api/raytree", withScene(sceneText, { x, y, sample }), { signal }),
  schema: () => request("GET", "/api/schema"),
  samples: (sceneText, x, y) => request("POST", "/api/samples", withScene(sceneText, { x, y })),
};
