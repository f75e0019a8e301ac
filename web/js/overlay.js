// The ray tree drawn over the rendered image: every ray's segment projected to pixels through the
// scene's own camera (vec.js projectToFilm, the inverse of the eye ray's formula), the picked pixel
// outlined. The eye ray runs along the line of sight, so it shows as a ring around its pixel.
import { strokeRay, styleKey } from "./rays.js";
import { fitCanvas } from "./util.js";
import { clipNear, projectToFilm } from "./vec.js";

function distToSegment(px, py, a, b) {
  const dx = b[0] - a[0];
  const dy = b[1] - a[1];
  const l2 = dx * dx + dy * dy;
  const t = l2 ? Math.max(0, Math.min(1, ((px - a[0]) * dx + (py - a[1]) * dy) / l2)) : 0;
  return Math.hypot(px - (a[0] + t * dx), py - (a[1] + t * dy));
}

export class Overlay {
  constructor(canvas, { onHover, onPick, onSelect }) {
    this.canvas = canvas;
    this.onHover = onHover;
    this.onPick = onPick; // a click away from the rays: the ray tree of that pixel
    this.onSelect = onSelect; // a click on a ray: keep it highlighted
    this.img = null;
    this.data = null; // {model, segments, basis, pixel, width, height}
    this.depth = Infinity;
    this.hl = null;
    this.drawn = []; // [{id, pts}] in canvas pixels, for hit tests
    canvas.addEventListener("mousemove", (e) => this.hover(e));
    canvas.addEventListener("mouseleave", () => this.onHover(null));
    canvas.addEventListener("click", (e) => this.click(e));
    new ResizeObserver(() => this.draw()).observe(canvas.parentElement);
  }

  /** imageUrl: the rendered image; basis: cameraBasis of the scene at the image's size. */
  set(imageUrl, data) {
    this.data = data;
    if (!imageUrl) {
      this.img = null;
      this.draw();
      return;
    }
    const img = new Image();
    img.onload = () => {
      if (this.data === data) {
        this.img = img;
        this.draw();
      }
    };
    img.src = imageUrl;
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

  size() {
    const d = this.data;
    const box = this.canvas.parentElement.getBoundingClientRect();
    const maxH = Math.max(200, window.innerHeight * 0.55);
    const scale = Math.min(box.width / d.width, maxH / d.height);
    return { cssW: Math.floor(d.width * scale), cssH: Math.floor(d.height * scale), scale };
  }

  draw() {
    const c = this.canvas;
    const d = this.data;
    if (!d) {
      c.dataset.rays = "0";
      return;
    }
    const { cssW, cssH, scale } = this.size();
    const ctx = fitCanvas(c, cssW, cssH);
    if (this.img) {
      ctx.imageSmoothingEnabled = false;
      ctx.globalAlpha = 0.85;
      ctx.drawImage(this.img, 0, 0, cssW, cssH);
      ctx.globalAlpha = 1;
    }
    const b = d.basis;
    const near = 1e-3;
    const toCanvas = (p) => {
      const f = projectToFilm(b, p);
      const clamp = (v) => Math.max(-1e5, Math.min(1e5, v));
      return [clamp(f.x * scale), clamp(f.y * scale)];
    };
    this.drawn = [];
    const order = [...d.model.nodes].sort((a, z) => (a.id === this.hl) - (z.id === this.hl)); // highlighted last
    const dots = [];
    for (const n of order) {
      if (n.depth > this.depth) continue;
      const seg = d.segments.get(n.id);
      const key = styleKey(n);
      const dim = this.hl !== null && this.hl !== n.id;
      if (n.kind === "eye") {
        // a pinhole eye ray projects to one point; a thin lens's starts off the pinhole: draw what shows
        const clipped = clipNear(seg.p, seg.q, b.from, b.forward, near);
        if (clipped) {
          const pts = clipped.map(toCanvas);
          if (Math.hypot(pts[1][0] - pts[0][0], pts[1][1] - pts[0][1]) > 3)
            strokeRay(ctx, pts, key, { highlight: this.hl === n.id, dim });
        }
        const f = projectToFilm(b, seg.q);
        const at =
          Number.isFinite(f.x) && f.z > 0
            ? [f.x * scale, f.y * scale]
            : [(d.pixel[0] + 0.5) * scale, (d.pixel[1] + 0.5) * scale];
        const r = 9;
        const ring = [];
        for (let i = 0; i <= 24; i++)
          ring.push([at[0] + r * Math.cos((i / 24) * 2 * Math.PI), at[1] + r * Math.sin((i / 24) * 2 * Math.PI)]);
        strokeRay(ctx, ring, key, { highlight: this.hl === n.id, dim });
        this.drawn.push({ id: n.id, pts: ring, ring: at });
        if (!seg.open) dots.push({ at, n, dim });
        continue;
      }
      const clipped = clipNear(seg.p, seg.q, b.from, b.forward, near);
      if (!clipped) continue;
      const pts = clipped.map(toCanvas);
      strokeRay(ctx, pts, key, { highlight: this.hl === n.id, dim });
      this.drawn.push({ id: n.id, pts });
      if (!seg.open && projectToFilm(b, seg.q).z > near) dots.push({ at: toCanvas(seg.q), n, dim });
    }
    for (const { at, n, dim } of dots) {
      ctx.globalAlpha = dim ? 0.3 : 1;
      ctx.beginPath();
      if (n.kind === "shadow" && n.occluded) {
        ctx.strokeStyle = "#ff4d6d";
        ctx.lineWidth = 2.5;
        ctx.moveTo(at[0] - 5, at[1] - 5);
        ctx.lineTo(at[0] + 5, at[1] + 5);
        ctx.moveTo(at[0] + 5, at[1] - 5);
        ctx.lineTo(at[0] - 5, at[1] + 5);
        ctx.stroke();
      } else if (n.kind !== "shadow") {
        ctx.arc(at[0], at[1], 3.2, 0, 2 * Math.PI);
        ctx.fillStyle = "#fff";
        ctx.strokeStyle = "#000";
        ctx.lineWidth = 1.5;
        ctx.fill();
        ctx.stroke();
      }
      ctx.globalAlpha = 1;
    }
    // the picked pixel
    const px = Math.max(scale, 4);
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 1.5;
    ctx.strokeRect((d.pixel[0] + 0.5) * scale - px / 2, (d.pixel[1] + 0.5) * scale - px / 2, px, px);
    c.dataset.rays = String(this.drawn.length);
  }

  pointer(e) {
    const r = this.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  nearest(x, y) {
    let best = null;
    let bestD = 8;
    for (const { id, pts, ring } of this.drawn) {
      let dist = Infinity;
      if (ring) dist = Math.abs(Math.hypot(x - ring[0], y - ring[1]) - 9);
      else for (let i = 1; i < pts.length; i++) dist = Math.min(dist, distToSegment(x, y, pts[i - 1], pts[i]));
      if (dist < bestD) {
        bestD = dist;
        best = id;
      }
    }
    return best;
  }

  hover(e) {
    const [x, y] = this.pointer(e);
    this.onHover(this.nearest(x, y));
  }

  click(e) {
    if (!this.data) return;
    const [x, y] = this.pointer(e);
    const id = this.nearest(x, y);
    if (id !== null) {
      this.onSelect(id);
      return;
    }
    const { scale } = this.size();
    const fx = Math.floor(x / scale);
    const fy = Math.floor(y / scale);
    if (fx >= 0 && fy >= 0 && fx < this.data.width && fy < this.data.height) this.onPick(fx, fy);
  }
}
