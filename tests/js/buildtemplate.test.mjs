// web/js/build.js's "New scene" menu without a browser (fetch, the editor and the menu stood in for): each
// template chosen is fetched (web/templates/), and two chosen in a row may answer out of order. The editor gets the
// one chosen last, not whichever answered last.
import assert from "node:assert/strict";
import { test } from "node:test";

import { BuildPanel } from "../../web/js/build.js";

test("two templates chosen in a row: the editor gets the one chosen last", async () => {
  const calls = [];
  globalThis.fetch = (url) =>
    new Promise((resolve) =>
      calls.push({
        answer: () =>
          resolve({ ok: true, status: 200, statusText: "", text: async () => JSON.stringify({ name: url }) }),
      }),
    );
  const b = Object.create(BuildPanel.prototype); // no DOM: the fields newScene uses, stood in for
  const loaded = [];
  b.onLoad = (text) => loaded.push(JSON.parse(text).name);
  b.say = () => {};
  b.notify = () => {};
  b.template = { value: "" };
  const first = b.newScene("cornell_box");
  const second = b.newScene("whitted");
  calls[1].answer();
  await second;
  calls[0].answer(); // the first chosen answers last
  await first;
  assert.deepEqual(loaded, ["templates/whitted.json"], "the template chosen first replaced the one chosen last");
});
