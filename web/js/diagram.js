// The ray tree as a diagram (SVG): one box per ray, the edge into a box drawn in the ray's style.
// A box shows what the ray hit (object, material), its weight, the local Phong terms there, the
// radiance it carries back, and why it ended; shadow rays get a smaller box.
import { RAY_STYLES, endWords, styleKey } from "./rays.js";
import { cssColour, num, rgb, s } from "./util.js";

const W = 184; // a ray's box
const H = 112;
const SW = 148; // a shadow ray's box
const SH = 66;
const GW = 188; // a group of shadow rays' box (as high as a shadow ray's)
const GROUP_FROM = 4; // a node's shadow rays to one light, this many or more, are one box until it is opened
const GAP = 14;
const ROW = H + 54;
const TOP = 40;

const cut = (text, chars) => (text.length > chars ? `${text.slice(0, chars - 1)}…` : text);
const mean = (v) => (Array.isArray(v) ? (v[0] + v[1] + v[2]) / 3 : v);

function hitName(n) {
  if (!n.hit) return n.kind === "shadow" ? `→ light ${n.light}` : "nothing: the background";
  return (
    n.hit.object_name ||
    (n.hit.light !== null && n.hit.light !== undefined ? `light ${n.hit.light}` : `object ${n.hit.object}`)
  );
}

/** Sizes and positions: a tidy tree where each subtree is as wide as its children side by side. `model`: the
 * boxes to draw ({root, children}, from `visible`). */
