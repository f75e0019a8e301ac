// Regrade requests (docs/assignments.md, "Regrade requests"; server/course/regrade.py).
// The student's side (`regradeControls`, called by feedback.js for the submission that counts): a "Request a
// regrade" button beside each test they can see and each released staff-graded item; it opens a form for the
// reason under the item (POST .../submissions/{sid}/regrade-requests), and their requests are listed below with
// the answer once given. The staff's side (`RegradePanel`, the dashboard's "Regrade requests" panel beside the
// grading queue): the queue (GET .../regrade-requests, open first), each request with the reason, the item's
// points now, its history, and a form to answer: a reply, new points (optional), Accept or Decline (PUT
// .../regrade-requests/{rid}); answered ones may be answered again. Plain buttons and labelled fields: keyboard
// usable as they are.
import { request } from "../api.js";
import { h } from "../util.js";
import { AS, say } from "./instructor_util.js";

const pts = (x) => (x === null || x === undefined ? "–" : String(Math.round(x * 1000) / 1000));
const STATUS = { open: "waiting for an answer", accepted: "accepted", declined: "declined" };
const A = (aid) => `/api/assignments/${encodeURIComponent(aid)}`;
let forms = 0; // ids of the forms on the page

/** The student's requests about submission `sub` (its feedback in `root`) and, when it is the one that counts, a
 * button beside each item they may ask about. Another submission's requests (it was the grade when they asked)
 * stay readable under it, without buttons; a submission with none shows nothing. ctx: {aid, token}. */
export function regradeControls(root, sub, ctx) {
  const asking = !!sub.counts;
  const url = `${A(ctx.aid)}/submissions/${encodeURIComponent(sub.id)}/regrade-requests`;
  const opts = { token: ctx.token, cache: "no-store" };
  const status = h("p", { class: "message a-regrade-status", role: "status", "aria-live": "polite" });
  const list = h("ul", { class: "a-regrade-list" });
  const deadline = h("p", { class: "hint a-regrade-deadline" });
  const section = h(
    "section",
    { class: "a-regrade", "aria-labelledby": `rg-h-${sub.id}` },
    h("h4", { id: `rg-h-${sub.id}` }, "Regrade requests"),
    asking ? deadline : h("p", { class: "hint" }, "This submission is no longer your grade: asked while it was."),
    list,
    status,
  );
  section.hidden = !asking; // until its requests are known: none, and it stays hidden
  let open = new Set(); // items with an open request

  const show = (data) => {
    const reqs = data.requests || [];
    if (!asking) section.hidden = !reqs.length;
    open = new Set(reqs.filter((r) => r.status === "open").map((r) => r.item));
    const closed = data.regrade_open === false; // the server's clock says
    deadline.textContent = data.regrade_deadline
      ? `${closed ? "Requests were taken until" : "You can ask until"} ${new Date(data.regrade_deadline).toLocaleString()}.`
      : "";
    list.replaceChildren(
      ...(reqs.length
        ? reqs.map((r) =>
            h(
              "li",
              { class: "a-regrade-req", dataset: { item: r.item, status: r.status } },
              h("strong", {}, r.item),
              " ",
              h(
                "span",
                { class: `badge ${r.status === "accepted" ? "passed" : r.status === "declined" ? "failed" : ""}` },
                STATUS[r.status] || r.status,
              ),
              h("p", { class: "a-regrade-reason" }, `You asked: ${r.reason}`),
              r.status !== "open" ? h("p", { class: "a-regrade-reply" }, `Answer: ${r.reply}`) : null,
              r.status !== "open" && r.points !== null
                ? h("p", { class: "hint" }, `Points now: ${pts(r.points)} / ${pts(r.max_points)}`)
                : null,
            ),
          )
        : [
            h(
              "li",
              { class: "hint" },
              closed
                ? "None: the regrade deadline has passed."
                : "None: a button beside each result asks for another look.",
            ),
          ]),
    );
    for (const b of root.querySelectorAll("button.a-regrade-ask")) {
      b.disabled = open.has(b.dataset.item) || closed;
      b.textContent = open.has(b.dataset.item) ? "Regrade requested" : "Request a regrade";
      b.hidden = closed && !open.has(b.dataset.item);
    }
  };
  let asked = 0; // the first read and a request's read may overlap: only the latest asked is shown
  const load = async () => {
    const mine = ++asked;
    try {
      const data = await request("GET", url, undefined, opts);
      if (mine === asked) show(data);
    } catch (err) {
      if (mine === asked) say(status, "error", `Could not read your regrade requests: ${err.message}`);
    }
  };

  const ask = (li, item, button) => {
    const existing = li.querySelector("form.a-regrade-form");
    if (existing) return existing.querySelector("textarea").focus();
    const id = `rg-form-${++forms}`;
    const reason = h("textarea", { id, name: "reason", rows: 3, maxlength: 2000, required: true });
    const send = h("button", { type: "submit" }, "Send the request");
    const cancel = h(
      "button",
      {
        type: "button",
        class: "secondary",
        onclick: () => {
          form.remove();
          button.focus();
        },
      },
      "Cancel",
    );
    const form = h(
      "form",
      { class: "a-regrade-form" },
      h("label", { for: id }, `Why should “${item}” be looked at again?`),
      reason,
      h("div", { class: "toolbar" }, send, cancel),
    );
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      send.disabled = true;
      try {
        await request("POST", url, { item, reason: reason.value }, opts);
        form.remove();
        say(status, "ok", `Sent: your request about “${item}” waits for the staff's answer.`);
        await load();
        button.focus();
      } catch (err) {
        say(status, "error", `Not sent: ${err.errors?.[0]?.message || err.message}`);
        send.disabled = false;
      }
    });
    li.append(form);
    reason.focus();
  };

  const items = [
    ...[...root.querySelectorAll("li.grade-test[data-test]")]
      .filter((li) => li.dataset.status !== "hidden")
      .map((li) => [li, li.dataset.test, li.querySelector("strong")?.textContent || li.dataset.test]),
    ...[...root.querySelectorAll("li.a-manual-item[data-item]")].map((li) => [li, li.dataset.item, li.dataset.item]),
  ];
  for (const [li, item, name] of asking ? items : []) {
    const button = h(
      "button",
      { type: "button", class: "small a-regrade-ask", dataset: { item }, "aria-label": `Request a regrade of ${name}` },
      "Request a regrade",
    );
    button.addEventListener("click", () => ask(li, item, button));
    li.querySelector(".grade-test-head")?.append(button);
  }
  load();
  return section;
}

