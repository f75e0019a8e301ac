// JSON with positions. JSON.parse says neither where a value is nor (portably) where a syntax error is,
// so this small recursive-descent parser records, for every value, its span in the text under its JSON
// path written as the server writes paths (`objects[2].radius`, `materials["my glass"].kd`).
// It accepts what the server's parser accepts: JSON plus the tokens NaN, Infinity and -Infinity
// (sent as typed, so the validator names them at their field).

const IDENT = /^[A-Za-z_][A-Za-z0-9_-]*$/;

/** ["objects", 2, "radius"] -> "objects[2].radius" (tracer.scene.json_path). */
export function pathString(parts) {
  let out = "";
  for (const p of parts) {
    if (typeof p === "number") out += `[${p}]`;
    else if (IDENT.test(p)) out += out ? `.${p}` : p;
    else out += `[${JSON.stringify(p)}]`;
  }
  return out;
}

/** "objects[2].radius" -> ["objects", 2, "radius"]; a path the server wrote, inverse of pathString. */
export function parsePath(path) {
  const parts = [];
  const re = /\.?([A-Za-z_][A-Za-z0-9_-]*)|\[(\d+)\]|\[("(?:[^"\\]|\\.)*")\]/y;
  let m;
  while (re.lastIndex < path.length && (m = re.exec(path))) {
    if (m[1] !== undefined) parts.push(m[1]);
    else if (m[2] !== undefined) parts.push(Number(m[2]));
    else parts.push(JSON.parse(m[3]));
  }
  return parts;
}

export class JSONSyntaxError extends Error {
  constructor(message, offset, line, col) {
    super(message);
    this.offset = offset;
    this.line = line; // 1-based
    this.col = col; // 1-based
  }
}

/** offset -> {line, col} (both 1-based) for one text. */
export function lineIndex(text) {
  const starts = [0];
  for (let i = 0; i < text.length; i++) if (text.charCodeAt(i) === 10) starts.push(i + 1);
  const at = (offset) => {
    let lo = 0;
    let hi = starts.length - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (starts[mid] <= offset) lo = mid;
      else hi = mid - 1;
    }
    return { line: lo + 1, col: offset - starts[lo] + 1 };
  };
  at.lineStart = (line) => starts[Math.max(0, Math.min(starts.length - 1, line - 1))];
  at.lines = starts.length;
  return at;
}

