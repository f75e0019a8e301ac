// A student's own tracer explained (docs/assignments.md, "Your own tracer's ray trees"): the answer of
// POST /api/assignments/{aid}/submissions/{sid}/trees (or GET of the latest one), one logged tree per pixel
// against the reference's tree through the same pixel's centre. A row of pixel buttons (each with its verdict)
// picks the pixel; for it, the server's sentence about the first difference, then the two trees side by side,
// each in the page's ray-tree views: the diagram (diagram.js), the rays over an image (overlay.js: the
// student's tree over the student's image, the reference's over the reference image), the 3D view (view3d.js)
// and the tree in words (raylist.js), linked within a side (hover or focus a ray: it is shown in each view).
// The first difference is marked by the node ids the answer gives (`student`, `reference`; null where that
// tree has no such ray).
//
// A logged tree has only the log's fields (tracer/grading/treelog.py): no `depth` (derived from the parents
// here: the eye ray 1, a reflection or transmission ray its parent's + 1, a shadow ray its parent's), no `end`,
// and objects by index (named here from the scene, else from the reference's hits). Used by the student's
// feedback (owntracer.js) and the instructor's view of a student (instructor_board.js), which also draws the
// class's first differences as a bar chart (`whatChart`).
import { blob } from "../api.js";
import { renderDiagram } from "../diagram.js";
import { Overlay } from "../overlay.js";
import { renderRayList } from "../raylist.js";
import { legend } from "../rays.js";
import { colourSwatch, drawRays, highlightRay, treeModel } from "../rayviews.js";
import { h, s } from "../util.js";
import { View3D } from "../view3d.js";
import { inWordsOf, mark } from "./compare.js";

/** The comparison's vocabulary (tracer/grading/explain.py), in words for the chart and the buttons. */
export const WHATS = {
  eye_ray: "eye ray",
  hit: "what a ray hits",
  normal: "normal",
  shadow_acne: "shadow acne",
  shadow: "shadow ray",
  reflection_direction: "reflection direction",
  refraction_direction: "refraction direction",
  total_internal_reflection: "total internal reflection",
  fresnel: "Fresnel weights",
  shading: "shading terms",
  attenuation: "attenuation",
  depth: "depth limit",
  missing_ray: "a missing ray",
  extra_ray: "an extra ray",
  encoding: "pixel encoding",
};
const whatWords = (what) => WHATS[what] || what;

/** The logged tree as the views draw it: each node's `depth` from its parents, each hit's object named (the
 * scene's objects, else a reference hit of the same object: the same node id first) with its material. */
export function studentTree(tree, reference, scene = null) {
  const byId = new Map(tree.nodes.map((n) => [n.id, n]));
  const refById = new Map((reference?.nodes || []).map((n) => [n.id, n]));
  const depths = new Map();
  const depthOf = (n) => {
    let d = 1; // walk up to the root: at most as many steps as nodes (the server refused cycles)
    for (let at = n, steps = 0; at.parent !== null && at.parent !== undefined && steps < byId.size; steps++) {
      if (at.kind !== "shadow") d++;
      at = byId.get(at.parent);
      if (!at) break;
    }
    return d;
  };
  for (const n of tree.nodes) depths.set(n.id, depthOf(n));
  const named = (n) => {
    if (!n.hit) return n.hit;
    const hit = { ...n.hit };
    const i = hit.object;
    const obj = Number.isInteger(i) ? scene?.objects?.[i] : null;
    const same = refById.get(n.id)?.hit;
    const like =
      same && same.object === i ? same : (reference?.nodes || []).find((r) => r.hit && r.hit.object === i)?.hit;
    if (!hit.object_name) hit.object_name = obj?.name || like?.object_name || null;
    if (!hit.material)
      hit.material = (typeof obj?.material === "string" ? obj.material : null) || like?.material || null;
    return hit;
  };
  return {
    ...tree,
    color: tree.color ?? null,
    nodes: tree.nodes.map((n) => ({ ...n, depth: depths.get(n.id), hit: named(n) })),
  };
}

