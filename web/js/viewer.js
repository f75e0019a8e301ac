// The progressive viewer: submit the editor's scene, follow the job's Server-Sent Events (each pass's
// image replaces the last), show samples, elapsed, ETA and rays by kind; cancel; download PNG / EXR;
// the AOVs one click away; "my jobs" (the ids this browser submitted, kept in localStorage with the token
// that owns them: web/js/api.js). Images and downloads are fetched with the token, shown as blob: URLs.
import { ApiError, api, blob, downloadFile } from "./api.js";
import { followJob } from "./jobs.js";
import { RAY_STYLES } from "./rays.js";
import { withDefaults } from "./schema.js";
import { $, h, integer, num, seconds, store } from "./util.js";

const JOBS_KEY = "rt.jobs";
const CURRENT_KEY = "rt.viewer.job";
const MAX_JOBS = 40;

const AOVS = [
  ["image", "Image"],
  ["rays", "Rays / pixel"],
  ["depth", "Depth"],
  ["normal", "Normals"],
  ["albedo", "Albedo"],
  ["variance", "Variance"],
];

/** Why pixels differ in the rays AOV, for the job's sampler ({type, spp}; null when unknown). */
function raysNote(sampler) {
  if (!sampler) return "Eye rays, and the shadow, reflection and transmission rays they spawned.";
  if (sampler.type === "adaptive")
    return "The adaptive sampler spends more eye rays where a pixel's corners and centre disagree: on edges.";
  const eye = sampler.spp === 1 ? "the same single eye ray" : `the same ${integer(sampler.spp)} eye rays`;
  return `The ${sampler.type} sampler gives every pixel ${eye}; the differences are the shadow, reflection and transmission rays they spawned.`;
}

function aovLegend(name, range, sampler = null) {
  const [lo, hi] = range || [0, 0];
  switch (name) {
    case "rays":
      return `Rays traced per pixel (all kinds): black 0 → red → yellow → white ${integer(hi)} (fewest here: ${integer(lo)}). ${raysNote(sampler)}`;
    case "depth":
      return `Distance to the eye ray's first hit: white = near (${num(lo)}) → dark grey = far (${num(hi)}); black = nothing hit.`;
    case "normal":
      return "Shading normal at the eye ray's hit, as colour 0.5 + 0.5 n: x → red, y → green, z → blue.";
    case "albedo":
      return "Albedo (kd after textures) at the eye ray's hit: the colour without any lighting.";
    case "variance":
      return `Variance of the pixel's samples (mean of R, G, B): black 0 → white ${num(hi)}. Noise lives where it is bright.`;
    default:
      return "";
  }
}

