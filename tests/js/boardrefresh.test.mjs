// web/js/course/instructor_board.js's class board without a browser (the API and the drawing stood in for): the
// board is read again every few seconds, and at once after an extension or "Send again". A poll asked before an
// extension and answered after it would draw the row as it was before (a test reads the row once it shows the
// extension), and each overlapping read would start a poll of its own. A student's detail, asked twice, is drawn
// from the latest answer too.
import assert from "node:assert/strict";
import { test } from "node:test";

import { Board } from "../../web/js/course/instructor_board.js";
import { course } from "../../web/js/course/instructor_util.js";

const ticks = async (n = 20) => {
  for (let i = 0; i < n; i++) await new Promise((r) => setTimeout(r, 0));
};

function board() {
  const asked = []; // each read of the board, answered by the test
  course.board = () => new Promise((answer) => asked.push(answer));
  const b = Object.create(Board.prototype); // no DOM: the fields refresh() uses, stood in for
  b.aid = "a1";
  b.closed = false;
  b.open_ = null;
  b.brief = { reference_grade: { status: "graded" } };
  b.drawn = [];
  b.renderSummary = () => {};
  b.renderTable = function () {
    this.drawn.push(this.data.students[0].extended);
  };
  b.access = () => false;
  b.status = { dataset: {}, replaceChildren() {} };
  b.poll = () => {};
  const timers = [];
  const realSet = globalThis.setTimeout;
  b.timers = timers;
  b.restore = () => {
    globalThis.setTimeout = realSet;
    b.closed = true;
  };
  // the board's own polls counted (setTimeout with POLL_MS), the test's ticks left alone
  globalThis.setTimeout = (f, ms, ...rest) => (ms ? timers.push(f) : realSet(f, ms, ...rest));
  return { b, asked };
}

const row = (extended) => ({ students: [{ id: "s4", extended }] });

test("a poll asked before an extension and answered after it does not draw the row back", async () => {
  const { b, asked } = board();
  try {
    const poll = b.refresh(); // the poll's read, in flight...
    const grant = b.refresh(); // ...when the extension's answer asks again
    asked[1](row(true));
    await grant;
    assert.deepEqual(b.drawn, [true]);
    asked[0](row(false)); // the poll's older answer
    await poll;
    await ticks();
    assert.deepEqual(b.drawn, [true], "the older answer drew the row as it was before the extension");
    assert.equal(b.data.students[0].extended, true);
    assert.equal(b.timers.length, 1, "each overlapping read started a poll of its own");
  } finally {
    b.restore();
  }
});

test("a student's detail asked twice is drawn from the latest answer", async () => {
  const { b } = board();
  const asked = [];
  course.student = () => new Promise((answer) => asked.push(answer));
  b.rows = new Map();
  globalThis.window ??= { history: { replaceState() {} } };
  // drawing the detail starts with its first element: which answer got that far is all the test needs
  const drawn = [];
  let answer = null;
  globalThis.document = {
    createElement() {
      drawn.push(answer);
      throw new Error("drawn");
    },
  };
  try {
    const first = b.renderStudent("s4", false).catch(() => {});
    const second = b.renderStudent("s4", false).catch(() => {});
    answer = "new";
    asked[1]({ id: "s4", history: [], deadline: null });
    await second;
    answer = "old";
    asked[0]({ id: "s4", history: [], deadline: null });
    await first;
    await ticks();
    assert.deepEqual(drawn, ["new"], "the older answer was drawn over the newer one");
  } finally {
    delete globalThis.document;
    b.restore();
  }
});
