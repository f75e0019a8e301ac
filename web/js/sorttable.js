// A table sorted by one column at a time, as the Grading tab's class (grading.js) and the course board's roster
// (course/instructor_board.js) are: a header button per sortable column (its `aria-sort`, an arrow), a first click
// on a column sorting it its better way first, a second click the other way; rows without a value last, whichever
// way, and ties in the table's own order.
import { $, h } from "./util.js";

const missing = (v) => v === null || v === undefined;

export class TableSort {
  /** Sorted by column `key`, `dir` 1 (ascending) or -1. */
  constructor(key, dir = 1) {
    this.key = key;
    this.dir = dir;
  }

  /** A click on column `key`: the other way if it is the sorted one, else its `first` way. */
  toggle(key, first = 1) {
    this.dir = this.key === key ? -this.dir : first;
    this.key = key;
  }

  /** A sorted copy of `rows` by `value(row)` in this direction: a null or undefined value last, ties by `tie`. */
  sorted(rows, value, tie = () => 0) {
    return [...rows].sort((a, b) => {
      const x = value(a);
      const y = value(b);
      if (missing(x) !== missing(y)) return missing(x) ? 1 : -1;
      if (x !== y && !missing(x)) return (x < y ? -1 : 1) * this.dir;
      return tie(a, b);
    });
  }

  /** A column's header cell: its button sorts by it (`first`: its first way), calls `redraw`, and keeps the focus
   * on the button drawn again in `within`; `num` right-aligns a column of numbers. */
  header(key, label, { first = 1, num = false, redraw, within }) {
    const on = this.key === key;
    return h(
      "th",
      {
        scope: "col",
        class: num ? "num" : null,
        dataset: { col: key },
        "aria-sort": on ? (this.dir > 0 ? "ascending" : "descending") : null,
      },
      h(
        "button",
        {
          type: "button",
          class: "sort",
          onclick: () => {
            this.toggle(key, first);
            redraw();
            $(`th[data-col="${key}"] button`, within)?.focus();
          },
        },
        label,
        h("span", { "aria-hidden": "true" }, on ? (this.dir > 0 ? " ▲" : " ▼") : ""),
      ),
    );
  }
}
