// The dashboard's lists read again on a change (web/js/course/regrade.js's RegradePanel: its filter, an answer;
// web/js/course/audit.js's AuditPanel: Show, Older) without a browser (fetch and the drawing stood in for): two
// reads in flight may answer out of order, and the older answer must not be drawn over the newer one (another
// filter's list, or the list from before an answer, under the words of the latest).
import assert from "node:assert/strict";
import { test } from "node:test";

import { AuditPanel } from "../../web/js/course/audit.js";
import { RegradePanel } from "../../web/js/course/regrade.js";

/** fetch stood in for: each call is kept until the test answers it, in any order. */
function heldFetch() {
  const calls = [];
  globalThis.fetch = (url) =>
    new Promise((resolve) =>
      calls.push({
        url,
        answer: (body) => resolve({ ok: true, status: 200, statusText: "", text: async () => JSON.stringify(body) }),
      }),
    );
  return calls;
}

const status = () => ({ dataset: {}, textContent: "" });

test("regrade requests: the latest filter's list is shown, whatever order the reads answer in", async () => {
  const calls = heldFetch();
  const p = Object.create(RegradePanel.prototype); // no DOM: the fields load uses, stood in for
  p.aid = "a1";
  p.access = () => false;
  p.status = status();
  p.filter = { value: "" };
  p.shown = [];
  p.show = (reqs) => p.shown.push(reqs.map((r) => r.id));
  const all = p.load(); // all...
  p.filter.value = "open";
  const open = p.load(); // ...then the open ones
  calls[1].answer({ requests: [{ id: "r2" }] });
  await open;
  calls[0].answer({ requests: [{ id: "r1" }, { id: "r2" }] });
  await all;
  assert.deepEqual(p.shown, [["r2"]], "the older filter's list was drawn over the newer one");
});

test("audit trail: the latest Show is drawn, whatever order the reads answer in", async () => {
  const calls = heldFetch();
  const a = Object.create(AuditPanel.prototype); // no DOM: the fields load uses, stood in for
  a.access = () => false;
  a.status = status();
  a.cid = { value: "c1" };
  a.student = { value: "" };
  a.assignment = { value: "" };
  a.more = { hidden: true };
  a.next = null;
  a.row = (e) => e.id;
  a.body = {
    children: [],
    replaceChildren(...rows) {
      this.children = rows;
    },
    append(...rows) {
      this.children.push(...rows);
    },
  };
  const every = a.load(); // everyone's changes...
  a.student.value = "ann";
  const ann = a.load(); // ...then ann's, before the first answered
  calls[1].answer({ events: [{ id: "e2" }], next: null });
  await ann;
  calls[0].answer({ events: [{ id: "e1" }, { id: "e2" }, { id: "e3" }], next: null });
  await every;
  assert.deepEqual(a.body.children, ["e2"], "the older read's rows were drawn over the newer one's");
  assert.equal(a.status.textContent, "1 change shown.");
});
