// web/js/course/submissions.js's list without a browser (the API, the rows and the list element stood in for):
// a read of the list asked before a submission was accepted may answer after it, without it. CI saw the third of
// three quick submissions never listed: the first's grade, ended, had asked for the list; the second's row was
// added, then taken away by that older answer, and with it the row's stream that would have asked again.
// The same for a followed submission's stream: its news (grading, then graded) may come while a read of the list
// is on its way; a read asked before the news and answered after it would take the row back (graded shown grading
// again, its score gone) until the stream's end read the list once more.
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
  return { l, asked, shown: () => l.list.items.map((li) => li.id), status: (id) => l.rows.get(id).view.status };
}

test("a read asked before a submission, answered after it, does not take its row away", async () => {
  const { l, asked, shown } = list();
  const a = { id: "a", status: "invalid" };
  const b = { id: "b", status: "queued" };
  l.load(); // the first's grade ended: the list is asked for...
  l.add(b); // ...and the second is accepted before it answers
  assert.deepEqual(shown(), ["b"]);
  asked[0]([a]); // the old answer, without the second
  await ticks();
  assert.deepEqual(shown(), ["b"], "the older answer took the new row away");
  assert.equal(asked.length, 2, "the list is read again after a submission");
  asked[1]([a, b]);
  await ticks();
  assert.deepEqual(shown(), ["b", "a"], "newest first");
});

test("the latest answer is drawn, whatever order they come in", async () => {
  const { l, asked, shown } = list();
  const a = { id: "a", status: "graded" };
  const b = { id: "b", status: "graded" };
  l.load();
  l.load();
  asked[1]([a, b]);
  asked[0]([a]);
  await ticks();
  assert.deepEqual(shown(), ["b", "a"]);
});

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
