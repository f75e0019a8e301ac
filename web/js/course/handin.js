// Handing in: a scene (typed or pasted here, opened from a .json file, or taken from the workspace's editor,
// which keeps its text in this browser's localStorage) or an image from the student's own ray tracer (PNG or
// EXR, sent as base64 with its `format`). **Check** shows at once what the policy shows now (no attempt used);
// **Submit** is acknowledged at once (202) and its row appears in "Your submissions". A refusal (the deadline,
// no attempts left, too many this hour, too large) is the server's own message, shown where the button is.
import { ApiError, withScene } from "../api.js";
import { keptText } from "../editor.js";
import { formatJSON, lineIndex, locate, nodeLine, parse } from "../jsonpos.js";
import { $, debounce, h, store } from "../util.js";
import { localTime } from "./brief.js";
import { problemList, testItem } from "./feedback.js";

const MAX_IMAGE = 20 * 1024 * 1024; // bytes: the grader's cap on a file

function base64(buffer) {
  const bytes = new Uint8Array(buffer);
  let bin = "";
  for (let i = 0; i < bytes.length; i += 0x8000) bin += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(bin);
}

export class HandIn {
  /** ctx: {aid, api, starter, onSubmitted(view)}. */
  constructor(root, ctx) {
    this.root = root;
    this.ctx = ctx;
    this.ta = $("#a-scene", root);
    this.note = $("#a-scene-note", root);
    this.status = $("#a-submit-status", root);
    this.result = $("#a-check-result", root);
    this.busy = false;
    this.key = `rt.course.${ctx.aid}.scene`;
    this.image = null; // {name, format, data (base64)}

    const kept = store.get(this.key, null);
    if (typeof kept === "string" && kept.trim()) this.ta.value = kept;
    else if (ctx.starter) this.ta.value = formatJSON(ctx.starter);
    const save = debounce(() => store.set(this.key, this.ta.value), 300);
    this.ta.addEventListener("input", save);
    window.addEventListener("pagehide", () => save.flush());

    for (const radio of root.querySelectorAll("input[name=a-kind]"))
      radio.addEventListener("change", () => this.showKind());
    $("#a-from-workspace", root).addEventListener("click", () => this.fromWorkspace());
    $("#a-open-scene", root).addEventListener("click", () => $("#a-scene-file", root).click());
    $("#a-scene-file", root).addEventListener("change", (e) => this.openFile(e.target));
    const starter = $("#a-from-starter", root);
    starter.hidden = !ctx.starter;
    starter.addEventListener("click", () => this.setText(formatJSON(ctx.starter), "Put the starter scene here."));
    $("#a-image", root).addEventListener("change", (e) => this.pickImage(e.target));
    $("#a-check", root).addEventListener("click", () => this.check());
    $("#a-submit", root).addEventListener("click", () => this.submit());
    this.showKind();
  }

  get kind() {
    return this.root.querySelector("input[name=a-kind]:checked").value;
  }

  showKind() {
    $("#a-scene-box", this.root).hidden = this.kind !== "scene";
    $("#a-image-box", this.root).hidden = this.kind !== "image";
    $("#a-submit", this.root).textContent = this.kind === "scene" ? "Submit this scene" : "Submit this image";
  }

  setText(text, note) {
    this.ta.value = text;
    store.set(this.key, text);
    this.note.textContent = note;
  }

  fromWorkspace() {
    const text = keptText();
    if (!text?.trim()) {
      this.note.textContent =
        "The workspace has no scene in this browser yet: open it (Workspace, above), write your scene, then come back.";
      return;
    }
    const lines = text.split("\n").length;
    this.setText(text, `Took the scene in the workspace's editor (${lines} line${lines > 1 ? "s" : ""}).`);
  }

  async openFile(input) {
    const file = input.files[0];
    input.value = "";
    if (!file) return;
    const opened = (this.opened = (this.opened || 0) + 1); // the latest file opened wins, as in pickImage
    const text = await file.text();
    if (opened === this.opened) this.setText(text, `Opened ${file.name}.`);
  }

  async pickImage(input) {
    const file = input.files[0];
    const note = $("#a-image-note", this.root);
    // a file picked while the last one's bytes are still being read replaces it: the older read, ending after,
    // must not put its image (and its note) back
    const picked = (this.picked = (this.picked || 0) + 1);
    this.image = null;
    if (!file) return (note.textContent = "");
    if (file.size > MAX_IMAGE) {
      note.textContent = `${file.name} is ${(file.size / 1e6).toFixed(1)} MB: at most 20 MB.`;
      return;
    }
    const format = /\.exr$/i.test(file.name) ? "exr" : "png";
    const data = base64(await file.arrayBuffer());
    if (picked !== this.picked) return;
    this.image = { name: file.name, format, data };
    note.textContent = `${file.name}: ${format.toUpperCase()}, ${(file.size / 1024).toFixed(1)} KB.`;
  }