export class Viewer {
  constructor({ getScene, onPick, onLoadScene, notify }) {
    this.getScene = getScene; // () -> {text, value} of the editor, or throws an Error to show
    this.onPick = onPick; // (view, x, y) when a pixel is chosen
    this.onLoadScene = onLoadScene; // (scene, name) "edit this job's scene"
    this.notify = notify;
    this.view = null; // {id, job, scene, sceneText, width, height}
    this.following = null; // followJob's handle while the job shown runs
    this.previews = 0;
    this.blobUrl = null;
    this.aov = "image";
    this.cursor = null; // [x, y] of the keyboard cursor / last pick
    this.jobs = new Map(); // id -> job (my jobs)
    this.onJob = null; // (view) when the job shown changes, or ends: the radiosity panel follows it
    this.el = {
      render: $("#btn-render"),
      cancel: $("#btn-cancel"),
      png: $("#dl-png"),
      exr: $("#dl-exr"),
      bar: $("#progress-bar"),
      stats: $("#job-stats"),
      rays: $("#job-rays"),
      message: $("#viewer-message"),
      stage: $("#stage"),
      img: $("#render-img"),
      marker: $("#stage-marker"),
      empty: $("#stage-empty"),
      aovs: $("#aov-buttons"),
      legend: $("#aov-legend"),
      list: $("#job-list"),
      title: $("#viewer-title"),
      near: $("#render-progress"), // the progress where the Render button is
      nearBar: $("#render-progress-bar"),
      nearText: $("#render-progress-text"),
    };
    $("#btn-to-picture").addEventListener("click", () => this.reveal(true));
    // the picture is kept in view while a new render starts (reveal), until the person scrolls or types
    for (const e of ["wheel", "touchstart", "keydown"])
      window.addEventListener(e, () => (this.revealing = false), { passive: true });
    this.el.render.addEventListener("click", () => this.submit());
    this.el.cancel.addEventListener("click", () => this.cancel());
    this.el.share = $("#btn-share");
    this.el.share.addEventListener("click", () => this.share());
    this.el.img.addEventListener("click", (e) => this.click(e));
    this.el.img.addEventListener("keydown", (e) => this.key(e));
    this.el.img.addEventListener("load", () => this.layout());
    this.el.aovs.replaceChildren(
      ...AOVS.map(([name, label]) => {
        const b = h(
          "button",
          {
            type: "button",
            dataset: { aov: name },
            "aria-pressed": name === "image" ? "true" : "false",
            disabled: name !== "image",
          },
          label,
        );
        b.addEventListener("click", () => this.showAov(name));
        return b;
      }),
    );
    for (const a of [this.el.png, this.el.exr]) {
      a.addEventListener("click", (e) => {
        e.preventDefault(); // the link's URL needs the token: fetched, then saved from a blob
        if (a.hasAttribute("href"))
          downloadFile(a.getAttribute("href"), a.getAttribute("download")).catch((err) =>
            this.message("error", `Could not download the image: ${err.message}.`),
          );
      });
    }
    new ResizeObserver(() => this.layout()).observe(this.el.stage);
    this.setDownloads(null);
  }

  // -- submitting and following ---------------------------------------------------------------

  async submit() {
    // Ctrl+Enter in the editor asks too, even while the button is disabled: one submission at a time, not two jobs
    if (this.submitting) return;
    let scene;
    try {
      scene = this.getScene();
    } catch (err) {
      this.message("error", err.message);
      return;
    }
    this.submitting = true;
    this.el.render.disabled = true;
    this.message("info", "Submitting…");
    this.near("info", "submitting…");
    this.revealing = true; // the picture is brought into view now, and kept there while it grows, until the job ends
    this.reveal();
    try {
      const job = await api.submit(scene.text);
      this.remember(job);
      await this.show(job, scene.value, scene.text);
      this.reveal();
    } catch (err) {
      if (err instanceof ApiError && err.status === 422) {
        this.message("error", "The server refused the scene; its errors are marked in the editor.", err.errors);
        this.onRefused?.(err.errors);
      } else this.message("error", `Could not submit the scene: ${err.message}.`);
    } finally {
      this.submitting = false;
      this.el.render.disabled = false;
    }
  }

  /** Show a job (new, or from my list): its latest image, and its events while it runs. */
  async show(job, scene = null, sceneText = null, { shared = false } = {}) {
    this.closeEvents();
    this.view = { id: job.id, job, scene, sceneText, width: job.width, height: job.height, shared };
    if (!shared) store.set(CURRENT_KEY, job.id); // a shared job is not this browser's: not kept for a reload
    this.el.stage.dataset.shared = String(shared);
    this.el.share.disabled = shared;
    $("#share-note").hidden = !shared;
    if (shared)
      $("#share-note").replaceChildren(
        `A shared job, read-only: its image and its ray trees (click a pixel). "Edit" in the editor makes a copy of your own.`,
      );
    this.previews = 0;
    this.runningPreviews = 0;
    this.cursor = null;
    delete this.el.marker.dataset.kind; // a lesson's mark belongs to the job it was made on
    this.el.marker.removeAttribute("title");
    this.aov = "image";
    this.latestImage = null;
    this.el.img.dataset.previews = "0";
    this.el.img.dataset.runningPreviews = "0";
    this.el.stage.dataset.job = job.id;
    this.el.title.textContent = job.name || "untitled scene";
    this.onJob?.(this.view);
    this.update(job);
    this.updateAovButtons(job);
    this.drawMarker();
    const view = this.view;
    if (job.image_url) await this.loadImage(job.image_url);
    else this.clearImage();
    // another job shown while this one's picture loaded (a click in "my jobs" while the reload's restore() was
    // still loading the last one): that job is followed now, and this one's end must not be said over it
    if (this.view !== view) return;
    if (job.finished) this.ended(job, false);
    else this.follow(job.id);
    this.renderList();
  }

