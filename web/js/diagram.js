// The ray tree as a diagram (SVG): one box per ray, the edge into a box drawn in the ray's style.
// A box shows what the ray hit (object, material), its weight, the local Phong terms there, the
// radiance it carries back, and why it ended; shadow rays get a smaller box.
import { RAY_STYLES, endWords, styleKey } from "./rays.js";
import { cssColour, num, rgb, s } from "./util.js";

const W = 184; // a ray's box
const H = 112;
const SW = 148; // a shadow ray's box
const SH = 66;
const GAP = 14;
const ROW = H + 54;
const TOP = 40;

const cut = (text, chars) => (text.length > chars ? text.slice(0, chars - 1) + "…" : text);
const mean = (v) => (Array.isArray(v) ? (v[0] + v[1] + v[2]) / 3 : v);

function hitName(n) {
  if (!n.hit) return n.kind === "shadow" ? `→ light ${n.light}` : "nothing: the background";
  return n.hit.object_name || (n.hit.light !== null && n.hit.light !== undefined ? `light ${n.hit.light}` : `object ${n.hit.object}`);
}

/** Sizes and positions: a tidy tree where each subtree is as wide as its children side by side. */
function layout(model) {
  const size = (n) => (n.kind === "shadow" ? [SW, SH] : [W, H]);
  const widths = new Map();
  const width = (n) => {
    const kids = model.children.get(n.id) || [];
    const own = size(n)[0];
    const sum = kids.reduce((a, k) => a + width(k), 0) + GAP * Math.max(0, kids.length - 1);
    const w = Math.max(own, sum);
    widths.set(n.id, w);
    return w;
  };
  const pos = new Map();
  const place = (n, x0, level) => {
    const [w, hgt] = size(n);
    const total = widths.get(n.id);
    pos.set(n.id, { x: x0 + total / 2 - w / 2, y: TOP + level * ROW, w, h: hgt });
    const kids = model.children.get(n.id) || [];
    const sum = kids.reduce((a, k) => a + widths.get(k.id), 0) + GAP * Math.max(0, kids.length - 1);
    let x = x0 + (total - sum) / 2;
    for (const k of kids) {
      place(k, x, level + 1);
      x += widths.get(k.id) + GAP;
    }
  };
  const root = model.root;
  const total = width(root);
  place(root, 12, 0);
  const levels = Math.max(...[...pos.values()].map((p) => p.y)) + H;
  return { pos, width: total + 24, height: levels + 16 };
}

function swatchRow(x, y, items) {
  // [label, rgb] pairs: a coloured square and the channel mean, side by side
  const g = s("g", { class: "swatches" });
  let cx = x;
  for (const [label, v] of items) {
    g.append(
      s("text", { x: cx, y }, label),
      s("rect", { x: cx + label.length * 6.2 + 2, y: y - 9, width: 10, height: 10, fill: cssColour(v), stroke: "#0008" }),
      s("text", { x: cx + label.length * 6.2 + 15, y }, num(mean(v), 2)),
    );
    cx += label.length * 6.2 + 15 + num(mean(v), 2).length * 6.2 + 8;
  }
  return g;
}

function nodeBox(n, p) {
  const key = styleKey(n);
  const st = RAY_STYLES[key];
  // a picture for the eye and the mouse: the words and the keyboard are the list's (web/js/raylist.js)
  const g = s("g", { class: "rt-node", transform: `translate(${p.x}, ${p.y})`, dataset: { id: n.id, kind: key, depth: n.depth } });
  g.append(s("rect", { class: "box", width: p.w, height: p.h, rx: 6 }));
  g.append(s("rect", { class: "head", width: p.w, height: 18, rx: 6, fill: st.colour }), s("rect", { width: p.w, height: 8, y: 10, fill: st.colour }));
  g.append(s("text", { class: "title", x: 7, y: 13 }, `#${n.id} ${n.kind} · depth ${n.depth}`));
  const line = (i, text, cls = "") => s("text", { x: 7, y: 18 + 14 * i + 1, class: cls }, text);
  if (n.kind === "shadow") {
    g.append(line(1, cut(`→ light ${n.light}`, 20)));
    g.append(line(2, n.occluded ? cut(`blocked by ${hitName(n)}`, 20) : "reached the light", n.occluded ? "bad" : "good"));
    g.append(swatchRow(7, 18 + 14 * 3 + 1, [["L", n.radiance]]));
    return g;
  }
  const mat = n.hit && n.hit.material ? ` · ${n.hit.material}` : "";
  g.append(line(1, cut(hitName(n) + mat, 28), "strong"));
  g.append(line(2, cut(`weight ${rgb(n.weight, 2)}${n.t !== null && n.t !== undefined ? ` · t ${num(n.t, 3)}` : ""}`, 28)));
  const t = n.terms;
  if (t) g.append(swatchRow(7, 18 + 14 * 3 + 1, [["a", t.ambient], ["d", t.diffuse], ["s", t.specular]]));
  else g.append(line(3, n.hit ? "no local terms" : "returns the background", "muted"));
  g.append(swatchRow(7, 18 + 14 * 4 + 1, [["L carried", n.radiance]]));
  if (n.end) g.append(line(5, cut(`end: ${endWords(n, true)}`, 28), "end"));
  return g;
}

