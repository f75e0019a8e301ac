// Lessons: the comparisons the lecture shows, side by side, one click each. Every panel is an example
// scene with a few fields changed, rendered small through the job API; what changed and what it cost
// (rays by kind, time) are written under it. A lesson's controls (sliders and choices bound to scene
// fields) re-render the panels they touch, a moment after the last change, cancelling the jobs they
// supersede. Each lesson ends with a question that the page checks, with an explanation.
// The lessons' entries (their scenes, changes, texts and questions) are data, one file per topic in lessons/.
import { ApiError, api, blob, showImage } from "./api.js";
import { inspectGroup } from "./inspect.js";
import { followJob } from "./jobs.js";
import { DISTRIBUTED } from "./lessons/distributed.js";
import { INDIRECT } from "./lessons/indirect.js";
import { RAY_TRACING } from "./lessons/raytracing.js";
import { SAMPLING } from "./lessons/sampling.js";
import { SURFACES } from "./lessons/surfaces.js";
import { drawSamples, samplerWords } from "./samplers.js";
import { $, clone, debounce, h, integer, num, seconds, store } from "./util.js";
import { dot, length, normalize, sub } from "./vec.js";

const SIZE = [160, 120]; // the largest lesson image; each keeps its scene's aspect
const SETTLE_MS = 350; // a control's panels re-render this long after its last change
const DONE_KEY = "rt.lessons.done"; // the ids of the lessons whose question was answered right, in localStorage

/** Every lesson, in the lecture's order. An entry: id, title, text; `scene` (an example's name), `set` ({dotted path:
 * value}) and `edit(scene)`, the changes every panel gets; `panels`, each with a `label` (text, or a function of its
 * scene), its own `scene`, `set`, `edit` and `note`; `controls`, each bound to a `path` (or `apply(scene, value)`
 * with a `note(value)`) of the `panels` it names (none: all); a `question` ({prompt, choices, answer, explain}, or
 * `make(context)` giving one); `more`, links to the reference ([text, address]) that explain what the text only
 * names; and what a lesson adds (samples, raysMap, stepper, coc, a panel's reveal and against). */
export const LESSONS = [...RAY_TRACING, ...SAMPLING, ...DISTRIBUTED, ...INDIRECT, ...SURFACES];

/** Set `obj`'s field at a dotted path ("render.max_depth"), making the sections on the way. */
function setPath(obj, dotted, value) {
  const keys = dotted.split(".");
  let o = obj;
  for (const k of keys.slice(0, -1)) {
    if (!o[k] || typeof o[k] !== "object") o[k] = {};
    o = o[k];
  }
  o[keys[keys.length - 1]] = value;
}

/** Does control `c` change panel `i`? (No `panels`: every panel.) */
const touches = (c, i) => !c.panels || c.panels.includes(i);

/** A control's change written as a note: `render.max_depth = 3`. */
function controlNote(c, v) {
  return c.note ? c.note(v) : `${c.path} = ${JSON.stringify(v)}`;
}

/** The rays a job traced, by kind: "12,345 rays: 9,600 eye, 2,745 shadow". */
function rayWords(rays) {
  if (!rays) return "";
  const kinds = Object.entries(rays).filter(([k, n]) => k !== "total" && n > 0);
  return `${integer(rays.total)} rays${kinds.length ? `: ${kinds.map(([k, n]) => `${integer(n)} ${k}`).join(", ")}` : ""}`;
}

/** The pixel [x, y] whose samples panel `panel` draws: its own `samples` (null: none), else the lesson's. */
function samplesPixel(lesson, panel) {
  const spec = lesson.panels[panel.index];
  return spec.samples !== undefined ? spec.samples : lesson.samples;
}

/** The RMS difference of two pictures' pixels (ImageData of one size) over R, G and B, in levels of 255. */
function rmsDifference(a, b) {
  if (a.width !== b.width || a.height !== b.height) return null;
  let sum = 0;
  for (let i = 0; i < a.data.length; i += 4) for (let k = 0; k < 3; k++) sum += (a.data[i + k] - b.data[i + k]) ** 2;
  return Math.sqrt(sum / (a.width * a.height * 3));
}

/** The image of a panel (its picture, or its rays-per-pixel map): made here only, one place for every panel. */
export function panelImage(panel, kind = "picture") {
  const { width, height } = panel.scene.film;
  const alt = kind === "picture" ? `${panel.label}: rendering` : `${panel.label}: rays per pixel`;
  return h("img", { class: kind === "picture" ? "lesson-picture" : "rays-map", alt, width, height });
}

/** The controls' first values of a lesson: {key: value}. */
const firstValues = (lesson) => Object.fromEntries((lesson.controls || []).map((c) => [c.key, c.value]));

