// The scene editor: a plain textarea with a line-number gutter, error marks drawn behind the text at
// their line (with their message), a list of problems, live validation against POST /api/validate, and
// the text kept in localStorage so unsaved work survives a reload.
// Undo and redo are the editor's own (Ctrl+Z, Ctrl+Shift+Z or Ctrl+Y, and the Undo and Redo buttons): a textarea
// forgets its native history when a script sets its text, and the form, the Build panel and the 3D view's handles
// all write into the text. Each of their writes is one step; typing is one step per pause.
import { ApiError, api } from "./api.js";
import { lineIndex, locate, nodeLine, parse, pathString, setValue } from "./jsonpos.js";
import { $, debounce, h, store } from "./util.js";

const KEY = "rt.editor.text";
const NAME_KEY = "rt.editor.name";
const LINE_HEIGHT = 20; // px, as .code in app.css
const PAD = 8; // px, the textarea's padding
const PAD_X = 10; // px, its left and right padding
const MIN_MESSAGE_CHARS = 16; // a message narrower than this is cut to one row instead
const HISTORY = 200; // steps kept for undo
const TYPING_PAUSE = 1000; // ms: keystrokes closer than this are one step of the history

/** The workspace editor's text as it was last kept (another page of the site, an assignment's, hands it in). */
export function keptText() {
  const text = store.get(KEY, null);
  return typeof text === "string" ? text : null;
}

export class SceneEditor {
  /** root: the element holding .code, #problems, #validation-status. */
  constructor(root, { onChange = () => {}, onRender = () => {}, onHistory = () => {}, onTravel = () => {} } = {}) {
    this.root = root;
    this.ta = $("textarea", root);
    this.gutter = $(".gutter-nums", root);
    this.gutterMarks = $(".gutter-marks", root);
    this.backdrop = $(".backdrop", root);
    this.problems = $("#problems", root);
    this.status = $("#validation-status", root);
    this.onChange = onChange;
    this.onRender = onRender;
    this.onHistory = onHistory; // (canUndo, canRedo): the buttons follow
    this.onTravel = onTravel; // ("undo" | "redo", what): an undo or redo went through; `what` names the step
    this.past = []; // [{text, sel, what}] before each step (what: the step's name), the latest last
    this.future = []; // steps undone, the next redo last
    this.typing = -Infinity; // when the student last typed (a pause starts a new step; -Infinity: none since the last step)
    this.state = {
      text: "",
      value: null,
      nodes: null,
      where: null,
      syntax: null,
      valid: null,
      errors: [],
      warnings: [],
    };
    this.marks = []; // [{line, col?, severity, message, path?}]
    this.flash = null; // {line, until}: the line a form control just wrote
    this.lines = 0;
    this.seq = 0;
    this.abort = null;
    this.scheduleValidate = debounce(() => this.validate(), 300);
    this.save = debounce(() => store.set(KEY, this.ta.value), 300);
    this.ta.addEventListener("beforeinput", (e) => this.beforeInput(e));
    this.ta.addEventListener("input", () => this.changed());
    this.ta.addEventListener("scroll", () => this.syncScroll());
    this.ta.addEventListener("keydown", (e) => this.keydown(e));
    window.addEventListener("pagehide", () => this.save.flush());
    new ResizeObserver(() => this.drawMarks()).observe(this.ta); // messages wrap to the new width
  }

  get text() {
    return this.ta.value;
  }

  get name() {
    return store.get(NAME_KEY, "scene");
  }

  /** Restore the text of the last visit; false when there is none. */
  restore() {
    const text = store.get(KEY, null);
    if (typeof text !== "string" || !text.trim()) return false;
    this.ta.value = text;
    this.changed(true);
    return true;
  }

  /** Replace the whole text (an example, a file, a lesson's variant): one step of the history. */
  setText(text, name = null) {
    this.record(`load ${name || "a new scene"}`);
    this.ta.value = text;
    if (name) store.set(NAME_KEY, name);
    this.ta.scrollTop = 0;
    this.ta.scrollLeft = 0;
    this.changed(true);
  }

  /** Write one value into the JSON text (form controls): only that value's characters change. */
  setField(parts, value) {
    return this.edit((text) => setValue(text, parts, value), `write ${pathString(parts)}`);
  }

  /** One change of the text, one step of the history: `change(text)` returns {text, start} (jsonpos.js's
   * setValue, appendItem, removeAt, or several of them in a row); `what` names it in an error message. */
  edit(change, what = "change the scene") {
    const old = this.ta.value;
    let result;
    try {
      result = change(old);
    } catch (err) {
      this.setStatus("error", `Could not ${what}: ${err.message}`);
      return false;
    }
    if (result.text === old) return true;
    this.record(what);
    // replace only the changed span, so the textarea keeps its scroll and selection elsewhere
    const next = result.text;
    let a = 0;
    while (a < old.length && a < next.length && old[a] === next[a]) a++;
    let b = 0;
    while (b < old.length - a && b < next.length - a && old[old.length - 1 - b] === next[next.length - 1 - b]) b++;
    this.ta.setRangeText(next.slice(a, next.length - b), a, old.length - b, "preserve");
    this.flash = { line: lineIndex(next)(result.start).line, until: performance.now() + 1500 };
    setTimeout(() => this.drawMarks(), 1600);
    this.changed();
    return true;
  }

