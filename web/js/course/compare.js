// Two ray trees at one pixel of a graded scene submission: the student's beside the reference's, each drawn as
// the page draws a ray tree (diagram.js: a box per ray, the edge into it in the ray's style), the first ray
// where they differ marked on both sides and scrolled into view, and the server's sentence about it above.
//
// GET /api/assignments/{aid}/submissions/{sid}/raytree?x&y[&sample] (docs/assignments.md, "Comparing ray trees
// at a pixel") answers {student, reference, difference: null | {student: path, reference: path, what, message,
// nodes: {student: id, reference: id}}}. A path is the child indices from the eye ray, children in id order.
// The student's page imports this module when the difference map is clicked (and links /css/compare.css);
// the instructor's dashboard (web/course.html links compare.css too) calls it with `as: "instructor"`: the same
// view of the student's tree, titled and worded for the instructor ("The student's eye ray…").
import { request } from "../api.js";
import { renderDiagram } from "../diagram.js";
import { renderRayList } from "../raylist.js";
import { legend } from "../rays.js";
import { colourSwatch, treeModel } from "../rayviews.js";
import { h, s } from "../util.js";

/** The two sides, titled for the reader: the student themselves, or their instructor (`as`). */
const SIDES = {
  student: [
    ["student", "Your ray tree"],
    ["reference", "The reference's"],
  ],
  instructor: [
    ["student", "The student's ray tree"],
    ["reference", "The reference's"],
  ],
};

/** The server's sentence (tracer/grading/treediff.py) speaks to the student ("Your eye ray hits…"): for their
 * instructor, the same sentence about the student ("The student's eye ray hits…"). */
export function inWordsOf(as, message) {
  if (as !== "instructor") return message;
  return message
    .replace(/\bYours\b/g, "The student's")
    .replace(/\bYour\b/g, "The student's")
    .replace(/\byours\b/g, "the student's")
    .replace(/\byour\b/g, "the student's");
}

/** The node at a path (child indices from the root), or null when the tree has none there. */
export function nodeAt(model, path) {
  let n = model.root;
  for (const i of path || []) {
    n = (model.children.get(n.id) || [])[i];
    if (!n) return null;
  }
  return n;
}

function side(name, title, tree, marked) {
  const model = treeModel(tree);
  const box = h("div", {
    class: "compare-tree",
    tabindex: 0,
    role: "group",
    "aria-label": `${title}: ${model.nodes.length} rays`,
  });
  const section = h(
    "section",
    { class: "compare-side", dataset: { side: name } },
    h("h3", {}, title),
    h(
      "p",
      { class: "compare-summary" },
      `${model.nodes.length} ray${model.nodes.length === 1 ? "" : "s"}; the pixel sample's colour `,
      ...colourSwatch(tree.color),
    ),
    box,
  );
  const words = h("ul", { class: "rt-list" }); // the tree in words for a screen reader (raylist.js), closed at first
  section.append(h("details", { class: "rt-text" }, h("summary", {}, "The tree in words"), words));
  return { section, box, words, title, model, marked };
}

/** Mark the differing node of a drawn side (its box and the edge into it) and say so in its label. `view`:
 * {box (the diagram's container), marked (the node)}; the tree-log view (treecompare.js) marks its sides so too. */
export function mark(view, what) {
  const n = view.marked;
  if (!n) return null;
  const g = view.box.querySelector(`g.rt-node[data-id="${n.id}"]`);
  if (!g) return null;
  g.classList.add("differs");
  view.box.querySelector(`g.rt-edge[data-id="${n.id}"]`)?.classList.add("differs");
  const svg = view.box.querySelector("svg"); // one image to a screen reader (diagram.js): its name says where
  svg?.setAttribute("aria-label", `${svg.getAttribute("aria-label")}; ray ${n.id} is the first difference (${what})`);
  const w = Number(g.querySelector("rect.box")?.getAttribute("width")) || 0; // right-aligned: the edge comes in at the middle
  g.append(s("text", { class: "differs-tag", x: w, y: -5, "text-anchor": "end" }, "first difference"));
  return g;
}

/**
 * Show the two ray trees of pixel (x, y) of submission `sid` in `container`: a `div.compare` with the server's
 * message (or `p.compare-error`) and a `section.compare-side` per tree. Resolves to the server's answer, or null
 * when it answered an error (shown in the container). `token`: send this one rather than the browser's token of `as`.
 */
export async function showCompare(container, { aid, sid, x, y, sample = null, as = "student", token }) {
  const root = h("div", { class: "compare", dataset: { x, y } });
  const whose = as === "instructor" ? "the student's" : "your";
  const status = h(
    "p",
    { class: "compare-status", role: "status" },
    `Tracing ${whose} ray tree and the reference's at pixel (${x}, ${y})…`,
  );
  root.append(status);
  container.replaceChildren(root);
  const query = new URLSearchParams({ x: String(x), y: String(y) });
  if (sample !== null && sample !== undefined) query.set("sample", String(sample));
  const url = `/api/assignments/${encodeURIComponent(aid)}/submissions/${encodeURIComponent(sid)}/raytree?${query}`;
  let answer;
  try {
    answer = await request("GET", url, undefined, { as, token }); // `token`: the page's own (a student's link), else `as`'s
  } catch (err) {
    root.replaceChildren(
      h("p", { class: "compare-error", role: "alert", dataset: { status: err.status } }, err.message),
    );
    return null;
  }
  const d = answer.difference;
  const head = h(
    "p",
    { class: "compare-message", dataset: { what: d ? d.what : "none" } },
    d
      ? inWordsOf(as, d.message)
      : "The two ray trees agree at this pixel sample: every ray hits the same, with the same weights and terms. Try another pixel of the difference map.",
  );
  const views = (SIDES[as] || SIDES.student).map(([name, title]) => {
    const tree = answer[name];
    const marked = d ? nodeAt(treeModel(tree), d[name]) : null;
    return side(name, title, tree, marked);
  });
  root.replaceChildren(
    h("h2", { class: "compare-title" }, `Ray trees at pixel (${answer.x}, ${answer.y}), sample ${answer.sample}`),
    head,
    h(
      "div",
      { class: "compare-sides" },
      views.map((v) => v.section),
    ),
    legend(),
  );
  let first = null;
  for (const v of views) {
    // a still picture: no linked views here; the differing ray is never folded into a group of shadow rays
    renderDiagram(v.box, v.model, { onHover: () => {}, onSelect: () => {}, open: v.marked ? [v.marked.id] : [] });
    renderRayList(v.words, v.model, {
      label: `${v.title}: ${v.model.nodes.length} rays`,
      onFocus: () => {},
      onSelect: () => {},
    });
    if (d && v.marked)
      v.words.querySelector(`[data-id="${v.marked.id}"] > .rt-li-text`)?.append(` The first difference: ${d.what}.`);
    const g = d ? mark(v, d.what) : null;
    if (g) {
      // the marked ray in view inside its own scrolling box (the page itself scrolls only as far as it must)
      const boxRect = v.box.getBoundingClientRect();
      const r = g.getBoundingClientRect();
      v.box.scrollLeft += r.left - boxRect.left - (boxRect.width - r.width) / 2;
      v.box.scrollTop += r.top - boxRect.top - 24;
      first = first || g;
    }
  }
  first?.scrollIntoView({ block: "nearest", inline: "nearest" });
  return answer;
}