const NUMBER = /-?(?:0|[1-9]\d*)(?:\.\d+)?(?:[eE][+-]?\d+)?/y;
// biome-ignore lint/suspicious/noControlCharactersInRegex: JSON forbids raw control characters in a string
const STRING = /"(?:[^"\\\u0000-\u001f]|\\(?:["\\/bfnrt]|u[0-9a-fA-F]{4}))*"/y;

/**
 * Parse `text`. Returns {value, nodes}: nodes maps each path string to
 * {start, end, keyStart, type, count, lastEnd, parts} (offsets into the text; keyStart -1 for array items
 * and the root). Throws JSONSyntaxError with the line and column of the first error.
 */
export function parse(text) {
  let i = 0;
  const nodes = new Map();
  let where = null;
  const fail = (message, at = i) => {
    where = where || lineIndex(text);
    const { line, col } = where(at);
    throw new JSONSyntaxError(message, at, line, col);
  };
  const ws = () => {
    for (;;) {
      const c = text.charCodeAt(i);
      if (c === 32 || c === 9 || c === 10 || c === 13) i++;
      else break;
    }
  };
  const string = () => {
    STRING.lastIndex = i;
    const m = STRING.exec(text);
    if (!m) {
      let j = i + 1;
      while (j < text.length && text[j] !== '"' && text[j] !== "\n") j += text[j] === "\\" ? 2 : 1;
      if (j >= text.length || text[j] === "\n") fail('unterminated string: a string must end with " on the same line');
      fail("invalid character or escape in the string", i);
    }
    i += m[0].length;
    return JSON.parse(m[0]);
  };
  const literal = (word, v) => {
    if (text.startsWith(word, i)) {
      i += word.length;
      return { v, ok: true };
    }
    return { ok: false };
  };
  const describe = (c) => (c === undefined ? "the end of the text" : `'${c}'`);

  function value(parts, keyStart) {
    ws();
    const start = i;
    const c = text[i];
    const info = { start, end: start, keyStart, type: "", count: 0, lastEnd: -1, lastKeyStart: -1, parts };
    let v;
    if (c === "{") {
      info.type = "object";
      v = {};
      i++;
      ws();
      if (text[i] === "}") i++;
      else {
        for (;;) {
          ws();
          if (text[i] === "}" && info.count > 0) fail("trailing comma: remove the ',' before '}'", i);
          if (text[i] === "'") fail('keys and strings need double quotes ("), not single quotes');
          if (text[i] !== '"') fail(`expected a "quoted" key, found ${describe(text[i])}`);
          const ks = i;
          const key = string();
          ws();
          if (text[i] !== ":") fail(`expected ':' after the key "${key}", found ${describe(text[i])}`);
          i++;
          v[key] = value([...parts, key], ks);
          info.count++;
          info.lastEnd = i;
          info.lastKeyStart = ks;
          ws();
          if (text[i] === ",") {
            i++;
            continue;
          }
          if (text[i] === "}") {
            i++;
            break;
          }
          fail(`expected ',' or '}' after a member of the object, found ${describe(text[i])}`);
        }
      }
    } else if (c === "[") {
      info.type = "array";
      v = [];
      i++;
      ws();
      if (text[i] === "]") i++;
      else {
        for (;;) {
          ws();
          if (text[i] === "]" && info.count > 0) fail("trailing comma: remove the ',' before ']'", i);
          v.push(value([...parts, info.count], -1));
          info.count++;
          info.lastEnd = i;
          ws();
          if (text[i] === ",") {
            i++;
            continue;
          }
          if (text[i] === "]") {
            i++;
            break;
          }
          fail(`expected ',' or ']' after an item of the array, found ${describe(text[i])}`);
        }
      }
    } else if (c === '"') {
      info.type = "string";
      v = string();
    } else {
      NUMBER.lastIndex = i;
      const m = NUMBER.exec(text);
      if (m && m[0] !== "-") {
        info.type = "number";
        v = Number(m[0]);
        i += m[0].length;
      } else {
        let r = { ok: false };
        for (const [word, val] of [
          ["true", true],
          ["false", false],
          ["null", null],
          ["NaN", NaN],
          ["Infinity", Infinity],
          ["-Infinity", -Infinity],
        ]) {
          r = literal(word, val);
          if (r.ok) break;
        }
        if (!r.ok) {
          if (c === "'") fail('strings and keys need double quotes ("), not single quotes');
          fail(`expected a value (object, array, string, number, true, false or null), found ${describe(c)}`);
        }
        info.type = r.v === null ? "null" : typeof r.v;
        v = r.v;
      }
    }
    info.end = i;
    nodes.set(pathString(parts), info);
    return v;
  }

  const v = value([], -1);
  ws();
  if (i < text.length) fail(`unexpected ${describe(text[i])} after the end of the scene's JSON object`);
  return { value: v, nodes };
}

/** The node of a server path, or of its nearest ancestor present in the text (a missing field is
 * reported where its parent is). Returns {node, exact} or null. */
export function locate(nodes, path) {
  const parts = parsePath(path);
  for (let k = parts.length; k >= 0; k--) {
    const node = nodes.get(pathString(parts.slice(0, k)));
    if (node) return { node, exact: k === parts.length };
  }
  return null;
}

/** The 1-based line where a node is shown: its key's line for a member, else its value's. */
export function nodeLine(where, node) {
  return where(node.keyStart >= 0 ? node.keyStart : node.start).line;
}

function indentAt(text, offset) {
  const lineStart = text.lastIndexOf("\n", offset - 1) + 1;
  const m = /^[ \t]*/.exec(text.slice(lineStart, offset));
  return m ? m[0] : "";
}

/**
 * Set the value at `parts` in the JSON text, changing only that value's characters (the rest of the
 * text, its layout and comments-free formatting, stays as the student wrote it). Missing members (and
 * missing parent objects) are added at the end of their object, indented like their siblings.
 * Returns {text, start, end}: the new text and the span of what was written.
 */
export function setValue(text, parts, newValue) {
  const { nodes } = parse(text);
  const json = inlineJSON(newValue);
  const node = nodes.get(pathString(parts));
  if (node) return splice(text, node.start, node.end, json);
  let k = parts.length - 1;
  while (k > 0 && !nodes.has(pathString(parts.slice(0, k)))) k--;
  const parent = nodes.get(pathString(parts.slice(0, k)));
  if (parent?.type !== "object" || typeof parts[k] === "number") {
    throw new Error(
      `cannot set ${pathString(parts)}: ${pathString(parts.slice(0, k)) || "the scene"} is not an object`,
    );
  }
  let v = newValue;
  for (let j = parts.length - 1; j > k; j--) v = { [parts[j]]: v };
  const member = `${JSON.stringify(parts[k])}: ${inlineJSON(v)}`;
  if (parent.count === 0) {
    const ind = indentAt(text, parent.start);
    return splice(text, parent.start, parent.end, `{\n${ind}  ${member}\n${ind}}`);
  }
  const lastKeyLineStart = text.lastIndexOf("\n", parent.lastKeyStart - 1) + 1;
  const inline = lastKeyLineStart <= parent.start; // the object's members share its first line
  const insert = inline ? `, ${member}` : `,\n${indentAt(text, parent.lastKeyStart)}${member}`;
  return splice(text, parent.lastEnd, parent.lastEnd, insert);
}

function splice(text, start, end, insert) {
  const offset = insert.startsWith(",") ? start + insert.indexOf('"') : start;
  return { text: text.slice(0, start) + insert + text.slice(end), start: offset, end: start + insert.length };
}

/** One-line JSON with a space after ',' and ':' (what the form writes). */
export function inlineJSON(v) {
  if (v === null || typeof v !== "object") return JSON.stringify(v) ?? "null";
  if (Array.isArray(v)) return `[${v.map(inlineJSON).join(", ")}]`;
  return `{${Object.entries(v)
    .map(([k, x]) => `${JSON.stringify(k)}: ${inlineJSON(x)}`)
    .join(", ")}}`;
}

const isPrimitive = (x) => x === null || typeof x !== "object";

/** Pretty JSON for reading: two-space indents, short arrays and small leaf objects on one line. */
export function formatJSON(value, indent = "") {
  if (isPrimitive(value)) return inlineJSON(value);
  const one = inlineJSON(value);
  const room = 96 - indent.length;
  if (Array.isArray(value)) {
    if (!value.length) return "[]";
    const flat = value.every(isPrimitive) || value.every((x) => Array.isArray(x) && x.every(isPrimitive));
    if (flat && one.length <= room) return one;
    const inner = `${indent}  `;
    return `[\n${value.map((x) => inner + formatJSON(x, inner)).join(",\n")}\n${indent}]`;
  }
  const keys = Object.keys(value);
  if (!keys.length) return "{}";
  const leaf = keys.every((k) => isPrimitive(value[k]) || (Array.isArray(value[k]) && value[k].every(isPrimitive)));
  if (indent.length >= 4 && leaf && keys.length <= 6 && one.length <= room - 8) return one;
  const inner = `${indent}  `;
  return `{\n${keys.map((k) => `${inner}${JSON.stringify(k)}: ${formatJSON(value[k], inner)}`).join(",\n")}\n${indent}}`;
}

/**
 * Append `newValue` to the array at `parts` (an array made there when it is missing), on a line of its own
 * indented like the items before it (on the same line when they share the array's line). The rest of the
 * text stays as it was. Returns {text, start, end} like setValue.
 */
export function appendItem(text, parts, newValue) {
  const { nodes } = parse(text);
  const node = nodes.get(pathString(parts));
  if (!node) {
    const made = setValue(text, parts, []);
    return appendItem(made.text, parts, newValue);
  }
  if (node.type !== "array") throw new Error(`${pathString(parts)} is not an array`);
  if (node.count === 0) {
    const ind = indentAt(text, node.keyStart >= 0 ? node.keyStart : node.start);
    const inner = `${ind}  `;
    const insert = `[\n${inner}${formatJSON(newValue, inner)}\n${ind}]`;
    return {
      text: text.slice(0, node.start) + insert + text.slice(node.end),
      start: node.start + 2 + inner.length,
      end: node.start + insert.length,
    };
  }
  const last = nodes.get(pathString([...parts, node.count - 1]));
  const lastLineStart = text.lastIndexOf("\n", last.start - 1) + 1;
  if (lastLineStart <= node.start) return splice(text, node.lastEnd, node.lastEnd, `, ${inlineJSON(newValue)}`);
  const ind = indentAt(text, last.start);
  const insert = `,\n${ind}${formatJSON(newValue, ind)}`;
  return {
    text: text.slice(0, node.lastEnd) + insert + text.slice(node.lastEnd),
    start: node.lastEnd + 2 + ind.length,
    end: node.lastEnd + insert.length,
  };
}

/**
 * Remove the value at `parts`: an array item or an object's member (its key with it), with the comma and
 * the line break that separated it from a neighbour. Returns {text, start, end}: `start` where it was.
 */
export function removeAt(text, parts) {
  if (!parts.length) throw new Error("cannot remove the whole scene");
  const { nodes } = parse(text);
  const node = nodes.get(pathString(parts));
  if (!node) throw new Error(`there is no ${pathString(parts)} to remove`);
  const parent = nodes.get(pathString(parts.slice(0, -1)));
  const from = node.keyStart >= 0 ? node.keyStart : node.start;
  const isWs = (c) => c === " " || c === "\t" || c === "\n" || c === "\r";
  if (parent.count === 1) {
    const empty = parent.type === "array" ? "[]" : "{}";
    return {
      text: text.slice(0, parent.start) + empty + text.slice(parent.end),
      start: parent.start,
      end: parent.start + 2,
    };
  }
  let j = node.end;
  while (j < text.length && isWs(text[j])) j++;
  if (text[j] === ",") {
    // a neighbour follows: remove up to it, so it takes this one's place (and its indentation)
    j++;
    while (j < text.length && isWs(text[j])) j++;
    return { text: text.slice(0, from) + text.slice(j), start: from, end: from };
  }
  // the last one: remove from the end of the one before (its comma included)
  let k = from - 1;
  while (k > parent.start && isWs(text[k])) k--;
  if (text[k] !== ",") throw new Error(`cannot remove ${pathString(parts)}: no comma before it`);
  return { text: text.slice(0, k) + text.slice(node.end), start: k, end: k };
}