  // -- history ------------------------------------------------------------------------------------

  /** Keep the text as it is now as a step to go back to (before a change named `what`: "move object 0 (sphere)"). */
  record(what = "typing") {
    const text = this.ta.value;
    this.typing = -Infinity;
    if (text.trim() && this.past.at(-1)?.text !== text)
      this.past.push({ text, sel: [this.ta.selectionStart, this.ta.selectionEnd], what });
    if (this.past.length > HISTORY) this.past.shift();
    this.future = [];
    this.onHistory(this.canUndo, this.canRedo);
  }

  get canUndo() {
    return this.past.length > 0;
  }

  get canRedo() {
    return this.future.length > 0;
  }

  /** Go back one step (true), or say there is none (false). */
  undo() {
    return this.travel(this.past, this.future, "Nothing to undo.", "undo");
  }

  redo() {
    return this.travel(this.future, this.past, "Nothing to redo.", "redo");
  }

  /** One step from `from` to `to`: a step keeps its name both ways (undone, it is the step that redo makes again). */
  travel(from, to, none, kind) {
    const step = from.pop();
    if (!step) {
      this.setStatus("warn", none);
      return false;
    }
    to.push({ text: this.ta.value, sel: [this.ta.selectionStart, this.ta.selectionEnd], what: step.what });
    this.typing = -Infinity;
    const top = this.ta.scrollTop;
    this.ta.value = step.text;
    this.ta.setSelectionRange(...step.sel);
    this.ta.scrollTop = top;
    // the form, the Build panel and its 3D view follow at once: a key pressed right after Ctrl+Z (an arrow that
    // moves the picked sphere) must start from the text it brought back, not from the step it undid
    this.changed(true);
    this.onHistory(this.canUndo, this.canRedo);
    this.onTravel(kind, step.what);
    return true;
  }

  /** Typing: a new step after a pause; the browser's own undo (its menu, a gesture) goes to ours. */
  beforeInput(e) {
    if (e.inputType === "historyUndo" || e.inputType === "historyRedo") {
      e.preventDefault();
      if (e.inputType === "historyUndo") this.undo();
      else this.redo();
      return;
    }
    this.noteTyping();
  }

  noteTyping() {
    const now = performance.now();
    if (now - this.typing > TYPING_PAUSE) this.record();
    this.typing = now;
  }

  changed(now = false) {
    this.updateGutter();
    this.save();
    if (now) {
      this.save.flush();
      this.scheduleValidate.flush();
    } else {
      this.drawMarks();
      this.scheduleValidate();
    }
  }

  /** Parse now (no server): {value} or {syntax}. */
  parseNow() {
    const text = this.ta.value;
    if (this.state.text === text && (this.state.value !== null || this.state.syntax)) return this.state;
    const where = lineIndex(text);
    try {
      const { value, nodes } = parse(text);
      Object.assign(this.state, { text, value, nodes, where, syntax: null });
    } catch (err) {
      if (!err.line) throw err;
      Object.assign(this.state, { text, value: null, nodes: null, where, syntax: err });
    }
    return this.state;
  }

  async validate() {
    const seq = ++this.seq;
    const st = this.parseNow();
    if (st.syntax) {
      const e = st.syntax;
      this.abort?.abort();
      Object.assign(this.state, { valid: false, errors: [], warnings: [] });
      this.setMarks([{ line: e.line, col: e.col, severity: "error", message: `JSON syntax: ${e.message}`, path: "" }]);
      this.setStatus("error", `JSON syntax error at line ${e.line}, column ${e.col}: ${e.message}`);
      this.onChange(this.state);
      return this.state;
    }
    if (st.value === null || typeof st.value !== "object" || Array.isArray(st.value)) {
      this.setMarks([{ line: 1, severity: "error", message: "a scene is a JSON object: { ... }", path: "" }]);
      this.setStatus("error", "A scene is one JSON object, { ... }.");
      this.onChange(this.state);
      return this.state;
    }
    this.onChange(this.state); // the form follows the text at once; the server's verdict follows
    this.abort?.abort();
    const abort = new AbortController();
    this.abort = abort;
    this.setStatus("busy", "Checking the scene…");
    const text = st.text;
    let answer;
    try {
      answer = await api.validate(text, abort.signal);
    } catch (err) {
      if (err.name === "AbortError" || seq !== this.seq) return this.state;
      const message =
        err instanceof ApiError && err.status === 0 ? err.message : `the server could not check it: ${err.message}`;
      this.setStatus("warn", `Could not validate: ${message}.`);
      return this.state;
    }
    if (seq !== this.seq) return this.state;
    this.state.valid = answer.valid;
    this.state.checked = text; // the text this verdict is about
    this.state.errors = answer.errors || [];
    this.state.warnings = answer.warnings || [];
    this.showProblems(this.state.errors, this.state.warnings);
    this.onChange(this.state);
    return this.state;
  }

