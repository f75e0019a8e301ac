// The dashboard's "Similarity" panel (web/course.html, one assignment's dashboard; docs/assignments.md,
// "Similarity reports"): ask for a report of the class's latest submissions (POST .../similarity: 202, computed
// on the server), follow it while it computes (GET, every few seconds, only while computing), and list the
// flagged pairs: each a table of the two submissions' facts side by side (the shared ones first), under the
// sentence that a flag is for a person to look at. Nothing here accuses anyone; the words are the server's note.
import { request } from "../api.js";
import { h } from "../util.js";
import { AS, course, say, when } from "./instructor_util.js";

const POLL_MS = 2000; // asked again this often while a report computes
const POLL_LIMIT = 300; // at most this many times (10 minutes): then the button asks again

const similarity = {
  ask: (aid) => request("POST", `${course.url(aid)}/similarity`, undefined, AS),
  get: (aid) => request("GET", `${course.url(aid)}/similarity`, undefined, { ...AS, cache: "no-store" }),
};

const dist = (x) => (x === null || x === undefined ? "–" : Number(x).toFixed(3));

export class SimilarityPanel {
  constructor(aid, { access }) {
    this.aid = aid;
    this.access = access;
    this.timer = null;
    this.polls = 0;
    this.closed = false;
    this.button = h(
      "button",
      { type: "button", id: "similarity-ask", onclick: () => this.ask() },
      "Make a similarity report",
    );
    this.status = h("p", { id: "similarity-status", class: "message", role: "status", "aria-live": "polite" });
    this.summary = h("div", { id: "similarity-summary" });
    this.list = h("div", { id: "similarity-pairs" });
    this.root = h(
      "section",
      { class: "panel board-similarity", id: "similarity", "aria-labelledby": "h-similarity" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-similarity" }, "Similarity"),
        h("span", { class: "toolbar" }, this.button),
      ),
      h(
        "p",
        { class: "hint", id: "similarity-note" },
        "Compares each student's latest submission with everyone else's: scenes by what they contain beyond the starter scene (names, order and small nudges of numbers do not count), pictures by how they look. A pair is listed only when it is much closer than this class's usual. It is for a person to look at, with what they know of the students and the task: it is not a finding of misconduct.",
      ),
      this.status,
      this.summary,
      this.list,
    );
  }

  close() {
    this.closed = true;
    clearTimeout(this.timer);
  }

  /** Each read or ask, counted: only the latest asked is shown. The dashboard's first read ("no report yet"),
   * answered after a report was asked for, would enable the button again and stop following the report. */
  ticket() {
    const asked = (this.asked = (this.asked || 0) + 1);
    return () => asked === this.asked;
  }

  /** The last report, if there is one (the dashboard opens). */
  async load() {
    const latest = this.ticket();
    try {
      const r = await similarity.get(this.aid);
      if (latest()) this.show(r);
    } catch (err) {
      if (latest() && !this.access(err) && err.status)
        say(this.status, "error", `Could not read the similarity report: ${err.message}`);
    }
  }

  async ask() {
    const latest = this.ticket();
    this.button.disabled = true;
    say(this.status, "info", "Asking for a report…");
    try {
      const r = await similarity.ask(this.aid);
      if (!latest()) return;
      this.polls = 0;
      this.show({ ...r, pairs: null });
    } catch (err) {
      if (!latest()) return;
      this.button.disabled = false;
      if (!this.access(err)) say(this.status, "error", `Could not make a report: ${err.message}`);
    }
  }

  follow() {
    clearTimeout(this.timer);
    if (this.closed || this.polls++ >= POLL_LIMIT) {
      this.button.disabled = false;
      return;
    }
    this.timer = setTimeout(() => this.load(), POLL_MS);
  }

