// One assignment's dashboard (the course page at /course#<id>): the roster upload and the links to mail
// (shown this once), the roster against each student's state (GET .../dashboard: one answer for the whole
// class, asked again every few seconds while the page is shown, so it fills live while a class submits),
// the distribution of the scores, a student's detail (their history with feedback and pictures, an
// extension, a replaced link, the latest comparison of an own tracer's tree log: treecompare.js), the class's
// first differences in those logs (a bar chart), the versions with the form that publishes a new one (and
// regrades), and the exports. Pictures and files are fetched with the instructor's header and shown as blob: URLs.
import { downloadFile, showImage } from "../api.js";
import { TableSort } from "../sorttable.js";
import { $, download, h, s } from "../util.js";
import { AssignmentForm } from "./instructor_form.js";
import { SimilarityPanel } from "./similarity.js";
import { GradingPanel } from "./grading.js";
import { RegradePanel } from "./regrade.js";
import { StatsPanel } from "./stats.js";
import { extensionHistory, tokensPanel } from "./latetokens.js";
import {
  AS,
  course,
  errorList,
  linkBox,
  localValue,
  pts,
  say,
  showFieldErrors,
  when,
  zoned,
  zoneName,
} from "./instructor_util.js";

const TA_MAY = "As a TA you follow the class, grant extensions and regrade.";
const POLL_MS = 3000; // the roster is asked again this often while the page is shown
const BINS = 10; // the histogram's bars: tenths of the spec's points
const STATE_TEXT = {
  none: "not submitted",
  submitted: "submitted",
  graded: "graded",
  invalid: "invalid only",
  failed: "ungradable",
};
const FILTERS = [
  ["all", "everyone"],
  ["none", "not submitted"],
  ["waiting", "waiting to be graded"],
  ["graded", "graded"],
  ["late", "late"],
  ["invalid", "invalid only"],
  ["failed", "ungradable"],
  ["extended", "with an extension"],
  ["self", "self-declared names"],
  ["inactive", "inactive (left the LMS course)"],
];
const PICTURES = [
  ["render.png", "their render"],
  ["reference.png", "the reference"],
  ["error_map.png", "FLIP error map"],
  ["rejected.png", "pixels the z test rejected"],
];