  /** The request's body: the scene's own text spliced in when it parses (numbers as typed, NaN reaching the
   * validator), else the text as a string (the server names the syntax error); the image as base64. */
  body() {
    if (this.kind === "image") {
      if (!this.image) throw new Error("Choose your image file (PNG or EXR) first.");
      return JSON.stringify({ image: this.image.data, format: this.image.format });
    }
    const text = this.ta.value;
    if (!text.trim()) throw new Error("The scene is empty: paste it, open its file, or take the workspace's.");
    try {
      parse(text);
      return withScene(text);
    } catch {
      return JSON.stringify({ scene: text });
    }
  }

  /** Where an error is in the text now: its JSON path's line, or the line a syntax error names. */
  jump() {
    const text = this.ta.value;
    let nodes = null;
    try {
      nodes = parse(text).nodes;
    } catch {
      nodes = null; // a syntax error: its message names the line
    }
    const where = lineIndex(text);
    const place = (e) => {
      const found = nodes && e.path ? locate(nodes, e.path) : null;
      if (found) return { line: nodeLine(where, found.node), start: found.node.start, end: found.node.end };
      const m = /line (\d+)/.exec(e.message);
      if (!m) return null;
      const line = Number(m[1]);
      const start = where.lineStart(line);
      const end = text.indexOf("\n", start);
      return { line, start, end: end < 0 ? text.length : end };
    };
    return {
      lineOf: (e) => place(e)?.line ?? null,
      go: (e) => {
        const p = place(e);
        if (!p) return;
        this.ta.focus();
        this.ta.setSelectionRange(p.start, p.end);
        this.ta.scrollTop = Math.max(0, (p.line - 3) * 19); // 12.5 px text, 1.5 line height (grading.css .grade-json)
      },
    };
  }

  setBusy(on) {
    this.busy = on;
    $("#a-check", this.root).disabled = on;
    $("#a-submit", this.root).disabled = on;
  }

  say(kind, ...content) {
    this.status.dataset.kind = kind;
    this.status.replaceChildren(...content);
  }

  /** Send the hand-in with `call` (the API's check or submit) while saying `doing`: its answer, or null when
   * the hand-in could not be read or the server refused it (said in the status line). */
  async send(call, doing, before = () => {}) {
    if (this.busy) return null;
    let body;
    try {
      body = this.body();
    } catch (err) {
      this.say("error", err.message);
      return null;
    }
    this.setBusy(true);
    this.say("info", doing);
    before();
    try {
      return await call(body);
    } catch (err) {
      this.say("error", refusal(err));
      return null;
    } finally {
      this.setBusy(false);
    }
  }

  async check() {
    const kind = this.kind;
    const res = await this.send(
      (body) => this.ctx.api.check(body),
      "Checking…",
      () => {
        this.result.hidden = true; // the last check's answer goes: it was about another text
        delete this.result.dataset.valid;
        $("#a-check-body", this.root).replaceChildren();
      },
    );
    if (!res) return;
    this.say("", "");
    this.showCheck(res, kind);
  }

  showCheck(res, kind) {
    const parts = [];
    const n = res.errors.length;
    parts.push(
      res.valid
        ? h(
            "p",
            { class: "message", dataset: { kind: "ok" }, id: "a-check-verdict" },
            kind === "scene" ? "The scene is valid." : "The image can be read.",
            " No attempt was used.",
          )
        : h(
            "p",
            { class: "message", dataset: { kind: "error" }, id: "a-check-verdict" },
            kind === "scene" ? `The scene is invalid: ${n} error${n > 1 ? "s" : ""}.` : "The image cannot be graded.",
            " No attempt was used.",
          ),
    );
    if (n)
      parts.push(
        problemList(res.errors, {
          title: "Errors, at their place in the JSON:",
          jump: kind === "scene" ? this.jump() : null,
        }),
      );
    if (res.warnings?.length)
      parts.push(
        problemList(res.warnings, { kind: "warn", title: "Warnings:", jump: kind === "scene" ? this.jump() : null }),
      );
    if (res.tests?.length)
      parts.push(h("ol", { class: "grade-tests a-tests", id: "a-check-tests" }, res.tests.map(testItem)));
    if (res.image_tests?.length)
      parts.push(
        h(
          "p",
          { class: "hint" },
          `The image tests (${res.image_tests.join(", ")}) need a render: they run when you submit.`,
        ),
      );
    $("#a-check-body", this.root).replaceChildren(...parts);
    this.result.hidden = false;
    this.result.dataset.valid = String(res.valid);
    $("#h-check", this.root).focus({ preventScroll: false });
  }

  async submit() {
    const view = await this.send((body) => this.ctx.api.submit(body), "Submitting…");
    if (!view) return;
    this.say(
      "ok",
      `Submitted at ${localTime(view.accepted_at)}${view.late ? " (late)" : ""}. It is graded in turn: its feedback arrives under “Your submissions” as soon as it is ready.`,
    );
    this.ctx.onSubmitted?.(view);
  }
}

/** The server's answer to a refused request, in its own words. */
function refusal(err) {
  if (!(err instanceof ApiError)) return `Something went wrong: ${err.message}`;
  const words = err.errors.map((e) => e.message).join("; ");
  if (err.status === 0) return words;
  if (err.status === 403 || err.status === 429 || err.status === 413) return `Not accepted: ${words}.`;
  if (err.status === 404)
    return "The server does not know this assignment for your link any more (was your link replaced?).";
  return `Not accepted (${err.status}): ${err.message}`;
}
