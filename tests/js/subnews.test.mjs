// web/js/course/submissions.js's list without a browser (the API, the rows and the list element stood in for): a
// followed submission's stream brings its news (grading, then graded) while a read of the list may be on its way.
// A read asked before the news and answered after it would take the row back (graded shown grading again, its
// score gone) until the stream's end read the list once more: a test that saw "graded" then read the row's head
// would read the older one.
import assert from "node:assert/strict";
import { test } from "node:test";

import { SubmissionList } from "../../web/js/course/submissions.js";

const ticks = async (n = 20) => {
  for (let i = 0; i < n; i++) await new Promise((r) => setTimeout(r, 0));
};

function list() {
  const asked = []; // each read of the list, answered by the test
  const l = Object.create(SubmissionList.prototype); // no DOM: the fields load, render and news use, stood in for
  const element = () => ({ dataset: {}, textContent: "", remove() {} });
  l.rows = new Map();
  l.open = new Set();
  l.ctx = { api: { submissions: () => new Promise((answer) => asked.push((subs) => answer({ submissions: subs }))) } };
  l.status = element();
  l.attempts = element();
  l.list = {
    items: [],
    replaceChildren(...li) {
      this.items = li;
    },
    prepend(li) {
      this.items.unshift(li);
    },
  };
  l.update = function (view, n) {
    const row = this.rows.get(view.id) || { li: { id: view.id, remove() {} } };
    if (n) row.n = n;
    row.view = view;
    this.rows.set(view.id, row);
  };
  l.paint = () => {};
  l.announce = () => {};
  return { l, asked, status: (id) => l.rows.get(id).view.status };
}

/** The submission's event stream stood in for (fetch): its `submission` events, then `end`. */
function stream(...views) {
  const text = [...views.map((v) => `event: submission\ndata: ${JSON.stringify(v)}\n\n`), "event: end\ndata: {}\n\n"];
  globalThis.fetch = async () => new Response(text.join(""), { status: 200 });
}

test("a read asked before a row's news, answered after it, does not take the row back", async () => {
  const { l, asked, status } = list();
  l.ctx.api.eventsUrl = (id) => `/api/assignments/a1/submissions/${id}/events`;
  l.add({ id: "b", status: "queued" }); // accepted: its row, and a read of the list asked
  stream({ id: "b", status: "grading" }, { id: "b", status: "graded", score: 13 });
  l.follow(l.rows.get("b")); // its stream: grading, then graded
  await ticks();
  assert.equal(status("b"), "graded");
  asked[0]([{ id: "b", status: "queued" }]); // the read asked at the submission, answered now
  await ticks();
  assert.equal(status("b"), "graded", "the older read took the row back");
  assert.equal(l.rows.get("b").n, 1);
  l.load(); // the stream's end: the list read again
  asked[1]([{ id: "b", status: "graded", score: 13, counts: true }]);
  await ticks();
  assert.equal(l.rows.get("b").view.counts, true, "a read asked after the news is drawn");
});