/** The scene of panel `index` of `lesson` made from `example` (its example scene, a copy: changed here): the
 * lesson's and the panel's changes and the controls' `values` (in that order), at lesson size; with the notes
 * that say what changed, and its label. */
export function panelScene(lesson, index, values, example) {
  const panel = lesson.panels[index];
  const s = example;
  for (const [k, v] of Object.entries(lesson.set || {})) setPath(s, k, v);
  if (lesson.edit) lesson.edit(s);
  for (const [k, v] of Object.entries(panel.set || {})) setPath(s, k, v);
  const notes = Object.entries(panel.set || {}).map(([key, v]) => `${key} = ${JSON.stringify(v)}`);
  for (const c of lesson.controls || []) {
    if (!touches(c, index)) continue;
    if (c.apply) c.apply(s, values[c.key]);
    else setPath(s, c.path, values[c.key]);
    notes.push(controlNote(c, values[c.key]));
  }
  if (panel.edit) panel.edit(s);
  if (panel.note) notes.push(panel.note);
  const w = s.film?.width ?? 256;
  const hh = s.film?.height ?? 256;
  const k = Math.min(SIZE[0] / w, SIZE[1] / hh);
  s.film = { ...(s.film || {}), width: Math.max(1, Math.round(w * k)), height: Math.max(1, Math.round(hh * k)) };
  const label = typeof panel.label === "function" ? panel.label(s) : panel.label;
  return { scene: s, notes, label };
}

/** Every lesson's panels at the controls' first values, as the page first renders them: [{lesson, index,
 * scene}], each example read by `sceneOf(name)` (a fresh copy each call). The server renders these ahead
 * (server/jobs/lesson_panels.py reads them from server/jobs/lesson_panels.json: `python -m bench.lessons --write-panels`). */
export async function firstPanels(sceneOf) {
  const out = [];
  for (const lesson of LESSONS) {
    for (let i = 0; i < lesson.panels.length; i++) {
      const example = await sceneOf(lesson.panels[i].scene || lesson.scene);
      out.push({ lesson: lesson.id, index: i, scene: panelScene(lesson, i, firstValues(lesson), example).scene });
    }
  }
  return out;
}

export class Lessons {
  /** openInWorkspace(scene, job, label, marks); onChoose(id): a lesson was chosen (the list, the switch, Next). */
  constructor(root, { openInWorkspace, onChoose = () => {} }) {
    this.root = root;
    this.openInWorkspace = openInWorkspace;
    this.onChoose = onChoose;
    this.list = $("#lesson-list", root);
    this.stage = $("#lesson-stage", root);
    this.scenes = new Map();
    this.runs = new Map(); // lesson id -> {values, panels: [...], question}, kept while the page lives
    const known = new Set(LESSONS.map((l) => l.id));
    const kept = store.get(DONE_KEY, []);
    this.done = new Set(Array.isArray(kept) ? kept.filter((id) => known.has(id)) : []); // answered right, on any visit
    this.list.replaceChildren(
      ...LESSONS.map((l) =>
        h(
          "li",
          {},
          h(
            "button",
            { type: "button", class: "lesson-button", dataset: { lesson: l.id }, onclick: () => this.choose(l.id) },
            l.title,
            this.doneMark(l.id),
          ),
        ),
      ),
    );
    this.stage.replaceChildren(h("p", { class: "hint" }, "Choose a comparison: its images render in a few seconds."));
  }

  /** A lesson chosen by the student: it runs, and the page's address follows (main.js). */
  choose(id) {
    this.onChoose(id);
    return this.run(id);
  }

  /** The mark of a lesson done (its question answered right): a tick, and words for a screen reader. */
  doneMark(id) {
    return h(
      "span",
      { class: "lesson-done", hidden: !this.done.has(id), title: "Done: its question answered right" },
      h("span", { "aria-hidden": "true" }, " \u2713"),
      h("span", { class: "sr-only" }, " (done)"),
    );
  }

  markDone(id) {
    if (this.done.has(id)) return;
    this.done.add(id);
    store.set(DONE_KEY, [...this.done]);
    const mark = this.list.querySelector(`[data-lesson="${id}"] .lesson-done`);
    if (mark) mark.hidden = false;
    const option = this.stage.querySelector(`.lesson-switch option[value="${id}"]`);
    if (option) option.textContent = this.optionText(LESSONS.find((l) => l.id === id));
  }

  optionText(l) {
    return `${LESSONS.indexOf(l) + 1}. ${l.title}${this.done.has(l.id) ? " \u2713 (done)" : ""}`;
  }