  follow(id) {
    this.closeEvents();
    const current = () => (this.view && this.view.id === id ? this.view : null);
    this.following = followJob(id, {
      onProgress: (p) => {
        const job = current()?.job;
        if (!job) return;
        job.status = p.status;
        job.finished = p.phase === "finished"; // the last progress event says so just before `end`
        Object.assign(job.progress, {
          samples_done: p.samples_done,
          samples_total: p.samples_total,
          fraction: p.fraction,
          passes_done: p.passes_done,
          spp_done: p.spp_done,
          spp_total: p.spp_total,
          phase: p.phase,
          solve: p.solve,
        });
        job.elapsed = p.elapsed;
        job.eta = p.eta;
        job.queue = p.queue;
        if (p.rays) job.rays = p.rays;
        this.update(job);
      },
      onPreview: (p) => {
        if (current()) this.loadImage(p.url);
      },
      onEnd: (job) => {
        this.following = null;
        if (current()) this.ended(job, true);
        this.jobs.set(job.id, job);
        this.renderList();
      },
      onDrop: () => this.message("warn", "The connection to the server dropped; reconnecting…"),
      onLost: () => {
        this.following = null;
        this.message("error", "Lost the connection to the server. Is it still running?", null, () => this.reopen(id));
      },
    });
  }

  async reopen(id) {
    try {
      const job = await api.job(id);
      await this.show(job, this.view?.scene, this.view?.sceneText);
    } catch (err) {
      this.message("error", `Still no answer from the server: ${err.message}.`, null, () => this.reopen(id));
    }
  }

  closeEvents() {
    this.following?.close();
    this.following = null;
  }

  async ended(job, live) {
    const view = this.view;
    this.view.job = job;
    if (this.revealing)
      requestAnimationFrame(() => {
        this.reveal();
        this.revealing = false;
      }); // its last layout
    this.update(job);
    if (!job.preview) this.el.empty.textContent = `No image: the job ${job.status} before its first pass.`;
    this.updateAovButtons(job);
    // said at once, with the stage's status (a test or a screen reader reading "done" reads the words that go
    // with it); the last picture follows, and a failure to load it says so over these words
    if (job.status === "failed")
      this.message(
        "error",
        `The job failed: ${job.error || "no reason given"}.`,
        job.errors?.length ? job.errors : null,
      );
    else if (job.status === "cancelled")
      this.message(
        "warn",
        job.preview
          ? `Cancelled after ${job.progress.passes_done} passes; the image of the last full pass is kept.`
          : "Cancelled before its first pass.",
      );
    else if (job.status === "done")
      this.message(
        "ok",
        `Done: ${job.width} × ${job.height}, ${job.progress.spp_done} samples per pixel, ${seconds(job.elapsed)}. Click a pixel to see its ray tree.`,
      );
    if (job.image_url && live) await this.loadImage(job.image_url);
    if (this.view !== view) return; // another job was shown meanwhile: its own view
    if (job.status === "done") this.loadAovRanges(job.id);
    this.view.ended = true;
    this.describe();
    this.onJob?.(this.view);
  }

  async cancel() {
    if (!this.view) return;
    try {
      const job = await api.cancel(this.view.id);
      this.message("info", job.status === "cancelled" ? "Cancelled." : "Stopping the render…");
    } catch (err) {
      this.message("error", `Could not cancel: ${err.message}.`);
    }
  }

  /** A read-only link to the job shown (its share token in the fragment, which is never sent to a server). */
  async share() {
    const v = this.view;
    if (!v || v.shared) return;
    const note = $("#share-note");
    try {
      const { link } = await api.share(v.id);
      const url = new URL(link, location.href).href;
      const field = h("input", {
        type: "text",
        readonly: true,
        value: url,
        class: "share-link",
        "aria-label": "read-only link to this job",
      });
      const copy = h("button", { type: "button", class: "small" }, "Copy");
      copy.addEventListener("click", () => copyText(field, copy));
      note.replaceChildren(
        h("span", {}, "Read-only link (its image and ray trees; no one can cancel or change it): "),
        field,
        copy,
      );
      note.hidden = false;
      field.select();
    } catch (err) {
      this.message("error", `Could not make a link: ${err.message}.`);
    }
  }