  /** Errors and warnings with JSON paths -> marks at their lines (also used for a refused job). */
  showProblems(errors, warnings = []) {
    const st = this.parseNow();
    if (!st.nodes) return;
    const marks = [];
    for (const [list, severity] of [
      [errors, "error"],
      [warnings, "warning"],
    ]) {
      for (const e of list) {
        const found = locate(st.nodes, e.path || "");
        const line = found ? nodeLine(st.where, found.node) : 1;
        const where = found && !found.exact ? ` (in ${pathString(found.node.parts) || "the scene"})` : "";
        marks.push({
          line,
          severity,
          message: e.message + where,
          path: e.path || "",
          node: found?.exact ? found.node : null,
        });
      }
    }
    this.setMarks(marks);
    const n = errors.length;
    const w = warnings.length;
    if (n)
      this.setStatus(
        "error",
        `${n} error${n > 1 ? "s" : ""}${w ? `, ${w} warning${w > 1 ? "s" : ""}` : ""}: the scene cannot be rendered yet.`,
      );
    else if (w) this.setStatus("warn", `Valid, with ${w} warning${w > 1 ? "s" : ""}.`);
    else this.setStatus("ok", "The scene is valid.");
  }

  setStatus(kind, text) {
    this.status.dataset.kind = kind;
    this.status.textContent = text;
  }

  setMarks(marks) {
    this.marks = marks.sort((a, b) => a.line - b.line);
    this.drawMarks();
    this.problems.replaceChildren(
      ...this.marks.map((m) =>
        h(
          "li",
          { class: m.severity },
          h(
            "button",
            { type: "button", class: "problem", onclick: () => this.jumpTo(m) },
            h("span", { class: "where" }, `line ${m.line}${m.col ? `:${m.col}` : ""}`),
            m.path ? h("code", {}, m.path) : null,
            h("span", { class: "msg" }, m.message),
          ),
        ),
      ),
    );
    this.root.dataset.errors = String(this.marks.filter((m) => m.severity === "error").length);
  }

  /** Select the offending value (or line) in the text and scroll it into view. */
  jumpTo(m) {
    const where = lineIndex(this.ta.value);
    let start = where.lineStart(m.line);
    let end = this.ta.value.indexOf("\n", start);
    if (end < 0) end = this.ta.value.length;
    if (m.node) [start, end] = [m.node.start, m.node.end];
    else if (m.col) [start, end] = [start + m.col - 1, start + m.col];
    this.ta.focus();
    this.ta.setSelectionRange(start, end);
    this.ta.scrollTop = Math.max(0, (m.line - 1) * LINE_HEIGHT - this.ta.clientHeight / 3);
    this.syncScroll();
  }

  updateGutter() {
    let n = 1;
    const t = this.ta.value;
    for (let i = 0; i < t.length; i++) if (t.charCodeAt(i) === 10) n++;
    if (n !== this.lines) {
      this.lines = n;
      let s = "";
      for (let i = 1; i <= n; i++) s += `${i}\n`;
      this.gutter.textContent = s;
    }
  }

  drawMarks() {
    const flashing = this.flash && performance.now() < this.flash.until;
    if (!this.marks.length && !flashing) {
      if (this.backdrop.firstChild) this.backdrop.replaceChildren();
      if (this.gutterMarks.firstChild) this.gutterMarks.replaceChildren();
      this.syncScroll();
      return;
    }
    const lines = this.ta.value.split("\n");
    const byLine = new Map();
    for (const m of this.marks) {
      if (m.line > lines.length) m.line = lines.length;
      if (!byLine.has(m.line)) byLine.set(m.line, []);
      byLine.get(m.line).push(m);
    }
    const rows = [];
    const gmarks = [];
    const top = (line) => `${PAD + (line - 1) * LINE_HEIGHT}px`;
    if (flashing && !byLine.has(this.flash.line)) {
      rows.push(
        h(
          "div",
          { class: "mark changed", style: `top:${top(this.flash.line)}` },
          h("span", { class: "ghost" }, lines[this.flash.line - 1] || " "),
        ),
      );
    }
    for (const [line, ms] of byLine) {
      const severity = ms.some((m) => m.severity === "error") ? "error" : "warning";
      const text = lines[line - 1] ?? "";
      const col = ms.find((m) => m.col)?.col;
      const parts = col
        ? [
            h("span", { class: "ghost" }, text.slice(0, col - 1)),
            h("span", { class: "ghost squiggle" }, text.slice(col - 1, col) || " "),
            h("span", { class: "ghost" }, text.slice(col)),
          ]
        : [h("span", { class: "ghost" }, text)];
      const message = ms.map((m) => m.message).join(" · ");
      const msg = h("span", { class: "msg" }, `◀ ${message}`);
      this.placeMessage(msg, lines, line);
      rows.push(h("div", { class: `mark ${severity}`, style: `top:${top(line)}`, dataset: { line } }, ...parts, msg));
      gmarks.push(h("div", { class: `gmark ${severity}`, style: `top:${top(line)}`, title: message }, String(line)));
    }
    this.backdrop.replaceChildren(...rows);
    this.gutterMarks.replaceChildren(...gmarks);
    this.syncScroll();
  }