  /** On a phone the list of lessons is under the lesson: a menu above it switches without scrolling past it. */
  switchElement(lesson) {
    const select = h(
      "select",
      { id: "lesson-switch", "aria-describedby": "lesson-switch-help" },
      ...LESSONS.map((l) => h("option", { value: l.id, selected: l.id === lesson.id }, this.optionText(l))),
    );
    select.addEventListener("change", () => this.choose(select.value));
    return h(
      "div",
      { class: "lesson-switch" },
      h("label", { for: "lesson-switch" }, "Lesson"),
      select,
      h(
        "small",
        { id: "lesson-switch-help", class: "hint" },
        `${LESSONS.indexOf(lesson) + 1} of ${LESSONS.length}; the list is also under the lesson.`,
      ),
    );
  }

  /** The way on: a button to the next lesson (none after the last). */
  nextElement(lesson) {
    const next = LESSONS[LESSONS.indexOf(lesson) + 1];
    if (!next) return h("p", { class: "lesson-next hint" }, "This was the last lesson.");
    return h(
      "div",
      { class: "lesson-next" },
      h(
        "button",
        { type: "button", id: "lesson-next", onclick: () => this.choose(next.id) },
        `Next lesson: ${next.title} \u2192`,
      ),
    );
  }

  async scene(name) {
    if (!this.scenes.has(name)) this.scenes.set(name, await api.scene(name));
    return clone(this.scenes.get(name));
  }

  /** The scene of panel `index` at the controls' `values`, ready to show (see panelScene). */
  async build(lesson, index, values) {
    const panel = lesson.panels[index];
    const example = await this.scene(panel.scene || lesson.scene);
    return {
      ...panelScene(lesson, index, values, example),
      index,
      lesson: lesson.id,
      reveal: panel.reveal,
      status: "new",
    };
  }

  async run(id) {
    const lesson = LESSONS.find((l) => l.id === id);
    for (const b of this.list.querySelectorAll("button"))
      b.setAttribute("aria-current", String(b.dataset.lesson === id));
    this.current = id;
    let run = this.runs.get(id);
    const fresh = !run;
    if (!run) {
      run = { values: firstValues(lesson), panels: [], answered: false };
      run.settle = debounce(() => this.rerender(lesson, run), SETTLE_MS);
      run.dirty = new Set();
      this.runs.set(id, run);
    }
    const grid = h("div", { class: "lesson-panels", dataset: { count: lesson.panels.length } });
    inspectGroup(grid, ".lesson-image img"); // a magnifier over every panel at once, and the full-size view
    const controls = this.controlsElement(lesson, run);
    const extra = h("div", { class: "lesson-extra" });
    const question = h("section", { class: "lesson-question", "aria-label": "Check yourself" });
    const title = h("h2", { tabindex: -1 }, lesson.title, this.doneMark(id));
    this.stage.replaceChildren(
      this.switchElement(lesson),
      title,
      h("p", { class: "lesson-text" }, lesson.text),
      moreElement(lesson),
      controls,
      grid,
      extra,
      question,
      this.nextElement(lesson),
    );
    this.stage.querySelector("h2").focus();
    this.stage.dataset.lesson = id;
    run.extra = extra;
    if (fresh)
      run.built = (async () => {
        for (let i = 0; i < lesson.panels.length; i++) run.panels.push(await this.build(lesson, i, run.values));
      })();
    try {
      await run.built;
    } catch (err) {
      if (this.runs.get(id) === run) this.runs.delete(id);
      grid.replaceChildren(
        h("p", { class: "message", dataset: { kind: "error" } }, `Could not load the lesson's scenes: ${err.message}.`),
      );
      return;
    }
    // left (another lesson chosen, or this one chosen again) while its scenes loaded: its panels are drawn where
    // it is shown now, by that run(), once they are built; this one only starts them. Before, a lesson chosen
    // again before its first run() had built them showed none (or some) of its panels, drawn out of sight.
    if (!grid.isConnected) {
      if (fresh) await this.start(run.panels);
      return;
    }
    for (const panel of run.panels) {
      panel.el = this.panelElement(lesson, run, panel);
      grid.append(panel.el.root);
      this.paint(panel);
    }
    if (lesson.coc)
      extra.append(
        run.cocText ??
          (run.cocText = h(
            "p",
            { class: "coc-text", role: "status" },
            "Click a point of a picture for its circle of confusion (keyboard: focus a picture, the arrow keys move the lens, Space).",
          )),
      );
    this.showQuestion(lesson, run, question);
    if (fresh) await this.start(run.panels);
  }