/** CSV text of rows (RFC 4180: a field with a comma, a quote or a line break is quoted). */
function csvText(rows) {
  const field = (v) => {
    const t = v === null || v === undefined ? "" : String(v);
    return /[",\r\n]/.test(t) ? `"${t.replace(/"/g, '""')}"` : t;
  };
  return `${rows.map((r) => r.map(field).join(",")).join("\n")}\n`;
}

function matches(row, filter) {
  switch (filter) {
    case "all":
      return true;
    case "waiting":
      return row.pending > 0;
    case "late":
      return row.late;
    case "extended":
      return row.extended;
    case "self":
      return row.self_declared;
    case "inactive":
      return row.active === false;
    default:
      return row.state === filter;
  }
}

const COLUMNS = [
  // key, header, sort value (null: last whichever way), first direction
  ["student", "Student", (r) => r.index, 1],
  ["state", "Status", (r) => ["none", "submitted", "invalid", "failed", "graded"].indexOf(r.state), 1],
  ["score", "Score", (r) => r.points, -1],
  ["submissions", "Submissions", (r) => r.submissions, -1],
  ["deadline", "Deadline", (r) => r.deadline, 1],
  ["last", "Last submitted", (r) => r.last_at, -1],
];

export class Board {
  constructor(aid, root, { access, onRole = () => {} }) {
    this.aid = aid;
    this.root = root;
    this.access = access;
    this.onRole = onRole; // (role): the page's token field says whose token it is
    this.rows = new Map(); // student id -> {sig, tr}
    this.data = null; // the last dashboard answer
    this.sort = new TableSort("student");
    this.filter = "all";
    this.timer = null;
    this.closed = false;
    this.open_ = null; // the student whose detail is shown
  }

  close() {
    this.closed = true;
    clearTimeout(this.timer);
    this.similarity?.close();
    this.classStats?.close();
    this.grading?.close();
    this.regrade?.close();
  }

  /** Load the assignment and its class; `student`: their detail opened too (the address named them). */
  async open(student = null) {
    this.root.replaceChildren(h("p", { class: "hint", role: "status" }, "Loading the assignment…"));
    try {
      this.brief = await course.brief(this.aid);
    } catch (err) {
      if (this.closed) return;
      this.access(err);
      this.root.replaceChildren(
        h(
          "section",
          { class: "panel" },
          h("h2", {}, "No such assignment"),
          h("p", { class: "message", dataset: { kind: "error" } }, err.message),
          h("p", {}, h("a", { href: "#" }, "All assignments")),
        ),
      );
      return;
    }
    if (this.closed) return;
    this.access(null);
    if (this.brief.you?.role) this.onRole(this.brief.you.role);
    this.build();
    await this.refresh();
    if (student) await this.showStudent(student);
  }

  // -- building -----------------------------------------------------------------------------------

  build() {
    const b = this.brief;
    document.title = `${b.name}: dashboard`;
    $("#crumbs").replaceChildren(
      h("a", { href: "#" }, "All assignments"),
      h("span", { "aria-hidden": "true" }, " › "),
      h("span", { "aria-current": "page" }, b.name),
    );
    this.head = h("section", { class: "panel board-head", "aria-labelledby": "h-board" });
    this.status = h("p", { id: "board-status", role: "status", "aria-live": "polite" });
    this.renderHead();

    // the roster and its links
    this.rosterInput = h("input", {
      type: "file",
      id: "roster-file",
      accept: ".csv,text/csv",
      "aria-describedby": "roster-help roster-errors",
    });
    this.rosterInput.addEventListener("change", () => this.uploadRoster());
    this.rosterErrors = errorList("roster-errors", "Problems in the roster");
    this.rosterStatus = h("p", { id: "roster-status", role: "status", "aria-live": "polite" });
    this.linksBox = h("div", { id: "links-box", class: "links-box", hidden: true });
    // a TA may not change the roster or its links (the server refuses them after the form is sent): no forms, the reason
    const rosterForms = this.may("roster")
      ? [
          h(
            "label",
            { for: "roster-file", class: "grade-label" },
            "Upload the roster (CSV with the header id,name,email)",
          ),
          this.rosterInput,
          h(
            "p",
            { id: "roster-help", class: "hint" },
            "New students get a personal link with a secret token; students already on the roster keep theirs (their names and emails are updated). Download the links after the upload; they can be downloaded again at any time.",
          ),
          this.rosterErrors,
          this.rosterStatus,
          h(
            "div",
            { class: "links-again" },
            h(
              "button",
              { type: "button", id: "links-again", onclick: () => this.linksAgain() },
              "Download links again",
            ),
            h("button", { type: "button", id: "links-reissue", onclick: () => this.reissueAll() }, "Re-issue all…"),
          ),
          this.linksBox,
        ]
      : [
          h(
            "p",
            { class: "hint", id: "roster-ta" },
            `${TA_MAY} The roster and the students' links are the instructors': ask one of them to upload a roster or re-issue a link.`,
          ),
        ];
    const roster = h(
      "section",
      { class: "panel", "aria-labelledby": "h-roster" },
      h("div", { class: "panel-head" }, h("h2", { id: "h-roster" }, "Roster and links")),
      ...rosterForms,
    );

    // the distribution
    this.stats = h("dl", { class: "stats board-stats", id: "board-stats", "aria-label": "The class" });
    this.histo = h("div", { class: "histo", id: "histogram" });
    const dist = h(
      "section",
      { class: "panel", "aria-labelledby": "h-dist" },
      h("div", { class: "panel-head" }, h("h2", { id: "h-dist" }, "Scores")),
      this.stats,
      this.histo,
      h(
        "p",
        { class: "hint" },
        "Each student's counting score, in the spec's points (an image, out of fewer points, is scaled as the gradebook scales it). Mean and median over the graded students.",
      ),
    );

    // the roster against the states
    this.filterSelect = h(
      "select",
      { id: "roster-filter" },
      FILTERS.map(([v, t]) => h("option", { value: v }, t)),
    );
    this.filterSelect.addEventListener("change", () => {
      this.filter = this.filterSelect.value;
      this.renderTable();
    });
    this.search = h("input", {
      type: "search",
      id: "roster-search",
      placeholder: "id or name",
      "aria-label": "Find a student by id or name",
    });
    this.search.addEventListener("input", () => this.renderTable());
    this.count = h("span", { class: "muted", id: "roster-count", "aria-live": "polite" });
    this.tbody = h("tbody", { id: "roster-rows" });
    this.thead = h("thead", {});
    this.caption = h("caption", { class: "sr-only" });
    const table = h(
      "section",
      { class: "panel board-roster", "aria-labelledby": "h-class" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-class" }, "The class"),
        this.count,
        h("span", { class: "toolbar" }, h("label", { class: "inline" }, "Show ", this.filterSelect), this.search),
      ),
      h(
        "p",
        { class: "hint" },
        `Filled live while the class submits (asked every ${POLL_MS / 1000} s). Click a student (or focus the row and press Enter) for their submissions, an extension or a new link.`,
      ),
      h(
        "div",
        { class: "grade-table-box board-table-box" },
        h("table", { class: "grade-table board-table", id: "roster-table" }, this.caption, this.thead, this.tbody),
      ),
    );

    this.detail = h("section", {
      class: "panel grade-detail board-detail",
      id: "student-detail",
      "aria-labelledby": "h-student",
      hidden: true,
    });
    this.versions = h("section", { class: "panel board-versions", "aria-labelledby": "h-versions" });
    this.renderVersions();
    // own tracers: what the class's tree logs get wrong first (GET .../dashboard `tree_whats`)
    this.whats = h("div", { id: "whats" });
    const whats = h(
      "section",
      { class: "panel board-whats", "aria-labelledby": "h-whats" },
      h("div", { class: "panel-head" }, h("h2", { id: "h-whats" }, "Own tracers: first differences")),
      h(
        "p",
        { class: "hint" },
        "For each student's latest tree log, each tree's first difference from the reference's, by what differs (the most frequent first): what the class gets wrong most.",
      ),
      this.whats,
    );
    this.similarity = new SimilarityPanel(this.aid, { access: this.access }); // web/js/course/similarity.js
    this.similarity.load();
    this.classStats = new StatsPanel(this.aid, { access: this.access }); // web/js/course/stats.js
    this.classStats.load();
    // staff-graded items: the grading queue (web/js/course/grading.js), when the spec has manual items
    this.grading = this.brief.spec?.manual?.length
      ? new GradingPanel(this.aid, { access: this.access, may: (a) => this.may(a) })
      : null;
    this.grading?.load();
    this.regrade = new RegradePanel(this.aid, { access: this.access }); // web/js/course/regrade.js
    this.regrade.load();
    this.root.replaceChildren(
      this.head,
      h("div", { class: "board-top" }, roster, dist),
      table,
      this.detail,
      ...(this.grading ? [this.grading.root] : []),
      this.regrade.root,
      whats,
      this.classStats.root,
      this.similarity.root,
      this.versions,
    );
  }

  renderHead() {
    const b = this.brief;
    const ref = b.reference_grade;
    const refText = !ref ? "–" : ref.status === "graded" ? `${pts(ref.score)} / ${pts(ref.max_score)}` : ref.status;
    const exp = (name, file) =>
      h(
        "button",
        {
          type: "button",
          id: `export-${name}`,
          onclick: () =>
            downloadFile(`${course.url(this.aid)}/${file}`, file, AS).catch((e) =>
              say(this.status, "error", `Could not download ${file}: ${e.message}`),
            ),
        },
        file,
      );
    this.head.replaceChildren(
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-board" }, b.name),
        h("span", { class: "muted" }, `version ${b.version} · ${b.max_score} points`),
        h(
          "span",
          { class: "toolbar", role: "group", "aria-label": "Exports" },
          exp("grades", "grades.csv"),
          exp("gradebook", "gradebook.csv"),
        ),
      ),
      h(
        "dl",
        { class: "stats" },
        h("div", {}, h("dt", {}, "deadline"), h("dd", { id: "board-deadline" }, when(b.deadline))),
        b.late_until
          ? h(
              "div",
              {},
              h("dt", {}, "late until"),
              h("dd", {}, `${when(b.late_until)} (−${Math.round(b.late_penalty * 100)} %)`),
            )
          : null,
        h("div", {}, h("dt", {}, "attempts"), h("dd", {}, b.max_submissions ?? "no limit")),
        h("div", {}, h("dt", {}, "the grade is"), h("dd", {}, `the ${b.counts} graded`)),
        h(
          "div",
          {
            title: "the reference scene graded against its own spec: full marks says the spec and its reference agree",
          },
          h("dt", {}, "reference's grade"),
          h("dd", { id: "reference-grade" }, refText),
        ),
        b.join ? h("div", {}, h("dt", {}, "open: join at"), h("dd", {}, h("code", {}, b.join))) : null,
      ),
      h(
        "p",
        { class: "hint" },
        "grades.csv: one row per roster student (id, name, score, max_score, late, submissions). gradebook.csv: the same for an LMS import (Canvas's columns). Each graded submission's Gradescope results.json is in the student's history.",
      ),
      this.status,
    );
  }

  // -- following the class --------------------------------------------------------------------------

  async refresh() {
    clearTimeout(this.timer);
    if (this.closed) return;
    // refreshes overlap (the poll's, an extension's, "Send again"'s): only the latest asked is drawn. A poll asked
    // before an extension and answered after it would put the row back as it was (CI reads the row once it shows
    // the extension), and each would start a poll of its own.
    const asked = (this.asked = (this.asked || 0) + 1);
    const latest = () => asked === this.asked && !this.closed;
    try {
      const data = await course.board(this.aid);
      if (!latest()) return;
      const before = this.data;
      this.data = data;
      this.renderSummary();
      this.renderTable();
      this.classStats?.follow(data); // says when the class statistics are no longer the class's
      if (this.open_) {
        const was = before?.students.find((r) => r.id === this.open_);
        const now = data.students.find((r) => r.id === this.open_);
        if (now && JSON.stringify(was) !== JSON.stringify(now)) this.showStudent(this.open_, false);
      }
      if (this.brief.reference_grade?.status !== "graded") {
        const brief = await course.brief(this.aid).catch(() => this.brief); // the reference is still being graded
        if (!latest()) return;
        this.brief = brief;
        this.renderHead();
      }
    } catch (err) {
      if (!latest()) return;
      if (!this.access(err) && err.status) say(this.status, "error", `Could not read the class: ${err.message}`);
    } finally {
      if (latest()) this.timer = setTimeout(() => this.poll(), POLL_MS); // one poll: the latest refresh's
    }
  }

  poll() {
    if (document.hidden) {
      this.timer = setTimeout(() => this.poll(), POLL_MS);
      return;
    }
    this.refresh();
  }

  renderSummary() {
    const d = this.data;
    const m = d.summary;
    const stat = (key, label, value) =>
      h("div", { dataset: { stat: key } }, h("dt", {}, label), h("dd", {}, String(value)));
    this.stats.replaceChildren(
      stat("students", "students", m.students),
      stat("submitted", "submitted", m.submitted),
      stat("graded", "graded", m.graded),
      stat("waiting", "waiting", m.waiting),
      stat("not_submitted", "not submitted", m.not_submitted),
      stat("invalid", "invalid only", m.invalid),
      stat("late", "late", m.late),
      stat("mean", "mean", m.mean === null ? "–" : `${pts(m.mean)} / ${pts(d.max_points)}`),
      stat("median", "median", m.median === null ? "–" : `${pts(m.median)} / ${pts(d.max_points)}`),
      ...(d.lms?.grades
        ? [
            stat("lms_pending", "grades to send to the LMS", d.lms.grades.pending),
            stat("lms_sent", "grades sent to the LMS", d.lms.grades.sent),
          ]
        : []),
    );
    this.renderLms();
    this.renderHistogram();
    this.renderWhats();
  }

  /** The class's first differences by `what` (treecompare.js whatChart), drawn again only when they change. */
  async renderWhats() {
    const counts = this.data.tree_whats || {};
    const sig = JSON.stringify(counts);
    if (sig === this.whatsSig) return;
    this.whatsSig = sig;
    const { whatChart } = await import("./treecompare.js");
    this.whats.replaceChildren(whatChart(counts));
  }

  /** The course's LMS, when it has one: its roster's last reading, and why grades wait (the LMS's last answer). */
  renderLms() {
    const l = this.data.lms;
    let note = this.stats.parentElement.querySelector("#lms-note");
    if (!l) return note?.remove();
    if (!note) {
      note = h("p", { class: "hint", id: "lms-note", role: "status" });
      this.stats.after(note);
    }
    const synced = l.roster_synced_at
      ? `roster read from the LMS ${when(new Date(l.roster_synced_at * 1000).toISOString())}`
      : "roster not read from the LMS yet";
    const waiting = l.grades?.error
      ? ` Grades wait: the LMS answered "${l.grades.error}"; the next try: ${when(new Date(l.grades.next_try * 1000).toISOString())}.`
      : "";
    note.textContent = `In the LMS: ${l.contexts.join(", ")} (${synced}).${waiting}`;
    this.renderRefused(note, l.grades?.refused || []);
  }

  /** The grades the LMS refused for good (a 4xx: not tried again): who, the LMS's status and why, and "Send
   * again" (POST .../lms/send-again) once the LMS's side is fixed. */
  renderRefused(note, refused) {
    let box = this.stats.parentElement.querySelector("#lms-refused");
    if (!refused.length) return box?.remove();
    if (!box) {
      box = h("div", { id: "lms-refused", class: "lms-refused", role: "region", "aria-labelledby": "h-lms-refused" });
      note.after(box);
    }
    const sig = JSON.stringify(refused);
    if (box.dataset.sig === sig) return; // drawn already (the poll must not clear what "Send again" said)
    box.dataset.sig = sig;
    const status = h("span", { class: "muted", role: "status" });
    const again = h("button", { type: "button", id: "lms-send-again" }, "Send again");
    again.addEventListener("click", async () => {
      again.disabled = true;
      try {
        const r = await course.lmsSendAgain(this.aid);
        say(
          this.status,
          "ok",
          `${r.queued} refused grade${r.queued === 1 ? "" : "s"} queued to be sent to the LMS again.`,
        );
        await this.refresh();
      } catch (e) {
        say(status, "error", `Could not queue them again: ${e.message}`);
      } finally {
        again.disabled = false;
      }
    });
    box.replaceChildren(
      h("h3", { id: "h-lms-refused" }, `Grades the LMS refused (${refused.length}): not tried again`),
      h(
        "ul",
        {},
        ...refused.map((x) =>
          h(
            "li",
            { dataset: { score: x.id } },
            h("strong", {}, x.student),
            ` ${pts(x.score_given)} / ${pts(x.score_max)}: HTTP ${x.status}, ${x.error}`,
          ),
        ),
      ),
      h(
        "p",
        { class: "hint" },
        "Fix it in the LMS first (the gradebook column, the student's enrolment), then send them again.",
        " ",
        again,
        " ",
        status,
      ),
    );
  }

  /** The scores as a bar chart (SVG): tenths of the spec's points, the count over each bar, the mean and
   * the median marked. */
  renderHistogram() {
    const d = this.data;
    const max = d.max_points || 1;
    const counts = new Array(BINS).fill(0);
    const scores = d.students.map((r) => r.points).filter((x) => typeof x === "number");
    for (const x of scores) counts[Math.min(BINS - 1, Math.max(0, Math.floor((x / max) * BINS)))]++;
    const W = 360,
      H = 160,
      L = 22,
      B = 24,
      T = 40,
      R = 8; // T: room above the bars for the two marks' labels
    const top = Math.max(1, ...counts);
    const bw = (W - L - R) / BINS;
    const y = (n) => H - B - (n / top) * (H - B - T);
    const x = (p) => L + (p / max) * (W - L - R);
    const bars = counts.map((n, i) => {
      const lo = (i * max) / BINS,
        hi = ((i + 1) * max) / BINS;
      return s(
        "g",
        { class: "bar", dataset: { bin: i, count: n } },
        s(
          "title",
          {},
          `${n} student${n === 1 ? "" : "s"} with ${pts(lo)} to ${i === BINS - 1 ? pts(hi) : `under ${pts(hi)}`} points`,
        ),
        s("rect", { x: L + i * bw + 1, y: y(n), width: bw - 2, height: H - B - y(n) }),
        n
          ? s("text", { x: L + (i + 0.5) * bw, y: y(n) - 3, "text-anchor": "middle", class: "count" }, String(n))
          : null,
      );
    });
    const ticks = [0, max / 2, max].map((p) =>
      s(
        "text",
        { x: x(p), y: H - B + 15, "text-anchor": p === 0 ? "start" : p === max ? "end" : "middle", class: "tick" },
        pts(p),
      ),
    );
    const mark = (value, cls, label, row) => {
      if (value === null) return null;
      const right = x(value) > W / 2; // the label on the side with room for it
      // the labels in two rows above the tallest bar's count, so that neither covers it nor the other
      const text = s(
        "text",
        { x: x(value) + (right ? -3 : 3), y: 10 + row * 11, "text-anchor": right ? "end" : "start", class: "mark" },
        `${label} ${pts(value)}`,
      );
      return s("g", { class: cls }, s("line", { x1: x(value), x2: x(value), y1: 2 + row * 11, y2: H - B }), text);
    };
    const m = d.summary;
    const label = scores.length
      ? `The distribution of ${scores.length} graded scores out of ${pts(max)} points: ${counts.map((n, i) => `${n} in ${pts((i * max) / BINS)}–${pts(((i + 1) * max) / BINS)}`).join(", ")}; mean ${pts(m.mean)}, median ${pts(m.median)}.`
      : "No graded scores yet.";
    const svg = s(
      "svg",
      { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": label, class: "histo-svg", id: "histogram-svg" },
      s("line", { x1: L, x2: W - R, y1: H - B, y2: H - B, class: "axis" }),
      s("text", { x: 2, y: T + 4, class: "tick" }, String(top)),
      bars,
      ticks,
      mark(m.mean, "mean", "mean", 0),
      mark(m.median, "median", "median", 1),
    );
    this.histo.replaceChildren(
      scores.length
        ? svg
        : h("p", { class: "hint histo-empty" }, "No graded scores yet: the bars appear as the class is graded."),
    );
  }

  columns() {
    const redraw = () => this.renderTable();
    return h(
      "tr",
      {},
      COLUMNS.map(([key, label, , first]) =>
        this.sort.header(key, label, {
          first,
          num: ["score", "submissions"].includes(key),
          redraw,
          within: this.thead,
        }),
      ),
    );
  }

  /** The table, kept fast at 300 rows: a row is built again only when its student's data changed. */
  renderTable() {
    if (!this.data) return;
    this.thead.replaceChildren(this.columns());
    const all = this.data.students.map((r, index) => ({ ...r, index }));
    const q = this.search.value.trim().toLowerCase();
    const shown = all.filter(
      (r) => matches(r, this.filter) && (!q || r.id.toLowerCase().includes(q) || r.name.toLowerCase().includes(q)),
    );
    const col = COLUMNS.find((c) => c[0] === this.sort.key) || COLUMNS[0];
    const sorted = this.sort.sorted(shown, col[2], (a, b) => a.index - b.index);
    const ids = new Set(all.map((r) => r.id));
    for (const id of this.rows.keys()) if (!ids.has(id)) this.rows.delete(id);
    const trs = sorted.map((r) => {
      const { index, ...data } = r;
      const sig = JSON.stringify(data);
      let kept = this.rows.get(r.id);
      if (!kept || kept.sig !== sig) {
        kept = { sig, tr: this.row(data) };
        this.rows.set(r.id, kept);
      }
      if (this.open_ === r.id) kept.tr.setAttribute("aria-current", "true");
      else kept.tr.removeAttribute("aria-current");
      return kept.tr;
    });
    if (!all.length)
      trs.push(
        h(
          "tr",
          { class: "empty" },
          h(
            "td",
            { colspan: COLUMNS.length },
            this.may("roster")
              ? "No students yet: upload the roster."
              : "No students yet: an instructor uploads the roster.",
          ),
        ),
      );
    else if (!shown.length)
      trs.push(h("tr", { class: "empty" }, h("td", { colspan: COLUMNS.length }, "No student matches.")));
    this.tbody.replaceChildren(...trs);
    const filtered = shown.length !== all.length ? `${shown.length} of ${all.length}` : `${all.length}`;
    this.count.textContent = `${filtered} student${all.length === 1 ? "" : "s"}`;
    this.caption.textContent = `The class: ${filtered} students, by ${col[1].toLowerCase()}`;
  }

  row(r) {
    const state = h("span", { class: `badge state-${r.state}` }, STATE_TEXT[r.state] || r.state);
    const tr = h(
      "tr",
      {
        tabindex: 0,
        class: "student",
        dataset: { student: r.id, state: r.state, late: r.late, extended: r.extended, pending: r.pending },
        "aria-label": `${r.name} (${r.id})${r.active === false ? ", inactive" : ""}: ${STATE_TEXT[r.state]}${r.score !== null ? `, ${r.total != null ? `${pts(r.total)} of ${pts(r.total_max)}${r.released ? "" : " (manual part not released)"}` : `${pts(r.score)} of ${pts(r.max_score)}`}` : ""}; Enter shows the details`,
      },
      h(
        "th",
        { scope: "row" },
        h("span", { class: "sid" }, r.id),
        " ",
        h("span", { class: "sname" }, r.name),
        r.self_declared
          ? h(
              "span",
              { class: "badge self", title: "joined the open assignment by a name they typed" },
              "self-declared",
            )
          : null,
        r.active === false
          ? h(
              "span",
              {
                class: "badge inactive",
                title: "no longer in the LMS course: kept with their submissions and grades; cannot submit",
              },
              "inactive",
            )
          : null,
      ),
      h(
        "td",
        { class: "state" },
        state,
        r.pending && r.state === "graded"
          ? h("span", { class: "badge state-submitted" }, `${r.pending} waiting`)
          : null,
        r.late ? h("span", { class: "badge late" }, "late") : null,
      ),
      h(
        "td",
        { class: "num score" },
        r.score === null
          ? h("span", { class: "muted" }, "–")
          : r.total != null
            ? [
                h("strong", {}, pts(r.total)),
                ` / ${pts(r.total_max)}`,
                r.released
                  ? null
                  : h(
                      "span",
                      {
                        class: "badge not-released",
                        title:
                          "auto part plus the manual part graded so far; students see the auto part until the release",
                      },
                      "not released",
                    ),
              ]
            : [h("strong", {}, pts(r.score)), ` / ${pts(r.max_score)}`],
      ),
      h("td", { class: "num subs" }, String(r.submissions)),
      h(
        "td",
        { class: "deadline" },
        when(r.deadline, true),
        r.extended
          ? h("span", { class: "badge extended", title: "an extension: their own deadline" }, "extended")
          : null,
      ),
      h("td", { class: "last" }, r.last_at ? when(r.last_at, true) : h("span", { class: "muted" }, "–")),
    );
    tr.addEventListener("click", () => this.showStudent(r.id));
    tr.addEventListener("keydown", (e) => {
      if (e.target !== tr) return;
      if (e.key === "Enter" || e.key === " ") {
        e.preventDefault();
        this.showStudent(r.id);
      } else if (e.key === "ArrowDown" || e.key === "ArrowUp") {
        e.preventDefault();
        (e.key === "ArrowDown" ? tr.nextElementSibling : tr.previousElementSibling)?.focus();
      }
    });
    return tr;
  }

  // -- the roster and its links -------------------------------------------------------------------

  async uploadRoster() {
    const file = this.rosterInput.files?.[0];
    if (!file) return;
    this.rosterErrors.replaceChildren();
    this.rosterInput.removeAttribute("aria-invalid");
    say(this.rosterStatus, "busy", `Uploading ${file.name}…`);
    try {
      const { students } = await course.roster(this.aid, await file.text());
      const fresh = students.filter((st) => st.link);
      const kept = students.length - fresh.length;
      say(
        this.rosterStatus,
        "ok",
        `${students.length} students on ${file.name}: ${fresh.length} new${kept ? `, ${kept} already on the roster (they keep their links)` : ""}.`,
      );
      this.showLinks(fresh, `links-${file.name.replace(/\.csv$/i, "")}.csv`);
      this.refresh();
    } catch (err) {
      showFieldErrors(err.errors || [{ path: "", message: String(err.message || err) }], {}, this.rosterErrors);
      this.rosterInput.setAttribute("aria-invalid", "true");
      say(
        this.rosterStatus,
        "error",
        `The roster was refused: ${err.errors?.length || 1} problem${err.errors?.length > 1 ? "s" : ""} (nothing was changed).`,
      );
      this.rosterInput.focus();
    } finally {
      this.rosterInput.value = "";
    }
  }

  /** Every roster student's link again (GET /api/courses/{cid}/links: the tokens are derived, so these are the
   * links already sent, still working), as the CSV to mail out. */
  async linksAgain() {
    say(this.rosterStatus, "busy", "Asking for the links…");
    try {
      const cid = this.data?.course || (await course.board(this.aid)).course;
      const { students } = await course.links(cid, this.aid);
      say(
        this.rosterStatus,
        "ok",
        `${students.length} link${students.length === 1 ? "" : "s"}: the ones already sent (they keep working).`,
      );
      this.showLinks(students, "links-again.csv", "again");
      if (students.length) $("#links-download", this.linksBox).click();
    } catch (err) {
      say(this.rosterStatus, "error", `Could not get the links: ${err.message}`);
    }
  }

  /** A new link for every roster student, in one request (POST /api/courses/{cid}/links/renew): each old link
   * stops working (in every assignment of the course), so this asks first. Then the new links, as the CSV to mail
   * out. */
  async reissueAll() {
    const students = this.data?.students || [];
    if (!students.length) {
      say(this.rosterStatus, "error", "No students on the roster yet: upload it first.");
      return;
    }
    const n = students.length;
    if (
      !confirm(
        `Re-issue all ${n} links? Every student gets a new link, and the links sent before stop working at once (in every assignment of the course ${this.data.course}): mail the new ones out.`,
      )
    )
      return;
    say(this.rosterStatus, "busy", `Re-issuing ${n} links…`);
    try {
      const { students: fresh } = await course.renewLinks(this.data.course, this.aid);
      say(this.rosterStatus, "ok", `${fresh.length} new links: the old ones no longer work.`);
      this.showLinks(fresh, "links-reissued.csv", "reissued");
    } catch (err) {
      say(
        this.rosterStatus,
        "error",
        `Could not re-issue the links: ${err.message}. The links sent before still work.`,
      );
    }
  }

  /** Links as a CSV to mail out (id,name,email,link): the new students' after an upload, every student's again
   * (`why` "again"), or the re-issued ones ("reissued"). */
  showLinks(students, name, why = "new") {
    if (!students.length) {
      this.linksBox.hidden = true;
      return;
    }
    const text = csvText([
      ["id", "name", "email", "link"],
      ...students.map((st) => [st.id, st.name, st.email, st.link]),
    ]);
    const button = h(
      "button",
      {
        type: "button",
        class: "primary",
        id: "links-download",
        onclick: () => download(name, new Blob([text], { type: "text/csv" })),
      },
      `Download ${name} (${students.length} link${students.length > 1 ? "s" : ""})`,
    );
    const said = {
      new: [
        h("strong", {}, "Download the links now. "),
        "Each link carries its student's secret token: mail each student theirs. If this page is left, \u201cDownload links again\u201d gives the same links. A lost link can be replaced (in the student's detail), which ends the old one.",
      ],
      again: [h("strong", {}, "The same links as before. "), "They still work: nothing changed for the students."],
      reissued: [h("strong", {}, "New links: mail them out. "), "The links sent before no longer work."],
    }[why];
    this.linksBox.replaceChildren(
      h("p", { class: "message", dataset: { kind: why === "again" ? "info" : "warn" } }, ...said),
      button,
      h(
        "details",
        {},
        h("summary", {}, "The links"),
        h(
          "ul",
          { class: "links-list" },
          students.map((st) =>
            h("li", {}, h("strong", {}, st.id), ` ${st.name}: `, linkBox(st.link, { label: `Copy ${st.id}'s link` })),
          ),
        ),
      ),
    );
    this.linksBox.hidden = false;
    button.focus();
  }

  // -- a student's detail ---------------------------------------------------------------------------

  /** Open a student's detail (a click, the address, or a change in their row while it is open). */
  showStudent(sid, focus = true) {
    return this.renderStudent(sid, focus).catch((err) =>
      say(this.status, "error", `Could not show ${sid}: ${err.message}`),
    );
  }

  async renderStudent(sid, focus) {
    this.open_ = sid;
    // the same student's detail can be asked again before it answers (a refresh that saw their row change, a
    // grant of tokens): only the latest asked is drawn, never an older answer after it
    const asked = (this.studentAsked = (this.studentAsked || 0) + 1);
    window.history.replaceState(null, "", `#${this.aid}/${encodeURIComponent(sid)}`); // a link to this student's detail
    for (const { tr } of this.rows.values()) {
      if (tr.dataset.student === sid) tr.setAttribute("aria-current", "true");
      else tr.removeAttribute("aria-current");
    }
    let d;
    try {
      d = await course.student(this.aid, sid);
    } catch (err) {
      if (asked === this.studentAsked) say(this.status, "error", `Could not read ${sid}: ${err.message}`);
      return;
    }
    if (this.open_ !== sid || this.closed || asked !== this.studentAsked) return;
    const ext = h("input", {
      type: "datetime-local",
      id: "ext-deadline",
      value: localValue(d.deadline),
      "aria-describedby": "ext-help ext-errors",
    });
    const extErrors = errorList("ext-errors", "Problems with the extension");
    const extStatus = h("p", { id: "ext-status", role: "status", "aria-live": "polite" });
    const grant = async (deadline) => {
      extErrors.replaceChildren();
      try {
        const r = await course.extend(this.aid, sid, deadline, $("#ext-why", this.detail)?.value || "");
        say(
          extStatus,
          "ok",
          deadline
            ? `${sid}'s deadline is now ${when(r.deadline)}${r.late_until ? ` (late until ${when(r.late_until)})` : ""}.`
            : `${sid} is back to the assignment's deadline.`,
        );
        await this.refresh();
      } catch (err) {
        showFieldErrors(err.errors || [], { deadline: { input: ext, list: extErrors } }, extErrors);
        say(extStatus, "error", "The extension was refused.");
      }
    };
    const linkOut = h("div", { id: "new-link", class: "new-link", "aria-live": "polite" });
    const replaceLink = async () => {
      if (!confirm(`Replace ${sid}'s link? Their old link stops working at once.`)) return;
      try {
        const r = await course.newLink(this.aid, sid);
        linkOut.replaceChildren(
          h("p", { class: "hint" }, "The new link, shown this once (the old one no longer works):"),
          linkBox(r.link, { label: `Copy ${sid}'s new link` }),
        );
        linkOut.querySelector("button.copy").focus();
      } catch (err) {
        linkOut.replaceChildren(
          h("p", { class: "message", dataset: { kind: "error" } }, `Could not replace the link: ${err.message}`),
        );
      }
    };
    const history = [...d.history].reverse(); // newest first
    this.detail.replaceChildren(
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-student", tabindex: -1 }, `${d.name} (${d.id})`),
        h(
          "span",
          {},
          h("span", { class: `badge state-${d.state}` }, STATE_TEXT[d.state]),
          d.score !== null ? h("strong", {}, ` ${pts(d.score)} / ${pts(d.max_score)}`) : null,
          d.email ? h("span", { class: "muted" }, ` · ${d.email}`) : null,
          d.self_declared ? h("span", { class: "badge self" }, "self-declared") : null,
          d.active === false
            ? h("span", { class: "badge inactive" }, "inactive: left the LMS course, cannot submit")
            : null,
        ),
        h(
          "span",
          { class: "toolbar" },
          this.may("roster")
            ? h("button", { type: "button", id: "btn-new-link", onclick: replaceLink }, "Replace lost link…")
            : null,
          h("button", { type: "button", id: "student-close", onclick: () => this.closeStudent() }, "Close"),
        ),
      ),
      linkOut,
      h(
        "form",
        { class: "ext-form", id: "ext-form", "aria-label": `An extension for ${sid}` },
        h("label", { for: "ext-deadline" }, `Their deadline${d.extended ? " (extended)" : ""}`),
        ext,
        h("label", { for: "ext-why" }, "Why"),
        h("input", { type: "text", id: "ext-why", maxlength: "500", placeholder: "kept in the history" }),
        h("button", { type: "submit", id: "ext-grant" }, "Grant the extension"),
        d.extended
          ? h(
              "button",
              { type: "button", id: "ext-clear", onclick: () => grant(null) },
              "Back to the assignment's deadline",
            )
          : null,
        h(
          "p",
          { id: "ext-help", class: "hint" },
          `In this browser's zone (${zoneName()}). An extension moves their deadline and their late cut-off by as much.`,
        ),
        extErrors,
        extStatus,
      ),
      extensionHistory(d),
      d.tokens ? tokensPanel(d, () => this.showStudent(sid, false)) : null,
      h("h3", {}, `Submissions (${d.history.length})`),
      history.length
        ? h(
            "ol",
            { class: "history", id: "history", reversed: true },
            history.map((sub, i) => this.submission(sub, history.length - i)),
          )
        : h("p", { class: "hint" }, "Nothing submitted yet."),
    );
    $("#ext-form", this.detail).addEventListener("submit", (e) => {
      e.preventDefault();
      if (!ext.value)
        return showFieldErrors(
          [{ path: "deadline", message: "pick a date and a time" }],
          { deadline: { input: ext, list: extErrors } },
          extErrors,
        );
      grant(zoned(ext.value));
    });
    this.detail.hidden = false;
    this.detail.dataset.student = sid;
    if (focus) {
      this.detail.scrollIntoView({ behavior: "smooth", block: "start" });
      $("#h-student", this.detail).focus({ preventScroll: true });
    }
  }

  /** The ray trees of a clicked pixel of a submission's error map, the student's beside the reference's
   * (web/js/course/compare.js, loaded when first asked for). */
  async compareAt(box, sub, img, e) {
    const r = img.getBoundingClientRect();
    const x = Math.min(img.naturalWidth - 1, Math.floor(((e.clientX - r.left) / r.width) * img.naturalWidth));
    const y = Math.min(img.naturalHeight - 1, Math.floor(((e.clientY - r.top) / r.height) * img.naturalHeight));
    try {
      const { showCompare } = await import("./compare.js");
      await showCompare(box, { aid: this.aid, sid: sub.id, x, y, as: "instructor" });
    } catch (err) {
      box.replaceChildren(
        h(
          "p",
          { class: "message", dataset: { kind: "error" } },
          `Could not compare the ray trees at (${x}, ${y}): ${err.message}`,
        ),
      );
    }
  }

  /** An image submission's latest tree log comparison (GET .../trees), shown on demand as the student saw it,
   * in the instructor's words (treecompare.js). */
  treesButton(sub, n) {
    const box = h("div", { class: "tl-box", dataset: { sid: sub.id } });
    const button = h(
      "button",
      { type: "button", class: "small tl-open", "aria-expanded": "false", dataset: { sid: sub.id } },
      "Their tree log comparison",
    );
    let asked = 0; // closed (or closed and opened again) before the answer came: only the latest open is drawn
    button.addEventListener("click", async () => {
      const mine = ++asked;
      if (button.getAttribute("aria-expanded") === "true") {
        button.setAttribute("aria-expanded", "false");
        return box.replaceChildren();
      }
      button.setAttribute("aria-expanded", "true");
      box.replaceChildren(h("p", { class: "hint", role: "status" }, "Reading their latest comparison…"));
      try {
        const [answer, { showTreeAnswers }] = await Promise.all([
          course.trees(this.aid, sub.id),
          import("./treecompare.js"),
        ]);
        if (mine !== asked) return;
        box.replaceChildren(h("h4", {}, `Their tree log against the reference's (submission ${n})`));
        const view = h("div", {});
        box.append(view);
        const files = sub.files || {};
        showTreeAnswers(view, answer, {
          as: "instructor",
          images: { student: files["render.png"], reference: files["reference.png"] },
          auth: AS,
          probes: sub.feedback?.probes || [],
        });
      } catch (err) {
        if (mine !== asked) return;
        const none = err.status === 404;
        box.replaceChildren(
          h(
            "p",
            { class: none ? "hint" : "message", role: "status", dataset: { kind: none ? "" : "error" } },
            none
              ? "They have not sent a tree log for this submission yet."
              : `Could not read their comparison: ${err.message}`,
          ),
        );
      }
    });
    return h("div", { class: "tl-instructor" }, button, box);
  }

  closeStudent() {
    const sid = this.open_;
    this.open_ = null;
    window.history.replaceState(null, "", `#${this.aid}`);
    this.detail.hidden = true;
    delete this.detail.dataset.student;
    this.renderTable();
    if (sid) this.tbody.querySelector(`tr[data-student="${CSS.escape(sid)}"]`)?.focus();
  }

  submission(sub, n) {
    const fb = sub.feedback || {};
    const files = sub.files || {};
    const tests = (fb.tests || []).map((t) => {
      const ok = t.status === "passed";
      const multi = (t.output || "").includes("\n");
      return h(
        "li",
        { class: `grade-test ${ok ? "pass" : "fail"}`, dataset: { test: t.test, status: t.status || "" } },
        h(
          "div",
          { class: "grade-test-head" },
          h("span", { class: "pf", "aria-hidden": "true" }, ok ? "✓" : "✗"),
          h("strong", {}, t.name),
          h(
            "span",
            { class: "muted", title: "when the student sees it" },
            `shown ${t.shown === "after_deadline" ? "after the deadline" : t.shown}`,
          ),
          h("span", { class: "pts" }, `${pts(t.score)} / ${pts(t.max_score)}`),
        ),
        t.output
          ? multi
            ? h("pre", { class: "grade-output" }, t.output)
            : h("p", { class: "grade-output" }, t.output)
          : null,
      );
    });
    const problem = (e) => h("li", {}, h("code", {}, e.path || "(the submission)"), " ", e.message);
    const compare = h("div", { class: "compare-box", "aria-live": "polite" });
    const trees = sub.kind !== "scene" && sub.status === "graded" ? this.treesButton(sub, n) : null;
    const figs = PICTURES.filter(([name]) => files[name]).map(([name, alt]) => {
      const img = h("img", { alt: `${alt} (submission ${n})` });
      showImage(img, files[name], AS);
      const pick = name === "error_map.png" && sub.kind === "scene"; // a pixel of it: their ray tree beside the reference's
      if (pick) {
        img.classList.add("pick");
        img.title = "Click a pixel: their ray tree beside the reference's there";
        img.addEventListener("click", (e) => this.compareAt(compare, sub, img, e));
      }
      const said = name === "rejected.png" ? sub.feedback?.metrics?.captions?.rejected || alt : alt; // the grader's caption
      return h(
        "figure",
        { class: "grade-fig", dataset: { picture: name.replace(".png", "") } },
        h("div", { class: "fig-box" }, img),
        h("figcaption", {}, pick ? `${alt} (click a pixel to compare ray trees)` : said),
      );
    });
    const results =
      sub.status === "graded"
        ? h(
            "button",
            {
              type: "button",
              class: "small",
              dataset: { results: sub.id },
              onclick: () =>
                downloadFile(`${sub.url}/results.json`, `results-${sub.student}-${n}.json`, AS).catch((e) =>
                  say(this.status, "error", e.message),
                ),
            },
            "results.json",
          )
        : null;
    return h(
      "li",
      { class: "history-item", dataset: { sid: sub.id, status: sub.status } },
      h(
        "div",
        { class: "history-head" },
        h("strong", {}, `#${n}`),
        h("span", {}, when(sub.accepted_at)),
        h(
          "span",
          { class: "muted" },
          `${sub.kind === "scene" ? "scene" : `image (${sub.kind.toUpperCase()})`} · version ${sub.version}`,
        ),
        h("span", { class: `badge ${sub.status}` }, sub.status),
        sub.late
          ? h("span", { class: "badge late" }, sub.penalty ? `late −${Math.round(sub.penalty * 100)} %` : "late")
          : null,
        sub.tokens_spent
          ? h(
              "span",
              { class: "badge tokens", dataset: { tokens: String(sub.tokens_spent) } },
              `${sub.tokens_spent} late ${sub.tokens_spent === 1 ? "token" : "tokens"} spent`,
            )
          : null,
        sub.counts ? h("span", { class: "badge counts", title: "this submission is the grade" }, "counts") : null,
        !sub.counts_as_attempt ? h("span", { class: "muted" }, "no attempt used") : null,
        h("span", { class: "pts" }, sub.score === null ? "" : `${pts(sub.score)} / ${pts(sub.max_score)}`),
        results,
      ),
      fb.errors?.length
        ? h(
            "div",
            { class: "message grade-problems", dataset: { kind: "error" } },
            h("strong", {}, `${fb.errors.length} error${fb.errors.length > 1 ? "s" : ""}:`),
            h("ul", {}, fb.errors.map(problem)),
          )
        : null,
      fb.warnings?.length
        ? h(
            "div",
            { class: "message grade-problems", dataset: { kind: "warn" } },
            h("strong", {}, "Warnings:"),
            h("ul", {}, fb.warnings.map(problem)),
          )
        : null,
      figs.length ? h("div", { class: "grade-figs" }, figs) : null,
      compare,
      trees,
      tests.length
        ? h("ol", { class: "grade-tests" }, tests)
        : sub.status === "queued" || sub.status === "grading"
          ? h("p", { class: "hint" }, `${sub.status === "queued" ? "Waiting to be graded" : "Being graded"}…`)
          : null,
    );
  }

  // -- versions and a new version -----------------------------------------------------------------

  renderVersions() {
    const b = this.brief;
    const form = new AssignmentForm({
      edit: b,
      onDone: async (a) => {
        this.brief = await course.brief(this.aid).catch(() => a);
        this.renderHead();
        this.renderVersions();
        say(this.status, "ok", `Version ${a.version} published.`);
        this.refresh();
      },
    });
    this.versions.replaceChildren(
      h("div", { class: "panel-head" }, h("h2", { id: "h-versions" }, "Versions")),
      h(
        "ol",
        { class: "versions", id: "versions" },
        (b.versions || []).map((v) =>
          h(
            "li",
            { dataset: { version: v.version } },
            `version ${v.version}, published ${when(v.created_at)}`,
            v.version === b.version ? h("span", { class: "badge graded" }, "current") : null,
          ),
        ),
      ),
      this.may("publish")
        ? h(
            "details",
            { class: "edit-box", id: "edit-box" },
            h("summary", {}, "Edit: publish a new version (and regrade)"),
            h(
              "p",
              { class: "hint" },
              "Every earlier version is kept. New submissions are graded under the new version; with regrading, every earlier submission is graded again under it. The roster, extensions and submissions stay.",
            ),
            form.el,
          )
        : h(
            "p",
            { class: "hint", id: "edit-ta" },
            `${TA_MAY} Editing the assignment (a new version) is the instructors'.`,
          ),
    );
  }

  /** May the caller `action` ("publish", "roster", "extend", "regrade")? The brief says (a TA: follow, extend and
   * regrade only); a server that does not say lets everyone (it refuses what it refuses). */
  may(action) {
    return this.brief?.you?.may?.[action] ?? true;
  }
}