  // -- the image --------------------------------------------------------------------------------

  async loadImage(url) {
    const id = this.view.id;
    // passes come every 0.1 s and their pictures may answer out of order: only the latest asked is shown (an
    // older pass answered after the end's picture would stay on screen as the job's last). The image and an AOV
    // are counted apart: a pass arriving while an AOV loads does not cancel the AOV.
    const kind = url.includes("/aov/") ? "aov" : "image";
    this.imageAsked ??= { image: 0, aov: 0 };
    const asked = ++this.imageAsked[kind];
    const latest = () => this.view?.id === id && asked === this.imageAsked[kind];
    let data;
    try {
      data = await blob(url);
    } catch (err) {
      if (latest()) this.message("warn", `Could not load the image: ${err.message}.`);
      return false;
    }
    if (!latest()) return false;
    if (this.aov !== "image" && !url.includes("/aov/")) {
      this.latestImage = data; // keep the AOV on screen; the image comes back with the "Image" button
      return true;
    }
    this.setImageBlob(data, url.includes("/aov/") ? "aov" : "image");
    return true;
  }

  setImageBlob(data, what) {
    const old = this.blobUrl;
    this.blobUrl = URL.createObjectURL(data);
    if (what === "image") this.imageBlobUrl = this.blobUrl;
    const img = this.el.img;
    img.onload = () => {
      // later, not now: a ray tree asked a moment ago may still be loading the old picture into its overlay
      if (old && old !== this.imageBlobUrl) setTimeout(() => URL.revokeObjectURL(old), 10_000);
      if (what === "image") {
        this.previews++;
        img.dataset.previews = String(this.previews);
        if (!this.view.job.finished) {
          this.runningPreviews = (this.runningPreviews || 0) + 1; // images shown while the job still ran
          img.dataset.runningPreviews = String(this.runningPreviews);
        }
      }
      this.el.empty.hidden = true;
      img.hidden = false;
      this.layout();
      if (this.revealing && what === "image") requestAnimationFrame(() => this.reveal()); // taller than the text was
    };
    img.src = this.blobUrl;
    this.describe();
  }

  /** The picture's text alternative: what it is (the scene, its size, its samples, the job's status, the AOV
   * shown) and how to choose a pixel. It changes when the job starts, ends or another AOV is shown, never
   * with each pass (a screen reader would hear every change of a focused picture's name). */
  describe() {
    const v = this.view;
    if (!v) return;
    const job = v.job;
    const p = job.progress || {};
    const spp = job.status === "done" ? (p.spp_done ?? p.spp_total) : p.spp_total;
    const samples = spp ? `, ${spp} sample${spp === 1 ? "" : "s"} per pixel` : "";
    const status = v.ended ? job.status : "rendering, the picture refines as the passes finish"; // ended: the last picture is in
    const aov = this.aov !== "image" ? ` The ${AOVS.find(([n]) => n === this.aov)?.[1] ?? this.aov} AOV.` : "";
    const alt = `Rendered picture of ${job.name || "the scene"}, ${job.width} × ${job.height} pixels${samples}, ${status}.${aov} Click a pixel, or use the arrow keys and Enter, to see its ray tree.`;
    if (this.el.img.alt !== alt) this.el.img.alt = alt;
  }

  clearImage() {
    this.el.img.hidden = true;
    this.el.img.removeAttribute("src");
    this.imageBlobUrl = null;
    this.el.empty.hidden = false;
    this.el.empty.textContent = "Waiting for the first pass…";
    this.drawMarker();
  }

  /** The current image as an <img> (for the ray tree's overlay), or null. */
  image() {
    return this.el.img.hidden || !this.imageBlobUrl ? null : this.imageBlobUrl;
  }