  /** Submit panels at once (the queue keeps their order), then follow them one by one. */
  async start(panels) {
    await Promise.all(
      panels.map(async (panel) => {
        try {
          panel.job = await api.submit(JSON.stringify(panel.scene));
          panel.status = "queued";
          if (panel.superseded) this.cancel(panel); // a control changed while it was being submitted
        } catch (err) {
          panel.status = "refused";
          panel.error = err instanceof ApiError ? err.errors : [{ path: "", message: err.message }];
        }
        this.paint(panel);
      }),
    );
    for (const panel of panels) if (panel.job && !panel.superseded) await this.follow(panel);
  }

  cancel(panel) {
    panel.following?.close();
    if (panel.job && !panel.job.finished && panel.status !== "done") api.cancel(panel.job.id).catch(() => {}); // it may have ended meanwhile
  }

  /** The lesson's controls: each change marks the panels it touches, which re-render once the changes settle. */
  controlsElement(lesson, run) {
    if (!lesson.controls?.length) return h("div", { class: "lesson-controls", hidden: true });
    return h(
      "form",
      { class: "lesson-controls", "aria-label": "What to change", onsubmit: (e) => e.preventDefault() },
      ...lesson.controls.map((c) => {
        const id = `lc-${lesson.id}-${c.key}`;
        const out = h("output", { for: id }, c.kind === "range" ? num(run.values[c.key]) : "");
        let input;
        if (c.kind === "range") {
          input = h("input", {
            type: "range",
            id,
            min: c.min,
            max: c.max,
            step: c.step,
            value: run.values[c.key],
            dataset: { key: c.key },
          });
          input.addEventListener("input", () => {
            out.textContent = num(Number(input.value));
            this.changed(lesson, run, c, Number(input.value));
          });
        } else {
          const current = JSON.stringify(run.values[c.key]);
          input = h(
            "select",
            { id, dataset: { key: c.key } },
            ...c.choices.map(([v, text]) =>
              h("option", { value: JSON.stringify(v), selected: JSON.stringify(v) === current }, text),
            ),
          );
          input.addEventListener("change", () => this.changed(lesson, run, c, JSON.parse(input.value)));
        }
        return h("div", { class: "lesson-control" }, h("label", { for: id }, c.label), input, out);
      }),
    );
  }

  changed(lesson, run, control, value) {
    run.values[control.key] = value;
    lesson.panels.forEach((_, i) => {
      if (touches(control, i)) run.dirty.add(i);
    });
    run.settle();
  }

  /** Render again the panels the controls changed: their old jobs are cancelled, their pictures stay until the new ones come. */
  async rerender(lesson, run) {
    const indices = [...run.dirty].sort();
    run.dirty.clear();
    const fresh = [];
    for (const i of indices) {
      const old = run.panels[i];
      old.superseded = true;
      this.cancel(old);
      const panel = await this.build(lesson, i, run.values);
      panel.samples = null;
      run.panels[i] = panel;
      if (old.el) {
        panel.el = old.el;
        panel.el.panel = panel;
        panel.el.info.textContent = "";
        this.caption(panel);
        if (panel.el.samples)
          this.drawPixelSamples(panel, samplesPixel(lesson, panel), panel.el.samples.canvas, panel.el.samples.words);
      }
      this.paint(panel);
      fresh.push(panel);
    }
    for (const p of run.panels)
      if (indices.includes(p.index) || indices.includes(lesson.panels[p.index].against)) this.clearError(p);
    await this.start(fresh);
  }

