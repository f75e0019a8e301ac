// The solution of a finished radiosity job (GET /api/jobs/{id}/radiosity), made visible: the patch mesh
// through the scene's camera, each patch filled with its radiosity after a chosen number of shots of
// progressive refinement, the patch that shoots at that step outlined; the convergence curve (the unshot
// power after each shot, on a log scale) and the energy balance of the final solution.
import { api } from "./api.js";
import { $, fitCanvas, h, num } from "./util.js";
import {
  add,
  cameraBasis,
  clipNear,
  cross,
  dot,
  length,
  mul,
  normalize,
  projectToFilm,
  sub,
  tangents,
  triple,
} from "./vec.js";

const SHOOTER = "#ff9f1c"; // the patch that shoots: the eye rays' orange, the page's focus colour
const LIGHT = "#ffd23f";
const CURVE = "#44a8ff";
const AXIS = "#8a96a6";

/** B (W/m^2) of a diffuse patch as a CSS colour: B / pi is its radiance, clamped to [0, 1], gamma 1/2.2. */
export function toneMap(b) {
  const c = (b || [0, 0, 0]).map((x) =>
    Math.round(255 * Math.min(1, Math.max(0, (Number.isFinite(x) ? x : 0) / Math.PI)) ** (1 / 2.2)),
  );
  return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
}

const sum3 = (v) => (v ? v[0] + v[1] + v[2] : 0);

/** The polygon p (world points) cut to the half-space in front of the camera (clipNear on each edge). */
function clipPolygon(pts, b, near) {
  const out = [];
  const same = (a, z) => a && a[0] === z[0] && a[1] === z[1] && a[2] === z[2];
  for (let i = 0; i < pts.length; i++) {
    const seg = clipNear(pts[i], pts[(i + 1) % pts.length], b.from, b.forward, near);
    if (!seg) continue;
    if (!same(out[out.length - 1], seg[0])) out.push(seg[0]);
    out.push(seg[1]);
  }
  if (out.length > 1 && same(out[0], out[out.length - 1])) out.pop();
  return out.length >= 3 ? out : null;
}

/** Where the ray o + t d meets a patch (parallelogram or triangle), or Infinity. */
function hitPatch(p, o, d) {
  const n = p.normal;
  const dn = dot(n, d);
  if (Math.abs(dn) < 1e-12) return Infinity;
  const t = dot(n, sub(p.corner, o)) / dn;
  if (!(t > 0)) return Infinity;
  const w = sub(add(o, mul(d, t)), p.corner);
  const den = dot(cross(p.e1, p.e2), n);
  const u = dot(cross(w, p.e2), n) / den;
  const v = dot(cross(p.e1, w), n) / den;
  const inside = p.triangle ? u >= 0 && v >= 0 && u + v <= 1 : u >= 0 && v >= 0 && u <= 1 && v <= 1;
  return inside ? t : Infinity;
}

