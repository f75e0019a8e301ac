// web/js/course/instructor_form.js's publish form without a browser (the file input and the fields stood in for):
// the spec file picked is read asynchronously, and it decides what the form asks for (a reference file the spec
// names) and sends. Publish pressed before that read ended checked and sent the form as for the last spec; and a
// spec picked while the last one was still being read could be overwritten by it.
import assert from "node:assert/strict";
import { test } from "node:test";

import { AssignmentForm } from "../../web/js/course/instructor_form.js";

/** A file whose text the test hands over when it likes. */
function heldFile(name, spec) {
  let give;
  const read = new Promise((r) => {
    give = r;
  });
  return { name, text: () => read.then(() => JSON.stringify(spec)), give: () => give() };
}

function form() {
  const f = Object.create(AssignmentForm.prototype); // no DOM: the fields readSpec and send use, stood in for
  f.specInput = { files: [], removeAttribute() {}, setAttribute() {} };
  f.fields = { spec: { list: { replaceChildren() {}, append() {} } } };
  f.afterSpec = () => {};
  f.edit = null;
  return f;
}

/** The form's change handler, as the constructor wires it: a file picked, read. */
const pick = (f, file) => {
  f.specInput.files = [file];
  f.specRead = f.readSpec();
};

test("a spec picked while the last one is read is the form's spec", async () => {
  const f = form();
  const a = heldFile("a.json", { name: "A" });
  const b = heldFile("b.json", { name: "B" });
  pick(f, a);
  const first = f.specRead;
  pick(f, b);
  b.give();
  await f.specRead;
  a.give(); // the older read ends last
  await first;
  assert.equal(f.spec?.name, "B", "the older file's spec was put back");
});

test("Publish waits for the spec just picked before checking the form", async () => {
  const f = form();
  const checked = [];
  f.precheck = () => {
    checked.push(f.spec?.name ?? null);
    return false; // stops there: what it checked against is all the test needs
  };
  f.status = { dataset: {}, textContent: "" };
  const named = heldFile("hw.json", { name: "HW", reference: { scene: "reference.json" } });
  pick(f, named);
  const sent = f.send(); // Publish, pressed before the spec was read
  named.give();
  await sent;
  assert.deepEqual(checked, ["HW"], "the form was checked before the spec picked was read");
});
