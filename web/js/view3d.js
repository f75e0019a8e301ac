// A 3D view of the scene and the ray tree on a 2D canvas: our own perspective projection of wireframes
// (shapes.js), orbited with the mouse or a finger (drag), zoomed with the wheel or a pinch, or from the
// keyboard (arrows orbit, + and - zoom, 0 resets). Hovering a ray highlights it in the other views.
import { sceneBounds, sceneLines } from "./shapes.js";
import { strokeRay, styleKey } from "./rays.js";
import { fitCanvas } from "./util.js";
import { add, clipNear, cross, dot, length, mul, normalize, sub } from "./vec.js";

const FOV = 50; // degrees, vertical, of the orbit camera

export class View3D {
  constructor(canvas, { onHover, onSelect }) {
    this.canvas = canvas;
    this.onHover = onHover;
    this.onSelect = onSelect;
    this.lines = [];
    this.rays = null; // {model, segments}
    this.depth = Infinity;
    this.hl = null;
    this.drawn = [];
    this.pointers = new Map();
    this.orbit = { yaw: 0, pitch: 0.3, dist: 10 };
    this.frameUp = [0, 1, 0];
    canvas.addEventListener("pointerdown", (e) => this.down(e));
    canvas.addEventListener("pointermove", (e) => this.move(e));
    canvas.addEventListener("pointerup", (e) => this.up(e));
    canvas.addEventListener("pointercancel", (e) => this.up(e));
    canvas.addEventListener("pointerleave", () => this.onHover(null));
    canvas.addEventListener("wheel", (e) => this.wheel(e), { passive: false });
    canvas.addEventListener("keydown", (e) => this.key(e));
    new ResizeObserver(() => this.draw()).observe(canvas.parentElement);
  }

  /** A new scene (film: {width, height} for the camera frustum); the view starts near the scene's camera. */
  setScene(scene, film) {
    this.scene = scene;
    this.lines = sceneLines(scene, film);
    const { centre, radius } = sceneBounds(scene);
    this.target = Array.isArray(scene.camera?.lookat) ? scene.camera.lookat : centre; // orbit what the camera looks at
    this.radius = radius;
    const up = normalize(scene.camera?.vup || [0, 1, 0]);
    this.frameUp = up;
    const [a, b] = this.frame();
    const from = sub(scene.camera?.lookfrom || add(centre, [0, 0, radius * 3]), this.target);
    const along = length(from) || radius * 3;
    this.home = {
      yaw: Math.atan2(dot(from, a), dot(from, b)) + 0.55,
      pitch: Math.min(1.2, Math.asin(Math.max(-1, Math.min(1, dot(from, up) / along))) + 0.35),
      dist: Math.max(along, radius * 0.8) * 1.25,
    };
    this.orbit = { ...this.home };
    this.draw();
  }

  /** Two horizontal axes perpendicular to the up vector. */
  frame() {
    const up = this.frameUp;
    const a = normalize(Math.abs(up[0]) > 0.9 ? cross(up, [0, 0, 1]) : cross([1, 0, 0], up));
    const b = cross(a, up);
    return [a, b];
  }

  setRays(rays) {
    this.rays = rays;
    this.draw();
  }

  setDepth(d) {
    this.depth = d;
    this.draw();
  }

  highlight(id) {
    this.hl = id;
    this.draw();
  }

  camera(w, h) {
    const { yaw, pitch, dist } = this.orbit;
    const [a, b] = this.frame();
    const dir = add(
      mul(add(mul(a, Math.sin(yaw)), mul(b, Math.cos(yaw))), Math.cos(pitch)),
      mul(this.frameUp, Math.sin(pitch)),
    );
    const eye = add(this.target, mul(dir, dist));
    const forward = normalize(sub(this.target, eye));
    const right = normalize(cross(forward, this.frameUp));
    const up = cross(right, forward);
    const f = h / 2 / Math.tan(((FOV / 2) * Math.PI) / 180);
    return { eye, forward, right, up, f, w, h };
  }

  project(cam, p) {
    const d = sub(p, cam.eye);
    const z = dot(d, cam.forward);
    return [cam.w / 2 + (dot(d, cam.right) / z) * cam.f, cam.h / 2 - (dot(d, cam.up) / z) * cam.f];
  }