/** The dashboard's "Regrade requests" panel of one assignment (its course's staff). */
export class RegradePanel {
  constructor(aid, { access }) {
    this.aid = aid;
    this.access = access;
    this.filter = h(
      "select",
      { id: "regrade-filter", onchange: () => this.load() },
      h("option", { value: "" }, "all (open first)"),
      h("option", { value: "open" }, "open"),
      h("option", { value: "accepted" }, "accepted"),
      h("option", { value: "declined" }, "declined"),
    );
    this.status = h("p", { id: "regrade-status", class: "message", role: "status", "aria-live": "polite" });
    this.count = h("p", { id: "regrade-count", class: "hint" }); // how many, after every load (an answer's words stay)
    this.list = h("ol", { id: "regrade-list", class: "regrade-list" });
    this.root = h(
      "section",
      { class: "panel board-regrade", id: "regrade", "aria-labelledby": "h-regrade" },
      h(
        "div",
        { class: "panel-head" },
        h("h2", { id: "h-regrade" }, "Regrade requests"),
        h("span", { class: "toolbar" }, h("label", { for: "regrade-filter" }, "Show "), this.filter),
      ),
      h(
        "p",
        { class: "hint" },
        "Students ask about one result of the submission that is their grade, until the regrade deadline. Accept with new points to change that item's points (the total, the exports and the LMS follow); decline to change nothing but the request. Each answer is kept.",
      ),
      this.count,
      this.status,
      this.list,
    );
  }

  close() {}

