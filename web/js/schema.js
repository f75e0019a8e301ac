// The scene format's rules as the server states them: GET /api/schema, the JSON Schema that tracer/scene/
// generates from its models. A field's kind, bounds, default, choices and description come from there, so
// the page holds no copy of them: fields.js keeps only labels, their order and the spinners' steps.
// main.js loads the schema once at start; without it (the server not answering) the form shows the text's
// values as they are, with no bounds or defaults.
import { api } from "./api.js";

let root = null; // the schema once loaded

/** Ask the server for the schema (once; later calls get the same promise). */
let loading = null;
export function loadSchema() {
  loading ??= api.schema().then(
    (schema) => (root = schema),
    (err) => {
      loading = null; // ask again next time
      throw err;
    },
  );
  return loading;
}

/** Follow "$ref"s to the definition they name. */
function deref(node) {
  while (node?.$ref) node = root.$defs[node.$ref.split("/").pop()];
  return node;
}

/** The object schema of one part of a scene: "camera", "film", "sampler", "render", "material" (a named or
 * inline material) or "light" with its type; null before the schema is loaded or for an unknown part. */
export function part(name, type = null) {
  if (!root) return null;
  const props = root.properties;
  if (name === "material") return deref(props.materials?.additionalProperties) ?? null;
  if (name === "light") {
    const ref = props.lights?.items?.discriminator?.mapping?.[type];
    return ref ? deref({ $ref: ref }) : null;
  }
  return deref(props[name]) ?? null;
}

/** The rule of field `key` of an object schema, or null when the schema does not know it:
 * kind ("number", "vec3", "rgb" (a number or r, g, b), "select", "check", "text"), integer, bounds
 * (min, max, exclusiveMin, exclusiveMax: the schema's minimum, maximum, exclusiveMinimum, exclusiveMaximum),
 * def (the default; see defaultOf), options (an enum's values), nullable, description. */
export function rule(object, key) {
  const prop = object?.properties?.[key];
  if (!prop) return null;
  const alts = (prop.anyOf || [prop]).map(deref);
  const given = alts.filter((a) => a.type !== "null");
  const number = given.find((a) => a.type === "number" || a.type === "integer");
  const array = given.find((a) => a.type === "array");
  const options = prop.enum || given.find((a) => a.enum)?.enum || null;
  let kind = "text";
  if (options) kind = "select";
  else if (given.some((a) => a.type === "boolean")) kind = "check";
  else if (number && array) kind = "rgb";
  else if (array && array.minItems === 3 && array.maxItems === 3) kind = "vec3";
  else if (number) kind = "number";
  const bounds = number || array?.prefixItems?.[0] || {};
  return {
    kind,
    integer: bounds.type === "integer",
    min: bounds.minimum,
    max: bounds.maximum,
    exclusiveMin: bounds.exclusiveMinimum,
    exclusiveMax: bounds.exclusiveMaximum,
    def: prop.default,
    defaultByType: prop["x-default-by-type"] || null, // a default that depends on the object's "type"
    options,
    nullable: alts.some((a) => a.type === "null"),
    description: prop.description || "",
  };
}

/** The value field `key` takes in `holder` when it is absent: the schema's default, or the default for the
 * holder's type (sampler.spp: 1 for center, 16 otherwise). */
export function defaultOf(object, key, holder = {}) {
  const r = rule(object, key);
  if (!r) return undefined;
  if (r.defaultByType) {
    const type = holder?.type ?? rule(object, "type")?.def;
    if (type in r.defaultByType) return r.defaultByType[type];
  }
  return r.def;
}

/** A part of a scene with every absent field at its default, e.g. withDefaults("sampler", scene.sampler). */
export function withDefaults(name, holder) {
  const given = holder && typeof holder === "object" ? holder : {};
  const object = part(name, given.type);
  const out = { ...given };
  if ("type" in (object?.properties || {}) && out.type === undefined) out.type = defaultOf(object, "type");
  for (const key of Object.keys(object?.properties || {}))
    if (out[key] === undefined) out[key] = defaultOf(object, key, out);
  return out;
}