  draw() {
    const c = this.canvas;
    if (!this.scene) {
      c.dataset.lines = "0";
      return;
    }
    const box = c.parentElement.getBoundingClientRect();
    const w = Math.max(200, Math.floor(box.width));
    const hgt = Math.max(220, Math.min(Math.floor(w * 0.75), Math.floor(window.innerHeight * 0.55)));
    const ctx = fitCanvas(c, w, hgt);
    const cam = this.camera(w, hgt);
    this.cam = cam; // the last drawing's projection (the build view's handles are found with it)
    const near = Math.max(1e-3, this.radius * 1e-3);
    const seg = (p, q) => {
      const cl = clipNear(p, q, cam.eye, cam.forward, near);
      return cl ? cl.map((x) => this.project(cam, x)) : null;
    };
    let count = 0;
    ctx.lineCap = "round";
    const dimScene = this.hl !== null;
    for (const line of this.lines) {
      ctx.strokeStyle = line.colour;
      ctx.lineWidth = line.width;
      ctx.setLineDash(line.dash || []);
      ctx.globalAlpha = dimScene ? 0.35 : line.group === "object" ? 0.8 : 1;
      ctx.beginPath();
      let drew = false;
      for (let i = 1; i < line.pts.length; i++) {
        const s2 = seg(line.pts[i - 1], line.pts[i]);
        if (!s2) continue;
        ctx.moveTo(s2[0][0], s2[0][1]);
        ctx.lineTo(s2[1][0], s2[1][1]);
        drew = true;
      }
      ctx.stroke();
      if (drew) count++;
    }
    ctx.setLineDash([]);
    ctx.globalAlpha = 1;
    ctx.font = "11px system-ui, sans-serif";
    for (const line of this.lines) {
      if (!line.label || !line.labelAt) continue;
      if (dot(sub(line.labelAt, cam.eye), cam.forward) < near) continue;
      const [x, y] = this.project(cam, line.labelAt);
      ctx.fillStyle = "#0009";
      const tw = ctx.measureText(line.label).width;
      ctx.fillRect(x + 4, y - 11, tw + 6, 14);
      ctx.fillStyle = line.colour;
      ctx.fillText(line.label, x + 7, y);
    }
    this.drawn = [];
    if (this.rays) {
      const nodes = [...this.rays.model.nodes].sort((a, z) => (a.id === this.hl) - (z.id === this.hl));
      for (const n of nodes) {
        if (n.depth > this.depth) continue;
        const sgm = this.rays.segments.get(n.id);
        const pts = seg(sgm.p, sgm.q);
        if (!pts) continue;
        strokeRay(ctx, pts, styleKey(n), { highlight: this.hl === n.id, dim: this.hl !== null && this.hl !== n.id });
        this.drawn.push({ id: n.id, pts });
        if (!sgm.open && n.kind !== "shadow") {
          ctx.beginPath();
          ctx.arc(pts[1][0], pts[1][1], 3, 0, 2 * Math.PI);
          ctx.fillStyle = "#fff";
          ctx.fill();
        }
      }
    }
    c.dataset.lines = String(count);
    c.dataset.rays = String(this.drawn.length);
  }

  // -- interaction ------------------------------------------------------------------------------

  down(e) {
    this.canvas.setPointerCapture(e.pointerId);
    this.pointers.set(e.pointerId, { x: e.clientX, y: e.clientY, x0: e.clientX, y0: e.clientY });
  }

  move(e) {
    const p = this.pointers.get(e.pointerId);
    if (!p) {
      if (e.pointerType === "mouse") this.hoverAt(e);
      return;
    }
    if (this.pointers.size === 2) {
      const [a, b] = [...this.pointers.values()];
      const before = Math.hypot(a.x - b.x, a.y - b.y);
      p.x = e.clientX;
      p.y = e.clientY;
      const after = Math.hypot(a.x - b.x, a.y - b.y);
      if (before > 0 && after > 0) this.zoom(before / after);
      return;
    }
    const dx = e.clientX - p.x;
    const dy = e.clientY - p.y;
    p.x = e.clientX;
    p.y = e.clientY;
    this.orbit.yaw -= dx * 0.008;
    this.orbit.pitch = Math.max(-1.5, Math.min(1.5, this.orbit.pitch + dy * 0.008));
    this.draw();
  }

  up(e) {
    const p = this.pointers.get(e.pointerId);
    this.pointers.delete(e.pointerId);
    if (p && Math.hypot(e.clientX - p.x0, e.clientY - p.y0) < 4 && this.pointers.size === 0) {
      const id = this.nearestAt(e);
      if (id !== null) this.onSelect(id);
    }
  }

  wheel(e) {
    e.preventDefault();
    this.zoom(Math.exp(e.deltaY * 0.0015));
  }

  zoom(k) {
    this.orbit.dist = Math.max(this.radius * 0.2, Math.min(this.radius * 40, this.orbit.dist * k));
    this.draw();
  }

  key(e) {
    const turns = { ArrowLeft: [0.1, 0], ArrowRight: [-0.1, 0], ArrowUp: [0, 0.1], ArrowDown: [0, -0.1] };
    if (turns[e.key]) {
      e.preventDefault();
      this.orbit.yaw += turns[e.key][0];
      this.orbit.pitch = Math.max(-1.5, Math.min(1.5, this.orbit.pitch + turns[e.key][1]));
      this.draw();
    } else if (e.key === "+" || e.key === "=") this.zoom(0.85);
    else if (e.key === "-") this.zoom(1 / 0.85);
    else if (e.key === "0" && this.home) {
      this.orbit = { ...this.home };
      this.draw();
    }
  }

  nearestAt(e) {
    const r = this.canvas.getBoundingClientRect();
    const x = e.clientX - r.left;
    const y = e.clientY - r.top;
    let best = null;
    let bestD = 8;
    for (const { id, pts } of this.drawn) {
      const [a, b] = pts;
      const dx = b[0] - a[0];
      const dy = b[1] - a[1];
      const l2 = dx * dx + dy * dy;
      const t = l2 ? Math.max(0, Math.min(1, ((x - a[0]) * dx + (y - a[1]) * dy) / l2)) : 0;
      const dist = Math.hypot(x - (a[0] + t * dx), y - (a[1] + t * dy));
      if (dist < bestD) {
        bestD = dist;
        best = id;
      }
    }
    return best;
  }

  hoverAt(e) {
    this.onHover(this.nearestAt(e));
  }
}
