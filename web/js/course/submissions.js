// "Your submissions": each with its time, late mark, status, score, whether it costs an attempt and whether it
// is the one that counts, and its feedback. A submission not yet graded is followed live through its event
// stream (GET .../submissions/{sid}/events, api.js's `followEvents` with the page's token), so its row moves
// from queued to grading to graded (or invalid, failed) without a reload.
import { followEvents } from "../api.js";
import { h } from "../util.js";
import { localTime, pts } from "./brief.js";
import { showFeedback } from "./feedback.js";

const FINAL = new Set(["graded", "invalid", "failed"]);
const STATUS = {
  queued: "queued",
  grading: "grading",
  graded: "graded",
  invalid: "invalid",
  failed: "could not be graded",
};

/** Follow one submission until its grade is final: onView(view) for each `submission` event, onEnd() once
 * (at its end, or when the stream is given up: the list read again shows where it stands). A 404 (not this
 * token's: a replaced link) just stops. */
export function followSubmission(url, token, { onView, onEnd }) {
  return followEvents(url, {
    token,
    news: ["submission"],
    onEvent(event, data) {
      if (event === "submission") onView(data);
      else if (event === "end") onEnd?.();
    },
    onGiveUp: () => onEnd?.(),
    onMissing: () => {},
  });
}

export class SubmissionList {
  /** ctx: {aid, token, api, compareBox, onFinal(view)}: onFinal when a followed submission's grade is final. */
  constructor(list, attempts, status, ctx) {
    this.list = list;
    this.attempts = attempts;
    this.status = status;
    this.ctx = ctx;
    this.rows = new Map(); // id -> {li, view, detail, follow}
    this.open = new Set(); // the ids whose feedback is shown
  }

  /** A count of what happened here (a read of the list asked, a row's news from its stream), in order. */
  tick() {
    this.clock = (this.clock || 0) + 1;
    return this.clock;
  }

  async load() {
    // loads overlap (a submit's, a grade's event): only the latest asked is drawn, never an older answer after it
    const asked = (this.asked = (this.asked || 0) + 1);
    const at = this.tick();
    let data;
    try {
      data = await this.ctx.api.submissions();
    } catch (err) {
      if (asked === this.asked) this.status.textContent = `Could not read your submissions: ${err.message}.`;
      return;
    }
    if (asked !== this.asked) return;
    const subs = data.submissions || [];
    if (!this.rows.size && subs.length) this.open.add(subs[subs.length - 1].id); // the latest, opened
    this.render(subs, at);
  }

  /** The list as read (`at`: when it was asked, tick()). A row whose stream brought news after the list was asked
   * keeps that news: the list's older view would take it back (a row seen graded shown grading again, without
   * its score, until the stream's end read the list once more). */
  render(subs, at = Number.POSITIVE_INFINITY) {
    const seen = new Set();
    subs.forEach((view, i) => {
      seen.add(view.id);
      const row = this.rows.get(view.id);
      if (row && row.news > at) {
        row.n = i + 1;
        this.paint(row);
      } else this.update(view, i + 1);
    });
    for (const [id, row] of this.rows) {
      if (!seen.has(id)) {
        row.follow?.close();
        row.li.remove();
        this.rows.delete(id);
      }
    }
    // newest first
    const ordered = subs.map((s) => this.rows.get(s.id).li).reverse();
    this.list.replaceChildren(...ordered);
    if (!subs.length) this.status.textContent = "None yet: Check your scene, then Submit it.";
    else if (this.status.textContent.startsWith("None yet")) this.status.textContent = "";
    const used = subs.filter((s) => s.counts_as_attempt).length;
    this.attempts.textContent = subs.length
      ? `${subs.length} submitted, ${used} counting as ${used === 1 ? "an attempt" : "attempts"}`
      : "";
  }

  /** A new submission (the 202's answer): at the top, opened, followed. A load asked before it (the last
   * one's grade, ended) may answer after it without it, and would take its row away: the list is read again. */
  add(view) {
    const n = this.rows.size + 1;
    for (const id of this.open) {
      this.open.delete(id); // the new one is the one to read: the others fold
      const row = this.rows.get(id);
      if (row) this.paint(row);
    }
    this.open.add(view.id);
    this.update(view, n);
    this.list.prepend(this.rows.get(view.id).li);
    this.status.textContent = "";
    this.load();
  }

