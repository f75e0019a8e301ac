// What the lessons' entries share: choices made of plain values, and ways into an example scene.

/** Every material of scene `s` (a name -> material map), `fn(material, name)` each. */
export function eachMaterial(s, fn) {
  for (const [name, m] of Object.entries(s.materials || {})) fn(m, name);
}

/** The object of scene `s` called `name`. */
export function named(s, name) {
  return (s.objects || []).find((o) => o.name === name);
}

/** Choices of a select control from plain values: [[value, text]]. */
export const values = (...xs) => xs.map((x) => [x, String(x)]);

/** A link of a lesson's `more` to a section of the scene format's reference (the server's /reference/ page). */
export const reference = (text, anchor) => [text, `/reference/scene-format.md#${anchor}`];
