// The dashboard's "Class statistics" panel (web/course.html, one assignment's dashboard; docs/assignments.md,
// "Class statistics"): GET .../stats once when the dashboard opens and again on "Refresh" (the status says when
// the dashboard's class has changed since: nothing is redrawn under a reader), drawn as three
// figures (the score distribution, each test's pass rate, attempts per student), each an SVG with role="img"
// and a sentence for a screen reader, its caption, and its numbers as a table under "The numbers"; the time
// from a student's first submission to full marks per student in a table, the class's median in the summary;
// stats.csv downloaded with the staff's header. Each student's counting submission is the server's (the
// dashboard's and the grades' rule): nothing is decided here.
import { downloadFile, request } from "../api.js";
import { h, s } from "../util.js";
import { AS, course, pts, say, when } from "./instructor_util.js";

const KIND = { validity: "validity", requirement: "requirement", image: "image test" };

const classStats = {
  get: (aid) => request("GET", `${course.url(aid)}/stats`, undefined, { ...AS, cache: "no-store" }),
};

const percent = (r) => (r === null || r === undefined ? "–" : `${Math.round(r * 100)}%`);
const plural = (n, one, many = `${one}s`) => `${n} ${n === 1 ? one : many}`;

/** Seconds as a person says them: 0 min, 45 min, 5 h 10 min, 2 d 3 h. */
export function duration(sec) {
  if (sec === null || sec === undefined) return "–";
  const m = Math.round(sec / 60);
  if (m < 60) return `${m} min`;
  const hrs = Math.floor(m / 60);
  if (hrs < 48) return m % 60 ? `${hrs} h ${m % 60} min` : `${hrs} h`;
  const d = Math.floor(hrs / 24);
  return hrs % 24 ? `${d} d ${hrs % 24} h` : `${d} d`;
}

function numbers(caption, head, rows) {
  return h(
    "details",
    { class: "stats-numbers" },
    h("summary", {}, "The numbers"),
    h(
      "div",
      { class: "grade-table-box", tabindex: "0", role: "region", "aria-label": caption }, // it may scroll: keys reach it
      h(
        "table",
        { class: "grade-table" },
        h("caption", {}, caption),
        h(
          "thead",
          {},
          h(
            "tr",
            {},
            head.map((t) => h("th", { scope: "col" }, t)),
          ),
        ),
        h(
          "tbody",
          {},
          rows.map(([first, ...rest]) =>
            h(
              "tr",
              {},
              h("th", { scope: "row" }, first),
              rest.map((c) => h("td", {}, c)),
            ),
          ),
        ),
      ),
    ),
  );
}

function figure(id, caption, svg, table) {
  return h("figure", { class: "stats-figure", id }, h("figcaption", {}, caption), svg, table);
}

/** Vertical bars: `bars` [{label, n, title}], the count over each; under them each `tickEvery`-th bar's label,
 * or (`edges`: [[share of the axis, text]]) labels at those places of the axis (a histogram's bin edges). */
