// The Build panel's 3D view: the scene's wireframe (view3d.js) with the picked object or light and its handles.
// Click a shape to pick it. Drag an arrow to move along that axis (x red, y green, z blue), the centre square to
// move on the horizontal plane, the round knob to scale about the centre, a spot light's orange knob (at the end
// of its beam's axis) to aim it, the cyan knob (under the centre, or beside it where an arrow is) sideways to turn it about the vertical
// (a box's or mesh's transform.rotate); elsewhere a drag orbits. While a
// handle is dragged only the drawing follows; letting go writes the move into the JSON as one step of the
// editor's history. Keys (the canvas focused): arrows move x and z, Page Up and Page Down move y, [ and ]
// scale, Q and E turn the picked shape 15 degrees about the vertical, A and D turn a spot or directional light's
// beam and W and S tilt it (5 degrees), Shift+arrows orbit,
// + and - zoom, N and L pick the next object and light, Escape lets go.
import { aimWrites, anchorOf, firstHit, itemAt, moveWrites, r3, rotateWrites, scaleWrites, stage } from "./edits.js";
import { sceneLines } from "./shapes.js";
import { clone } from "./util.js";
import { add, dot, mul, normalize, sub } from "./vec.js";
import { View3D } from "./view3d.js";

const AXES = [
  { name: "x", dir: [1, 0, 0], colour: "#ff5c5c" },
  { name: "y", dir: [0, 1, 0], colour: "#4fe07a" },
  { name: "z", dir: [0, 0, 1], colour: "#5ca8ff" },
];
const GRAB = 12; // px: how near the pointer must be to a handle to take it
const KNOB = [34, 34]; // px from the centre: the scale knob
const TURNS = [
  [0, 46],
  [-44, 0],
  [-34, 34],
  [-34, -34],
  [34, -34],
]; // px from the centre: where the turn knob may go (the first clear of the arrows)
const TURN_COLOUR = "#3fd0ff";
const TURN_PER_PX = 0.5; // degrees of turn per pixel of a sideways drag of the turn knob
const TURN_STEP = 15; // degrees: one press of Q or E
const AIM = "#ff9f1c"; // a spot light's aim knob and beam
const AIM_STEP = 5; // degrees: one press of A, D (turn) or W, S (tilt) on a light with a direction

/** Set a value at a JSON path of a plain object, making the missing objects on the way. */
function setPath(obj, parts, v) {
  let o = obj;
  for (const p of parts.slice(0, -1)) {
    if (!o[p] || typeof o[p] !== "object") o[p] = {};
    o = o[p];
  }
  o[parts.at(-1)] = v;
}

const distTo = (p, a, b) => {
  const d = sub([...b, 0], [...a, 0]);
  const l2 = d[0] * d[0] + d[1] * d[1];
  const t = l2 ? Math.max(0, Math.min(1, ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / l2)) : 0;
  return Math.hypot(p[0] - (a[0] + t * d[0]), p[1] - (a[1] + t * d[1]));
};

export class BuildView extends View3D {
  /** onPick(of | null): a shape clicked (or keys); onEdit(writes, what): a finished drag or a key's change. */
  constructor(canvas, { onPick, onEdit }) {
    super(canvas, { onHover: () => {}, onSelect: () => {} });
    this.onPick = onPick;
    this.onEdit = onEdit;
    this.picked = null; // ["objects", i] or ["lights", i]
    this.drag = null;
  }

  /** Follow the editor's scene; the orbit stays where the student turned it while the scene's camera stays. */
  update(scene, film) {
    // a new scene (another camera: a template, an example, a file) is framed anew
    const camera = JSON.stringify([scene.camera?.lookfrom, scene.camera?.lookat]);
    if (!this.scene || camera !== this.framed) {
      this.framed = camera;
      return this.setScene(scene, film);
    }
    this.scene = scene;
    this.film = film;
    this.lines = sceneLines(scene, film);
    this.draw();
  }

