// The course page's "Audit trail" panel (web/course.html, the course's home at /course; docs/assignments.md, "The
// audit trail"): the course's changes, newest first (GET /api/courses/{cid}/audit): when, who, what, on what, before
// and after, why; filtered by a student's id and an assignment, a page at a time ("Older" asks for the page after
// the last event shown: `next`), and audit.csv downloaded with the staff's header with the same filters. A table
// with a caption and column headers; what it shows is said in a status line.
import { downloadFile, request } from "../api.js";
import { h } from "../util.js";
import { AS, say, when } from "./instructor_util.js";

const PAGE = 50; // events a page

const A = (cid) => `/api/courses/${encodeURIComponent(cid)}/audit`;
const query = (params) => {
  const q = new URLSearchParams(Object.entries(params).filter(([, v]) => v !== null && v !== undefined && v !== ""));
  return q.toString() ? `?${q}` : "";
};

const ACTIONS = {
  publish: "published",
  edit: "edited",
  regrade: "regraded",
  extension: "extension",
  "student.add": "student added",
  "student.change": "student changed",
  "student.enrol": "student enrolled",
  "student.join": "student joined",
  "student.remove": "student removed",
  "link.renew": "new link",
  "staff.add": "staff added",
  "staff.change": "staff changed",
  "staff.remove": "staff removed",
  "tokens.course": "late tokens of the course",
  "tokens.grant": "tokens granted",
  "tokens.spend": "tokens spent",
  "manual.grade": "manual grade",
  "manual.rescore": "manual grades re-scored",
  "manual.graders": "graders assigned",
  "manual.anonymous": "anonymous grading",
  "assignment.release": "manual grades released",
};

/** A value before or after a change, as short text: a dict's fields as "key: value", one a line. */
function shown(value) {
  if (value === null || value === undefined) return "–";
  if (typeof value !== "object") return String(value);
  return Object.entries(value)
    .map(([k, v]) => `${k}: ${v !== null && typeof v === "object" ? JSON.stringify(v) : v === null ? "none" : v}`)
    .join("\n");
}

function targetText(t, names) {
  const parts = [];
  if (t.assignment) parts.push(`assignment ${names.get(t.assignment) || t.assignment.slice(0, 8)}`);
  if (t.student) parts.push(`student ${t.student}`);
  if (t.submission) parts.push(`submission ${t.submission.slice(0, 8)}`);
  if (t.staff) parts.push(`staff ${t.staff}`);
  return parts.join(", ") || `course ${t.course}`;
}

export class AuditPanel {
  /** `courses`: [{id, name}] the token sees; `assignments`: [{id, name, course}] (the filter's choices). */
  constructor(courses, assignments, { access }) {
    this.access = access;
    this.assignments = assignments;
    this.names = new Map(assignments.map((a) => [a.id, a.name]));
    this.next = null;
    this.cid = h(
      "select",
      { id: "audit-course" },
      ...courses.map((c) => h("option", { value: c.id }, `${c.name} (${c.id})`)),
    );
    this.student = h("input", { id: "audit-student", maxlength: 80, autocomplete: "off", placeholder: "any" });
    this.assignment = h("select", { id: "audit-assignment" });
    this.status = h("p", { id: "audit-status", class: "message", role: "status", "aria-live": "polite" });
    this.body = h("tbody", {});
    this.more = h(
      "button",
      { type: "button", id: "audit-more", hidden: true, onclick: () => this.load(true) },
      "Older",
    );
    const form = h(
      "form",
      { class: "audit-filters", id: "audit-filters", "aria-label": "Filter the audit trail" },
      ...(courses.length > 1 ? [h("label", { for: "audit-course" }, "Course"), this.cid] : []),
      h("label", { for: "audit-student" }, "Student id"),
      this.student,
      h("label", { for: "audit-assignment" }, "Assignment"),
      this.assignment,
      h("button", { type: "submit", id: "audit-apply" }, "Show"),
      h("button", { type: "button", id: "audit-csv", onclick: () => this.csv() }, "audit.csv"),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.load(false);
    });
    this.cid.addEventListener("change", () => this.choices());
    const columns = ["When", "Who", "What", "On", "Before", "After", "Why"];
    this.root = h(
      "section",
      { class: "panel", id: "audit", "aria-labelledby": "h-audit" },
      h("div", { class: "panel-head" }, h("h2", { id: "h-audit" }, "Audit trail")),
      h(
        "p",
        { class: "hint" },
        "Every change to the course's grades, extensions, assignments, roster and staff: who made it, when, what it was before and after, and why. Newest first.",
      ),
      form,
      this.status,
      h(
        "div",
        { class: "audit-table-wrap" },
        h(
          "table",
          { class: "audit-table", id: "audit-table" },
          h("caption", { class: "hint" }, "The course's changes, newest first"),
          h("thead", {}, h("tr", {}, ...columns.map((c) => h("th", { scope: "col" }, c)))),
          this.body,
        ),
      ),
      this.more,
    );
    this.choices();
  }

  /** The assignment filter's choices: the chosen course's assignments. */
  choices() {
    const mine = this.assignments.filter((a) => !a.course || a.course === this.cid.value);
    this.assignment.replaceChildren(
      h("option", { value: "" }, "any"),
      ...mine.map((a) => h("option", { value: a.id }, a.name)),
    );
  }

  filters() {
    return { student: this.student.value.trim(), assignment: this.assignment.value };
  }

  /** The newest page (or, `older`, the page after the last one shown). */
  async load(older = false) {
    const params = { ...this.filters(), limit: PAGE, before: older ? this.next : null };
    say(this.status, "busy", "Reading the audit trail…");
    // reads overlap (Show pressed again, Older then Show): only the latest asked is drawn, never an older
    // filter's rows (or older rows appended) after it
    const asked = (this.asked = (this.asked || 0) + 1);
    try {
      const r = await request("GET", A(this.cid.value) + query(params), undefined, { ...AS, cache: "no-store" });
      if (asked !== this.asked) return;
      const rows = r.events.map((e) => this.row(e));
      if (older) this.body.append(...rows);
      else this.body.replaceChildren(...rows);
      this.next = r.next;
      this.more.hidden = r.next === null;
      const n = this.body.children.length;
      say(
        this.status,
        "ok",
        n
          ? `${n} change${n === 1 ? "" : "s"} shown${r.next === null ? "" : "; older ones with Older"}.`
          : "No changes match.",
      );
    } catch (err) {
      if (asked === this.asked && !this.access(err))
        say(this.status, "error", `Could not read the audit trail: ${err.message}`);
    }
  }

  row(e) {
    const cell = (label, text, cls) => h("td", { dataset: { label }, ...(cls ? { class: cls } : {}) }, text);
    return h(
      "tr",
      { dataset: { id: e.id, action: e.action } },
      cell("When", h("time", { datetime: e.at }, when(e.at))),
      cell("Who", e.who),
      cell("What", ACTIONS[e.action] || e.action),
      cell("On", targetText(e.target, this.names)),
      cell("Before", shown(e.before), "audit-value"),
      cell("After", shown(e.after), "audit-value"),
      cell("Why", e.why || "–"),
    );
  }

  csv() {
    downloadFile(`${A(this.cid.value)}.csv${query(this.filters())}`, "audit.csv", AS).catch((err) =>
      say(this.status, "error", `Could not download audit.csv: ${err.message}`),
    );
  }
}
