// web/js/jsonpos.js without a browser (it uses no DOM): `node --test tests/js/` runs it in milliseconds, and
// tests/js/test_js.py runs it in pytest. Ported from tests/web/test_web_build.py, which ran it in Chromium.
import assert from "node:assert/strict";
import { test } from "node:test";

import * as j from "../../web/js/jsonpos.js";

test("appendItem and removeAt keep the rest of the text", () => {
  const t =
    '{\n  "objects": [\n    {"type": "sphere"},\n    {"type": "plane"}\n  ],\n' +
    '  "lights": [],\n  "m": {"a": 1, "b": 2}\n}\n';
  const a = j.appendItem(t, ["objects"], { type: "box" }).text;
  const b = j.appendItem(a, ["lights"], { type: "point" }).text;
  const c = j.appendItem(b, ["extra"], 1).text;
  const r0 = j.removeAt(t, ["objects", 0]).text;
  const r1 = j.removeAt(t, ["objects", 1]).text;
  const ma = j.removeAt(t, ["m", "a"]).text;
  const mb = j.removeAt(t, ["m", "b"]).text;
  const all = j.removeAt(j.removeAt(t, ["objects", 1]).text, ["objects", 0]).text;

  assert.deepEqual(a.split("\n").slice(2, 5), [
    '    {"type": "sphere"},',
    '    {"type": "plane"},',
    '    {"type": "box"}',
  ]);
  assert.ok(b.includes('"lights": [\n    {"type": "point"}\n  ]'), b);
  assert.deepEqual(JSON.parse(c).extra, [1]);
  assert.deepEqual(JSON.parse(r0).objects, [{ type: "plane" }]);
  assert.ok(r0.includes('  "objects": [\n    {"type": "plane"}\n  ]'), r0);
  assert.deepEqual(JSON.parse(r1).objects, [{ type: "sphere" }]);
  assert.deepEqual(JSON.parse(ma).m, { b: 2 });
  assert.deepEqual(JSON.parse(mb).m, { a: 1 });
  assert.ok(all.includes('"objects": [],'), all);
});

test("pathString and parsePath are each other's inverse, in the server's notation", () => {
  const cases = [
    [["objects", 2, "radius"], "objects[2].radius"],
    [["materials", "my glass", "kd"], 'materials["my glass"].kd'],
    [["camera"], "camera"],
  ];
  for (const [parts, path] of cases) {
    assert.equal(j.pathString(parts), path);
    assert.deepEqual(j.parsePath(path), parts);
  }
});
