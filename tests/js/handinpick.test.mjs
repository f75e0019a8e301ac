// web/js/course/handin.js's file pickers without a browser (the files, the note and the textarea stood in for): a
// file is read asynchronously, so a second one picked while the first is still being read may be read first. The
// older read, ending after, must not put its image (or its scene) back over the one picked last.
import assert from "node:assert/strict";
import { test } from "node:test";

import { HandIn } from "../../web/js/course/handin.js";

/** A file whose bytes (or text) the test hands over when it likes. */
function heldFile(name, size = 4) {
  let give;
  const read = new Promise((r) => {
    give = r;
  });
  return {
    name,
    size,
    arrayBuffer: () => read.then(() => new Uint8Array(size).buffer),
    text: () => read.then(() => `{"from": "${name}"}`),
    give: () => give(),
  };
}

function handin() {
  const hi = Object.create(HandIn.prototype); // no DOM: the fields the pickers use, stood in for
  const note = { textContent: "" };
  hi.root = { querySelector: () => note };
  hi.image = null;
  hi.ta = { value: "" };
  hi.note = { textContent: "" };
  hi.key = "rt.course.a1.scene";
  return { hi, note };
}

test("an image picked while the last one is read is the one sent", async () => {
  const { hi, note } = handin();
  const png = heldFile("mine.png");
  const exr = heldFile("mine.exr");
  const first = hi.pickImage({ files: [png], value: "" });
  const second = hi.pickImage({ files: [exr], value: "" });
  exr.give();
  await second;
  png.give(); // the older read ends last
  await first;
  assert.equal(hi.image?.format, "exr", "the older file's image was put back");
  assert.match(note.textContent, /^mine\.exr: EXR/);
});

test("a scene file opened while the last one is read is the one shown", async () => {
  const { hi } = handin();
  const a = heldFile("a.json");
  const b = heldFile("b.json");
  const first = hi.openFile({ files: [a], value: "" });
  const second = hi.openFile({ files: [b], value: "" });
  b.give();
  await second;
  a.give();
  await first;
  assert.equal(hi.ta.value, '{"from": "b.json"}', "the older file's text was put back");
  assert.equal(hi.note.textContent, "Opened b.json.");
});
