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
  for (const [fx, fy] of [
    [80, 60],
    [0.5, 0.5],
    [150, 20],
  ]) {
    const p = v.add(b.from, v.mul(v.pixelDirection(b, fx, fy), 7));
    const f = v.projectToFilm(b, p);
    assert.ok(Math.abs(f.x - fx) < 1e-9 && Math.abs(f.y - fy) < 1e-9, JSON.stringify([fx, fy, f]));
    assert.ok(f.z > 0);
  }
});

test("rotateWrites turns a box, a mesh, a quad and a triangle in place about the vertical", () => {
  const apply = (o, writes) => {
    const out = structuredClone(o);
    for (const [path, value] of writes) out[path.at(-1)] = value;
    return out;
  };
  const close = (a, b) => a.every((x, i) => Math.abs(x - b[i]) < 2e-3);
  // the example assignment's cube: turned about the origin by its transform, away from it; 25 more degrees
  const cube = { type: "box", min: [-2, 0, -0.9], max: [-0.8, 1.2, 0.3], transform: { rotate: [0, 20, 0] } };
  const turned = apply(cube, e.rotateWrites(cube, [], 25));
  assert.deepEqual(turned.transform.rotate, [0, 45, 0]);
  assert.ok(close(e.anchorOf(turned), e.anchorOf(cube)), JSON.stringify(turned));
  // a box without a transform gets one; a turn of 90 degrees takes its +x face to -z
  const box = { type: "box", min: [1, 0, 1], max: [3, 1, 2] };
  const quarter = apply(box, e.rotateWrites(box, ["objects", 0], 90));
  assert.deepEqual(quarter.transform.rotate, [0, 90, 0]);
  assert.ok(close(e.anchorOf(quarter), [2, 0.5, 1.5]));
  const m = v.transformMatrix(quarter.transform);
  assert.ok(close(v.applyPoint(m, [3, 0.5, 1.5]), [2, 0.5, 0.5])); // the +x face's middle, now at -z of the centre
  assert.deepEqual(e.rotateWrites(box, ["objects", 0], 90)[0][0], ["objects", 0, "transform"]);
  // its scale is kept; angles stay in (-180, 180]
  const scaled = { type: "box", min: [-1, -1, -1], max: [1, 1, 1], transform: { rotate: [0, 170, 0], scale: 2 } };
  assert.deepEqual(apply(scaled, e.rotateWrites(scaled, [], 20)).transform, {
    translate: [0, 0, 0],
    rotate: [0, -170, 0],
    scale: 2,
  });
  // a mesh turns about its origin (its anchor)
  const mesh = { type: "mesh", vertices: [], faces: [], transform: { translate: [1, 0, 0] } };
  assert.deepEqual(apply(mesh, e.rotateWrites(mesh, [], 30)).transform, { translate: [1, 0, 0], rotate: [0, 30, 0] });
  // a quad's corner and edges and a triangle's vertices turn about their centre
  const quad = { type: "quad", corner: [-1, 0, -1], edge1: [2, 0, 0], edge2: [0, 0, 2] };
  const q = apply(quad, e.rotateWrites(quad, [], 90));
  assert.ok(close(e.anchorOf(q), [0, 0, 0]) && close(q.edge1, [0, 0, -2]), JSON.stringify(q));
  const tri = {
    type: "triangle",
    vertices: [
      [0, 0, 0],
      [3, 0, 0],
      [0, 0, 3],
    ],
  };
  assert.ok(close(e.anchorOf(apply(tri, e.rotateWrites(tri, [], 45))), [1, 0, 1]));
  // what does not turn: a sphere, a plane, a point light
  for (const o of [
    { type: "sphere", center: [0, 0, 0], radius: 1 },
    { type: "plane", point: [0, 0, 0], normal: [0, 1, 0] },
    { type: "point", position: [0, 1, 0] },
  ])
    assert.equal(e.rotateWrites(o, [], 10), null);
});
