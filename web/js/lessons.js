// Lessons: the comparisons the lecture shows, side by side, one click each. Every panel is an example
// scene with a few fields changed, rendered small through the job API; what changed is written under it.
import { ApiError, api, showImage } from "./api.js";
import { inspectGroup } from "./inspect.js";
import { followJob } from "./jobs.js";
import { drawSamples, samplerWords } from "./samplers.js";
import { $, clone, h, integer, seconds } from "./util.js";

const SIZE = [160, 120]; // the largest lesson image; each keeps its scene's aspect

export const LESSONS = [
  {
    id: "bounces",
    title: "Ray casting vs 2 vs 3 bounces",
    scene: "whitted",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "max_depth counts bounces of light on the way to the eye. With 1 (ray casting) the mirror and the glass show only their own Phong shading; with 2 the mirror reflects the scene but the glass ball is dark inside, because the transmitted ray is cut before it can leave the ball; with 3 the refracted floor appears through the glass.",
    panels: [
      { label: "ray casting (1 bounce)", set: { "render.max_depth": 1 } },
      { label: "ray tracing, 2 bounces", set: { "render.max_depth": 2 } },
      { label: "ray tracing, 3 bounces", set: { "render.max_depth": 3 } },
    ],
  },
  {
    id: "sampling",
    title: "One ray per pixel vs supersampling vs adaptive vs jittered",
    samples: [44, 37], // the pixel whose samples are drawn (at 160 x 120): the ball's edge against the sky crosses it
    text: "The same scene sampled four ways; under each, where the sampler puts its rays inside one pixel. One ray per pixel gives jaggies, broken thin poles and moiré near the horizon. A regular grid smooths edges but the moiré only moves. Adaptive supersampling starts from the corners and the centre and splits only cells whose colours differ (here across an edge). Jittered sampling (one random point per cell) turns the moiré into noise.",
    panels: [
      { label: "one ray per pixel (center)", scene: "antialias_center" },
      { label: "supersampling: 4 × 4 grid", scene: "antialias_grid" },
      { label: "adaptive supersampling", scene: "antialias_adaptive" },
      { label: "stochastic: jittered 4 × 4", scene: "antialias_jittered" },
    ],
  },
  {
    id: "shadows",
    title: "Hard vs soft shadows",
    set: { "sampler.type": "jittered", "sampler.spp": 4 },
    text: "A point light casts hard shadows: a point is lit or not. An area light is sampled with light_samples shadow rays per shading point: the fraction that reaches the light makes the penumbra. With 1 shadow ray the penumbra is noise; with 16 it is smooth (and the render costs more shadow rays).",
    panels: [
      { label: "point light: hard shadows", scene: "cornell" },
      { label: "area light, 1 shadow ray", scene: "cornell_whitted_area", set: { "render.light_samples": 1 } },
      { label: "area light, 16 shadow rays", scene: "cornell_whitted_area", set: { "render.light_samples": 16 } },
    ],
  },
  {
    id: "dof",
    title: "Pinhole vs depth of field",
    scene: "depth_of_field",
    text: "A pinhole camera sends every eye ray through one point: everything is sharp. A thin lens starts eye rays at random points of the lens, all through the point where the pinhole ray meets the focal plane: objects on that plane stay sharp, the others blur in proportion to their distance from it.",
    panels: [
      { label: "pinhole", set: { "camera.lens_radius": 0 } },
      { label: (s) => `thin lens, radius ${s.camera.lens_radius}, focused at ${s.camera.focus_distance ?? "lookat"}`, set: {} },
    ],
  },
  {
    id: "motion",
    title: "Still vs motion blur",
    scene: "motion_blur",
    text: "Each eye ray gets its own time while the shutter is open, and moving objects are where they are at that time: averaging the samples blurs them along their motion. The still version is the same scene with every velocity removed.",
    panels: [
      { label: "still (velocities removed)", edit: (s) => (s.objects || []).forEach((o) => delete o.velocity), note: "objects[*].velocity removed" },
      { label: (s) => `moving, shutter open ${(s.camera.shutter || [0, 1]).join(" → ")}`, set: {} },
    ],
  },
  {
    id: "integrators",
    title: "Whitted vs path tracing vs radiosity",
    scene: "cornell_path",
    set: { "sampler.spp": 16 },
    text: "The same Cornell box and ceiling light. Whitted's ray tree follows only mirror and refraction rays: soft shadows from the area light, but light does not bounce between walls. The path tracer samples diffuse bounces too: red and green bleed onto the white blocks and the ceiling is lit. Radiosity solves diffuse interreflection between the diffuse surfaces first (patches and form factors), then traces the ray tree for direct light and mirrors.",
    panels: [
      { label: "Whitted ray tracing", set: { "render.integrator": "whitted" } },
      { label: "path tracing", set: { "render.integrator": "path" } },
      { label: "radiosity", set: { "render.integrator": "radiosity" } },
    ],
  },
];