  setScene(scene, film) {
    this.film = film;
    super.setScene(scene, film);
    // farther out than the ray tree's view: the lights over the scene (where the Build panel puts them) show too
    this.home.dist *= 1.2;
    this.orbit = { ...this.home };
    this.draw();
  }

  setPicked(of) {
    const changed = JSON.stringify(of) !== JSON.stringify(this.picked);
    this.picked = of;
    this.draw();
    if (changed) this.bringIntoView();
  }

  /** A newly picked item outside the drawing (a light high over the scene): zoom out until its handles show. */
  bringIntoView() {
    const p = anchorOf(itemAt(this.scene, this.picked));
    for (let k = 0; p && this.cam && k < 8; k++) {
      const [x, y] = this.project(this.cam, p);
      const inside =
        dot(sub(p, this.cam.eye), this.cam.forward) > 0 &&
        x > 40 &&
        x < this.cam.w - 40 &&
        y > 40 &&
        y < this.cam.h - 40;
      if (inside) return;
      this.orbit.dist *= 1.25;
      this.draw();
    }
  }

  /** The handles of the picked item in canvas pixels: {a (centre), tips: [{axis, p}], knob, aim} or null (aim: a
   * spot light's knob, `aimAt` its point in the scene, on the beam's axis). */
  handles() {
    const item = itemAt(this.shown || this.scene, this.picked);
    const p = anchorOf(item);
    if (!p || !this.cam || dot(sub(p, this.cam.eye), this.cam.forward) <= 0) return null;
    const L = this.orbit.dist * 0.14;
    const a = this.project(this.cam, p);
    const tips = AXES.map((axis) => ({ axis, p: this.project(this.cam, add(p, mul(axis.dir, L))) }));
    const knob = scaleWrites(item, [], 1) ? [a[0] + KNOB[0], a[1] + KNOB[1]] : null;
    // the turn knob: the first of its places clear of the arrows' tips and the scale knob (they turn with the view)
    const taken = [...tips.map((t) => t.p), ...(knob ? [knob] : [])];
    const spot = TURNS.map(([dx, dy]) => [a[0] + dx, a[1] + dy]).find((q) =>
      taken.every((t) => Math.hypot(q[0] - t[0], q[1] - t[1]) >= 2 * GRAB),
    );
    const turn = rotateWrites(item, [], 0) ? spot || [a[0] + TURNS[0][0], a[1] + TURNS[0][1]] : null;
    const axis = item.type === "spot" && Array.isArray(item.direction) ? normalize(item.direction) : null;
    const aimAt = axis?.every(Number.isFinite) ? add(p, mul(axis, L * 1.6)) : null;
    const aim = aimAt && dot(sub(aimAt, this.cam.eye), this.cam.forward) > 0 ? this.project(this.cam, aimAt) : null;
    return { at: p, a, tips, knob, turn, L, aim, aimAt };
  }

