// web/js/sorttable.js's order without a browser: the Grading tab's class and the course board's roster sort so.
import assert from "node:assert/strict";
import { test } from "node:test";

import { TableSort } from "../../web/js/sorttable.js";

const rows = [
  { name: "b", score: 2, index: 0 },
  { name: "a", score: null, index: 1 },
  { name: "c", score: 5, index: 2 },
  { name: "d", score: 2, index: 3 },
  { name: "e", index: 4 },
];
const names = (sort) =>
  sort
    .sorted(
      rows,
      (r) => r.score,
      (x, y) => x.index - y.index,
    )
    .map((r) => r.name)
    .join("");

test("rows without a value go last whichever way, ties keep the table's order", () => {
  const sort = new TableSort("score");
  assert.equal(names(sort), "bdcae");
  sort.dir = -1;
  assert.equal(names(sort), "cbdae");
  assert.equal(rows[0].name, "b"); // a sorted copy: the rows stay as they were
});

test("a first click sorts a column its first way, a second the other way", () => {
  const sort = new TableSort("student");
  sort.toggle("score", -1);
  assert.deepEqual([sort.key, sort.dir], ["score", -1]);
  sort.toggle("score", -1);
  assert.deepEqual([sort.key, sort.dir], ["score", 1]);
  sort.toggle("student");
  assert.deepEqual([sort.key, sort.dir], ["student", 1]);
});