function setPath(obj, dotted, value) {
  const keys = dotted.split(".");
  let o = obj;
  for (const k of keys.slice(0, -1)) {
    if (!o[k] || typeof o[k] !== "object") o[k] = {};
    o = o[k];
  }
  o[keys[keys.length - 1]] = value;
}

export class Lessons {
  constructor(root, { openInWorkspace }) {
    this.root = root;
    this.openInWorkspace = openInWorkspace;
    this.list = $("#lesson-list", root);
    this.stage = $("#lesson-stage", root);
    this.scenes = new Map();
    this.runs = new Map(); // lesson id -> {panels: [...]}, kept while the page lives
    this.list.replaceChildren(
      ...LESSONS.map((l) =>
        h("li", {}, h("button", { type: "button", class: "lesson-button", dataset: { lesson: l.id }, onclick: () => this.run(l.id) }, l.title)),
      ),
    );
    this.stage.replaceChildren(h("p", { class: "hint" }, "Choose a comparison: its images render in a few seconds."));
  }

  async scene(name) {
    if (!this.scenes.has(name)) this.scenes.set(name, await api.scene(name));
    return clone(this.scenes.get(name));
  }

  /** The scene of one panel: its example, the lesson's and the panel's changes, at lesson size. */
  async build(lesson, panel) {
    const s = await this.scene(panel.scene || lesson.scene);
    const changes = { ...(lesson.set || {}), ...(panel.set || {}) };
    for (const [k, v] of Object.entries(changes)) setPath(s, k, v);
    if (panel.edit) panel.edit(s);
    const w = s.film?.width ?? 256;
    const hh = s.film?.height ?? 256;
    const k = Math.min(SIZE[0] / w, SIZE[1] / hh);
    s.film = { ...(s.film || {}), width: Math.max(1, Math.round(w * k)), height: Math.max(1, Math.round(hh * k)) };
    const notes = Object.entries(panel.set || {}).map(([key, v]) => `${key} = ${JSON.stringify(v)}`);
    if (panel.note) notes.push(panel.note);
    return { scene: s, notes, label: typeof panel.label === "function" ? panel.label(s) : panel.label };
  }

  async run(id) {
    const lesson = LESSONS.find((l) => l.id === id);
    for (const b of this.list.querySelectorAll("button")) b.setAttribute("aria-current", String(b.dataset.lesson === id));
    this.current = id;
    const grid = h("div", { class: "lesson-panels", dataset: { count: lesson.panels.length } });
    inspectGroup(grid, ".lesson-image img"); // a magnifier over every panel at once, and the full-size view
    this.stage.replaceChildren(h("h2", { tabindex: -1 }, lesson.title), h("p", { class: "lesson-text" }, lesson.text), grid);
    this.stage.querySelector("h2").focus();
    this.stage.dataset.lesson = id;
    let run = this.runs.get(id);
    const fresh = !run;
    if (!run) {
      run = { panels: [] };
      this.runs.set(id, run);
      try {
        for (const p of lesson.panels) run.panels.push({ ...(await this.build(lesson, p)), status: "new" });
      } catch (err) {
        this.runs.delete(id);
        grid.replaceChildren(h("p", { class: "message", dataset: { kind: "error" } }, `Could not load the lesson's scenes: ${err.message}.`));
        return;
      }
    }
    for (const panel of run.panels) {
      panel.el = this.panelElement(lesson, panel);
      grid.append(panel.el.root);
      this.paint(panel);
    }
    if (!fresh) return;
    // submit every panel at once (the queue keeps their order), then follow them one by one
    await Promise.all(
      run.panels.map(async (panel) => {
        try {
          panel.job = await api.submit(JSON.stringify(panel.scene));
          panel.status = "queued";
        } catch (err) {
          panel.status = "refused";
          panel.error = err instanceof ApiError ? err.errors : [{ path: "", message: err.message }];
        }
        this.paint(panel);
      }),
    );
    for (const panel of run.panels) if (panel.job) await this.follow(panel);
  }

