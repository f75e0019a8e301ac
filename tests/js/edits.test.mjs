// web/js/edits.js and vec.js without a browser (neither uses the DOM): ported from tests/web/test_web_build.py,
// which ran edits.js's firstHit in Chromium.
import assert from "node:assert/strict";
import { test } from "node:test";

import * as e from "../../web/js/edits.js";
import * as v from "../../web/js/vec.js";

test("a rotated box is hit where it is drawn", () => {
  // a box turned 45 degrees about z is a diamond seen along z; a ray by its bounds' corner (inside the
  // axis-aligned bounds of its corners) misses it, a ray through it meets its front face at the right distance,
  // and a moved and scaled box is met where its transform puts it
  const box = (transform) => ({ objects: [{ type: "box", min: [-1, -1, -1], max: [1, 1, 1], transform }] });
  const t = (scene, o) => e.firstHit(scene, o, [0, 0, -1])?.t ?? null;
  const turned = box({ rotate: [0, 0, 45] });
  const moved = box({ translate: [3, 0, 0], scale: 2 });
  assert.equal(t(turned, [1.2, 1.2, 5]), null);
  assert.equal(t(moved, [5.5, 0, 10]), null);
  assert.ok(Math.abs(t(turned, [0, 0, 5]) - 4) < 1e-9);
  assert.ok(Math.abs(t(turned, [0.6, 0.6, 5]) - 4) < 1e-9);
  assert.ok(Math.abs(t(moved, [4.5, 0, 10]) - 8) < 1e-9);
});

test("projectToFilm is the inverse of pixelDirection (the Build panel's picks in the picture)", () => {
  const camera = { lookfrom: [0, 1, 5], lookat: [0.5, 0.5, 0], vup: [0, 1, 0], vfov: 40 };
  const b = v.cameraBasis(camera, 160, 120);
  for (const [fx, fy] of [[80, 60], [0.5, 0.5], [150, 20]]) {
    const p = v.add(b.from, v.mul(v.pixelDirection(b, fx, fy), 7));
    const f = v.projectToFilm(b, p);
    assert.ok(Math.abs(f.x - fx) < 1e-9 && Math.abs(f.y - fy) < 1e-9, JSON.stringify([fx, fy, f]));
    assert.ok(f.z > 0);
  }
});