  show(r) {
    if (this.closed) return;
    this.button.disabled = r.status === "computing";
    if (r.status === "computing") {
      say(this.status, "info", `Comparing ${r.students} students' latest submissions (started ${when(r.started_at)})…`);
      this.follow();
      if (r.pairs === null) return;
    } else if (r.status === "none") {
      say(this.status, "info", "No report yet.");
    } else if (r.status === "failed") {
      say(this.status, "error", `The report failed: ${r.error}`);
    } else {
      const since = r.since ? ` ${r.since} submission(s) came since: make it again to include them.` : "";
      const flagged = r.pairs.length
        ? `${r.pairs.length} pair(s) much closer than usual.`
        : "No pair much closer than this class's usual.";
      say(this.status, r.pairs.length ? "warn" : "ok", `Report of ${when(r.computed_at)}: ${flagged}${since}`);
    }
    this.renderSummary(r);
    this.renderPairs(r.pairs || []);
  }

  renderSummary(r) {
    const groups = Object.entries(r.groups || {});
    if (!groups.length) {
      this.summary.replaceChildren();
      return;
    }
    const rows = groups.map(([kind, g]) =>
      h(
        "tr",
        {},
        h("th", { scope: "row" }, kind === "scene" ? "scenes" : "pictures"),
        h("td", {}, String(g.compared)),
        h("td", {}, dist(g.typical)),
        h("td", {}, g.threshold === null ? "too few to tell" : dist(g.threshold)),
        h("td", {}, String(g.candidates)),
      ),
    );
    const table = h(
      "table",
      { class: "grade-table similarity-groups" },
      h("caption", {}, "What is usual in this class (distance 0: the same; 1: nothing in common)"),
      h(
        "thead",
        {},
        h(
          "tr",
          {},
          ["Kind", "Compared", "Usual nearest distance", "Flagged at or below", "Candidate pairs"].map((t) =>
            h("th", { scope: "col" }, t),
          ),
        ),
      ),
      h("tbody", {}, rows),
    );
    const how = h(
      "details",
      {},
      h("summary", {}, "How a pair is flagged"),
      h("p", { class: "hint", id: "similarity-how" }, r.how || ""),
    );
    const skipped = r.skipped || [];
    const left = skipped.length
      ? [
          h(
            "details",
            {},
            h("summary", {}, `${skipped.length} not compared`),
            h(
              "ul",
              {},
              skipped.map((s) => h("li", {}, `${s.student}: ${s.why}`)),
            ),
          ),
        ]
      : [];
    this.summary.replaceChildren(h("div", { class: "grade-table-box" }, table), how, ...left);
  }

  renderPairs(pairs) {
    this.list.replaceChildren(
      ...pairs.map((p, i) => {
        const id = `similarity-pair-${i}`;
        const facts = h(
          "table",
          { class: "grade-table similarity-facts" },
          h(
            "caption",
            {},
            `${p.kind === "scene" ? "Their scenes' facts beyond the starter" : "Their pictures"}, side by side: shared first, then those that differ`,
          ),
          h(
            "thead",
            {},
            h(
              "tr",
              {},
              h("th", { scope: "col" }, "Fact"),
              h("th", { scope: "col" }, p.a),
              h("th", { scope: "col" }, p.b),
              h("th", { scope: "col" }, "Same after rounding"),
            ),
          ),
          h(
            "tbody",
            {},
            p.facts.map((f) =>
              h(
                "tr",
                { class: f.shared ? "shared" : "differs" },
                h("th", { scope: "row" }, h("code", {}, f.path)),
                h("td", {}, f.a ?? "—"),
                h("td", {}, f.b ?? "—"),
                h("td", {}, f.shared ? "yes" : "no"),
              ),
            ),
          ),
        );
        return h(
          "article",
          { class: "similarity-pair", "aria-labelledby": id },
          h(
            "h3",
            { id },
            `${p.a} and ${p.b}`,
            h("span", { class: "muted" }, ` · distance ${dist(p.score)}, the class's usual ${dist(p.typical)}`),
          ),
          h("div", { class: "grade-table-box" }, facts),
          p.facts_more ? h("p", { class: "hint" }, `and ${p.facts_more} more fact(s)`) : null,
        );
      }),
    );
  }
}
