// What the instructor's course page (web/course.html) shares between its parts: the requests (each with the
// instructor's token, `as: "instructor"`), times between the server's ISO 8601 and the browser's
// datetime-local inputs, and the server's errors shown at the field they name.
import { ApiError, request } from "../api.js";
import { h, num } from "../util.js";

export const AS = { as: "instructor" };
const A = (aid) => `/api/assignments/${encodeURIComponent(aid)}`;

export const course = {
  into: null, // the course the publish form publishes into (null: the token's own, else the default one)
  list: () => request("GET", "/api/assignments", undefined, { ...AS, cache: "no-store" }),
  publish: (form) =>
    request(
      "POST",
      course.into ? `/api/courses/${encodeURIComponent(course.into)}/assignments` : "/api/assignments",
      form,
      AS,
    ),
  courses: () => request("GET", "/api/courses", undefined, { ...AS, cache: "no-store" }),
  courseView: (cid) =>
    request("GET", `/api/courses/${encodeURIComponent(cid)}`, undefined, { ...AS, cache: "no-store" }),
  createCourse: (body) => request("POST", "/api/courses", body, AS),
  addStaff: (cid, body) => request("POST", `/api/courses/${encodeURIComponent(cid)}/staff`, body, AS),
  // what a student would see under the form's policy, before publishing (nothing is kept)
  preview: (form) =>
    request(
      "POST",
      `/api/assignments/preview-feedback${course.into ? `?course=${encodeURIComponent(course.into)}` : ""}`,
      form,
      AS,
    ),
  edit: (aid, form, regrade) => request("PUT", `${A(aid)}${regrade ? "?regrade=true" : ""}`, form, AS),
  brief: (aid) => request("GET", A(aid), undefined, { ...AS, cache: "no-store" }),
  board: (aid) => request("GET", `${A(aid)}/dashboard`, undefined, { ...AS, cache: "no-store" }),
  lmsSendAgain: (aid) => request("POST", `${A(aid)}/lms/send-again`, {}, AS), // the grades the LMS refused, queued again
  student: (aid, sid) =>
    request("GET", `${A(aid)}/students/${encodeURIComponent(sid)}`, undefined, { ...AS, cache: "no-store" }),
  trees: (aid, sid) =>
    request("GET", `${A(aid)}/submissions/${encodeURIComponent(sid)}/trees`, undefined, { ...AS, cache: "no-store" }), // the latest tree log comparison
  extend: (aid, student, deadline, why = "") => request("POST", `${A(aid)}/extensions`, { student, deadline, why }, AS),
  newLink: (aid, student) => request("POST", `${A(aid)}/students/${encodeURIComponent(student)}/link`, undefined, AS),
  roster: (aid, text) => request("POST", `${A(aid)}/roster`, text, { ...AS, type: "text/csv" }), // a CSV body
  renewLinks: (cid, aid) =>
    request(
      "POST",
      `/api/courses/${encodeURIComponent(cid)}/links/renew?assignment=${encodeURIComponent(aid)}`,
      undefined,
      AS,
    ),
  links: (cid, aid) =>
    request("GET", `/api/courses/${encodeURIComponent(cid)}/links?assignment=${encodeURIComponent(aid)}`, undefined, {
      ...AS,
      cache: "no-store",
    }),
  url: A,
};

/** Why the server refused for want of the instructor's token (401, 403), or null. */
export function tokenProblem(err, hasToken) {
  if (!(err instanceof ApiError)) return null;
  if (err.status === 403 && err.errors?.[0]?.path === "Authorization")
    return `The server has no instructor: ${err.message}`;
  if (err.status === 401)
    return hasToken ? "The server refused this token: check it above (or open your staff link again)." : NO_TOKEN;
  return null;
}

/** What a person does on /course without a token (the server's answer speaks HTTP: "send 'Authorization: Bearer'"). */
export const NO_TOKEN =
  "This page is for a course's staff. Open the staff link you were sent (it signs you in), or paste your token above: " +
  "the instructor's (the server's TRACER_INSTRUCTOR_TOKEN) or a TA's. A student's page is the link from their instructor.";

/** An error's words for a person: the token's problem when it is one, else the server's message. */
export const errorWords = (err, hasToken) => tokenProblem(err, hasToken) || err.message;

// -- times ----------------------------------------------------------------------------------------

const pad = (n, w = 2) => String(Math.trunc(Math.abs(n))).padStart(w, "0");

/** A datetime-local input's value ("2026-12-08T23:59") as ISO 8601 with this browser's zone offset on that
 * date ("2026-12-08T23:59:00-05:00"): the server refuses a time without a zone. "" -> null. */