  layout() {
    const v = this.view;
    const img = this.el.img;
    if (!v || img.hidden) return;
    const box = this.el.stage.getBoundingClientRect();
    // the share of the window's height the picture may take (app.css: less where a ray tree shares its column)
    const share = Number.parseFloat(getComputedStyle(this.el.stage).getPropertyValue("--stage-share")) || 0.62;
    const maxH = Math.max(160, Math.min(window.innerHeight * share, 720));
    const scale = Math.min(box.width / v.width, maxH / v.height);
    img.style.width = `${Math.max(1, Math.floor(v.width * scale))}px`;
    img.style.height = `${Math.max(1, Math.floor(v.height * scale))}px`;
    this.drawMarker();
  }

  pixelAt(e) {
    const r = this.el.img.getBoundingClientRect();
    const x = Math.floor(((e.clientX - r.left) / r.width) * this.view.width);
    const y = Math.floor(((e.clientY - r.top) / r.height) * this.view.height);
    return [Math.min(this.view.width - 1, Math.max(0, x)), Math.min(this.view.height - 1, Math.max(0, y))];
  }

  click(e) {
    if (!this.view) return;
    const [x, y] = this.pixelAt(e);
    this.pick(x, y);
  }

  key(e) {
    if (!this.view) return;
    const step = e.shiftKey ? 10 : 1;
    const c = this.cursor || [Math.floor(this.view.width / 2), Math.floor(this.view.height / 2)];
    const moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] };
    if (moves[e.key]) {
      e.preventDefault();
      this.cursor = [
        Math.min(this.view.width - 1, Math.max(0, c[0] + moves[e.key][0])),
        Math.min(this.view.height - 1, Math.max(0, c[1] + moves[e.key][1])),
      ];
      this.drawMarker();
    } else if (e.key === "Enter" || e.key === " ") {
      e.preventDefault();
      this.pick(...c);
    }
  }

  /** Mark pixel (x, y) of the picture shown, as a lesson asks the student to click it: the keyboard's cursor
   * starts there too (Enter on the picture picks it). */
  markPixel(x, y, why) {
    if (!this.view) return;
    this.cursor = [Math.min(this.view.width - 1, x), Math.min(this.view.height - 1, y)];
    this.el.marker.dataset.kind = "lesson";
    this.el.marker.title = why;
    this.drawMarker();
    this.message("info", `${why}: click it on the picture (or press Enter on the picture) to see its ray tree.`);
  }

  pick(x, y) {
    this.cursor = [x, y];
    delete this.el.marker.dataset.kind;
    this.el.marker.removeAttribute("title");
    this.drawMarker();
    this.onPick(this.view, x, y);
  }

  drawMarker() {
    const m = this.el.marker;
    const v = this.view;
    if (!v || !this.cursor || this.el.img.hidden) {
      m.hidden = true;
      return;
    }
    const r = this.el.img.getBoundingClientRect();
    const s = this.el.stage.getBoundingClientRect();
    const px = r.width / v.width;
    const size = Math.max(px, 7);
    m.hidden = false;
    m.style.left = `${r.left - s.left + (this.cursor[0] + 0.5) * px - size / 2}px`;
    m.style.top = `${r.top - s.top + (this.cursor[1] + 0.5) * (r.height / v.height) - size / 2}px`;
    m.style.width = m.style.height = `${size}px`;
  }

  // -- numbers ----------------------------------------------------------------------------------

  update(job) {
    const p = job.progress || {};
    const st = this.el.stats;
    const solving = p.phase === "radiosity" && p.solve; // the radiosity solve runs before the first pass
    const fraction = solving ? p.solve.fraction : p.fraction || 0;
    this.el.bar.value = fraction;
    this.el.bar.textContent = `${Math.round(fraction * 100)}%`;
    this.el.nearBar.value = fraction;
    this.el.nearBar.textContent = `${Math.round(fraction * 100)}%`;
    this.el.stage.dataset.status = job.status;
    const running = !job.finished;
    this.el.cancel.disabled = !running || !!this.view?.shared;
    const row = (k, v) => [h("div", {}, h("dt", {}, k), h("dd", {}, v))];
    st.replaceChildren(
      ...row("status", job.status),
      ...row(
        "samples",
        `${integer(p.samples_done)} / ${integer(p.samples_total)} (${Math.round((p.fraction || 0) * 100)}%)`,
      ),
      ...row("passes", `${p.passes_done ?? 0} · ${p.spp_done ?? 0} of ${p.spp_total ?? "?"} spp`),
      ...(p.solve
        ? row(
            "radiosity",
            `${integer(p.solve.shots)} shots · ${integer(p.solve.patches)} patch sides · ${seconds(p.solve.seconds)}`,
          )
        : []),
      ...row("elapsed", seconds(job.elapsed)),
      ...row("ETA", running ? seconds(job.eta) : "–"),
    );
    const rays = job.rays || {};
    const chip = (kind) =>
      h("span", { class: "chip", style: `--c:${RAY_STYLES[kind].colour}` }, `${kind} ${integer(rays[kind] ?? 0)}`);
    const solveChip = rays.radiosity
      ? [
          h(
            "span",
            { class: "chip", style: "--c:#c792ea", title: "form-factor rays of the radiosity solve" },
            `radiosity ${integer(rays.radiosity)}`,
          ),
        ]
      : [];
    this.el.rays.replaceChildren(
      h("span", { class: "label" }, "rays:"),
      chip("eye"),
      chip("shadow"),
      chip("reflection"),
      chip("transmission"),
      ...solveChip,
      h("span", {}, `total ${integer(rays.total ?? 0)}`),
    );
    this.setDownloads(job);
    if (this.revealing) requestAnimationFrame(() => this.reveal()); // the rows above the stage grew: still in view
    const pct = `${Math.round(fraction * 100)}%`;
    if (running)
      this.near("info", job.status === "queued" ? "queued…" : solving ? `radiosity ${pct}` : `${pct} rendered`);
    else if (job.status === "done") this.near("ok", `done in ${seconds(job.elapsed)}`);
    else this.near(job.status === "failed" ? "error" : "warn", job.status);
    if (running && solving)
      this.message(
        "info",
        `Solving radiosity before the first pass: ${Math.round(fraction * 100)}% · ${integer(p.solve.shots)} shots · ${(100 * p.solve.unshot).toFixed(2)}% of the power still unshot…`,
      );
    else if (running)
      this.message(
        "info",
        job.status === "queued"
          ? queuedText(job)
          : `Rendering pass ${(p.passes_done ?? 0) + 1}: ${Math.round(fraction * 100)}% of the samples…`,
      );
    if (this.jobs.has(job.id)) {
      this.jobs.set(job.id, job);
    }
  }

  setDownloads(job) {
    for (const [a, fmt] of [
      [this.el.png, "png"],
      [this.el.exr, "exr"],
    ]) {
      if (job?.preview) {
        a.href = api.imageUrl(job.id, fmt);
        a.setAttribute("download", `${(job.name || "render").replace(/[^A-Za-z0-9_-]+/g, "_").slice(0, 40)}.${fmt}`);
        a.removeAttribute("aria-disabled");
        a.removeAttribute("tabindex");
      } else {
        a.removeAttribute("href");
        a.setAttribute("aria-disabled", "true");
      }
    }
  }

  /** Bring the picture into view after Render (on a phone it is a screen or more below the button): the whole
   * stage, with the button still on screen when both fit (`force`: the stage's top, whatever the button). */
  reveal(force = false) {
    const stage = this.el.stage.getBoundingClientRect();
    const button = this.el.render.getBoundingClientRect();
    const room = window.innerHeight;
    if (!force && stage.top >= 0 && stage.bottom <= room) return; // already in view
    if (!force && stage.bottom - button.top + 24 <= room)
      window.scrollBy({ top: stage.bottom - room + 16, behavior: "instant" });
    else this.el.stage.scrollIntoView({ block: "start", behavior: "instant" });
  }

  /** The render's state beside the Render button, in a few words (a problem in full: it is why nothing renders). */
  near(kind, text) {
    this.el.near.hidden = false;
    this.el.near.dataset.kind = kind;
    this.el.nearText.textContent = text;
  }

  message(kind, text, errors = null, retry = null) {
    if (kind === "error" || kind === "warn") this.near(kind, text); // and beside the Render button
    const m = this.el.message;
    m.dataset.kind = kind;
    const parts = [h("span", {}, text)];
    if (errors)
      parts.push(
        h(
          "ul",
          {},
          errors.map((e) => h("li", {}, e.path ? h("code", {}, e.path) : null, e.path ? " " : null, e.message)),
        ),
      );
    if (retry) parts.push(h("button", { type: "button", onclick: retry }, "Try again"));
    m.replaceChildren(...parts);
  }

  // -- AOVs -------------------------------------------------------------------------------------

  updateAovButtons(job) {
    for (const b of this.el.aovs.querySelectorAll("button")) {
      const name = b.dataset.aov;
      b.disabled = name !== "image" && job.status !== "done";
      b.setAttribute("aria-pressed", String(name === this.aov));
      b.title = b.disabled ? "AOVs are saved when the job is done" : "";
    }
    if (this.aov === "image")
      this.el.legend.textContent =
        job.status === "done" ? "The AOVs (arbitrary output variables) show what the renderer saw at each pixel." : "";
  }

  async loadAovRanges(id) {
    try {
      const { ranges } = await api.aovs(id);
      if (this.view && this.view.id === id) this.view.aovRanges = ranges;
    } catch {
      // the legend then shows no numbers
    }
  }

  async showAov(name) {
    if (!this.view) return;
    this.aov = name;
    this.updateAovButtons(this.view.job);
    if (name === "image") {
      if (this.latestImage) {
        this.setImageBlob(this.latestImage, "image");
        this.latestImage = null;
      } else if (this.imageBlobUrl) {
        this.el.img.src = this.imageBlobUrl;
        this.blobUrl = this.imageBlobUrl;
      }
      this.el.legend.textContent = "";
      return;
    }
    const view = this.view;
    const ok = await this.loadImage(api.aovUrl(view.id, name));
    let sampler = null; // the rays legend names the job's own sampler
    if (ok && name === "rays") {
      try {
        const given = withDefaults("sampler", (await this.sceneOf(view)).scene.sampler);
        sampler = { type: given.type, spp: view.job.progress?.spp_total ?? given.spp };
      } catch {
        // the legend then names no sampler
      }
    }
    if (ok && this.view === view && this.aov === name)
      this.el.legend.textContent = aovLegend(name, view.aovRanges?.[name], sampler);
  }

  // -- my jobs ----------------------------------------------------------------------------------

  remember(job) {
    const ids = [job.id, ...store.get(JOBS_KEY, []).filter((x) => x !== job.id)].slice(0, MAX_JOBS);
    store.set(JOBS_KEY, ids);
    this.jobs = new Map([[job.id, job], ...this.jobs]);
    this.renderList();
  }

  /** Load my jobs from the server (and the one shown before the reload). */
  async restore({ show = true } = {}) {
    const ids = store.get(JOBS_KEY, []);
    const found = await Promise.all(
      ids.map((id) =>
        api.job(id).then(
          (job) => job,
          (err) => (err.status === 404 ? null : { id, missing: err.message }),
        ),
      ),
    );
    const jobs = found.filter(Boolean);
    store.set(
      JOBS_KEY,
      jobs.map((j) => j.id),
    );
    this.jobs = new Map(jobs.filter((j) => !j.missing).map((j) => [j.id, j]));
    this.renderList();
    const current = store.get(CURRENT_KEY, null);
    if (show && current && this.jobs.has(current)) await this.show(this.jobs.get(current));
  }

  async open(id) {
    try {
      const job = await api.job(id);
      this.jobs.set(id, job);
      await this.show(job);
    } catch (err) {
      this.message("error", `Could not open the job: ${err.message}.`);
    }
  }

  forget(id) {
    store.set(
      JOBS_KEY,
      store.get(JOBS_KEY, []).filter((x) => x !== id),
    );
    this.jobs.delete(id);
    this.renderList();
  }

  /** The scene a job rendered (for its ray tree): kept from the submission, else asked of the server. */
  async sceneOf(view) {
    if (!view.scene) {
      view.scene = await api.jobScene(view.id);
      view.sceneText = JSON.stringify(view.scene);
    }
    return view;
  }

  /** A job's image for the list, as a blob: URL fetched once per pass shown (null if it cannot be had). */
  thumbnail(job) {
    this.thumbs ??= new Map(); // id -> {url, made: Promise of the blob: URL}
    const had = this.thumbs.get(job.id);
    if (had && had.url === job.image_url) return had.made;
    if (had) had.made.then((u) => u && URL.revokeObjectURL(u));
    const made = blob(job.image_url).then(
      (data) => URL.createObjectURL(data),
      () => null,
    );
    this.thumbs.set(job.id, { url: job.image_url, made });
    return made;
  }

  renderList() {
    const list = this.el.list;
    const items = [...this.jobs.values()];
    if (!items.length) {
      list.replaceChildren(h("li", { class: "empty" }, "Jobs you submit from this browser appear here."));
      return;
    }
    list.replaceChildren(
      ...items.map((job) => {
        const when = job.created_at
          ? new Date(job.created_at).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" })
          : "";
        const thumb = job.image_url
          ? h("img", { alt: "", width: 64, height: Math.round((64 * job.height) / job.width) })
          : h("span", { class: "thumb-empty" }, "no image");
        if (job.image_url) this.thumbnail(job).then((url) => url && (thumb.src = url));
        return h(
          "li",
          { class: this.view && this.view.id === job.id ? "current" : "", dataset: { status: job.status, id: job.id } },
          h(
            "button",
            { type: "button", class: "job-open", onclick: () => this.open(job.id) }, // named by its text: the job's name, status and size (WCAG 2.5.3)
            thumb,
            h(
              "span",
              { class: "job-text" },
              h("strong", {}, job.name || "untitled"),
              h(
                "span",
                {},
                `${job.status} · ${job.width}×${job.height} · ${job.progress?.spp_total ?? "?"} spp · ${when}`,
              ),
            ),
          ),
          h(
            "span",
            { class: "job-actions" },
            h(
              "button",
              {
                type: "button",
                class: "small",
                title: "Load this job's scene into the editor",
                "aria-label": `Edit the scene of ${job.name || "this job"}`,
                onclick: () => this.loadSceneOf(job),
              },
              "Edit",
            ),
            h(
              "button",
              {
                type: "button",
                class: "small",
                "aria-label": `Remove ${job.name || "job"} from my list`,
                title: "Remove from my list",
                onclick: () => this.forget(job.id),
              },
              "×",
            ),
          ),
        );
      }),
    );
  }

  async loadSceneOf(job) {
    try {
      const scene = await api.jobScene(job.id);
      this.onLoadScene(scene, job.name || "job");
    } catch (err) {
      this.message("error", `Could not load the job's scene: ${err.message}.`);
    }
  }
}

