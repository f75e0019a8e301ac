// The ray tree as text: a nested list that a screen reader follows and the keyboard walks (the ARIA tree
// pattern: one tab stop; Up and Down go from ray to ray, Right opens a ray's children or goes to the first,
// Left closes them or goes to the parent, Home and End, Enter or Space keeps a ray chosen). Each item says
// one ray in words: its kind and depth, what it hit and where (or that it missed, or for a shadow ray whether
// it reached its light), its weight, the colour it carried back to its parent, and why it ended. The same
// nodes as the diagram (web/js/diagram.js), from the ray-tree JSON (docs/scene-format.md, "The ray tree").
import { RAY_STYLES, endWords, styleKey } from "./rays.js";
import { cssColour, h, num } from "./util.js";

const KIND_WORDS = {
  eye: "eye ray",
  reflection: "reflection ray",
  transmission: "transmission ray",
  shadow: "shadow ray",
};

/** An RGB triple in words: one number when the three are equal (a grey), else "RGB (r, g, b)". */
function colour(v) {
  if (!Array.isArray(v)) return num(v);
  if (v[0] === v[1] && v[1] === v[2]) return num(v[0]);
  return `RGB (${v.map((x) => num(x)).join(", ")})`;
}

const point = (p) => `(${p.map((x) => num(x)).join(", ")})`;

function hitName(hit) {
  return (
    hit.object_name || (hit.light !== null && hit.light !== undefined ? `light ${hit.light}` : `object ${hit.object}`)
  );
}

/** One ray in a sentence, e.g. "Ray 0: eye ray, depth 1, hit glass ball (material glass) at (0.3, 1, 0.2);
 * weight 1; carried back RGB (0.36, 0.5, 0.74)." */
export function rayWords(n) {
  const head = `Ray ${n.id}: ${KIND_WORDS[n.kind] || `${n.kind} ray`}`;
  if (n.kind === "shadow") {
    const result = n.occluded
      ? `blocked by ${n.hit ? `${hitName(n.hit)} at ${point(n.hit.point)}` : "an object"}`
      : "reached the light";
    return `${head} towards light ${n.light}, depth ${n.depth}: ${result}; weight ${colour(n.weight)}; carried back ${colour(n.radiance)}.`;
  }
  const hit = n.hit
    ? `hit ${hitName(n.hit)}${n.hit.material ? ` (material ${n.hit.material})` : ""} at ${point(n.hit.point)}${n.hit.front_face === false ? ", its back face" : ""}`
    : "missed: left the scene";
  const end = n.end && n.end !== "miss" ? `; ended: ${endWords(n, true)}` : "";
  return `${head}, depth ${n.depth}, ${hit}; weight ${colour(n.weight)}; carried back ${colour(n.radiance)}${end}.`;
}

/**
 * Fill `tree` (a <ul>) with the rays of `model` ({nodes, children, root}) as an ARIA tree named `label`.
 * onFocus(id) when the keyboard (or a click) comes to a ray, onFocus(null) when it leaves the list;
 * onSelect(id) on Enter, Space or a click. Returns {highlight(id), select(id), setDepth(d)}.
 */
export function renderRayList(tree, model, { label, onFocus, onSelect }) {
  const itemOf = new Map();
  const item = (n, level) => {
    const kids = model.children.get(n.id) || [];
    const st = RAY_STYLES[styleKey(n)];
    const li = h(
      "li",
      {
        role: "treeitem",
        "aria-level": level,
        "aria-selected": "false",
        tabindex: n === model.root ? 0 : -1,
        dataset: { id: n.id, kind: styleKey(n), depth: n.depth },
      },
      h(
        "span",
        { class: "rt-li-text" },
        h("span", { class: "kind-dot", style: `background:${st.colour}`, "aria-hidden": "true" }),
        rayWords(n),
        h("span", {
          class: "sw",
          style: `background:${cssColour(n.radiance)}`,
          "aria-hidden": "true",
          title: "the colour it carried back",
        }),
      ),
    );
    if (kids.length) {
      li.setAttribute("aria-expanded", "true");
      li.append(
        h(
          "ul",
          { role: "group" },
          kids.map((k) => item(k, level + 1)),
        ),
      );
    }
    itemOf.set(n.id, li);
    return li;
  };
  tree.setAttribute("role", "tree");
  tree.setAttribute("aria-label", label);
  tree.replaceChildren(item(model.root, 1));

  const visible = () =>
    [...tree.querySelectorAll("[role=treeitem]")].filter(
      (li) => !li.parentElement.closest("[role=treeitem][aria-expanded=false]"),
    );
  const focusItem = (li) => {
    if (!li) return;
    for (const other of itemOf.values()) other.tabIndex = -1;
    li.tabIndex = 0;
    li.focus();
  };
  const parentItem = (li) => li.parentElement.closest("[role=treeitem]");
  const on = {}; // the handlers of this tree; the listeners are added to the <ul> once (it is filled again per tree)
  on.keydown = (e) => {
    const li = e.target.closest("[role=treeitem]");
    if (!li || e.altKey || e.ctrlKey || e.metaKey) return;
    const shown = visible();
    const at = shown.indexOf(li);
    const open = li.getAttribute("aria-expanded");
    const moves = {
      ArrowDown: () => focusItem(shown[at + 1]),
      ArrowUp: () => focusItem(shown[at - 1]),
      Home: () => focusItem(shown[0]),
      End: () => focusItem(shown[shown.length - 1]),
      ArrowRight: () =>
        open === "false"
          ? li.setAttribute("aria-expanded", "true")
          : open === "true"
            ? focusItem(li.querySelector("[role=treeitem]"))
            : null,
      ArrowLeft: () => (open === "true" ? li.setAttribute("aria-expanded", "false") : focusItem(parentItem(li))),
      Enter: () => onSelect(Number(li.dataset.id)),
      " ": () => onSelect(Number(li.dataset.id)),
    };
    if (!moves[e.key]) return;
    e.preventDefault();
    e.stopPropagation();
    moves[e.key]();
  };
  on.focusin = (e) => {
    const li = e.target.closest("[role=treeitem]");
    if (li) onFocus(Number(li.dataset.id));
  };
  on.focusout = (e) => {
    if (!tree.contains(e.relatedTarget)) onFocus(null);
  };
  on.click = (e) => {
    const li = e.target.closest("[role=treeitem]");
    if (!li) return;
    focusItem(li);
    onSelect(Number(li.dataset.id));
  };
  if (!tree.rayList) for (const type of Object.keys(on)) tree.addEventListener(type, (e) => tree.rayList[type](e));
  tree.rayList = on;
  let current = null;
  return {
    /** Mark the ray shown in the other views (hovered there, or chosen). */
    highlight(id) {
      itemOf.get(current)?.classList.remove("hl");
      current = id;
      itemOf.get(id)?.classList.add("hl");
    },
    /** The ray kept chosen (aria-selected), or none. */
    select(id) {
      for (const [k, li] of itemOf) li.setAttribute("aria-selected", String(k === id));
    },
    /** Dim the rays deeper than the depth the other views show. */
    setDepth(limit) {
      for (const n of model.nodes) itemOf.get(n.id).classList.toggle("future", n.depth > limit);
    },
  };
}