export function zoned(value) {
  if (!value) return null;
  const [date, time = "00:00"] = value.split("T");
  const [y, mo, d] = date.split("-").map(Number);
  const [hh, mm, ss = 0] = time.split(":").map(Number);
  const local = new Date(y, mo - 1, d, hh, mm, Math.floor(ss));
  const offset = -local.getTimezoneOffset(); // minutes east of UTC, on that date (summer time included)
  const sign = offset >= 0 ? "+" : "-";
  return `${date}T${pad(hh)}:${pad(mm)}:${pad(Math.floor(ss))}${sign}${pad(offset / 60)}:${pad(offset % 60)}`;
}

/** An ISO 8601 instant as a datetime-local value in this browser's zone (for a prefilled field). */
export function localValue(iso) {
  if (!iso) return "";
  const t = new Date(iso);
  return `${t.getFullYear()}-${pad(t.getMonth() + 1)}-${pad(t.getDate())}T${pad(t.getHours())}:${pad(t.getMinutes())}`;
}

const DATE_FMT = new Intl.DateTimeFormat(undefined, { dateStyle: "medium", timeStyle: "short" });
const SHORT_FMT = new Intl.DateTimeFormat(undefined, {
  month: "short",
  day: "numeric",
  hour: "2-digit",
  minute: "2-digit",
});

/** An instant for people: "Dec 8, 2026, 11:59 PM" in this browser's zone (`short`: without the year). */
export function when(iso, short = false) {
  if (!iso) return "–";
  const t = new Date(iso);
  return Number.isNaN(t.getTime()) ? iso : (short ? SHORT_FMT : DATE_FMT).format(t);
}

/** This browser's zone, as the deadline fields say it: "Europe/Paris, UTC+01:00". */
export function zoneName() {
  const zone = Intl.DateTimeFormat().resolvedOptions().timeZone || "local time";
  const offset = -new Date().getTimezoneOffset();
  return `${zone}, UTC${offset >= 0 ? "+" : "-"}${pad(offset / 60)}:${pad(offset % 60)}`;
}

/** A score without trailing zeros: 13, 6.5, "–". */
export function pts(x) {
  return typeof x === "number" ? num(Math.round(x * 1000) / 1000, 4) : "–";
}

// -- errors at their fields ------------------------------------------------------------------------

/** The server's errors ([{path, message}]) shown beside the fields: `fields` maps a path's first part
 * ("deadline", "spec", "feedback") to {input, list}; the others go to `general`. Clears the old ones. */
export function showFieldErrors(errors, fields, general) {
  for (const f of Object.values(fields)) {
    f.list.replaceChildren();
    f.input?.removeAttribute("aria-invalid");
  }
  general.replaceChildren();
  let first = null;
  for (const e of errors) {
    const key = (e.path || "").split(/[.[]/)[0];
    const f = fields[key];
    const item = h(
      "li",
      { dataset: { path: e.path || "" } },
      e.path ? h("span", { class: "where" }, e.path) : null,
      h("span", { class: "msg" }, e.message),
    );
    if (f) {
      f.list.append(item);
      f.input?.setAttribute("aria-invalid", "true");
      first ??= f.input;
    } else {
      general.append(item);
    }
  }
  return first;
}

/** A list of problems (for a field, or a form), announced when it changes. */
export function errorList(id, label) {
  return h("ul", { id, class: "grade-errors field-errors", "aria-label": label, "aria-live": "polite" });
}

/** A status line: `kind` busy | ok | error. */
export function say(el, kind, text) {
  el.dataset.kind = kind;
  el.textContent = text;
}

/** The text of a picked file, or null when none is picked. */
export async function fileText(input) {
  const f = input.files?.[0];
  return f ? f.text() : null;
}

/** A link to hand out (a student's, a TA's): its text wraps anywhere (a token is one long word) beside a Copy
 * button. `id` goes to the link's text; `label` names the button for screen readers. */
export function linkBox(url, { id, label = "Copy the link" } = {}) {
  const text = h("code", { class: "link-text", ...(id ? { id } : {}) }, url);
  const copy = h("button", { type: "button", class: "small copy", "aria-label": label }, "Copy");
  copy.addEventListener("click", () => {
    const done = () => (copy.textContent = "Copied");
    if (navigator.clipboard && window.isSecureContext) return navigator.clipboard.writeText(url).then(done, () => {});
    getSelection().selectAllChildren(text); // else the selection, as the workspace's share links do
    if (document.execCommand?.("copy")) done();
  });
  return h("span", { class: "course-link" }, text, copy);
}