  update(view, n) {
    let row = this.rows.get(view.id);
    if (!row) {
      const detail = h("div", { class: "a-sub-detail", id: `a-sub-${view.id}` });
      const head = h("button", { type: "button", class: "a-sub-head", "aria-controls": detail.id });
      head.addEventListener("click", () => {
        if (this.open.has(view.id)) this.open.delete(view.id);
        else this.open.add(view.id);
        this.paint(row);
      });
      const li = h("li", { class: "a-sub", dataset: { id: view.id } }, head, detail);
      row = { li, head, detail, view, n };
      this.rows.set(view.id, row);
    }
    if (n) row.n = n;
    row.view = view;
    this.paint(row);
    if (!FINAL.has(view.status) && !row.follow) this.follow(row);
  }

  paint(row) {
    const v = row.view;
    const open = this.open.has(v.id);
    row.li.dataset.status = v.status;
    row.li.dataset.late = String(!!v.late);
    row.li.dataset.counts = String(!!v.counts);
    row.head.setAttribute("aria-expanded", String(open));
    const released = v.manual?.released && v.total !== null && v.total !== undefined; // the staff's part added
    const score = released
      ? h("span", { class: "a-sub-score" }, `${pts(v.total)} / ${pts(v.total_max)}`)
      : v.score !== null && v.score !== undefined
        ? h("span", { class: "a-sub-score" }, `${pts(v.score)} / ${pts(v.max_score)}`)
        : v.status === "graded"
          ? h(
              "span",
              { class: "a-sub-score muted" },
              this.ctx.scoreWhen === "never" ? "score not shown" : "score shown after the deadline",
            )
          : null;
    const parts = [
      h("span", { class: "a-sub-n" }, `#${row.n}`),
      h("span", { class: "a-sub-time" }, h("time", { datetime: v.accepted_at }, localTime(v.accepted_at))),
      h("span", { class: "muted" }, v.kind === "scene" ? "scene" : `${v.kind.toUpperCase()} image`),
      v.late ? h("span", { class: "badge a-late" }, "late") : null,
      v.tokens_spent
        ? h(
            "span",
            { class: "badge a-tokens" },
            `${v.tokens_spent} late ${v.tokens_spent === 1 ? "token" : "tokens"} spent: on time`,
          )
        : null,
      h("span", { class: `badge ${v.status} a-sub-status` }, STATUS[v.status] || v.status),
      score,
      v.counts ? h("span", { class: "badge a-counts", title: "the submission that is your grade" }, "★ counts") : null,
      h(
        "span",
        { class: "a-sub-attempt muted" },
        v.counts_as_attempt ? (FINAL.has(v.status) ? "an attempt" : "holds an attempt") : "no attempt used",
      ),
      h("span", { class: "a-sub-toggle", "aria-hidden": "true" }, open ? "▾" : "▸"),
    ];
    row.head.replaceChildren(...parts.filter(Boolean));
    row.detail.hidden = !open;
    // drawn again only when it changed (an open comparison stays); "counts" only where it changes what is drawn: the
    // regrade controls of the graded submission that is the grade (feedback.js)
    const key = JSON.stringify({ ...v, counts: v.status === "graded" && !!v.counts });
    if (open && row.drawn !== key) {
      row.drawn = key;
      showFeedback(row.detail, v, this.ctx);
    }
  }

  follow(row) {
    const id = row.view.id;
    row.follow = followSubmission(this.ctx.api.eventsUrl(id), this.ctx.token, {
      onView: (view) => this.news(id, view),
      onEnd: () => {
        const r = this.rows.get(id);
        if (r) r.follow = null;
        this.ctx.onFinal?.(this.rows.get(id)?.view);
      },
    });
  }

  /** A followed submission's news (its stream's `submission` event): drawn, and said when its status moved. */
  news(id, view) {
    const r = this.rows.get(id);
    if (!r) return;
    r.news = this.tick();
    const moved = view.status !== r.view.status;
    this.update(view);
    if (moved) this.announce(r);
  }

  /** Say (to a screen reader too: the status line is a live region) where a followed submission now is. */
  announce(row) {
    const v = row.view;
    const score = v.score !== null && v.score !== undefined ? `: ${pts(v.score)} / ${pts(v.max_score)}` : "";
    const what = {
      queued: "is queued",
      grading: "is being graded",
      graded: `is graded${score}`,
      invalid: "is invalid (no attempt used)",
      failed: "could not be graded (no attempt used)",
    }[v.status];
    this.status.textContent = `Submission #${row.n} ${what || v.status}.`;
  }

  close() {
    for (const row of this.rows.values()) row.follow?.close();
  }
}
