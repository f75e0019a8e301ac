// web/js/lessons.js's circle of confusion without a browser (the API, the panels and the drawing stood in for):
// each click on a picture asks the server for the ray tree of its pixel. Two clicks in a row may answer out of
// order; the circle drawn and the words under the pictures (with their data-diameter) are the latest click's.
import assert from "node:assert/strict";
import { test } from "node:test";

import { api } from "../../web/js/api.js";
import { Lessons } from "../../web/js/lessons.js";

const scene = (lens) => ({
  camera: { lookfrom: [0, 0, 0], lookat: [0, 0, -1], vfov: 40, lens_radius: lens, focus_distance: 5 },
  film: { width: 64, height: 48 },
});
/** The ray tree of a pixel whose eye ray hits `name` at depth `t`. */
const tree = (name, t) => ({ nodes: [{ t, direction: [0, 0, -1], hit: { object_name: name } }] });

test("two clicks answered out of order: the latest click's circle is said", async () => {
  const asked = [];
  api.raytree = (_scene, x, y) => new Promise((answer) => asked.push({ x, y, answer }));
  const l = Object.create(Lessons.prototype); // no DOM: the fields circleOfConfusion uses, stood in for
  const clicks = [
    [10, 20],
    [30, 24],
  ];
  l.pixelAt = () => clicks.shift();
  l.drawCoc = () => {};
  const run = { panels: [{ scene: scene(0) }, { scene: scene(0.2) }], cocText: { dataset: {}, textContent: "" } };
  const near = l.circleOfConfusion(null, run, run.panels[0], {}); // the near ball...
  const focus = l.circleOfConfusion(null, run, run.panels[0], {}); // ...then the one in focus, at once
  asked[1].answer(tree("green", 5));
  await focus;
  asked[0].answer(tree("red", 2)); // the older click answers last
  await near;
  assert.match(run.cocText.textContent, /^Pixel \(30, 24\) sees the green/, "the older click's words were said");
  assert.equal(run.cocText.dataset.diameter, "0.00");
});
