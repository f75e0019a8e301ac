// web/js/course/submissions.js's list without a browser (the API, the rows and the list element stood in for):
// a read of the list asked before a submission was accepted may answer after it, without it. CI saw the third of
// three quick submissions never listed: the first's grade, ended, had asked for the list; the second's row was
// added, then taken away by that older answer, and with it the row's stream that would have asked again.
import assert from "node:assert/strict";
import { test } from "node:test";

import { SubmissionList } from "../../web/js/course/submissions.js";

const ticks = async (n = 20) => {
  for (let i = 0; i < n; i++) await new Promise((r) => setTimeout(r, 0));
};

function list() {
  const asked = []; // each read of the list, answered by the test
  const l = Object.create(SubmissionList.prototype); // no DOM: the fields load, render and add use, stood in for
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
  l.update = function (view) {
    if (!this.rows.has(view.id)) this.rows.set(view.id, { li: { id: view.id, remove() {} }, view });
  };
  l.paint = () => {};
  return { l, asked, shown: () => l.list.items.map((li) => li.id) };
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
