// web/js/share.js (scenes in links) without a browser: node has CompressionStream, Blob and atob as browsers do.
import assert from "node:assert/strict";
import { test } from "node:test";

import { decodeScene, encodeScene } from "../../web/js/share.js";

test("a scene's text survives the link, and its data is base64url", async () => {
  const text = JSON.stringify({ camera: { lookfrom: [0, 1, 5] }, objects: [{ type: "sphere", name: "é ü" }] }, null, 2);
  const data = await encodeScene(text);
  assert.match(data, /^[A-Za-z0-9_-]+$/);
  assert.equal(await decodeScene(data), text);
});

test("a broken link says what is wrong with it", async () => {
  await assert.rejects(decodeScene(""), /holds no scene/);
  await assert.rejects(decodeScene("a+b/"), /characters a scene's data never has/);
  const data = await encodeScene('{"a": 1}');
  await assert.rejects(decodeScene(data.slice(0, 3)), /cut short or damaged/);
  await assert.rejects(decodeScene(await encodeScene("not json")), /not JSON/);
});