const shownPictures = new WeakMap(); // container -> the object URLs of its answer's two pictures

/** The object URL of a picture that needs the token (null when it cannot be read). */
async function picture(url, auth) {
  if (!url) return null;
  try {
    return URL.createObjectURL(await blob(url, auth));
  } catch {
    return null;
  }
}

/** One side: its title, colour, diagram, the rays over its image and in 3D, the tree in words. */
function side(name, title, tree, markedId, ctx) {
  const model = treeModel(tree);
  const marked = markedId === null || markedId === undefined ? null : model.byId.get(markedId) || null;
  const n = model.nodes.length;
  const colour = Array.isArray(tree.color) ? colourSwatch(tree.color) : ["not logged"];
  const box = h("div", { class: "compare-tree", tabindex: 0, role: "group", "aria-label": `${title}: ${n} rays` });
  const section = h(
    "section",
    { class: "compare-side", dataset: { side: name } },
    h("h4", {}, title),
    h("p", { class: "compare-summary" }, `${n} ray${n === 1 ? "" : "s"}; the pixel's colour `, ...colour),
    box,
  );
  const view = { section, box, model, marked, title, name };
  if (ctx.scene) {
    const where =
      name === "student" ? (ctx.as === "instructor" ? "the student's image" : "your image") : "the reference image";
    view.overlayCanvas = h("canvas", { role: "img", "aria-label": `${title}: its ${n} rays drawn over ${where}` });
    view.canvas3d = h("canvas", {
      tabindex: 0,
      role: "img",
      "aria-label": `${title}: its ${n} rays in 3D in the scene; arrow keys orbit, plus and minus zoom, 0 resets`,
    });
    section.append(
      h(
        "div",
        { class: "tl-views" },
        h(
          "figure",
          { class: "rt-fig" },
          h("figcaption", {}, `Over ${where}`),
          h("div", { class: "canvas-box" }, view.overlayCanvas),
        ),
        h(
          "figure",
          { class: "rt-fig" },
          h("figcaption", {}, "In 3D (drag, wheel; keys: arrows, + −, 0)"),
          h("div", { class: "canvas-box" }, view.canvas3d),
        ),
      ),
    );
  }
  view.words = h("ul", { class: "rt-list" });
  section.append(h("details", { class: "rt-text" }, h("summary", {}, "The tree in words"), view.words));
  return view;
}

/** Draw a side's views once it is in the page, linked: a ray hovered or focused in one is shown in the others;
 * the first difference is the ray shown when none is. */
function draw(view, ctx, image, d) {
  const { model, marked } = view;
  let diagram = null;
  let list = null;
  const show = (id) =>
    highlightRay({ diagram, list, overlay: view.overlay, view3d: view.view3d }, id ?? marked?.id ?? null);
  diagram = renderDiagram(view.box, model, {
    onHover: show,
    onSelect: show,
    open: marked ? [marked.id] : [],
    label: `${view.title}: ${model.nodes.length} rays (the tree in words, below, names each)`,
  });
  list = renderRayList(view.words, model, {
    label: `${view.title}: ${model.nodes.length} rays`,
    onFocus: show,
    onSelect: show,
  });
  if (marked)
    view.words
      .querySelector(`[data-id="${marked.id}"] > .rt-li-text`)
      ?.append(` The first difference: ${whatWords(d.what)}.`);
  if (ctx.scene) {
    view.overlay = new Overlay(view.overlayCanvas, { onHover: show, onSelect: show, onPick: () => {} });
    view.view3d = new View3D(view.canvas3d, { onHover: show, onSelect: show });
    drawRays(view.overlay, view.view3d, image, model, ctx);
  }
  const g = marked ? mark(view, whatWords(d.what)) : null;
  show(null);
  return g;
}