  /** A mark's message wraps inside the visible width, in rows of the code's height, to the right of every line it
   * spans, so it never covers the text; with no room for it there, one row cut with an ellipsis. */
  placeMessage(msg, lines, line) {
    const { code, text } = this.charWidths();
    const width = (l) => (l ?? "").replace(/\t/g, "  ").length;
    const view = this.ta.scrollLeft + this.ta.clientWidth - 2 * PAD_X; // px of text the visible width holds
    const need = (msg.textContent.length + 1) * text; // px of the message on one row
    let left = width(lines[line - 1]) + 2;
    for (let i = 0; i < 8; i++) {
      const rows = Math.ceil(need / Math.max(view - left * code, 1)) + 1; // one row spare: words wrap early
      const next = Math.max(...lines.slice(line - 1, line - 1 + rows).map(width)) + 2;
      if (next === left) break;
      left = next;
    }
    if (view - left * code < MIN_MESSAGE_CHARS * text) {
      left = width(lines[line - 1]) + 2;
      msg.classList.add("clip");
    }
    msg.style.left = `${PAD_X + left * code}px`;
    msg.style.width = `calc(var(--view-right) - ${PAD_X * 2 + left * code}px)`;
  }

  /** The width of a character of the code (monospace) and of a message (on average), in px. */
  charWidths() {
    if (!this.widths) {
      const probe = (cls, s) => {
        const el = h("span", { class: cls, style: "position:absolute;white-space:pre" }, s);
        const row = h("div", { class: "mark", style: "visibility:hidden" }, el);
        this.backdrop.append(row);
        const w = el.getBoundingClientRect().width / s.length;
        row.remove();
        return w;
      };
      const sample = "unknown field 'colour'; did you mean 'kd'? must be a finite number";
      this.widths = { code: probe("", "0".repeat(40)), text: probe("msg", sample) };
      if (!this.widths.code) this.widths = null; // not laid out yet (hidden): measured at the next draw
      return this.widths || { code: 8, text: 6.5 };
    }
    return this.widths;
  }

  syncScroll() {
    const y = this.ta.scrollTop;
    const x = this.ta.scrollLeft;
    this.backdrop.style.transform = `translate(${-x}px, ${-y}px)`;
    this.backdrop.style.setProperty("--view-right", `${x + this.ta.clientWidth}px`); // where a mark's message wraps
    this.gutter.style.transform = `translateY(${-y}px)`;
    this.gutterMarks.style.transform = `translateY(${-y}px)`;
  }

  keydown(e) {
    const key = e.key.toLowerCase();
    if ((e.ctrlKey || e.metaKey) && !e.altKey && (key === "z" || key === "y")) {
      e.preventDefault();
      if (key === "y" || e.shiftKey) this.redo();
      else this.undo();
      return;
    }
    if ((e.ctrlKey || e.metaKey) && e.key === "Enter") {
      e.preventDefault();
      this.onRender();
      return;
    }
    if (e.key === "Enter" && !e.shiftKey && !e.altKey && !e.ctrlKey && !e.metaKey) {
      // keep the indentation of the line (and indent after an opening bracket)
      const t = this.ta.value;
      const pos = this.ta.selectionStart;
      const lineStart = t.lastIndexOf("\n", pos - 1) + 1;
      const indent = /^[ \t]*/.exec(t.slice(lineStart, pos))[0];
      const before = t.slice(lineStart, pos).trimEnd();
      const extra = before.endsWith("{") || before.endsWith("[") ? "  " : "";
      e.preventDefault();
      this.noteTyping(); // execCommand sends no beforeinput
      const insert = `\n${indent}${extra}`;
      if (!document.execCommand?.("insertText", false, insert)) {
        this.ta.setRangeText(insert, pos, this.ta.selectionEnd, "end");
        this.changed();
      }
    }
  }
}