  panelElement(lesson, run, panel) {
    const img = panelImage(panel);
    const state = h("div", { class: "panel-state" });
    const bar = h("progress", { max: 1, value: 0, "aria-label": `${panel.label}: progress` });
    const info = h("p", { class: "panel-info" });
    const title = h("strong", {});
    const notes = h("ul", { class: "panel-notes", "aria-label": "what changed" });
    const el = { img, state, bar, info, title, notes, panel };
    const marks = () => (run.marks || []).filter((m) => m.panel === panel.index); // the question's pixel, if on this one
    const open = h(
      "button",
      {
        type: "button",
        class: "small",
        disabled: true,
        onclick: () => this.openInWorkspace(el.panel.scene, el.panel.job, el.panel.label, marks()),
      },
      "Open in workspace",
    );
    const rays = h(
      "button",
      { type: "button", class: "small", disabled: true, "aria-pressed": "false" },
      "Rays / pixel",
    );
    rays.addEventListener("click", () => {
      const on = rays.getAttribute("aria-pressed") !== "true";
      rays.setAttribute("aria-pressed", String(on));
      const job = el.panel.job;
      showImage(img, on ? api.aovUrl(job.id, "rays") : api.imageUrl(job.id, "png", job.preview));
    });
    const actions = [open, rays];
    if (lesson.stepper) {
      const step = h("button", { type: "button", class: "small", disabled: true }, "Step through the shooting");
      step.addEventListener("click", async () => {
        await this.openInWorkspace(el.panel.scene, el.panel.job, el.panel.label);
        $("#radiosity")?.scrollIntoView({ block: "start" });
      });
      el.step = step;
      actions.push(step);
    }
    let samples = null;
    if (samplesPixel(lesson, panel)) {
      const canvas = h("canvas", {
        class: "samples",
        role: "img",
        "aria-label": `where the ${panel.scene.sampler?.type} sampler puts the rays of one pixel`,
      });
      const words = h("small", {}, "asking the renderer where the samples go…");
      samples = h("div", { class: "samples-box" }, canvas, words);
      el.samples = { canvas, words };
      this.drawPixelSamples(panel, samplesPixel(lesson, panel), canvas, words);
    }
    let map = null;
    if (lesson.raysMap) {
      el.map = panelImage(panel, "rays");
      map = h("div", { class: "lesson-image rays-box", title: "rays per pixel: black few, white many" }, el.map);
    }
    if (lesson.panels[panel.index].against != null) el.error = h("p", { class: "panel-error" });
    // the progress bar lies along the picture's foot: gone when the render ends, it moves nothing under it
    const image = h("div", { class: "lesson-image" }, img, state, bar);
    if (lesson.coc) {
      el.overlay = h("canvas", { class: "lesson-overlay", "aria-hidden": "true" });
      image.append(el.overlay);
      img.addEventListener("click", (e) => this.circleOfConfusion(lesson, run, el.panel, e));
      img.classList.add("clickable");
    }
    el.image = image;
    el.root = h(
      "figure",
      { class: "lesson-panel", dataset: { status: panel.status, index: panel.index } },
      image,
      h("figcaption", {}, title, notes, info, el.error),
      map,
      samples,
      h("div", { class: "panel-actions" }, ...actions),
    );
    Object.assign(el, { open, rays });
    el.panel = panel;
    panel.el = el;
    this.caption(panel);
    this.clearError(panel);
    for (const m of run.marks || []) if (m.panel === panel.index) this.drawMark(panel, m.x, m.y);
    return el;
  }

  /** The panel's label and what changed (a mystery picture's hidden until its question is answered). */
  caption(panel) {
    const el = panel.el;
    const run = this.runs.get(panel.lesson);
    const hidden = panel.reveal && !run?.answered;
    el.title.textContent = panel.reveal && !hidden ? panel.reveal : panel.label;
    el.notes.replaceChildren(...(hidden ? [] : panel.notes.map((n) => h("li", {}, h("code", {}, n))))); // one change a line
    el.notes.hidden = !el.notes.childElementCount;
  }

  /** A panel's error against its reference, not known (yet). */
  clearError(panel) {
    const e = panel.el?.error;
    if (!e) return;
    delete e.dataset.rms;
    delete e.dataset.pair;
    e.textContent = "RMS difference from the reference: once both pictures are done";
  }

  /** Each panel compared with its reference (`against`): the RMS difference of their final pictures, once both
   * jobs have ended (their own PNGs, fetched and decoded here: what an <img> shows may still be a pass). The
   * reference's own noise is in it too (small: it has many more rays). */
  async compare(lesson, run) {
    for (const p of run.panels) {
      const e = p.el?.error;
      const ref = run.panels[lesson.panels[p.index].against];
      if (!e || !ref || p.job?.status !== "done" || ref.job?.status !== "done") continue;
      const pair = `${p.job.image_url} ${ref.job.image_url}`;
      if (e.dataset.pair === pair) continue;
      e.dataset.pair = pair; // a later change of either panel clears it (clearError)
      let rms;
      try {
        rms = rmsDifference(await this.pixels(run, p.job.image_url), await this.pixels(run, ref.job.image_url));
      } catch (err) {
        if (e.dataset.pair === pair) e.textContent = `Could not compare with the reference: ${err.message}.`;
        continue;
      }
      if (e.dataset.pair !== pair || rms == null) continue; // superseded meanwhile
      e.dataset.rms = rms.toFixed(4);
      e.textContent = `RMS difference from the reference: ${rms.toFixed(1)} of 255`;
    }
  }