/** What a queued job waits for: its place in its lane and the expected wait (from the server). */
export function queuedText(job) {
  const q = job.queue;
  if (!q) return "Queued: waiting for the render worker…";
  if (!q.workers) return `Queued in the ${q.lane} lane, but no worker takes ${q.lane} jobs right now.`;
  const place = q.ahead === 0 ? "next in line" : `${ordinal(q.position)} in line (${q.ahead} ahead)`;
  const wait =
    q.expected_wait == null
      ? ""
      : q.expected_wait < 1
        ? ", starting in a moment"
        : `, about ${seconds(q.expected_wait)} to wait`;
  const lane = q.lane === "batch" ? " (batch lane: interactive work goes first)" : "";
  return `Queued: ${place}${wait}${lane}…`;
}

function ordinal(n) {
  const s = n % 100 >= 11 && n % 100 <= 13 ? "th" : { 1: "st", 2: "nd", 3: "rd" }[n % 10] || "th";
  return `${n}${s}`;
}

/** Copy a text field's value (the clipboard API where the page may use it, else the selection). */
export function copyText(field, button) {
  field.select();
  const done = () => (button.textContent = "Copied");
  if (navigator.clipboard && window.isSecureContext) navigator.clipboard.writeText(field.value).then(done, () => {});
  else if (document.execCommand?.("copy")) done();
}