  panelElement(lesson, panel) {
    const img = h("img", { alt: `${panel.label}: rendering`, width: panel.scene.film.width, height: panel.scene.film.height });
    const state = h("div", { class: "panel-state" });
    const bar = h("progress", { max: 1, value: 0, "aria-label": `${panel.label}: progress` });
    const info = h("p", { class: "panel-info" });
    const open = h("button", { type: "button", class: "small", disabled: true, onclick: () => this.openInWorkspace(panel.scene, panel.job, panel.label) }, "Open in workspace");
    const rays = h("button", { type: "button", class: "small", disabled: true, "aria-pressed": "false" }, "Rays / pixel");
    rays.addEventListener("click", () => {
      const on = rays.getAttribute("aria-pressed") !== "true";
      rays.setAttribute("aria-pressed", String(on));
      showImage(img, on ? api.aovUrl(panel.job.id, "rays") : api.imageUrl(panel.job.id, "png", panel.job.preview));
    });
    let samples = null;
    if (lesson.samples) {
      const canvas = h("canvas", { class: "samples", role: "img", "aria-label": `where the ${panel.scene.sampler?.type} sampler puts the rays of one pixel` });
      const words = h("small", {}, "asking the renderer where the samples go…");
      samples = h("div", { class: "samples-box" }, canvas, words);
      this.drawPixelSamples(panel, lesson.samples, canvas, words);
    }
    const root = h(
      "figure",
      { class: "lesson-panel", dataset: { status: panel.status } },
      h("div", { class: "lesson-image" }, img, state),
      bar,
      h("figcaption", {}, h("strong", {}, panel.label), panel.notes.length ? h("code", {}, panel.notes.join(", ")) : null, info),
      samples,
      h("div", { class: "panel-actions" }, open, rays),
    );
    return { root, img, state, bar, info, open, rays };
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
    drawSamples(canvas, panel.samples);
    words.textContent = `pixel (${panel.samples.pixel.join(", ")}): ${samplerWords(panel.samples)}`;
  }

  paint(panel) {
    const el = panel.el;
    if (!el) return;
    el.root.dataset.status = panel.status;
    const job = panel.job;
    if (panel.status === "refused") {
      el.state.replaceChildren(h("div", { class: "refused", role: "note" }, h("strong", {}, "The server refused this scene:"), ...panel.error.map((e) => h("p", {}, e.path ? h("code", {}, e.path) : null, e.path ? ": " : null, e.message))));
      el.img.hidden = true;
      el.bar.hidden = true;
      return;
    }
    const solving = job?.progress?.phase === "radiosity" && job.progress.solve; // the radiosity solve comes first
    el.bar.value = solving ? job.progress.solve.fraction : job?.progress?.fraction ?? 0;
    if (job && job.image_url && !el.rays.getAttribute("aria-pressed").includes("true")) {
      showImage(el.img, job.image_url); // fetched with the token (once per pass)
      el.img.alt = panel.label;
    }
    if (panel.status === "done") {
      el.state.replaceChildren();
      el.info.textContent = `${integer(job.rays?.total)} rays · ${seconds(job.elapsed)}`;
      el.open.disabled = false;
      el.rays.disabled = false;
      el.bar.hidden = true;
    } else if (job?.finished) {
      el.state.replaceChildren(h("div", { class: "refused" }, `The job ${panel.status}: ${job.error || ""}`));
    } else el.state.replaceChildren(h("span", { class: "spinner" }, panel.status === "new" ? "submitting…" : panel.status === "queued" ? queuedShort(job) : solving ? "solving radiosity…" : "rendering…"));
  }

  /** Follow one panel's job by its event stream until it ends. */
  follow(panel) {
    return followJob(panel.job.id, {
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
    }).done;
  }
}

/** A lesson panel's queued job: its place in line (from the server). */
function queuedShort(job) {
  const q = job?.progress?.queue || job?.queue;
  if (!q) return "queued…";
  const wait = q.expected_wait != null && q.expected_wait >= 1 ? `, ~${Math.round(q.expected_wait)} s` : "";
  return q.ahead === 0 ? `queued: next${wait}…` : `queued: #${q.position}${wait}…`;
}