  /** The pixels (ImageData) of a job's picture at `url`, fetched with the token once per lesson run. */
  pixels(run, url) {
    run.pixels ??= new Map();
    if (!run.pixels.has(url)) {
      const decoded = blob(url)
        .then((b) => createImageBitmap(b))
        .then((bitmap) => {
          const c = document.createElement("canvas");
          c.width = bitmap.width;
          c.height = bitmap.height;
          const ctx = c.getContext("2d", { willReadFrequently: true });
          ctx.drawImage(bitmap, 0, 0);
          return ctx.getImageData(0, 0, c.width, c.height);
        });
      decoded.catch(() => run.pixels.delete(url)); // asked again next time
      run.pixels.set(url, decoded);
    }
    return run.pixels.get(url);
  }

  /** The renderer's own sample positions in pixel [x, y] of the panel's scene (POST /api/samples), drawn. */
  async drawPixelSamples(panel, [x, y], canvas, words) {
    drawSamples(canvas, null);
    try {
      panel.samples ??= await api.samples(JSON.stringify(panel.scene), x, y);
    } catch (err) {
      words.textContent = `Could not ask the server where the samples go: ${err.message}.`;
      return;
    }
    if (panel.superseded) return;
    drawSamples(canvas, panel.samples);
    words.textContent = `pixel (${panel.samples.pixel.join(", ")}): ${samplerWords(panel.samples)}`;
  }

  paint(panel) {
    const el = panel.el;
    if (!el || el.panel !== panel) return;
    el.root.dataset.status = panel.status;
    const job = panel.job;
    if (job) el.root.dataset.job = job.id;
    if (panel.status === "refused") {
      el.state.replaceChildren(
        h(
          "div",
          { class: "refused", role: "note" },
          h("strong", {}, "The server refused this scene:"),
          ...panel.error.map((e) => h("p", {}, e.path ? h("code", {}, e.path) : null, e.path ? ": " : null, e.message)),
        ),
      );
      el.img.hidden = true;
      el.bar.hidden = true;
      return;
    }
    el.img.hidden = false;
    const solving = job?.progress?.phase === "radiosity" && job.progress.solve; // the radiosity solve comes first
    el.bar.value = solving ? job.progress.solve.fraction : (job?.progress?.fraction ?? 0);
    // what the render has cost so far, in the words its end will say (the line is there while it runs: its end
    // changes numbers, not the panel's height)
    if (job?.progress?.rays && panel.status === "running")
      el.info.textContent = `${rayWords(job.progress.rays)} · ${seconds(job.progress.elapsed)}`;
    if (job?.image_url && el.rays.getAttribute("aria-pressed") !== "true") {
      const url = job.image_url;
      showImage(el.img, url).then((ok) => ok && el.img.dataset.src === url && (el.img.dataset.shown = url)); // fetched with the token (once per pass)
      el.img.alt = panel.label;
    }
    const done = panel.status === "done";
    for (const b of [el.open, el.rays, el.step]) if (b) b.disabled = !done;
    if (!done) el.rays.setAttribute("aria-pressed", "false");
    if (done) {
      el.state.replaceChildren();
      const lesson = LESSONS.find((l) => l.id === panel.lesson);
      if (job.status === "done" && lesson.panels.some((p) => p.against != null))
        this.compare(lesson, this.runs.get(panel.lesson)); // its job has ended
      el.info.textContent = `${rayWords(job.rays)} · ${seconds(job.elapsed)}`;
      el.root.dataset.image = job.image_url;
      el.bar.hidden = true;
      if (el.map)
        showImage(el.map, api.aovUrl(job.id, "rays")).then(
          (ok) => ok && (el.map.alt = `${panel.label}: rays per pixel`),
        );
    } else if (job?.finished) {
      el.state.replaceChildren(h("div", { class: "refused" }, `The job ${panel.status}: ${job.error || ""}`));
    } else {
      el.bar.hidden = false;
      el.state.replaceChildren(
        h(
          "span",
          { class: "spinner" },
          panel.status === "new"
            ? "submitting…"
            : panel.status === "queued"
              ? queuedShort(job)
              : solving
                ? "solving radiosity…"
                : "rendering…",
        ),
      );
    }
  }

  /** Follow one panel's job by its event stream until it ends (or a control supersedes it). */
  follow(panel) {
    panel.following = followJob(panel.job.id, {
      onProgress: (p) => {
        panel.status = p.status;
        panel.job.finished = p.phase === "finished"; // the last progress event says so just before `end`
        panel.job.progress = { ...panel.job.progress, ...p };
        this.paint(panel);
      },
      onPreview: (p) => {
        panel.job.image_url = p.url;
        this.paint(panel);
      },
      onEnd: (job) => {
        panel.job = job;
        panel.status = job.status;
        this.paint(panel);
      },
      onLost: () => {
        panel.status = "failed";
        panel.job = { ...panel.job, finished: true, error: "lost the connection to the server" }; // given up here
        this.paint(panel);
      },
    });
    return panel.following.done;
  }

