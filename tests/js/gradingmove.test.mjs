// web/js/course/grading.js's moves between submissions ("n", "b") without a browser (the API, the card and the
// status stood in for): a submission read while a save is still on its way could come back without it (a level
// pressed, then "b" and "n" at once: the card drawn unchecked, and a grader's next key undoes it), and two moves
// answered out of order would draw the one asked first.
import assert from "node:assert/strict";
import { test } from "node:test";

import { GradingPanel, grading } from "../../web/js/course/grading.js";

const ticks = async (n = 20) => {
  for (let i = 0; i < n; i++) await new Promise((r) => setTimeout(r, 0));
};

function panel() {
  const asked = []; // each request, answered by the test: {what, answer}
  const held = (what) => () => new Promise((answer) => asked.push({ what, answer }));
  grading.put = held("put");
  grading.next = held("next");
  grading.one = held("one");
  const p = Object.create(GradingPanel.prototype); // no DOM: the fields save, next and back use, stood in for
  p.aid = "a1";
  p.access = () => false;
  p.scope = { value: "mine" };
  p.history = [];
  p.sub = { submission: "s1", manual: {} };
  p.status = { dataset: {}, textContent: "", replaceChildren() {} };
  p.card = { querySelector: () => ({ textContent: "" }), replaceChildren() {} };
  p.items = [
    {
      item: { name: "creativity", points: 3 },
      boxes: [{ checked: true, dataset: { level: "good" } }],
      comment: { value: "" },
      score: {},
    },
  ];
  p.shown = [];
  p.show = function (r) {
    this.sub = r;
    this.shown.push(r.submission);
  };
  p.load = () => {};
  return { p, asked };
}

test("the next submission is read once the saves made before it have landed", async () => {
  const { p, asked } = panel();
  const saved = p.save(0);
  const moved = p.next();
  await ticks();
  assert.deepEqual(
    asked.map((a) => a.what),
    ["put"],
    "the next submission was read before the save made on this one landed",
  );
  asked[0].answer({ manual: { items: [{ points: 2 }] } });
  await saved;
  await ticks();
  assert.deepEqual(
    asked.map((a) => a.what),
    ["put", "next"],
  );
  asked[1].answer({ submission: "s2", manual: {} });
  await moved;
  assert.deepEqual(p.shown, ["s2"]);
});

test("two moves answered out of order: the latest asked is drawn", async () => {
  const { p, asked } = panel();
  p.history = ["s0"];
  const forth = p.next(); // "n"...
  await ticks();
  const back = p.back(); // ...then "b" at once
  await ticks();
  assert.deepEqual(
    asked.map((a) => a.what),
    ["next", "one"],
  );
  asked[1].answer({ submission: "s0", manual: {} });
  await back;
  asked[0].answer({ submission: "s2", manual: {} }); // the older move answers last
  await forth;
  await ticks();
  assert.equal(p.sub.submission, "s0", "the older move's answer was drawn over the newer one");
});
