// A student's late tokens and their extensions' history, in the instructor's detail of one student (/course;
// server/course/tokens.py): tokens left in the course, each grant (who, when, before, after, why), a form to grant
// more (instructors and TAs), and every extension of this assignment with who granted it, when and why.
import { request } from "../api.js";
import { h } from "../util.js";
import { AS, errorList, say, showFieldErrors, when } from "./instructor_util.js";

const C = (cid) => `/api/courses/${encodeURIComponent(cid)}`;

export const tokens = {
  of: (cid, sid) =>
    request("GET", `${C(cid)}/students/${encodeURIComponent(sid)}/tokens`, undefined, { ...AS, cache: "no-store" }),
  grant: (cid, sid, add, why) =>
    request("POST", `${C(cid)}/students/${encodeURIComponent(sid)}/tokens`, { add, why }, AS),
};

const days = (n) => `${n} ${n === 1 ? "token" : "tokens"}`;

/** The tokens' part of a student's detail: `d` is GET /api/assignments/{aid}/students/{sid}; `refresh()` reads
 * the detail again after a grant. */
export function tokensPanel(d, refresh) {
  const t = d.tokens;
  const add = h("input", {
    type: "number",
    id: "tok-add",
    min: "1",
    max: "60",
    step: "1",
    value: "1",
    required: true,
    "aria-describedby": "tok-errors",
  });
  const why = h("input", { type: "text", id: "tok-why", maxlength: "500", placeholder: "e.g. a doctor's note" });
  const errors = errorList("tok-errors", "Problems with the grant");
  const status = h("p", { id: "tok-status", role: "status", "aria-live": "polite" });
  const form = h(
    "form",
    { class: "ext-form", id: "tok-form", "aria-label": `Late tokens for ${d.id}` },
    h("label", { for: "tok-add" }, "Grant tokens (days)"),
    add,
    h("label", { for: "tok-why" }, "Why"),
    why,
    h("button", { type: "submit", id: "tok-grant" }, "Grant"),
    errors,
    status,
  );
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    errors.replaceChildren();
    try {
      const r = await tokens.grant(d.course, d.id, Number(add.value), why.value);
      say(status, "ok", `${d.id} now has ${days(r.left)} left.`);
      await refresh();
    } catch (err) {
      showFieldErrors(
        err.errors || [{ path: "", message: err.message }],
        { add: { input: add, list: errors } },
        errors,
      );
      say(status, "error", "The grant was refused.");
    }
  });
  const grants = t.grants.length
    ? h(
        "ul",
        { id: "tok-grants", class: "history" },
        [...t.grants]
          .reverse()
          .map((g) =>
            h(
              "li",
              {},
              `${when(g.at)}: ${g.who} granted ${days(g.add)} (${g.before} → ${g.after})`,
              g.why ? ` — ${g.why}` : "",
            ),
          ),
      )
    : null;
  return h(
    "section",
    { class: "late-tokens", id: "late-tokens", "aria-labelledby": "h-tokens" },
    h("h3", { id: "h-tokens" }, "Late tokens"),
    h(
      "p",
      { id: "tok-left", dataset: { left: String(t.left) } },
      `${days(t.left)} left in the course: ${t.late_tokens} given, ${t.granted} granted, ${t.spent} spent. A late submission spends what it needs (whole days), if they have that many.`,
    ),
    grants,
    form,
  );
}

/** Every extension of this assignment for the student, newest first (who, when, from what to what, why). */
export function extensionHistory(d) {
  if (!d.extensions?.length) return null;
  const deadline = (iso) => (iso ? when(iso) : "the assignment's");
  return h(
    "div",
    { class: "ext-history" },
    h("h3", {}, "Extensions granted"),
    h(
      "ol",
      { id: "ext-history", class: "history", reversed: true },
      [...d.extensions]
        .reverse()
        .map((e) =>
          h(
            "li",
            {},
            `${when(e.at)}: ${e.who} moved their deadline from ${deadline(e.before)} to ${deadline(e.after)}`,
            e.why ? ` — ${e.why}` : "",
          ),
        ),
    ),
  );
}