  // -- the question ----------------------------------------------------------------------------------

  async showQuestion(lesson, run, box) {
    if (!lesson.question) return;
    box.replaceChildren(h("h3", {}, "Check yourself"), h("p", { class: "hint" }, "Preparing the question…"));
    if (!run.question) {
      try {
        run.question = lesson.question.make ? await lesson.question.make(this.context(lesson, run)) : lesson.question;
      } catch (err) {
        box.replaceChildren(
          h("h3", {}, "Check yourself"),
          h("p", { class: "message", dataset: { kind: "error" } }, `Could not prepare the question: ${err.message}.`),
        );
        return;
      }
    }
    const q = run.question;
    box.question = q; // the page's tests read the answer here
    const feedback = h("div", { class: "feedback", role: "status", "aria-live": "polite", "aria-atomic": "true" });
    const choices = q.choices.map((text, i) =>
      h(
        "button",
        {
          type: "button",
          class: "choice",
          dataset: { choice: i },
          onclick: () => this.answer(lesson, run, i, choices, feedback, true),
        },
        text,
      ),
    );
    box.replaceChildren(
      h("h3", {}, "Check yourself"),
      h("p", { class: "question" }, q.prompt),
      h("div", { class: "choices", role: "group", "aria-label": "answers" }, ...choices),
      feedback,
    );
    if (run.chosen != null) this.answer(lesson, run, run.chosen, choices, feedback);
  }

  /** An answer chosen (`clicked`: by the student now, not shown again on coming back): right or not, said in the
   * feedback (a live region: a screen reader reads it) and brought into view with the Next button under it. */
  answer(lesson, run, i, buttons, feedback, clicked = false) {
    const q = run.question;
    const right = i === q.answer;
    run.chosen = i;
    buttons.forEach((b, k) => {
      b.setAttribute("aria-pressed", String(k === i));
      b.dataset.verdict = k === i ? (right ? "right" : "wrong") : "";
    });
    feedback.dataset.verdict = right ? "right" : "wrong";
    feedback.replaceChildren(
      right
        ? h("p", {}, h("strong", {}, "Right. "), q.explain)
        : h(
            "p",
            {},
            h("strong", {}, "Not quite. "),
            "Look at the pictures again (change the controls if it helps) and try another answer.",
          ),
    );
    if (right && !run.answered) {
      run.answered = true;
      for (const p of run.panels) if (p.reveal && p.el) this.caption(p);
    }
    if (right) {
      this.markDone(lesson.id);
      const title = this.stage.querySelector("h2 .lesson-done");
      if (title) title.hidden = false;
    }
    if (clicked) {
      this.stage.querySelector(".lesson-next")?.scrollIntoView({ block: "nearest" });
      feedback.scrollIntoView({ block: "nearest" }); // the answer wins where both do not fit
    }
  }

  /** What a question's `make` may use: the example scenes, the lessons' picture size, and marks on the panels. */
  context(_lesson, run) {
    return {
      scene: (name) => this.scene(name),
      size: SIZE,
      panel: (i) => run.panels[i],
      mark: (i, x, y) => {
        run.marks = [...(run.marks || []), { panel: i, x, y }];
        const p = run.panels[i];
        if (p?.el) this.drawMark(p, x, y);
      },
    };
  }

  /** A marker on pixel (x, y) of a panel's picture. */
  drawMark(panel, x, y) {
    const { width, height } = panel.scene.film;
    const mark = h("span", { class: "lesson-mark", title: `pixel (${x}, ${y})`, dataset: { x, y } });
    mark.style.left = `${((x + 0.5) / width) * 100}%`;
    mark.style.top = `${((y + 0.5) / height) * 100}%`;
    panel.el.image.append(mark);
  }

  // -- depth of field: the circle of confusion of a clicked point -----------------------------------

  /** The pixel under a click on a panel's picture (object-fit: contain), or null. */
  pixelAt(panel, e) {
    const { width, height } = panel.scene.film;
    const r = panel.el.img.getBoundingClientRect();
    const k = Math.min(r.width / width, r.height / height);
    const x = Math.floor((e.clientX - r.left - (r.width - width * k) / 2) / k);
    const y = Math.floor((e.clientY - r.top - (r.height - height * k) / 2) / k);
    return x >= 0 && y >= 0 && x < width && y < height ? [x, y] : null;
  }