  draw() {
    super.draw();
    const c = this.canvas;
    c.dataset.picked = this.picked ? this.picked.join(".") : "";
    const hs = this.scene && this.picked ? this.handles() : null;
    c.dataset.handles = hs ? "true" : "false";
    if (!hs) {
      c.dataset.handleAt = c.dataset.handleTips = c.dataset.knob = c.dataset.aim = c.dataset.turn = "";
      return;
    }
    const ctx = c.getContext("2d");
    ctx.save();
    // the picked item's lines, drawn again on top, thick
    ctx.strokeStyle = "#ffffff";
    ctx.lineWidth = 2.4;
    for (const line of this.lines) {
      if (!line.of || line.of.join() !== this.picked.join()) continue;
      ctx.beginPath();
      for (let i = 0; i < line.pts.length; i++) {
        const [x, y] = this.project(this.cam, line.pts[i]);
        if (i) ctx.lineTo(x, y);
        else ctx.moveTo(x, y);
      }
      ctx.stroke();
    }
    for (const { axis, p } of hs.tips) {
      ctx.strokeStyle = axis.colour;
      ctx.fillStyle = axis.colour;
      ctx.lineWidth = 3;
      ctx.beginPath();
      ctx.moveTo(...hs.a);
      ctx.lineTo(...p);
      ctx.stroke();
      ctx.beginPath();
      ctx.arc(p[0], p[1], 7, 0, 2 * Math.PI);
      ctx.fill();
      ctx.fillStyle = "#10151c";
      ctx.font = "bold 10px system-ui, sans-serif";
      ctx.fillText(axis.name, p[0] - 3, p[1] + 3.5);
    }
    ctx.fillStyle = "#ffd23f";
    ctx.fillRect(hs.a[0] - 6, hs.a[1] - 6, 12, 12);
    if (hs.knob) {
      ctx.strokeStyle = "#ffffff";
      ctx.setLineDash([3, 3]);
      ctx.lineWidth = 1;
      ctx.beginPath();
      ctx.moveTo(...hs.a);
      ctx.lineTo(...hs.knob);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = "#ffffff";
      ctx.beginPath();
      ctx.arc(hs.knob[0], hs.knob[1], 7, 0, 2 * Math.PI);
      ctx.fill();
    }
    if (hs.turn) {
      // a knob with a round arrow: drag it sideways to turn the shape about the vertical
      ctx.strokeStyle = TURN_COLOUR;
      ctx.setLineDash([3, 3]);
      ctx.lineWidth = 1;
      ctx.beginPath();
      ctx.moveTo(...hs.a);
      ctx.lineTo(...hs.turn);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = TURN_COLOUR;
      ctx.beginPath();
      ctx.arc(hs.turn[0], hs.turn[1], 7, 0, 2 * Math.PI);
      ctx.fill();
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(hs.turn[0], hs.turn[1], 11, 0.2 * Math.PI, 1.6 * Math.PI);
      ctx.stroke();
    }
    if (hs.aim) {
      ctx.strokeStyle = AIM;
      ctx.fillStyle = AIM;
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.moveTo(...hs.a);
      ctx.lineTo(...hs.aim);
      ctx.stroke();
      ctx.beginPath();
      ctx.arc(hs.aim[0], hs.aim[1], 7, 0, 2 * Math.PI);
      ctx.fill();
    }
    ctx.restore();
    // where the handles are, for tests and for anyone scripting the page
    c.dataset.handleAt = hs.a.map(Math.round).join(",");
    c.dataset.handleTips = hs.tips.map((t) => `${t.axis.name}:${t.p.map(Math.round).join(",")}`).join(" ");
    c.dataset.knob = hs.knob ? hs.knob.map(Math.round).join(",") : "";
    c.dataset.aim = hs.aim ? hs.aim.map(Math.round).join(",") : "";
    c.dataset.turn = hs.turn ? hs.turn.map(Math.round).join(",") : "";
  }

