// web/js/course/similarity.js's panel without a browser (fetch and the drawing stood in for): the dashboard reads
// the last report when it opens; a report asked for before that read answered must not be undone by it (the old
// "no report yet" would enable the button again and stop following the report being computed).
import assert from "node:assert/strict";
import { test } from "node:test";

import { SimilarityPanel } from "../../web/js/course/similarity.js";

/** fetch stood in for: each call is kept until the test answers it, in any order. */
function heldFetch() {
  const calls = [];
  globalThis.fetch = (_url, init) =>
    new Promise((resolve) =>
      calls.push({
        method: init.method,
        answer: (body, status = 200) =>
          resolve({ ok: status < 300, status, statusText: "", text: async () => JSON.stringify(body) }),
      }),
    );
  return calls;
}

function panel() {
  const p = Object.create(SimilarityPanel.prototype); // no DOM: the fields load and ask use, stood in for
  p.aid = "a1";
  p.access = () => false;
  p.closed = false;
  p.polls = 0;
  p.button = { disabled: false };
  p.status = { dataset: {}, replaceChildren() {} };
  p.shown = [];
  p.show = (r) => p.shown.push(r.status);
  return p;
}

test("the dashboard's first read, answered after a report was asked for, does not undo it", async () => {
  const calls = heldFetch();
  const p = panel();
  const read = p.load(); // the dashboard opens...
  const ask = p.ask(); // ...and the report is asked for before the read answers
  assert.deepEqual(
    calls.map((c) => c.method),
    ["GET", "POST"],
  );
  calls[1].answer({ status: "computing", students: 3, started_at: "2026-12-07T17:00:00Z" }, 202);
  await ask;
  calls[0].answer({ status: "none" }); // the older read, answered last
  await read;
  assert.deepEqual(p.shown, ["computing"], "the older read's answer was shown over the report asked for");
});
