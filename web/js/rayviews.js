// What the ray-tree views share, wherever a tree is shown (the workspace's ray tree, raytree.js; the comparison
// at a pixel, course/compare.js; an own tracer's logged trees, course/treecompare.js): the diagram's model of a
// tree, its pixel's colour, its rays drawn over the image and in 3D, and one ray highlighted in every view.
import { raySegments, sceneBounds } from "./shapes.js";
import { cssColour, h, rgb } from "./util.js";
import { cameraBasis } from "./vec.js";

/** The diagram's model of a tree (diagram.js): its nodes, each node's children in id order, the root. */
export function treeModel(tree) {
  const nodes = [...tree.nodes].sort((a, b) => a.id - b.id);
  const children = new Map(nodes.map((n) => [n.id, []]));
  for (const n of nodes) if (n.parent !== null && n.parent !== undefined) children.get(n.parent)?.push(n);
  const root = nodes.find((n) => n.parent === null || n.parent === undefined);
  return {
    tree,
    nodes,
    children,
    root,
    maxDepth: Math.max(...nodes.map((n) => n.depth)),
    byId: new Map(nodes.map((n) => [n.id, n])),
  };
}

/** A pixel's colour: a swatch as the display shows it, then its numbers. */
export function colourSwatch(color) {
  return [
    h("span", { class: "sw", style: `background:${cssColour(color)}`, title: "the colour, as the display shows it" }),
    `RGB (${color.map((x) => rgb(x)).join(", ")})`,
  ];
}

/** Ray `id` (null: none) highlighted in each view drawn of one tree: the diagram (scrolled to it with `scroll`),
 * the tree in words, the rays over the image, the 3D view. */
export function highlightRay({ diagram, list, overlay, view3d }, id, scroll = false) {
  diagram?.highlight(id, scroll);
  list?.highlight(id);
  overlay?.highlight(id);
  view3d?.highlight(id);
}

/** The rays of tree `model` over `image` (an Overlay) and in the scene in 3D (a View3D); `view`: {scene, width,
 * height}, the scene the tree was traced in and its film's size. */
export function drawRays(overlay, view3d, image, model, { scene, width, height }) {
  const segments = raySegments(model.tree, scene, Math.max(1, sceneBounds(scene).radius * 0.6));
  const pixel = [model.tree.pixel[0], model.tree.pixel[1]];
  overlay.set(image, { model, segments, basis: cameraBasis(scene.camera, width, height), pixel, width, height });
  view3d.setScene(scene, { width, height });
  view3d.setRays({ model, segments });
}