function layout(model) {
  const size = (n) => (n.group ? [GW, SH] : n.kind === "shadow" ? [SW, SH] : [W, H]);
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

const hasParent = (n) => n.parent !== null && n.parent !== undefined;
const groupKey = (n) => (n.kind === "shadow" && hasParent(n) ? `${n.parent}:${n.light}` : null);

/** The boxes to draw: every ray, except that a node's shadow rays to one light, GROUP_FROM or more of them (16
 * light samples: 16 boxes, unreadable side by side), are one group box ("16 shadow rays: 11 reach the light, 5
 * blocked") unless its key ("parent:light") is in `open`. {nodes, children, root, groupOf: ray id -> its group}. */
export function visible(model, open = new Set()) {
  const counts = new Map();
  for (const n of model.nodes) {
    const key = groupKey(n);
    if (key) counts.set(key, (counts.get(key) || 0) + 1);
  }
  const nodes = [];
  const groups = new Map();
  const groupOf = new Map();
  for (const n of model.nodes) {
    const key = groupKey(n);
    if (!key || counts.get(key) < GROUP_FROM || open.has(key)) {
      nodes.push(n);
      continue;
    }
    let g = groups.get(key);
    if (!g) {
      g = {
        group: true,
        id: `g${key}`,
        key,
        parent: n.parent,
        light: n.light,
        kind: "shadow",
        depth: n.depth,
        members: [],
      };
      groups.set(key, g);
      nodes.push(g);
    }
    g.members.push(n);
    g.depth = Math.min(g.depth, n.depth);
    groupOf.set(n.id, g);
  }
  const children = new Map();
  for (const n of nodes) {
    if (!hasParent(n)) continue;
    if (!children.has(n.parent)) children.set(n.parent, []);
    children.get(n.parent).push(n);
  }
  return { nodes, children, root: model.root, groupOf, groups };
}

/** A group's words: "16 shadow rays to light 0", "11 reach the light, 5 blocked". */
export function groupWords(g) {
  const blocked = g.members.filter((m) => m.occluded).length;
  const reach = g.members.length - blocked;
  return [
    `${g.members.length} shadow rays to light ${g.light}`,
    `${reach} reach${reach === 1 ? "es" : ""} the light, ${blocked} blocked`,
  ];
}

function swatchRow(x, y, items) {
  // [label, rgb] pairs: a coloured square and the channel mean, side by side
  const g = s("g", { class: "swatches" });
  let cx = x;
  for (const [label, v] of items) {
    g.append(
      s("text", { x: cx, y }, label),
      s("rect", {
        x: cx + label.length * 6.2 + 2,
        y: y - 9,
        width: 10,
        height: 10,
        fill: cssColour(v),
        stroke: "#0008",
      }),
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
  const g = s("g", {
    class: "rt-node",
    transform: `translate(${p.x}, ${p.y})`,
    dataset: { id: n.id, kind: key, depth: n.depth },
  });
  g.append(s("rect", { class: "box", width: p.w, height: p.h, rx: 6 }));
  g.append(
    s("rect", { class: "head", width: p.w, height: 18, rx: 6, fill: st.colour }),
    s("rect", { width: p.w, height: 8, y: 10, fill: st.colour }),
  );
  g.append(s("text", { class: "title", x: 7, y: 13 }, `#${n.id} ${n.kind} · depth ${n.depth}`));
  const line = (i, text, cls = "") => s("text", { x: 7, y: 18 + 14 * i + 1, class: cls }, text);
  if (n.kind === "shadow") {
    g.append(line(1, cut(`→ light ${n.light}`, 20)));
    g.append(
      line(2, n.occluded ? cut(`blocked by ${hitName(n)}`, 20) : "reached the light", n.occluded ? "bad" : "good"),
    );
    g.append(swatchRow(7, 18 + 14 * 3 + 1, [["L", n.radiance]]));
    return g;
  }
  const mat = n.hit?.material ? ` · ${n.hit.material}` : "";
  g.append(line(1, cut(hitName(n) + mat, 28), "strong"));
  g.append(
    line(2, cut(`weight ${rgb(n.weight, 2)}${n.t !== null && n.t !== undefined ? ` · t ${num(n.t, 3)}` : ""}`, 28)),
  );
  const t = n.terms;
  if (t)
    g.append(
      swatchRow(7, 18 + 14 * 3 + 1, [
        ["a", t.ambient],
        ["d", t.diffuse],
        ["s", t.specular],
      ]),
    );
  else g.append(line(3, n.hit ? "no local terms" : "returns the background", "muted"));
  g.append(swatchRow(7, 18 + 14 * 4 + 1, [["L carried", n.radiance]]));
  if (n.end) g.append(line(5, cut(`end: ${endWords(n, true)}`, 28), "end"));
  return g;
}

function groupBox(g, p) {
  const st = RAY_STYLES[styleKey(g.members[0])];
  const [count, outcome] = groupWords(g);
  const blocked = g.members.some((m) => m.occluded);
  const node = s("g", {
    class: "rt-node rt-group",
    transform: `translate(${p.x}, ${p.y})`,
    dataset: { group: g.key, kind: "shadow", depth: g.depth, count: g.members.length },
  });
  node.append(s("rect", { class: "box", width: p.w, height: p.h, rx: 6 }));
  node.append(
    s("rect", { class: "head", width: p.w, height: 18, rx: 6, fill: st.colour }),
    s("rect", { width: p.w, height: 8, y: 10, fill: st.colour }),
  );
  node.append(
    s("text", { class: "title", x: 7, y: 13 }, `#${g.members[0].id}–#${g.members.at(-1).id} shadow · depth ${g.depth}`),
  );
  const line = (i, text, cls = "") => s("text", { x: 7, y: 18 + 14 * i + 1, class: cls }, text);
  node.append(
    line(1, count, "strong"),
    line(2, outcome, blocked ? "bad" : "good"),
    line(3, "▸ click to show each", "muted"),
  );
  return node;
}

/**
 * Draw the tree into `container`. Returns {highlight(id), setDepth(d), count}.
 * Hovering a box calls onHover(id); a click calls onSelect(id). The drawing is one image to a screen reader,
 * named `label`: the rays in words are the list of web/js/raylist.js (or the caller's own text).
 */
export function renderDiagram(container, model, { onHover, onSelect, label = null, open = [] }) {
  const name = label || `ray tree diagram, ${model.nodes.length} rays`;
  const opened = new Set(); // the groups of shadow rays shown ray by ray ("parent:light")
  for (const id of open) {
    const n = model.nodes.find((x) => x.id === id);
    if (n && groupKey(n)) opened.add(groupKey(n)); // a ray the caller marks is never hidden in a group
  }
  let fitted = false;
  let depthLimit = Infinity;
  let current = null;
  let drawn = null; // {svg, pos, width, height, view, nodeOf, edgeOf}

  const draw = () => {
    const view = visible(model, opened);
    const { pos, width, height } = layout(view);
    const grouped = view.groups.size ? "; a node's shadow rays to a light are one box: click it to show each" : "";
    const svg = s("svg", {
      class: "rt-svg",
      width,
      height,
      viewBox: `0 0 ${width} ${height}`,
      role: "img",
      "aria-label": name + grouped,
    });
    const edges = s("g", { class: "edges" });
    const boxes = s("g", { class: "boxes" });
    const edgeOf = new Map();
    const nodeOf = new Map();
    for (const n of view.nodes) {
      const p = pos.get(n.id);
      const st = RAY_STYLES[styleKey(n.group ? n.members[0] : n)];
      let d;
      if (!hasParent(n)) {
        d = `M ${p.x + p.w / 2} ${p.y - 30} L ${p.x + p.w / 2} ${p.y}`;
        const eye = s(
          "g",
          { class: "eye-icon", transform: `translate(${p.x + p.w / 2}, ${p.y - 32})` },
          s("ellipse", { rx: 11, ry: 6 }),
          s("circle", { r: 3 }),
        );
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
      const path = s("path", {
        d,
        class: "edge",
        stroke: st.colour,
        "stroke-width": st.width,
        "stroke-dasharray": st.dash.join(" ") || null,
      });
      const eg = s(
        "g",
        { class: "rt-edge", dataset: n.group ? { group: n.key, depth: n.depth } : { id: n.id, depth: n.depth } },
        under,
        path,
      );
      edges.append(eg);
      edgeOf.set(n.id, eg);
      if (n.group) {
        const box = groupBox(n, p);
        box.addEventListener("click", () => toggle(n.key));
        boxes.append(box);
        nodeOf.set(n.id, box);
        continue;
      }
      const box = nodeBox(n, p);
      box.addEventListener("mouseenter", () => onHover(n.id));
      box.addEventListener("mouseleave", () => onHover(null));
      box.addEventListener("click", () => onSelect(n.id));
      boxes.append(box);
      nodeOf.set(n.id, box);
    }
    // an opened group folds back from a tab over its first ray
    for (const key of opened) {
      const first = view.nodes.find((n) => groupKey(n) === key);
      const p = first && pos.get(first.id);
      if (!p || !view.nodes.some((n) => n.id !== first.id && groupKey(n) === key)) continue;
      const count = view.nodes.filter((n) => groupKey(n) === key).length;
      const words = `▴ fold the ${count} shadow rays`;
      const fold = s(
        "g",
        { class: "rt-fold", dataset: { group: key } },
        s("rect", { x: p.x, y: p.y - 21, width: words.length * 6.2 + 10, height: 17, rx: 4 }),
        s("text", { x: p.x + 5, y: p.y - 9 }, words),
      ); // a tab over its first ray, on a plate: the edges pass behind
      fold.addEventListener("click", () => toggle(key));
      boxes.append(fold);
    }
    svg.append(edges, boxes);
    container.replaceChildren(svg);
    container.dataset.nodes = String(model.nodes.length);
    container.dataset.boxes = String(view.nodes.length);
    drawn = { svg, pos, width, height, view, nodeOf, edgeOf };
  };

  /** Open or fold a group; the view keeps its place at the group (its first ray). */
  const toggle = (key) => {
    const before = boxAt(`g${key}`) || boxAt(drawn.view.nodes.find((n) => groupKey(n) === key)?.id);
    if (opened.has(key)) opened.delete(key);
    else opened.add(key);
    draw();
    apply();
    const after = boxAt(`g${key}`) || boxAt(drawn.view.nodes.find((n) => groupKey(n) === key)?.id);
    if (before && after) {
      container.scrollLeft += after.left - before.left;
      container.scrollTop += after.top - before.top;
    }
  };

  /** Where a box is in the container's scrolled content (px, as drawn now), or null. */
  const boxAt = (id) => {
    const p = id !== undefined ? drawn.pos.get(id) : null;
    if (!p) return null;
    const k = drawn.svg.getBoundingClientRect().width / drawn.width || 1;
    return { left: p.x * k, top: p.y * k, w: p.w * k, h: p.h * k };
  };

  /** The size (fitted or not), the depth and the highlight, again on a fresh drawing. */
  const apply = () => {
    const maxH = parseFloat(getComputedStyle(container).maxHeight) || window.innerHeight * 0.75;
    const { svg, width, height } = drawn;
    const k = fitted ? Math.min(1, (container.clientWidth || width) / width, maxH / height) : 1;
    svg.setAttribute("width", String(Math.floor(width * k)));
    svg.setAttribute("height", String(Math.floor(height * k)));
    container.dataset.scale = String(k);
    setDepth(depthLimit);
    highlight(current);
  };

  /** The eye ray's box in view: at the top, in the middle across. */
  const toRoot = () => {
    const r = boxAt(model.root.id);
    container.scrollTop = 0;
    container.scrollLeft = r ? Math.max(0, r.left + r.w / 2 - container.clientWidth / 2) : 0;
  };

  const shownId = (id) => (drawn.view.groupOf.has(id) ? drawn.view.groupOf.get(id).id : id);

  const highlight = (id, scroll = false) => {
    if (current !== null) {
      drawn.nodeOf.get(shownId(current))?.classList.remove("hl");
      drawn.edgeOf.get(shownId(current))?.classList.remove("hl");
    }
    current = id ?? null;
    if (current === null) return;
    const shown = shownId(current); // a ray of a folded group: its group
    drawn.nodeOf.get(shown)?.classList.add("hl");
    drawn.edgeOf.get(shown)?.classList.add("hl");
    if (scroll) {
      const b = boxAt(shown);
      if (!b) return;
      if (b.left < container.scrollLeft || b.left + b.w > container.scrollLeft + container.clientWidth)
        container.scrollTo({ left: Math.max(0, b.left - container.clientWidth / 2 + b.w / 2), behavior: "smooth" });
      if (b.top < container.scrollTop || b.top + b.h > container.scrollTop + container.clientHeight)
        container.scrollTo({ top: Math.max(0, b.top - 40), behavior: "smooth" });
    }
  };

  const setDepth = (limit) => {
    depthLimit = limit;
    for (const n of drawn.view.nodes) {
      const future = n.depth > limit;
      drawn.nodeOf.get(n.id).classList.toggle("future", future);
      drawn.edgeOf.get(n.id).classList.toggle("future", future);
    }
  };

  draw();
  toRoot();
  return {
    count: model.nodes.length,
    highlight,
    setDepth,
    /** on: the whole tree inside the panel (scaled down, never up), from its top left; off: its natural size,
     * scrolled to the eye ray's box. */
    fit(on) {
      fitted = on;
      apply();
      if (on) container.scrollTo({ left: 0, top: 0 });
      else toRoot();
    },
  };
}
