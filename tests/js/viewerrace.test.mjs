// web/js/viewer.js's job view without a browser (the API, the elements and the drawing stood in for): a pass's
// picture may answer after a later one (or after the end's), and a job's show() may resume after another job was
// shown meanwhile (a click in "my jobs" while the reload's restore was still loading the last job's picture).
// Neither older answer may take the screen: the last picture stays the end's, the stage the job clicked. And
// Ctrl+Enter in the editor, pressed while a submission is on its way, does not submit a second job.
import assert from "node:assert/strict";
import { test } from "node:test";

import { api } from "../../web/js/api.js";
import { Viewer } from "../../web/js/viewer.js";

const ticks = async (n = 20) => {
  for (let i = 0; i < n; i++) await new Promise((r) => setTimeout(r, 0));
};

/** fetch stood in for: each picture is kept until the test answers it, in any order. */
function heldFetch() {
  const calls = [];
  globalThis.fetch = (url) =>
    new Promise((resolve) =>
      calls.push({ url, answer: () => resolve({ ok: true, status: 200, blob: async () => `blob of ${url}` }) }),
    );
  return calls;
}

const element = () => ({ dataset: {}, hidden: false, textContent: "", removeAttribute() {}, replaceChildren() {} });

function viewer() {
  const v = Object.create(Viewer.prototype); // no DOM: the fields show and loadImage use, stood in for
  v.el = { stage: element(), share: element(), marker: element(), img: element(), title: element() };
  v.shown = []; // the pictures put on screen
  v.said = []; // what happened to the stage, in order
  v.setImageBlob = (data) => v.shown.push(data);
  v.message = () => {};
  v.closeEvents = () => {};
  v.update = (job) => v.said.push(`status ${job.id} ${job.status}`);
  v.updateAovButtons = () => {};
  v.drawMarker = () => {};
  v.renderList = () => {};
  v.clearImage = () => {};
  v.describe = () => {};
  v.follow = (id) => v.said.push(`follow ${id}`);
  globalThis.document = { querySelector: () => element() };
  return v;
}

test("a pass's picture answered after a later one is not shown over it", async () => {
  const calls = heldFetch();
  const v = viewer();
  v.view = { id: "j1", job: { id: "j1" } };
  v.aov = "image";
  const first = v.loadImage("/api/jobs/j1/image?pass=3");
  const last = v.loadImage("/api/jobs/j1/image"); // the end's picture
  await ticks();
  calls[1].answer();
  await last;
  calls[0].answer(); // the older pass, answered last
  await first;
  assert.deepEqual(v.shown, ["blob of /api/jobs/j1/image"], "an older pass's picture took the screen after the end's");
});

test("a job shown while the one before was still loading its picture keeps the stage", async () => {
  const calls = heldFetch();
  const v = viewer();
  const old = { id: "old", status: "cancelled", finished: true, image_url: "/api/jobs/old/image", progress: {} };
  const clicked = { id: "new", status: "running", finished: false, image_url: "/api/jobs/new/image", progress: {} };
  v.ended = function (job) {
    this.view.job = job;
    this.said.push(`ended ${job.id} on ${this.view.id}`);
  };
  const restore = v.show(old); // the reload's restore()...
  await ticks();
  const click = v.show(clicked); // ...and a click in "my jobs" before its picture came
  await ticks();
  calls[1].answer();
  await click;
  calls[0].answer();
  await restore;
  await ticks();
  assert.equal(v.view.id, "new");
  assert.equal(v.view.job.id, "new", "the older job's end was said over the one clicked");
  assert.deepEqual(v.said, ["status old cancelled", "status new running", "follow new"]);
  delete globalThis.document;
});

test("a second Render (Ctrl+Enter) while a submission is on its way sends no second job", async () => {
  const v = viewer();
  const sent = [];
  let accept;
  api.submit = (text) => {
    sent.push(text);
    return new Promise((r) => {
      accept = r;
    });
  };
  v.getScene = () => ({ text: '{"version": 1}', value: { version: 1 } });
  v.el.render = { disabled: false };
  v.near = () => {};
  v.reveal = () => {};
  v.remember = () => {};
  v.show = async () => {};
  const first = v.submit(); // the button...
  const second = v.submit(); // ...and Ctrl+Enter at once
  accept({ id: "j1", status: "queued" });
  await Promise.all([first, second]);
  assert.equal(sent.length, 1, "two jobs were submitted");
  assert.equal(v.el.render.disabled, false);
  delete globalThis.document;
});