function columns(id, label, bars, { tickEvery = 1, edges = null } = {}) {
  const W = 360,
    H = 150,
    L = 22,
    B = 22,
    T = 14,
    R = 6;
  const top = Math.max(1, ...bars.map((b) => b.n));
  const bw = (W - L - R) / Math.max(1, bars.length);
  const y = (n) => H - B - (n / top) * (H - B - T);
  return s(
    "svg",
    { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": label, class: "stats-svg", id },
    s("line", { x1: L, x2: W - R, y1: H - B, y2: H - B, class: "axis" }),
    s("text", { x: 2, y: T + 4, class: "tick" }, String(top)),
    bars.map((b, i) =>
      s(
        "g",
        { class: "bar", dataset: { count: b.n } },
        s("title", {}, b.title),
        s("rect", { x: L + i * bw + 1, y: y(b.n), width: Math.max(1, bw - 2), height: H - B - y(b.n) }),
        b.n
          ? s("text", { x: L + (i + 0.5) * bw, y: y(b.n) - 3, "text-anchor": "middle", class: "count" }, String(b.n))
          : null,
        !edges && (i % tickEvery === 0 || i === bars.length - 1)
          ? s("text", { x: L + (i + 0.5) * bw, y: H - B + 14, "text-anchor": "middle", class: "tick" }, b.label)
          : null,
      ),
    ),
    (edges || []).map(([at, text]) =>
      s(
        "text",
        {
          x: L + at * (W - L - R),
          y: H - B + 14,
          "text-anchor": at === 0 ? "start" : at === 1 ? "end" : "middle",
          class: "tick",
        },
        text,
      ),
    ),
  );
}

/** What the statistics depend on, the same from the dashboard's rows and the statistics' per_student. */
const sig = (rows) => JSON.stringify(rows.map((r) => [r.id, r.state, r.submissions, r.points]));

export class StatsPanel {
  constructor(aid, { access }) {
    this.aid = aid;
    this.access = access;
    this.closed = false;
    this.refreshButton = h("button", { type: "button", id: "stats-refresh", onclick: () => this.load() }, "Refresh");
    this.csvButton = h(
      "button",
      {
        type: "button",
        id: "export-stats",
        onclick: () =>
          downloadFile(`${course.url(this.aid)}/stats.csv`, "stats.csv", AS).catch((e) =>
            say(this.status, "error", `Could not download stats.csv: ${e.message}`),
          ),
      },
      "stats.csv",
    );
    this.status = h("p", { id: "stats-status", class: "message", role: "status", "aria-live": "polite" });
    this.summary = h("dl", { class: "stats", id: "stats-summary", "aria-label": "The class's statistics" });
    this.figures = h("div", { class: "stats-figures", id: "stats-figures" });
    this.people = h("div", { id: "stats-students" });
    this.root = h(
      "section",
      { class: "panel board-class-stats", id: "class-stats", "aria-labelledby": "h-class-stats" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-class-stats" }, "Class statistics"),
        h("span", { class: "toolbar", role: "group", "aria-label": "Statistics" }, this.refreshButton, this.csvButton),
      ),
      h(
        "p",
        { class: "hint" },
        "Over each student's counting submission (the one that is their grade, as in grades.csv): the scores, each test's pass rate and the requirement failed most; over all their submissions: attempts (an invalid or ungradable submission costs none) and the time from a student's first submission to full marks (every test passed, a late penalty aside). Refresh to count what came since.",
      ),
      this.status,
      this.summary,
      this.figures,
      this.people,
    );
  }

  close() {
    this.closed = true;
  }

  /** The dashboard's latest answer (every few seconds): when its class is no longer the one counted (a new
   * submission, a grade), the status says so once, and Refresh counts again; nothing is redrawn under the reader. */
  follow(board) {
    if (!this.counted || this.stale) return;
    if (sig(board.students) !== this.counted) {
      this.stale = true;
      say(this.status, "info", `${this.status.textContent} The class has changed since: Refresh to count it again.`);
    }
  }

  async load() {
    this.refreshButton.disabled = true;
    try {
      const d = await classStats.get(this.aid);
      if (!this.closed) this.show(d);
    } catch (err) {
      if (!this.access(err)) say(this.status, "error", `Could not read the statistics: ${err.message}`);
    } finally {
      this.refreshButton.disabled = false;
    }
  }

  show(d) {
    this.counted = sig(d.per_student);
    this.stale = false;
    say(this.status, "info", `${plural(d.graded, "graded student")} of ${d.students}, counted ${when(d.now)}.`);
    const worst = d.fails_most.length
      ? d.fails_most.map((t) => `${t.name} (${t.failed} of ${t.graded} fail it)`).join("; ")
      : "none";
    const fm = d.full_marks;
    const items = [
      ["Mean", pts(d.histogram.mean)],
      ["Median", pts(d.histogram.median)],
      ["Attempts (median, most)", `${pts(d.attempts.median)}, ${d.attempts.max}`],
      ["Full marks", `${fm.students} of ${fm.submitted} who submitted`],
      ["Median time to full marks", duration(fm.median_seconds)],
      ["Requirement failed most", worst],
    ];
    this.summary.replaceChildren(
      ...items.map(([k, v]) => h("div", {}, h("dt", {}, k), h("dd", { dataset: { stat: k } }, v))),
    );
    this.figures.replaceChildren(this.histogram(d), this.passRates(d), this.attempts(d));
    this.renderStudents(d);
  }

  histogram(d) {
    const bins = d.histogram.bins;
    const last = bins.length - 1;
    const range = (b, i) => `${pts(b.from)} to ${i === last ? pts(b.to) : `under ${pts(b.to)}`}`;
    const label = d.graded
      ? `Score distribution of ${d.graded} graded students out of ${pts(d.max_points)} points: ${bins.map((b, i) => `${b.count} with ${range(b, i)}`).join(", ")}; mean ${pts(d.histogram.mean)}, median ${pts(d.histogram.median)}.`
      : "Score distribution: no graded scores yet.";
    const svg = columns(
      "stats-histogram-svg",
      label,
      bins.map((b, i) => ({
        label: pts(b.from),
        n: b.count,
        title: `${plural(b.count, "student")} with ${range(b, i)} points`,
      })),
      {
        edges: [
          [0, "0"],
          [0.5, pts(d.max_points / 2)],
          [1, pts(d.max_points)],
        ],
      },
    );
    const table = numbers(
      "Students by score (the counting submission's points)",
      ["Points", "Students"],
      bins.map((b, i) => [range(b, i), String(b.count)]),
    );
    return figure(
      "stats-histogram",
      `Score distribution (${pts(d.max_points)} points; mean ${pts(d.histogram.mean)}, median ${pts(d.histogram.median)})`,
      svg,
      table,
    );
  }

  passRates(d) {
    const tests = d.tests;
    const worst = new Set(d.fails_most.map((t) => t.test));
    const W = 360,
      row = 22,
      L = 150,
      R = 70,
      T = 4;
    const H = T * 2 + row * Math.max(1, tests.length);
    const cut = (t) => (t.length > 24 ? `${t.slice(0, 23)}…` : t);
    const label = tests.length
      ? `Pass rates of the counting submissions: ${tests.map((t) => `${t.name} (${KIND[t.kind] || t.kind}) ${t.passed} of ${t.graded}${t.graded ? `, ${percent(t.rate)}` : ""}${worst.has(t.test) ? ", failed most" : ""}`).join("; ")}.`
      : "Pass rates: no tests.";
    const svg = s(
      "svg",
      {
        viewBox: `0 0 ${W} ${H}`,
        role: "img",
        "aria-label": label,
        class: "stats-svg rates-svg",
        id: "stats-rates-svg",
      },
      tests.map((t, i) => {
        const y = T + i * row;
        const w = (t.rate || 0) * (W - L - R);
        return s(
          "g",
          { class: `rate${worst.has(t.test) ? " worst" : ""}`, dataset: { test: t.test, rate: t.rate ?? "" } },
          s("title", {}, `${t.name} (${KIND[t.kind] || t.kind}): ${t.passed} of ${t.graded} passed`),
          s("text", { x: L - 6, y: y + 15, "text-anchor": "end", class: "tick" }, cut(t.name)),
          s("rect", { x: L, y: y + 4, width: W - L - R, height: row - 8, class: "track" }),
          s("rect", { x: L, y: y + 4, width: w, height: row - 8, class: "fill" }),
          s("text", { x: W - R + 6, y: y + 15, class: "count" }, `${percent(t.rate)}${worst.has(t.test) ? " ▲" : ""}`),
        );
      }),
    );
    const table = numbers(
      "Each test: the counting submissions that passed it (every point of it)",
      ["Test", "Kind", "Passed", "Graded", "Rate"],
      tests.map((t) => [
        worst.has(t.test) ? `${t.name} (failed most)` : t.name,
        KIND[t.kind] || t.kind,
        String(t.passed),
        String(t.graded),
        percent(t.rate),
      ]),
    );
    return figure("stats-rates", "Pass rate of each test (▲: the requirement failed most)", svg, table);
  }

  attempts(d) {
    const a = d.attempts;
    const label = `Attempts per student: ${a.students.map((b) => `${plural(b.students, "student")} with ${b.attempts}`).join(", ")}; median ${pts(a.median)}, mean ${pts(a.mean)}.`;
    const every = Math.max(1, Math.ceil(a.students.length / 12));
    const svg = columns(
      "stats-attempts-svg",
      label,
      a.students.map((b) => ({
        label: String(b.attempts),
        n: b.students,
        title: `${plural(b.students, "student")} with ${plural(b.attempts, "attempt")}`,
      })),
      { tickEvery: every },
    );
    const table = numbers(
      "Students by their number of attempts",
      ["Attempts", "Students"],
      a.students.map((b) => [String(b.attempts), String(b.students)]),
    );
    return figure(
      "stats-attempts",
      `Attempts per student (median ${pts(a.median)}, mean ${pts(a.mean)}, most ${a.max})`,
      svg,
      table,
    );
  }

  renderStudents(d) {
    const rows = d.per_student.map((r) => [
      `${r.name} (${r.id})`,
      pts(r.points),
      String(r.attempts),
      String(r.submissions),
      when(r.first_at),
      r.full_marks_at ? when(r.full_marks_at) : "not yet",
      duration(r.to_full_marks),
    ]);
    const table = h(
      "table",
      { class: "grade-table", id: "stats-student-table" },
      h("caption", {}, "Each student: attempts and the time from their first submission to full marks"),
      h(
        "thead",
        {},
        h(
          "tr",
          {},
          ["Student", "Points", "Attempts", "Submissions", "First submitted", "Full marks", "Time to full marks"].map(
            (t) => h("th", { scope: "col" }, t),
          ),
        ),
      ),
      h(
        "tbody",
        {},
        rows.map(([first, ...rest]) =>
          h(
            "tr",
            {},
            h("th", { scope: "row" }, first),
            rest.map((c) => h("td", {}, c)),
          ),
        ),
      ),
    );
    this.people.replaceChildren(
      h(
        "details",
        { class: "stats-numbers" },
        h("summary", {}, `Each student (${d.per_student.length})`),
        h("div", { class: "grade-table-box", tabindex: "0", role: "region", "aria-label": "Each student" }, table),
      ),
    );
  }
}