  async circleOfConfusion(_lesson, run, panel, e) {
    const at = this.pixelAt(panel, e);
    if (!at) return;
    const [x, y] = at;
    const lens = run.panels.find((p) => p.scene.camera.lens_radius > 0) || run.panels[run.panels.length - 1];
    const pinhole = clone(lens.scene);
    pinhole.camera.lens_radius = 0;
    delete pinhole.camera.focus_distance;
    pinhole.sampler = { type: "center" };
    run.cocText.textContent = `Tracing pixel (${x}, ${y})…`;
    // two clicks in a row may answer out of order: only the latest click's circle is drawn and said
    const asked = (run.cocAsked = (run.cocAsked || 0) + 1);
    let tree;
    try {
      tree = await api.raytree(JSON.stringify(pinhole), x, y, 0);
    } catch (err) {
      if (asked === run.cocAsked) run.cocText.textContent = `Could not trace that pixel: ${err.message}.`;
      return;
    }
    if (asked !== run.cocAsked) return;
    const eye = tree.nodes[0];
    if (!eye?.hit) {
      delete run.cocText.dataset.diameter; // no circle: not the last one's diameter under these words
      run.cocText.textContent = `Pixel (${x}, ${y}) sees the background: it has no depth, and no circle of confusion.`;
      run.coc = null;
      for (const p of run.panels) this.drawCoc(p, null);
      return;
    }
    const c = lens.scene.camera;
    const forward = normalize(sub(c.lookat, c.lookfrom));
    const z = eye.t * dot(eye.direction, forward); // the hit's depth along the view direction
    const F = c.focus_distance ?? length(sub(c.lookat, c.lookfrom));
    const hTan = Math.tan(((c.vfov ?? 40) * Math.PI) / 360);
    // the lens's disk, seen from the point through the focal point: radius A |1 - F / z| on the focal plane,
    // whose height 2 F tan(vfov / 2) spans the film's rows
    const diameter = (2 * (c.lens_radius || 0) * Math.abs(1 - F / z) * lens.scene.film.height) / (2 * F * hTan);
    run.coc = { x, y, diameter };
    for (const p of run.panels) this.drawCoc(p, p === lens ? run.coc : { x, y, diameter: 0 });
    run.cocText.dataset.diameter = diameter.toFixed(2);
    run.cocText.textContent = `Pixel (${x}, ${y}) sees the ${eye.hit.object_name} at depth ${num(z)} (along the view); the lens focuses at ${num(F)}. With lens radius ${num(c.lens_radius || 0)} a point there spreads into a disk ${num(diameter)} pixels across on the lens picture (diameter = 2·r·|1 − F/z|·height / (2·F·tan(vfov/2))).`;
  }

  /** Draw a circle of confusion (`coc`: {x, y, diameter} in film pixels; null: none) over a panel's picture. */
  drawCoc(panel, coc) {
    const canvas = panel.el?.overlay;
    if (!canvas) return;
    const box = panel.el.image.getBoundingClientRect();
    const { width, height } = panel.scene.film;
    const dpr = window.devicePixelRatio || 1;
    canvas.width = Math.round(box.width * dpr);
    canvas.height = Math.round(box.height * dpr);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, box.width, box.height);
    canvas.dataset.diameter = coc ? coc.diameter.toFixed(2) : "";
    if (!coc) return;
    const k = Math.min(box.width / width, box.height / height);
    const cx = (box.width - width * k) / 2 + (coc.x + 0.5) * k;
    const cy = (box.height - height * k) / 2 + (coc.y + 0.5) * k;
    ctx.strokeStyle = "#ff7a00";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.arc(cx, cy, Math.max((coc.diameter / 2) * k, 0.5), 0, 2 * Math.PI);
    ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(cx - 5, cy);
    ctx.lineTo(cx + 5, cy);
    ctx.moveTo(cx, cy - 5);
    ctx.lineTo(cx, cy + 5);
    ctx.stroke();
  }
}

/** The lesson's links to the reference (`more`), opened beside the lesson (which keeps its pictures). */
function moreElement(lesson) {
  if (!lesson.more?.length) return h("p", { class: "lesson-more", hidden: true });
  const links = lesson.more.map(([text, href]) => h("a", { href, target: "_blank", rel: "noopener" }, text));
  return h(
    "p",
    { class: "lesson-more" },
    "More in the reference: ",
    ...links.flatMap((a, i) => (i ? [", ", a] : [a])),
    ".",
  );
}

/** A lesson panel's queued job: its place in line (from the server). */
function queuedShort(job) {
  const q = job?.progress?.queue || job?.queue;
  if (!q) return "queued…";
  const wait = q.expected_wait != null && q.expected_wait >= 1 ? `, ~${Math.round(q.expected_wait)} s` : "";
  return q.ahead === 0 ? `queued: next${wait}…` : `queued: #${q.position}${wait}…`;
}
