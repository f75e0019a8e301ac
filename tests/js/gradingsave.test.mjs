// web/js/course/grading.js's saves without a browser (fetch, the boxes and the status stood in for): a grader's
// choices are PUT one after another in the order they were made. Two at once could land out of order (an item's
// older state over its newer one), and the status would name whichever answered last (CI saw "Saved creativity,
// with a comment" after "Saved lighting": the comment's PUT had answered second).
import assert from "node:assert/strict";
import { test } from "node:test";

import { GradingPanel } from "../../web/js/course/grading.js";

/** fetch stood in for: each call is kept until the test answers it, in any order. */
function heldFetch() {
  const calls = [];
  globalThis.fetch = (url, init) =>
    new Promise((resolve) => {
      const body = JSON.parse(init.body);
      calls.push({
        url,
        body,
        answer: (points) =>
          resolve(new Response(JSON.stringify({ manual: { items: [{ points }, { points }] } }), { status: 200 })),
        refuse: (status, message) =>
          resolve(new Response(JSON.stringify({ errors: [{ path: "", message }] }), { status })),
      });
    });
  return calls;
}

const ticks = async (n = 20) => {
  for (let i = 0; i < n; i++) await new Promise((r) => setTimeout(r, 0));
};

function panel() {
  const p = Object.create(GradingPanel.prototype); // no DOM: the fields save() reads, stood in for
  p.aid = "a1";
  p.access = () => false;
  p.sub = { submission: "s1", manual: {} };
  p.status = { dataset: {}, textContent: "" };
  p.card = { querySelector: () => ({ textContent: "" }) };
  const item = (name) => ({
    item: { name, points: 3 },
    boxes: [{ checked: false, dataset: { level: "good" } }],
    comment: { value: "" },
    score: { textContent: "" },
  });
  p.items = [item("creativity"), item("lighting")];
  return p;
}

test("a save waits for the one before; each sends its item as it was when made", async () => {
  const calls = heldFetch();
  const p = panel();
  p.items[0].comment.value = "a story";
  const first = p.save(0); // the comment, left by Tab
  p.items[1].boxes[0].checked = true;
  const second = p.save(1); // then a level of the next item
  p.items[1].boxes[0].checked = false;
  const third = p.save(1); // and the same key again: off
  await ticks();
  assert.equal(calls.length, 1, "the second PUT went before the first answered");
  assert.match(calls[0].url, /\/manual\/creativity$/);
  assert.deepEqual(calls[0].body, { rubric: [], comment: "a story" });
  calls[0].answer(1);
  await first;
  assert.equal(p.status.textContent, "Saved creativity: 1 points, with a comment.");
  await ticks();
  assert.equal(calls.length, 2);
  assert.match(calls[1].url, /\/manual\/lighting$/);
  assert.deepEqual(calls[1].body, { rubric: ["good"], comment: "" });
  calls[1].answer(2);
  await second;
  await ticks();
  assert.deepEqual(calls[2].body, { rubric: [], comment: "" }); // the newest state, sent last
  calls[2].answer(0);
  await third;
  assert.equal(p.status.textContent, "Saved lighting: 0 points.");
});

test("a save made before moving on to the next submission is still sent; its answer leaves the new card alone", async () => {
  const calls = heldFetch();
  const p = panel();
  p.items[0].boxes[0].checked = true;
  const saved = p.save(0);
  p.sub = { submission: "s2", manual: {} }; // "n": the next submission's card
  p.status.textContent = "Grading Student 2.";
  await ticks();
  assert.equal(calls.length, 1);
  assert.match(calls[0].url, /\/submissions\/s1\/manual\/creativity$/);
  calls[0].answer(2);
  await saved;
  assert.equal(p.status.textContent, "Grading Student 2.");
});

test("a refused save says so and does not stop the ones after it", async () => {
  const calls = heldFetch();
  const p = panel();
  const first = p.save(0);
  const second = p.save(1);
  await ticks();
  assert.equal(calls.length, 1);
  calls[0].refuse(409, "the grades are released");
  await first;
  assert.equal(p.status.textContent, "Could not save creativity: the grades are released");
  await ticks();
  assert.equal(calls.length, 2);
  calls[1].answer(1);
  await second;
  assert.equal(p.status.textContent, "Saved lighting: 1 points.");
});

test("a save whose answer throws on the way does not stop the ones after it", async () => {
  const calls = heldFetch();
  const p = panel();
  p.access = () => {
    throw new Error("the page's own handler failed");
  };
  const first = p.save(0);
  const second = p.save(1);
  await ticks();
  calls[0].refuse(403, "not staff");
  await assert.rejects(first);
  await ticks();
  assert.equal(calls.length, 2, "the second save was never sent");
  calls[1].answer(1);
  await second;
  assert.equal(p.status.textContent, "Saved lighting: 1 points.");
});