  async load() {
    const q = this.filter.value ? `?status=${encodeURIComponent(this.filter.value)}` : "";
    // reads overlap (the filter changed twice, an answer's read): only the latest asked is shown, never the list
    // of another filter, or of before the answer, after it
    const asked = (this.asked = (this.asked || 0) + 1);
    try {
      const data = await request("GET", `${A(this.aid)}/regrade-requests${q}`, undefined, { ...AS, cache: "no-store" });
      if (asked === this.asked) this.show(data.requests || []);
    } catch (err) {
      if (asked === this.asked && !this.access?.(err))
        say(this.status, "error", `Could not read the regrade requests: ${err.message}`);
    }
  }

  show(reqs) {
    const open = reqs.filter((r) => r.status === "open").length;
    const shown = this.filter.value ? ` ${this.filter.value}` : "";
    this.count.textContent = !reqs.length
      ? `No${shown} regrade requests.`
      : shown
        ? `${reqs.length}${shown}.`
        : `${open} open, ${reqs.length} in all.`;
    this.list.replaceChildren(...reqs.map((r, i) => this.item(r, i)));
  }

  item(r, i) {
    const id = `regrade-${i}`;
    const reply = h("textarea", { id: `${id}-reply`, rows: 2, maxlength: 4000 }, "");
    const points = h("input", {
      id: `${id}-points`,
      type: "number",
      min: 0,
      max: r.max_points ?? undefined,
      step: "any",
      inputmode: "decimal",
    });
    const answer = (status) => this.answer(r, status, reply, points);
    const history = r.history.map((e) =>
      h(
        "li",
        {},
        `${new Date(e.at).toLocaleString()} · ${e.who} · ${e.kind === "request" ? `asked: ${e.reason}` : `${e.status}${e.points !== undefined && e.points !== null ? ` (points ${pts(e.points_before)} → ${pts(e.points)})` : ""}: ${e.reply}`}`,
      ),
    );
    return h(
      "li",
      { class: "regrade-req", dataset: { id: r.id, status: r.status } },
      h(
        "h3",
        { id: `${id}-h` },
        `${r.label}: ${r.item}`,
        " ",
        h(
          "span",
          { class: `badge ${r.status === "accepted" ? "passed" : r.status === "declined" ? "failed" : ""}` },
          r.status,
        ),
      ),
      h("p", { class: "regrade-reason" }, `Reason: ${r.reason}`),
      h(
        "p",
        { class: "hint" },
        `${r.kind === "manual" ? "Staff-graded item" : "Test"}; points now ${pts(r.points)} / ${pts(r.max_points)}; asked ${new Date(r.asked_at).toLocaleString()}.`,
      ),
      r.reply ? h("p", { class: "regrade-reply" }, `Reply: ${r.reply}`) : null,
      h(
        "details",
        { class: "regrade-history" },
        h("summary", {}, `History (${r.history.length})`),
        h("ol", {}, history),
      ),
      h(
        "form",
        { class: "regrade-answer", "aria-labelledby": `${id}-h`, onsubmit: (e) => e.preventDefault() },
        h("label", { for: reply.id }, r.status === "open" ? "Reply to the student" : "Answer again: reply"),
        reply,
        h("label", { for: points.id }, `New points, when accepting (optional, 0 to ${pts(r.max_points)})`),
        points,
        h(
          "div",
          { class: "toolbar" },
          h("button", { type: "button", class: "regrade-accept", onclick: () => answer("accepted") }, "Accept"),
          h(
            "button",
            { type: "button", class: "secondary regrade-decline", onclick: () => answer("declined") },
            "Decline",
          ),
        ),
      ),
    );
  }

  async answer(r, status, reply, points) {
    const body = { status, reply: reply.value };
    if (status === "accepted" && points.value !== "") body.points = Number(points.value);
    try {
      await request("PUT", r.url, body, AS);
      say(this.status, "ok", `Answered: ${r.label}'s request about ${r.item} ${status}.`);
      await this.load();
      this.list.querySelector(`li[data-id='${r.id}'] h3`)?.setAttribute("tabindex", "-1");
      this.list.querySelector(`li[data-id='${r.id}'] h3`)?.focus();
    } catch (err) {
      if (!this.access?.(err))
        say(
          this.status,
          "error",
          `Not answered: ${err.errors?.[0]?.path ? `${err.errors[0].path}: ` : ""}${err.errors?.[0]?.message || err.message}`,
        );
    }
  }
}