function insidePolygon(x, y, pts) {
  let inside = false;
  for (let i = 0, j = pts.length - 1; i < pts.length; j = i++) {
    const [xi, yi] = pts[i];
    const [xj, yj] = pts[j];
    if (yi > y !== yj > y && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

/** The light's outline (world points) as the mesh view draws it, or null for a light without a surface. */
function lightOutline(l, b) {
  const ring = (c, n, r) => {
    const [t1, t2] = tangents(normalize(n));
    return Array.from({ length: 32 }, (_, i) =>
      add(c, add(mul(t1, r * Math.cos((i / 32) * 2 * Math.PI)), mul(t2, r * Math.sin((i / 32) * 2 * Math.PI)))),
    );
  };
  switch (l.type) {
    case "quad":
      return {
        pts: [l.corner, add(l.corner, l.edge1), add(add(l.corner, l.edge1), l.edge2), add(l.corner, l.edge2)],
        centre: add(l.corner, mul(add(l.edge1, l.edge2), 0.5)),
      };
    case "disk":
      return { pts: ring(l.center, l.normal, l.radius), centre: l.center };
    case "sphere":
      return { pts: ring(l.center, sub(b.from, l.center), l.radius), centre: l.center };
    default:
      return null;
  }
}

/** The solution as the panel uses it: patches with their world polygons, B per side at every snapshot. */
function prepare(sol, scene, view) {
  const P = sol.patches;
  const sides = sol.radiosity.length;
  const n = sides / 2; // side i < n is the front of patch i, side i + n its back
  const patches = [];
  for (let i = 0; i < n; i++) {
    const [corner, e1, e2] = [P.corner[i], P.e1[i], P.e2[i]];
    const triangle = Boolean(P.triangle[i]);
    const pts = triangle
      ? [corner, add(corner, e1), add(corner, e2)]
      : [corner, add(corner, e1), add(add(corner, e1), e2), add(corner, e2)];
    const centre = add(corner, mul(add(e1, e2), triangle ? 1 / 3 : 0.5));
    patches.push({
      index: i,
      corner,
      e1,
      e2,
      triangle,
      pts,
      centre,
      normal: P.normal[i],
      object: P.object[i],
      area: P.area[i],
      reflectance: P.reflectance[i],
    });
  }
  const history = sol.history || [];
  const steps = history.length;
  const snapshots = new Map(
    Object.entries(sol.snapshots || {})
      .map(([k, rows]) => [Number(k), rows])
      .filter(([k]) => Number.isInteger(k) && k >= 0 && k <= steps),
  );
  snapshots.set(steps, sol.radiosity); // the final solution
  const keys = [...snapshots.keys()].sort((a, z) => a - z);
  // before any shot only the emitting patches glow (the emission is on the front side)
  const initial = Array.from({ length: sides }, (_, s) =>
    P.emission.length === sides || s < n ? P.emission[s] || [0, 0, 0] : [0, 0, 0],
  );
  const emitted = sum3(sol.energy?.emitted);
  const unshot = [emitted || history[0]?.unshot || 0, ...history.map((e) => e.unshot)];
  const threshold = (scene.render?.radiosity?.threshold ?? 0.01) * emitted;
  const basis = cameraBasis(scene.camera, view.width, view.height);
  return {
    id: view.id,
    scene,
    sol,
    n,
    sides,
    patches,
    history,
    steps,
    snapshots,
    keys,
    initial,
    unshot,
    threshold,
    basis,
    width: view.width,
    height: view.height,
  };
}

export class RadiosityPanel {
  constructor({ sceneOf }) {
    this.sceneOf = sceneOf; // async (view) -> the view, with its scene
    this.el = {
      section: $("#radiosity"),
      summary: $("#rad-summary"),
      status: $("#rad-status"),
      body: $("#rad-body"),
      lines: $("#rad-lines"),
      step: $("#rad-step"),
      stepNum: $("#rad-step-num"),
      stepOut: $("#rad-step-out"),
      prev: $("#rad-prev"),
      play: $("#rad-play"),
      next: $("#rad-next"),
      shot: $("#rad-shot"),
      mesh: $("#rad-mesh"),
      hover: $("#rad-hover"),
      curve: $("#rad-curve"),
      energy: $("#rad-energy"),
    };
    this.data = null;
    this.loading = null; // the id of the job whose solution is on its way
    this.seq = 0;
    this.step = 0;
    this.B = null; // B per side at the step shown
    this.timer = null;
    this.hovered = null;
    this.drawn = []; // what the mesh view drew, back to front, in canvas pixels (for hover)
    const e = this.el;
    e.step.addEventListener("input", () => this.setStep(e.step.value));
    e.stepNum.addEventListener("change", () => this.setStep(e.stepNum.value));
    e.prev.addEventListener("click", () => this.setStep(this.step - 1));
    e.next.addEventListener("click", () => this.setStep(this.step + 1));
    e.play.addEventListener("click", () => (this.timer ? this.stop() : this.play()));
    e.lines.addEventListener("change", () => this.draw());
    e.mesh.addEventListener("mousemove", (ev) => this.hover(ev));
    e.mesh.addEventListener("mouseleave", () => this.hover(null));
    e.mesh.addEventListener("keydown", (ev) => this.patchKey(ev));
    e.curve.addEventListener("pointerdown", (ev) => {
      e.curve.setPointerCapture(ev.pointerId);
      this.curvePick(ev);
    });
    e.curve.addEventListener("pointermove", (ev) => ev.buttons && this.curvePick(ev));
    new ResizeObserver(() => this.draw()).observe(e.mesh.parentElement);
    new ResizeObserver(() => this.drawCurve()).observe(e.curve.parentElement);
  }

  /** The viewer shows a job, or the job it shows changed: the panel shows a finished radiosity job's
   * solution, and hides for anything else. */
  async update(view) {
    if (view?.job.status !== "done") return this.hide();
    if (this.loading === view.id || (this.data && this.data.id === view.id)) return;
    this.hide();
    const seq = this.seq;
    this.loading = view.id;
    try {
      await this.sceneOf(view);
    } catch {
      if (seq === this.seq) this.loading = null; // no scene, no panel (the ray tree says why if asked)
      return;
    }
    if (seq !== this.seq) return;
    if (view.scene?.render?.integrator !== "radiosity") {
      this.loading = null;
      return;
    }
    this.el.section.hidden = false;
    this.el.section.dataset.job = view.id;
    this.status("busy", "Loading the radiosity solution…");
    let sol;
    try {
      sol = await api.radiosity(view.id); // with the job's token (web/js/api.js)
    } catch (err) {
      if (seq === this.seq) {
        this.loading = null;
        this.status("error", `Could not load the radiosity solution: ${err.message}.`);
      }
      return;
    }
    if (seq !== this.seq) return;
    this.loading = null;
    this.show(prepare(sol, view.scene, view));
  }

  hide() {
    this.seq++;
    this.stop();
    this.loading = null;
    this.data = null;
    this.hovered = null;
    this.el.section.hidden = true;
    this.el.body.hidden = true;
    delete this.el.section.dataset.job;
  }

  status(kind, text) {
    this.el.status.dataset.kind = kind;
    this.el.status.textContent = text;
  }

  show(d) {
    this.data = d;
    const e = this.el;
    const lights = d.history.filter((x) => typeof x.shooter === "string").length;
    e.summary.textContent = `${d.n} patches (${d.sides} sides) · ${d.steps} shots`;
    const share = num(100 * (d.scene.render?.radiosity?.threshold ?? 0.01));
    const last = d.unshot[d.steps];
    this.status(
      "ok",
      `Progressive refinement: the light${lights === 1 ? "" : "s"} shoot${lights === 1 ? "s" : ""} first (${lights} shot${lights === 1 ? "" : "s"}), then at each step the patch side with the most unshot power shoots it into the scene. ${
        last <= d.threshold
          ? `After ${d.steps} shots less than ${share}% of the emitted power was left unshot: the solution stopped there.`
          : `It stopped at the step limit, ${d.steps} shots, with ${num((100 * last) / (d.unshot[0] || 1))}% of the emitted power unshot.`
      }`,
    );
    e.section.dataset.steps = String(d.steps);
    for (const input of [e.step, e.stepNum]) input.max = String(d.steps);
    e.body.hidden = false;
    this.energy();
    this.setStep(d.steps);
  }

  // -- the step -----------------------------------------------------------------------------------

  /** The largest snapshot key <= k, or null before the first snapshot. */
  snapshotAt(k) {
    let best = null;
    for (const key of this.data.keys) if (key <= k) best = key;
    return best;
  }

  objectName(i) {
    if (i === null || i === undefined || i < 0) return "no object";
    const o = (this.data.scene.objects || [])[i];
    return o && typeof o.name === "string" && o.name ? `'${o.name}'` : `objects[${i}]`;
  }

  /** "patch 367 (the back of patch 231, object 'left wall')" for a side index. */
  sideWords(s) {
    const d = this.data;
    const back = s >= d.n;
    const p = d.patches[back ? s - d.n : s];
    return `patch ${s} (${back ? `the back of patch ${s - d.n}` : "front"}, object ${this.objectName(p?.object)})`;
  }

  /** Who shoots at step k (1-based: the k-th shot), and the unshot power left after it. */
  shotWords(k) {
    const e = this.data.history[k - 1];
    if (!e) return { who: "nobody", left: "" };
    const who =
      typeof e.shooter === "string"
        ? `${e.shooter}${this.lightType(e.shooter)} shoots its power`
        : `${this.sideWords(e.shooter)} shoots ${num(e.power)} W`;
    return { who, left: `${num(e.unshot)} W is left unshot` };
  }

  lightType(name) {
    const m = /^lights\[(\d+)\]$/.exec(name);
    const l = m ? (this.data.scene.lights || [])[Number(m[1])] : null;
    return l ? ` (${l.type})` : "";
  }

  setStep(k) {
    const d = this.data;
    if (!d) return;
    k = Math.max(0, Math.min(d.steps, Math.round(Number(k) || 0)));
    this.step = k;
    const e = this.el;
    e.step.value = String(k);
    e.stepNum.value = String(k);
    const key = this.snapshotAt(k);
    this.snapshot = key;
    this.B = key === null ? d.initial : d.snapshots.get(key);
    e.stepOut.textContent =
      key === null
        ? `B before any shot: the emitters only`
        : key === k
          ? `B after ${k} of ${d.steps} shots`
          : `B after ${key} of ${d.steps} shots (the last snapshot before step ${k})`;
    const { who, left } = this.shotWords(k || 1);
    const shot =
      k === 0
        ? `Before the first shot only the emitting patches have radiosity. Shot 1: ${who}.`
        : `Shot ${k} of ${d.steps}: ${who}; ${left}.`;
    e.shot.textContent = shot;
    e.shot.dataset.step = String(k);
    e.step.setAttribute("aria-valuetext", `step ${k} of ${d.steps}`);
    e.prev.disabled = k === 0;
    e.next.disabled = k === d.steps;
    this.draw();
    this.drawCurve();
  }

  play() {
    const d = this.data;
    if (!d?.steps) return;
    if (this.step >= d.steps) this.setStep(0);
    const ms = Math.max(33, Math.min(250, 8000 / d.steps)); // about 8 s from the first shot to the last
    const stride = Math.max(1, Math.round((d.steps * ms) / 8000));
    this.el.play.textContent = "❚❚ Pause";
    this.el.shot.setAttribute("aria-live", "off"); // no running commentary while it plays
    this.timer = setInterval(() => {
      this.setStep(this.step + stride);
      if (this.step >= d.steps) this.stop();
    }, ms);
  }

  stop() {
    if (this.timer) clearInterval(this.timer);
    this.timer = null;
    this.el.play.textContent = "▶ Play";
    this.el.shot.setAttribute("aria-live", "polite");
  }

  // -- the mesh through the camera ----------------------------------------------------------------

  size() {
    const d = this.data;
    const box = this.el.mesh.parentElement.getBoundingClientRect();
    const maxH = Math.max(200, window.innerHeight * 0.55);
    const scale = Math.min(box.width / d.width, maxH / d.height);
    return { cssW: Math.max(1, Math.floor(d.width * scale)), cssH: Math.max(1, Math.floor(d.height * scale)), scale };
  }

  draw() {
    const d = this.data;
    const c = this.el.mesh;
    if (!d || this.el.section.hidden) return;
    const { cssW, cssH, scale } = this.size();
    const ctx = fitCanvas(c, cssW, cssH);
    const b = d.basis;
    const near = 1e-3;
    const toCanvas = (p) => {
      const f = projectToFilm(b, p);
      const clamp = (v) => Math.max(-1e5, Math.min(1e5, v));
      return [clamp(f.x * scale), clamp(f.y * scale)];
    };
    const items = [];
    for (const p of d.patches) {
      const poly = clipPolygon(p.pts, b, near);
      if (!poly) continue;
      const side = dot(p.normal, sub(b.from, p.centre)) >= 0 ? p.index : p.index + d.n; // the side facing the camera
      items.push({
        patch: p,
        side,
        pts: poly.map(toCanvas),
        dist: length(sub(p.centre, b.from)),
        fill: toneMap(this.B[side]),
      });
    }
    // area lights, with the patches in painter's order; one the camera sees (its centre unblocked) on top
    const onTop = [];
    (d.scene.lights || []).forEach((l, i) => {
      const o = lightOutline(l, b);
      const poly = o && clipPolygon(o.pts, b, near);
      if (!poly) return;
      const item = {
        light: i,
        pts: poly.map(toCanvas),
        dist: length(sub(o.centre, b.from)),
        fill: toneMap(mul(triple(l.radiance ?? 1), Math.PI)),
      };
      const dir = sub(o.centre, b.from);
      const tl = length(dir);
      const blocked = d.patches.some((p) => hitPatch(p, b.from, mul(dir, 1 / tl)) < tl * (1 - 1e-3) - 1e-4);
      (blocked ? items : onTop).push(item);
    });
    items.sort((a, z) => z.dist - a.dist);
    items.push(...onTop);
    const lines = this.el.lines.checked;
    ctx.lineJoin = "round";
    for (const it of items) {
      path(ctx, it.pts);
      ctx.fillStyle = it.fill;
      ctx.fill();
      // mesh lines, or the patch's own colour over the seams between neighbours
      ctx.strokeStyle = it.light !== undefined ? LIGHT : lines ? "rgba(140, 152, 168, 0.7)" : it.fill;
      ctx.lineWidth = it.light !== undefined ? 1.5 : lines ? 0.7 : 0.8;
      ctx.stroke();
    }
    // the point and spot lights: a star where they are
    (d.scene.lights || []).forEach((l, i) => {
      if ((l.type !== "point" && l.type !== "spot") || projectToFilm(b, l.position).z <= near) return;
      const [x, y] = toCanvas(l.position);
      star(ctx, x, y, 7, LIGHT);
      items.push({
        light: i,
        pts: [
          [x - 7, y - 7],
          [x + 7, y - 7],
          [x + 7, y + 7],
          [x - 7, y + 7],
        ],
        star: true,
      });
    });
    this.drawn = items;
    const hovered =
      this.hovered &&
      items.find((x) =>
        this.hovered.light !== undefined
          ? x.light === this.hovered.light
          : x.patch && x.patch.index === this.hovered.patch,
      );
    if (hovered) outline(ctx, hovered.pts, "#fff", 1.5, []);
    this.el.hover.textContent = this.hoverText(hovered);
    // the shooter of this step
    const e = d.history[this.step - 1];
    let shooter = "";
    if (e && typeof e.shooter === "number") {
      const s = e.shooter;
      const p = d.patches[s % d.n];
      const poly = p && clipPolygon(p.pts, b, near);
      if (poly) {
        const pts = poly.map(toCanvas);
        const facing = dot(p.normal, sub(b.from, p.centre)) >= 0 === s < d.n;
        outline(ctx, pts, SHOOTER, 3, facing ? [] : [5, 4]);
        tag(ctx, pts, `${s}`);
        shooter = String(s);
      }
    } else if (e) {
      const m = /^lights\[(\d+)\]$/.exec(e.shooter);
      const it = m && items.find((x) => x.light === Number(m[1]));
      if (it) {
        outline(ctx, it.pts, SHOOTER, 3, []);
        tag(ctx, it.pts, e.shooter);
        shooter = e.shooter;
      }
    }
    c.dataset.patches = String(items.filter((x) => x.patch).length);
    c.dataset.step = String(this.step);
    c.dataset.snapshot = this.snapshot === null ? "" : String(this.snapshot);
    c.dataset.shooter = shooter;
    c.setAttribute(
      "aria-label",
      `the patch mesh after ${this.snapshot ?? 0} shots, each patch the colour of its radiosity${shooter ? `; ${shooter === String(Number(shooter)) ? `patch ${shooter}` : shooter} is outlined: it shoots at step ${this.step}` : ""}`,
    );
  }

  hover(ev) {
    const d = this.data;
    if (!d) return;
    let found = null;
    if (ev) {
      const r = this.el.mesh.getBoundingClientRect();
      const x = ev.clientX - r.left;
      const y = ev.clientY - r.top;
      for (let i = this.drawn.length - 1; i >= 0; i--) {
        if (insidePolygon(x, y, this.drawn[i].pts)) {
          found = this.drawn[i];
          break;
        }
      }
    }
    const key = found ? (found.patch ? { patch: found.patch.index } : { light: found.light }) : null;
    if (JSON.stringify(key) === JSON.stringify(this.hovered)) return;
    this.hovered = key;
    this.draw();
  }

  /** The keyboard's hover: the arrow keys go from patch to patch (and the lights) in the order they are
   * drawn, Escape lets go; the numbers are said as the pointer's are (#rad-hover). */
  patchKey(ev) {
    const n = this.drawn.length;
    if (!this.data || !n) return;
    const move = { ArrowRight: 1, ArrowDown: 1, ArrowLeft: -1, ArrowUp: -1 }[ev.key];
    if (!move && ev.key !== "Escape") return;
    ev.preventDefault();
    const keyOf = (it) => (it.patch ? { patch: it.patch.index } : { light: it.light });
    const at = this.hovered
      ? this.drawn.findIndex((it) => JSON.stringify(keyOf(it)) === JSON.stringify(this.hovered))
      : -1;
    this.hovered =
      ev.key === "Escape" ? null : keyOf(this.drawn[at < 0 ? (move > 0 ? 0 : n - 1) : (at + move + n) % n]);
    this.draw();
  }

  /** The numbers of the patch (or light) under the pointer, at the step shown. */
  hoverText(it) {
    if (!it) return "";
    if (it.patch) {
      const B = this.B[it.side];
      const p = it.patch;
      return `${this.sideWords(it.side)}: B = ${B.map((x) => num(x)).join(" ")} W/m² (radiance B/π = ${B.map((x) => num(x / Math.PI)).join(" ")}), reflectance ${(p.reflectance || []).map((x) => num(x)).join(" ")}, area ${num(p.area)} m²`;
    }
    const l = this.data.scene.lights[it.light];
    return `lights[${it.light}] (${l.type})${
      l.radiance !== undefined
        ? `: radiance ${[l.radiance]
            .flat()
            .map((x) => num(x))
            .join(" ")} W/(m² sr)`
        : ""
    }`;
  }

  // -- the convergence curve ----------------------------------------------------------------------

  curveLayout() {
    const box = this.el.curve.parentElement.getBoundingClientRect();
    const cssW = Math.max(160, Math.floor(box.width));
    const cssH = Math.round(Math.max(150, Math.min(240, cssW * 0.42)));
    return { cssW, cssH, l: 50, r: 14, t: 12, b: 32 };
  }

  curvePick(ev) {
    const d = this.data;
    if (!d) return;
    const { cssW, l, r } = this.curveLayout();
    const x = ev.clientX - this.el.curve.getBoundingClientRect().left;
    this.setStep(((x - l) / (cssW - l - r)) * d.steps);
  }

  drawCurve() {
    const d = this.data;
    const c = this.el.curve;
    if (!d || this.el.section.hidden) return;
    const { cssW, cssH, l, r, t, b } = this.curveLayout();
    const ctx = fitCanvas(c, cssW, cssH);
    const u = d.unshot;
    const positive = u.filter((v) => v > 0);
    if (d.threshold > 0) positive.push(d.threshold);
    if (!positive.length) return;
    const lo = Math.floor(Math.log10(Math.min(...positive)));
    let hi = Math.ceil(Math.log10(Math.max(...positive)));
    if (hi <= lo) hi = lo + 1;
    const pw = cssW - l - r;
    const ph = cssH - t - b;
    const X = (k) => l + (d.steps ? k / d.steps : 0) * pw;
    const Y = (v) => t + (1 - (Math.log10(Math.max(v, 10 ** lo)) - lo) / (hi - lo)) * ph;
    ctx.font = "11px system-ui, sans-serif";
    ctx.lineWidth = 1;
    // decades
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    const every = Math.max(1, Math.ceil((hi - lo) / Math.max(2, Math.floor(ph / 22))));
    for (let e = lo; e <= hi; e++) {
      ctx.strokeStyle = "#2a3442";
      ctx.beginPath();
      ctx.moveTo(l, Y(10 ** e));
      ctx.lineTo(l + pw, Y(10 ** e));
      ctx.stroke();
      if ((e - lo) % every === 0) {
        ctx.fillStyle = AXIS;
        ctx.fillText(`${num(10 ** e)} W`, l - 5, Y(10 ** e));
      }
    }
    // steps
    ctx.textAlign = "center";
    ctx.textBaseline = "top";
    for (const k of niceTicks(d.steps, Math.max(2, Math.floor(pw / 70)))) {
      ctx.strokeStyle = AXIS;
      ctx.beginPath();
      ctx.moveTo(X(k), t + ph);
      ctx.lineTo(X(k), t + ph + 4);
      ctx.stroke();
      ctx.fillStyle = AXIS;
      const half = ctx.measureText(String(k)).width / 2;
      ctx.fillText(String(k), Math.min(cssW - 2 - half, X(k)), t + ph + 6);
    }
    ctx.textAlign = "right";
    ctx.fillText("shots", l + pw, t + ph + 18);
    ctx.strokeStyle = AXIS;
    ctx.beginPath();
    ctx.moveTo(l, t);
    ctx.lineTo(l, t + ph);
    ctx.lineTo(l + pw, t + ph);
    ctx.stroke();
    // where it stops
    if (d.threshold > 0) {
      ctx.strokeStyle = "#ff8a9e";
      ctx.setLineDash([5, 4]);
      ctx.beginPath();
      ctx.moveTo(l, Y(d.threshold));
      ctx.lineTo(l + pw, Y(d.threshold));
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = "#ff8a9e";
      ctx.textBaseline = "bottom";
      ctx.fillText("stop", l + pw - 2, Y(d.threshold) - 2);
    }
    // the curve, the lights' shots as yellow dots
    ctx.strokeStyle = CURVE;
    ctx.lineWidth = 1.6;
    ctx.beginPath();
    u.forEach((v, k) => {
      if (k) ctx.lineTo(X(k), Y(v));
      else ctx.moveTo(X(k), Y(v));
    });
    ctx.stroke();
    ctx.fillStyle = LIGHT;
    d.history.forEach((e, i) => {
      if (typeof e.shooter !== "string") return;
      ctx.beginPath();
      ctx.arc(X(i + 1), Y(u[i + 1]), 3, 0, 2 * Math.PI);
      ctx.fill();
    });
    // the step shown
    const k = this.step;
    ctx.strokeStyle = SHOOTER;
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.moveTo(X(k), t);
    ctx.lineTo(X(k), t + ph);
    ctx.stroke();
    ctx.beginPath();
    ctx.arc(X(k), Y(u[k]), 4.5, 0, 2 * Math.PI);
    ctx.fillStyle = SHOOTER;
    ctx.fill();
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 1;
    ctx.stroke();
    ctx.fillStyle = "#fff";
    ctx.textBaseline = "top";
    ctx.textAlign = X(k) > l + pw * 0.6 ? "right" : "left";
    ctx.fillText(`step ${k}: ${num(u[k])} W unshot`, X(k) + (ctx.textAlign === "right" ? -6 : 6), t + 2);
    c.dataset.step = String(k);
    c.setAttribute(
      "aria-label",
      `the unshot power after each shot, on a log scale: ${num(u[0])} W at first, ${num(u[d.steps])} W after the last of ${d.steps} shots; at step ${k}, ${num(u[k])} W`,
    );
  }

  energy() {
    const d = this.data;
    const en = d.sol.energy || {};
    const names = [
      ["emitted", "emitted by the lights and emitting patches"],
      ["absorbed", "absorbed by the patches (and the lights' black faces)"],
      ["unshot", "received but not yet shot again"],
      ["escaped", "left the scene"],
    ];
    const total = sum3(en.emitted) || 1;
    const row = ([k, what]) =>
      h(
        "tr",
        { dataset: { row: k } },
        h("th", { scope: "row" }, k, h("small", {}, ` ${what}`)),
        ...(en[k] || [0, 0, 0]).map((x) => h("td", {}, num(x))),
        h("td", {}, num(sum3(en[k]))),
        h("td", {}, k === "emitted" ? "100%" : `${num((100 * sum3(en[k])) / total, 2)}%`),
      );
    const parts = ["absorbed", "unshot", "escaped"].map((k) => sum3(en[k]));
    this.el.energy.replaceChildren(
      h(
        "table",
        { class: "rad-energy" },
        h("caption", {}, "Energy balance of the final solution (W)"),
        h(
          "thead",
          {},
          h(
            "tr",
            {},
            h("th", { scope: "col" }, ""),
            ...["R", "G", "B", "R+G+B", "share"].map((x) => h("th", { scope: "col" }, x)),
          ),
        ),
        h("tbody", {}, names.map(row)),
      ),
      h(
        "p",
        { class: "rad-balance" },
        `emitted ${num(sum3(en.emitted), 4)} W = absorbed ${num(parts[0], 4)} + unshot ${num(parts[1], 4)} + escaped ${num(parts[2], 4)} (= ${num(parts[0] + parts[1] + parts[2], 4)} W)`,
      ),
    );
  }
}

function path(ctx, pts) {
  ctx.beginPath();
  pts.forEach(([x, y], i) => {
    if (i) ctx.lineTo(x, y);
    else ctx.moveTo(x, y);
  });
  ctx.closePath();
}

function outline(ctx, pts, colour, width, dash) {
  path(ctx, pts);
  ctx.setLineDash([]);
  ctx.strokeStyle = "#000";
  ctx.lineWidth = width + 2;
  ctx.stroke();
  ctx.setLineDash(dash);
  ctx.strokeStyle = colour;
  ctx.lineWidth = width;
  ctx.stroke();
  ctx.setLineDash([]);
}

/** A label beside a shape (above its top, inside the canvas). */
function tag(ctx, pts, text) {
  const xs = pts.map((p) => p[0]);
  const ys = pts.map((p) => p[1]);
  const cssW = ctx.canvas.width / (window.devicePixelRatio || 1);
  ctx.font = "bold 12px system-ui, sans-serif";
  const w = ctx.measureText(text).width + 8;
  const x = Math.max(2, Math.min(cssW - w - 2, (Math.min(...xs) + Math.max(...xs)) / 2 - w / 2));
  const top = Math.min(...ys);
  const y = top > 22 ? top - 20 : Math.max(...ys) + 4;
  ctx.fillStyle = "#000c";
  ctx.fillRect(x, y, w, 17);
  ctx.fillStyle = SHOOTER;
  ctx.textAlign = "left";
  ctx.textBaseline = "middle";
  ctx.fillText(text, x + 4, y + 9);
}

function star(ctx, x, y, r, colour) {
  ctx.beginPath();
  for (let i = 0; i < 8; i++) {
    const a = (i / 8) * 2 * Math.PI;
    ctx.moveTo(x, y);
    ctx.lineTo(x + r * Math.cos(a), y + r * Math.sin(a));
  }
  ctx.strokeStyle = colour;
  ctx.lineWidth = 2;
  ctx.stroke();
}

/** Up to about `count` round step numbers from 0 to n (both ends included). */
function niceTicks(n, count) {
  if (n <= 0) return [0];
  const raw = n / count;
  const p = 10 ** Math.floor(Math.log10(raw));
  const stepSize = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw) || raw;
  const ticks = [];
  for (let k = 0; k < n - stepSize * 0.6; k += Math.max(1, Math.round(stepSize))) ticks.push(k);
  ticks.push(n);
  return ticks;
}
