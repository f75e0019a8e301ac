// web/js/grading.js's list of submissions without a browser (fetch and the table stood in for): files added are
// named by the server (POST /api/grade/students) before they join the list. Files added again before that
// answered (a drop, then a pick) were lost: each add put back the list as it was when it began.
import assert from "node:assert/strict";
import { test } from "node:test";

import { GradingPanel } from "../../web/js/grading.js";

/** fetch stood in for: each call is kept until the test answers it, in any order. */
function heldFetch() {
  const calls = [];
  globalThis.fetch = (_url, init) =>
    new Promise((resolve) => {
      const { files } = JSON.parse(init.body);
      calls.push({
        answer: () =>
          resolve({
            ok: true,
            status: 200,
            statusText: "",
            text: async () => JSON.stringify({ students: files.map((f) => f.replace(/\.[^.]+$/, "")) }),
          }),
      });
    });
  return calls;
}

const file = (name) => ({ name, size: 10 });

test("files added while the last ones are being named are all kept", async () => {
  const calls = heldFetch();
  const p = Object.create(GradingPanel.prototype); // no DOM: the fields addFiles uses, stood in for
  p.subs = [];
  p.setSubs = (subs) => {
    p.subs = subs;
  };
  p.showSubErrors = () => {};
  const dropped = p.addFiles([file("alice.json")]);
  const picked = p.addFiles([file("bob.json")]);
  calls[0].answer();
  await dropped;
  calls[1].answer();
  await picked;
  assert.deepEqual(
    p.subs.map((s) => s.student),
    ["alice", "bob"],
    "files added before the last ones were named were lost",
  );
});
