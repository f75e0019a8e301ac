// web/js/api.js's showImage without a browser (fetch and the img stood in for): a second call for the URL still
// being fetched waits for the picture (the lessons' panels mark a picture shown when it resolves: it must not
// resolve while the img still shows the one before).
import assert from "node:assert/strict";
import { test } from "node:test";

import { showImage } from "../../web/js/api.js";

/** fetch stood in for: each call waits until the test answers it (`answer(url, text)`). */
function heldFetch() {
  const waiting = new Map();
  globalThis.fetch = (url) =>
    new Promise((resolve) => waiting.set(url, (text) => resolve(new Response(new Blob([text]), { status: 200 }))));
  return async (url, text) => {
    for (let i = 0; i < 50 && !waiting.has(url); i++) await new Promise((r) => setTimeout(r, 0));
    waiting.get(url)(text);
  };
}

const settled = (promise) =>
  Promise.race([promise.then(() => true), new Promise((r) => setTimeout(() => r(false), 20))]);

test("a second call for the URL being fetched resolves only once the img shows it", async () => {
  const answer = heldFetch();
  const img = { dataset: {}, src: "" };
  const first = showImage(img, "/api/jobs/a/image?pass=2");
  const second = showImage(img, "/api/jobs/a/image?pass=2");
  assert.equal(await settled(second), false); // not before the picture came
  assert.equal(img.src, "");
  await answer("/api/jobs/a/image?pass=2", "png of a");
  assert.equal(await second, true);
  assert.equal(await first, true);
  assert.ok(img.src.startsWith("blob:"));
  assert.equal(img.src, img.dataset.blob);
  assert.equal(await showImage(img, "/api/jobs/a/image?pass=2"), true); // shown already: at once, no new fetch
});

test("a newer URL asked for meanwhile wins: the older call resolves false and does not replace the picture", async () => {
  const answer = heldFetch();
  const img = { dataset: {}, src: "" };
  const older = showImage(img, "/api/jobs/b/image?pass=1");
  const newer = showImage(img, "/api/jobs/b/image?pass=2");
  await answer("/api/jobs/b/image?pass=2", "pass 2");
  assert.equal(await newer, true);
  const shown = img.src;
  await answer("/api/jobs/b/image?pass=1", "pass 1");
  assert.equal(await older, false);
  assert.equal(img.src, shown);
  assert.equal(img.dataset.src, "/api/jobs/b/image?pass=2");
});

test("a fetch that fails resolves false and the next call fetches again", async () => {
  globalThis.fetch = () => Promise.reject(new TypeError("network down"));
  const img = { dataset: {}, src: "" };
  assert.equal(await showImage(img, "/api/jobs/c/image"), false);
  assert.equal(img.dataset.src, undefined);
  const answer = heldFetch();
  const again = showImage(img, "/api/jobs/c/image");
  await answer("/api/jobs/c/image", "png of c");
  assert.equal(await again, true);
});