/**
 * Draw the tree into `container`. Returns {highlight(id), setDepth(d), count}.
 * Hovering a box calls onHover(id); a click calls onSelect(id). The drawing is one image to a screen reader,
 * named `label`: the rays in words are the list of web/js/raylist.js (or the caller's own text).
 */
export function renderDiagram(container, model, { onHover, onSelect, label = null }) {
  const { pos, width, height } = layout(model);
  const name = label || `ray tree diagram, ${model.nodes.length} rays`;
  const svg = s("svg", { class: "rt-svg", width, height, viewBox: `0 0 ${width} ${height}`, role: "img", "aria-label": name });
  const edges = s("g", { class: "edges" });
  const boxes = s("g", { class: "boxes" });
  const edgeOf = new Map();
  const nodeOf = new Map();
  for (const n of model.nodes) {
    const p = pos.get(n.id);
    const st = RAY_STYLES[styleKey(n)];
    let d;
    if (n.parent === null || n.parent === undefined) {
      d = `M ${p.x + p.w / 2} ${p.y - 30} L ${p.x + p.w / 2} ${p.y}`;
      const eye = s("g", { class: "eye-icon", transform: `translate(${p.x + p.w / 2}, ${p.y - 32})` }, s("ellipse", { rx: 11, ry: 6 }), s("circle", { r: 3 }));
      edges.append(eye);
    } else {
      const q = pos.get(n.parent);
      const x1 = q.x + q.w / 2;
      const y1 = q.y + q.h;
      const x2 = p.x + p.w / 2;
      const y2 = p.y;
      const my = (y1 + y2) / 2;
      d = `M ${x1} ${y1} C ${x1} ${my}, ${x2} ${my}, ${x2} ${y2}`;
    }
    const under = s("path", { d, class: "edge-under" });
    const path = s("path", { d, class: "edge", stroke: st.colour, "stroke-width": st.width, "stroke-dasharray": st.dash.join(" ") || null });
    const eg = s("g", { class: "rt-edge", dataset: { id: n.id, depth: n.depth } }, under, path);
    edges.append(eg);
    edgeOf.set(n.id, eg);
    const box = nodeBox(n, p);
    box.addEventListener("mouseenter", () => onHover(n.id));
    box.addEventListener("mouseleave", () => onHover(null));
    box.addEventListener("click", () => onSelect(n.id));
    boxes.append(box);
    nodeOf.set(n.id, box);
  }
  svg.append(edges, boxes);
  container.replaceChildren(svg);
  container.dataset.nodes = String(model.nodes.length);
  const rootPos = pos.get(model.root.id);
  container.scrollLeft = Math.max(0, rootPos.x + rootPos.w / 2 - container.clientWidth / 2); // the eye ray in view
  container.scrollTop = 0;
  let current = null;
  return {
    count: model.nodes.length,
    highlight(id, scroll = false) {
      if (current !== null) {
        nodeOf.get(current)?.classList.remove("hl");
        edgeOf.get(current)?.classList.remove("hl");
      }
      current = id;
      if (id === null || id === undefined) return;
      nodeOf.get(id)?.classList.add("hl");
      edgeOf.get(id)?.classList.add("hl");
      if (scroll) {
        const p = pos.get(id);
        const scaleX = svg.getBoundingClientRect().width / width || 1;
        const left = p.x * scaleX;
        const top = p.y * scaleX;
        if (left < container.scrollLeft || left + p.w * scaleX > container.scrollLeft + container.clientWidth)
          container.scrollTo({ left: Math.max(0, left - container.clientWidth / 2 + (p.w * scaleX) / 2), behavior: "smooth" });
        if (top < container.scrollTop || top + p.h * scaleX > container.scrollTop + container.clientHeight)
          container.scrollTo({ top: Math.max(0, top - 40), behavior: "smooth" });
      }
    },
    setDepth(limit) {
      for (const n of model.nodes) {
        const future = n.depth > limit;
        nodeOf.get(n.id).classList.toggle("future", future);
        edgeOf.get(n.id).classList.toggle("future", future);
      }
    },
    /** on: the whole tree inside the panel (scaled down, never up); off: its natural size, scrolled. */
    fit(on) {
      const maxH = parseFloat(getComputedStyle(container).maxHeight) || window.innerHeight * 0.75;
      const k = on ? Math.min(1, (container.clientWidth || width) / width, maxH / height) : 1;
      svg.setAttribute("width", String(Math.floor(width * k)));
      svg.setAttribute("height", String(Math.floor(height * k)));
      container.dataset.scale = String(k);
      if (on) container.scrollTo({ left: 0, top: 0 });
    },
  };
}
