// web/js/diagram.js's grouping of shadow rays without a browser: which boxes the ray-tree diagram draws (issue #42:
// 16 light samples made 16 shadow-ray boxes under each hit, unreadable side by side, even fitted to the panel).
import assert from "node:assert/strict";
import { test } from "node:test";

import { groupWords, visible } from "../../web/js/diagram.js";

/** A tree: an eye ray hitting the floor, 16 shadow rays from there to light 0 (5 blocked), 2 to light 1, and a
 * reflection ray with one shadow ray of its own. */
function tree() {
  const nodes = [{ id: 0, parent: null, kind: "eye", depth: 0 }];
  for (let i = 0; i < 16; i++)
    nodes.push({ id: nodes.length, parent: 0, kind: "shadow", depth: 1, light: 0, occluded: i % 3 === 0 });
  nodes.push({ id: nodes.length, parent: 0, kind: "shadow", depth: 1, light: 1, occluded: false });
  nodes.push({ id: nodes.length, parent: 0, kind: "shadow", depth: 1, light: 1, occluded: true });
  const refl = nodes.length;
  nodes.push({ id: refl, parent: 0, kind: "reflection", depth: 1 });
  nodes.push({ id: nodes.length, parent: refl, kind: "shadow", depth: 2, light: 0, occluded: false });
  return { nodes, root: nodes[0] };
}

test("a node's shadow rays to one light, four or more, are one box that says how many reach the light", () => {
  const model = tree();
  const v = visible(model);
  // the eye ray, one group (light 0's 16), light 1's two rays, the reflection ray and its one shadow ray
  assert.equal(v.nodes.length, 1 + 1 + 2 + 1 + 1);
  const groups = v.nodes.filter((n) => n.group);
  assert.equal(groups.length, 1);
  const [g] = groups;
  assert.equal(g.key, "0:0");
  assert.equal(g.members.length, 16);
  assert.deepEqual(groupWords(g), ["16 shadow rays to light 0", "10 reach the light, 6 blocked"]);
  assert.equal(v.children.get(0).length, 4); // under the eye ray: the group, two rays to light 1, the reflection
  for (const m of g.members) assert.equal(v.groupOf.get(m.id), g); // a hidden ray is shown by its group
  assert.equal(v.groupOf.has(17), false);
});

test("an opened group is drawn ray by ray", () => {
  const v = visible(tree(), new Set(["0:0"]));
  assert.equal(v.nodes.length, tree().nodes.length);
  assert.equal(
    v.nodes.some((n) => n.group),
    false,
  );
});

test("one of a group's rays reaching the light reads in the singular", () => {
  const nodes = [{ id: 0, parent: null, kind: "eye", depth: 0 }];
  for (let i = 0; i < 4; i++) nodes.push({ id: i + 1, parent: 0, kind: "shadow", depth: 1, light: 2, occluded: i > 0 });
  const [, g] = visible({ nodes, root: nodes[0] }).nodes;
  assert.deepEqual(groupWords(g), ["4 shadow rays to light 2", "1 reaches the light, 3 blocked"]);
});