  local(e) {
    const r = this.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  /** Which handle is under the canvas point m: "x", "y", "z", "plane", "scale", "turn", "aim" or null. */
  handleAt(m) {
    const hs = this.picked ? this.handles() : null;
    if (!hs) return null;
    if (hs.aim && Math.hypot(m[0] - hs.aim[0], m[1] - hs.aim[1]) < GRAB) return { kind: "aim", hs };
    if (hs.knob && Math.hypot(m[0] - hs.knob[0], m[1] - hs.knob[1]) < GRAB) return { kind: "scale", hs };
    if (hs.turn && Math.hypot(m[0] - hs.turn[0], m[1] - hs.turn[1]) < GRAB) return { kind: "turn", hs };
    for (const { axis, p } of hs.tips) if (Math.hypot(m[0] - p[0], m[1] - p[1]) < GRAB) return { kind: axis.name, hs };
    if (Math.abs(m[0] - hs.a[0]) < GRAB && Math.abs(m[1] - hs.a[1]) < GRAB) return { kind: "plane", hs };
    for (const { axis, p } of hs.tips) if (distTo(m, hs.a, p) < 5) return { kind: axis.name, hs };
    return null;
  }

  /** The point of the plane through p with normal n (default: the horizontal plane, for the centre square's
   * drag) under canvas point m. */
  onPlane(m, p, n = this.frameUp) {
    const { eye, forward, right, up, f, w, h } = this.cam;
    const dir = normalize(add(mul(forward, f), add(mul(right, m[0] - w / 2), mul(up, h / 2 - m[1]))));
    const den = dot(dir, n);
    if (Math.abs(den) < 1e-6) return null;
    const t = dot(sub(p, eye), n) / den;
    return t > 0 ? add(eye, mul(dir, t)) : null;
  }

  down(e) {
    const m = this.local(e);
    const grab = this.handleAt(m);
    if (!grab) return super.down(e);
    e.preventDefault();
    this.canvas.setPointerCapture(e.pointerId);
    const item = clone(itemAt(this.scene, this.picked));
    this.drag = {
      ...grab,
      m0: m,
      item,
      base: [...this.picked],
      on0: grab.kind === "plane" ? this.onPlane(m, grab.hs.at) : null,
      writes: null,
    };
  }

  /** The writes a drag to canvas point m means. */
  dragWrites(m) {
    const { kind, hs, m0, item, base } = this.drag;
    if (kind === "aim") {
      // the knob follows the pointer on the plane facing the view through it; the beam points at the knob
      const q = this.onPlane(m, hs.aimAt, this.cam.forward);
      const d = q && sub(q, hs.at);
      if (!d || Math.hypot(...d) < 1e-6) return null;
      return [[[...base, "direction"], normalize(d).map(r3)]];
    }
    if (kind === "turn") {
      // sideways: to the right turns the side facing the view to the right (a positive angle about y)
      const deg = Math.round((m[0] - m0[0]) * TURN_PER_PX);
      return deg ? rotateWrites(item, base, deg) : null;
    }
    if (kind === "scale") {
      const r0 = Math.hypot(m0[0] - hs.a[0], m0[1] - hs.a[1]);
      const k = Math.max(0.05, Math.min(20, Math.hypot(m[0] - hs.a[0], m[1] - hs.a[1]) / Math.max(r0, 1)));
      return scaleWrites(item, base, k);
    }
    let d;
    if (kind === "plane") {
      const p = this.onPlane(m, hs.at);
      if (!p || !this.drag.on0) return null;
      d = sub(p, this.drag.on0);
    } else {
      const { axis, p } = hs.tips.find((t) => t.axis.name === kind);
      const s = [p[0] - hs.a[0], p[1] - hs.a[1]];
      const s2 = s[0] * s[0] + s[1] * s[1];
      if (s2 < 4) return null; // the axis points at the eye: it cannot be dragged from here
      d = mul(axis.dir, (((m[0] - m0[0]) * s[0] + (m[1] - m0[1]) * s[1]) / s2) * hs.L);
    }
    return moveWrites(item, base, d);
  }

  move(e) {
    if (!this.drag) return super.move(e);
    const writes = this.dragWrites(this.local(e));
    if (!writes) return;
    this.drag.writes = writes;
    // only the drawing follows while the handle moves: the text changes once, when it is let go
    const shown = clone(this.scene);
    for (const [parts, v] of writes) setPath(shown, parts, v);
    this.shown = shown;
    this.lines = sceneLines(shown, this.film);
    this.draw();
  }

  up(e) {
    if (this.drag) {
      const { writes, kind } = this.drag;
      this.drag = null;
      this.shown = null;
      if (writes) this.onEdit(writes, { scale: "scale", aim: "aim", turn: "rotate" }[kind] || "move");
      else this.draw();
      return;
    }
    const p = this.pointers.get(e.pointerId);
    this.pointers.delete(e.pointerId);
    if (p && Math.hypot(e.clientX - p.x0, e.clientY - p.y0) < 4 && this.pointers.size === 0)
      this.onPick(this.shapeAt(this.local(e)));
  }

  /** What a click at canvas point m picks: a light drawn within 8 px (a point light is only its star), else the
   * surface the view's ray through m meets first (inside a sphere's outline, not only on its lines), else the
   * object drawn nearest within 8 px; null for empty space. */
  shapeAt(m) {
    const light = this.lineAt(m, (of) => of[0] === "lights");
    if (light) return light;
    const { eye, forward, right, up, f, w, h } = this.cam;
    const dir = normalize(add(mul(forward, f), add(mul(right, m[0] - w / 2), mul(up, h / 2 - m[1]))));
    return firstHit(this.scene, eye, dir)?.of || this.lineAt(m);
  }

  /** The object or light whose lines pass nearest canvas point m (within 8 px), or null. */
  lineAt(m, wanted = () => true) {
    let best = null;
    let bestD = 8;
    const near = Math.max(1e-3, this.radius * 1e-3);
    for (const line of this.lines) {
      if (!line.of || !wanted(line.of)) continue;
      for (let i = 1; i < line.pts.length; i++) {
        const [p, q] = [line.pts[i - 1], line.pts[i]];
        if (dot(sub(p, this.cam.eye), this.cam.forward) < near || dot(sub(q, this.cam.eye), this.cam.forward) < near)
          continue;
        const d = distTo(m, this.project(this.cam, p), this.project(this.cam, q));
        if (d < bestD) {
          bestD = d;
          best = line.of;
        }
      }
    }
    return best;
  }

  key(e) {
    const item = itemAt(this.scene, this.picked);
    const next = { n: "objects", N: "objects", l: "lights", L: "lights" }[e.key];
    if (next && !e.ctrlKey && !e.metaKey && !e.altKey) {
      e.preventDefault();
      const list = Array.isArray(this.scene?.[next]) ? this.scene[next] : [];
      if (!list.length) return;
      const i = this.picked?.[0] === next ? (this.picked[1] + 1) % list.length : 0;
      this.onPick([next, i]);
      return;
    }
    if (!item || e.shiftKey || e.ctrlKey || e.metaKey || e.altKey) return super.key(e);
    if (e.key === "Escape") {
      e.preventDefault();
      this.onPick(null);
      return;
    }
    const { step } = stage(this.scene);
    const moves = {
      ArrowLeft: [-step, 0, 0],
      ArrowRight: [step, 0, 0],
      ArrowUp: [0, 0, -step],
      ArrowDown: [0, 0, step],
      PageUp: [0, step, 0],
      PageDown: [0, -step, 0],
    };
    let writes = null;
    let what = "move";
    const aim = { a: [AIM_STEP, 0], d: [-AIM_STEP, 0], w: [0, AIM_STEP], s: [0, -AIM_STEP] }[e.key.toLowerCase()];
    const aimed = aim && aimWrites(item, this.picked, aim[0], aim[1], this.frameUp); // null: no direction to aim
    if (moves[e.key]) writes = moveWrites(item, this.picked, moves[e.key]);
    else if (aimed) {
      writes = aimed;
      what = "aim";
    } else if ((e.key === "q" || e.key === "e") && rotateWrites(item, this.picked, 0)) {
      writes = rotateWrites(item, this.picked, e.key === "e" ? TURN_STEP : -TURN_STEP);
      what = "rotate";
    } else if (e.key === "[" || e.key === "]") {
      writes = scaleWrites(item, this.picked, e.key === "]" ? 1.1 : 1 / 1.1);
      what = "scale";
    } else return super.key(e);
    e.preventDefault();
    if (writes) this.onEdit(writes, what);
  }
}