/**
 * Show a tree-log answer ({submission, width, height, trees, scene?}) in `container`. `as`: "student" or
 * "instructor" (the words and the titles); `images`: {student, reference} API URLs of the two pictures;
 * `auth`: the request options that read them ({token} or {as}); `probes`: [{x, y, why}] to say why a pixel
 * was asked for. Returns {select(i)}.
 */
export function showTreeAnswers(container, answer, { as = "student", images = {}, auth = {}, probes = [] } = {}) {
  const trees = answer.trees || [];
  const scene = answer.scene?.camera ? answer.scene : null;
  const ctx = { as, scene, width: answer.width, height: answer.height };
  const whose = as === "instructor" ? "The student's" : "Your";
  const differ = trees.filter((t) => !t.matches);
  const root = h("div", { class: "compare tl", dataset: { trees: trees.length, differ: differ.length } });
  const said = h(
    "p",
    { class: "tl-verdict", role: "status", "aria-live": "polite" },
    !trees.length
      ? "The log had no trees."
      : differ.length
        ? `${trees.length} tree${trees.length === 1 ? "" : "s"} compared: ${differ.length} differ${differ.length === 1 ? "s" : ""} from the reference's (first differences: ${[...new Set(differ.map((t) => whatWords(t.differences[0].what)))].join(", ")}).`
        : `${trees.length} tree${trees.length === 1 ? "" : "s"} compared: every one matches the reference's.`,
  );
  const picker = h("div", { class: "tl-pixels", role: "group", "aria-label": "Pixels of the log" });
  const body = h("div", { class: "tl-body" });
  root.append(said, picker, body);
  container.replaceChildren(root);
  const pictures = Promise.all([picture(images.student, auth), picture(images.reference, auth)]);
  for (const url of shownPictures.get(container) || []) if (url) URL.revokeObjectURL(url); // the last answer's
  pictures.then((urls) => shownPictures.set(container, urls));
  const buttons = trees.map((t, i) => {
    const d = t.differences[0];
    const b = h(
      "button",
      {
        type: "button",
        class: `small tl-pixel-button ${t.matches ? "same" : "differs"}`,
        "aria-pressed": "false",
        dataset: { i, what: d ? d.what : "none" },
        onclick: () => select(i),
      },
      h("span", { "aria-hidden": "true" }, t.matches ? "✓" : "✗"),
      `(${t.pixel[0]}, ${t.pixel[1]})${t.matches ? " matches" : `: ${whatWords(d.what)}`}`,
    );
    return b;
  });
  picker.replaceChildren(...buttons);
  picker.hidden = trees.length < 2;
  let seq = 0;
  async function select(i) {
    const t = trees[i];
    if (!t) return;
    const mine = ++seq;
    // not drawn until this pixel's trees are (the pictures may still be loading): a test or a reader that waits
    // for data-drawn must not take the last pixel's drawing for this one's
    delete body.dataset.drawn;
    for (const [j, b] of buttons.entries()) b.setAttribute("aria-pressed", String(j === i));
    const d = t.differences[0] || null;
    const probe = probes.find((p) => p.x === t.pixel[0] && p.y === t.pixel[1]);
    const head = h(
      "p",
      { class: "compare-message", dataset: { what: d ? d.what : "none" } },
      d
        ? inWordsOf(as, d.message)
        : `${whose} tree at this pixel matches the reference's: the same rays, hits, directions and terms.`,
    );
    const more = t.differences.slice(1);
    const views = [
      side(
        "student",
        as === "instructor" ? "The student's tree" : "Your tree (from your log)",
        studentTree(t.student, t.reference, scene),
        d ? d.student : null,
        ctx,
      ),
      side("reference", "The reference's tree", t.reference, d ? d.reference : null, ctx),
    ];
    const moreList = more.length
      ? h(
          "details",
          { class: "tl-more" },
          h("summary", {}, `${more.length} more difference${more.length === 1 ? "" : "s"} after the first`),
          h(
            "ul",
            {},
            more.map((m) =>
              h(
                "li",
                { dataset: { what: m.what } },
                h("strong", {}, whatWords(m.what)),
                ": ",
                inWordsOf(as, m.message),
              ),
            ),
          ),
        )
      : "";
    body.replaceChildren(
      h(
        "h3",
        { class: "compare-title", tabindex: -1 },
        `Ray trees at pixel (${t.pixel[0]}, ${t.pixel[1]})`,
        probe?.why ? h("span", { class: "muted tl-why" }, ` · ${probe.why}`) : null,
      ),
      head,
      moreList,
      h(
        "div",
        { class: "compare-sides" },
        views.map((v) => v.section),
      ),
      legend(),
    );
    body.dataset.x = String(t.pixel[0]);
    body.dataset.y = String(t.pixel[1]);
    const [studentImage, referenceImage] = await pictures;
    if (mine !== seq) return;
    for (const v of views) {
      const g = draw(v, ctx, v.name === "student" ? studentImage : referenceImage, d);
      if (g) {
        const boxRect = v.box.getBoundingClientRect(); // the marked ray in view inside its own scrolling box
        const r = g.getBoundingClientRect();
        v.box.scrollLeft += r.left - boxRect.left - (boxRect.width - r.width) / 2;
        v.box.scrollTop += r.top - boxRect.top - 24;
      }
    }
    body.dataset.drawn = "true";
  }
  const first = trees.findIndex((t) => !t.matches);
  if (trees.length) select(Math.max(first, 0));
  return { select };
}

/**
 * The class's first differences (the dashboard's `tree_whats`, {what: count}) as a bar chart, the most
 * frequent first: an SVG picture (one image to a screen reader, named with the counts) and the same counts
 * in a table below it.
 */
export function whatChart(counts) {
  const rows = Object.entries(counts || {}).sort((a, b) => b[1] - a[1] || a[0].localeCompare(b[0]));
  if (!rows.length)
    return h(
      "p",
      { class: "hint", id: "whats-empty" },
      "No tree log compared yet: the bars appear as students send their tracers' logs.",
    );
  const W = 420,
    L = 170,
    R = 36,
    BAR = 18,
    GAP = 6,
    T = 4; // prettier-ignore
  const H = T + rows.length * (BAR + GAP);
  const top = Math.max(...rows.map(([, n]) => n));
  const total = rows.reduce((a, [, n]) => a + n, 0);
  const label = `First differences over the class, ${total} tree${total === 1 ? "" : "s"}: ${rows.map(([w, n]) => `${whatWords(w)} ${n}`).join(", ")}.`;
  const svg = s(
    "svg",
    { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": label, class: "whats-svg", id: "whats-svg" },
    rows.map(([what, n], i) => {
      const y = T + i * (BAR + GAP);
      const w = Math.max(2, ((W - L - R) * n) / top);
      return s(
        "g",
        { class: "bar", dataset: { what, count: n } },
        s("title", {}, `${whatWords(what)}: ${n}`),
        s("text", { x: L - 6, y: y + BAR - 5, "text-anchor": "end", class: "tick" }, whatWords(what)),
        s("rect", { x: L, y, width: w, height: BAR, rx: 2 }),
        s("text", { x: L + w + 4, y: y + BAR - 5, class: "count" }, String(n)),
      );
    }),
  );
  const table = h(
    "table",
    { class: "grade-table whats-table", id: "whats-table" },
    h("caption", { class: "sr-only" }, "First differences of the class's tree logs, by what differs"),
    h(
      "thead",
      {},
      h("tr", {}, h("th", { scope: "col" }, "what differs first"), h("th", { scope: "col", class: "num" }, "trees")),
    ),
    h(
      "tbody",
      {},
      rows.map(([what, n]) =>
        h(
          "tr",
          { dataset: { what } },
          h("th", { scope: "row" }, whatWords(what), " ", h("code", {}, what)),
          h("td", { class: "num" }, String(n)),
        ),
      ),
    ),
  );
  return h(
    "div",
    { class: "whats" },
    svg,
    h("details", { class: "whats-text" }, h("summary", {}, "The counts as a table"), table),
  );
}
