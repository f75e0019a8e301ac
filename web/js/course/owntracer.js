// An image submission's probe pixels and the student's tree log (docs/assignments.md, "Your own tracer's ray
// trees"): the feedback of an image from the student's own ray tracer lists the pixels to log (`probes`, where
// the error map is shown; `probes_hidden` says when they appear), and here the student opens or pastes their
// tracer's tree log (the format of docs/scene-format.md, "Tree log") and sends it: POST .../submissions/{sid}/trees.
// The answer is shown by treecompare.js (loaded then); a log with errors shows every error at its JSON path
// (feedback.js problemList), a refusal (403 while the policy hides it, 413 past 4 MB) the server's own words.
import { ApiError, request } from "../api.js";
import { h } from "../util.js";
import { problemList } from "./feedback.js";

const MAX_LOG = 4 * 1024 * 1024; // bytes: the route's own limit (TRACER_MAX_TREE_LOG_BYTES)

/** The routes of one submission's tree log, with the page's token. */
function treesApi(aid, sid, token) {
  const url = `/api/assignments/${encodeURIComponent(aid)}/submissions/${encodeURIComponent(sid)}/trees`;
  return {
    send: (text) => request("POST", url, text, { token, cache: "no-store" }),
  };
}

/** "[[x, y], ...]": the probes as a tracer's command line or config may take them. */
const pixelList = (probes) => `[${probes.map((p) => `[${p.x}, ${p.y}]`).join(", ")}]`;

/** The probes and the log's form for image submission `sub` (its feedback has `probes`): an element. `ctx`:
 * {aid, token}. */
export function treeLogSection(sub, ctx) {
  const probes = sub.feedback.probes;
  const id = `tl-${sub.id}`;
  const api = treesApi(ctx.aid, sub.id, ctx.token);
  const text = h("textarea", {
    id: `${id}-log`,
    class: "grade-json tl-log",
    wrap: "off",
    spellcheck: "false",
    autocomplete: "off",
    autocapitalize: "off",
    rows: 8,
    placeholder: '{"trees": [{"pixel": [x, y], "nodes": [...]}]}',
    "aria-describedby": `${id}-help`,
  });
  const file = h("input", { type: "file", id: `${id}-file`, accept: ".json,application/json", hidden: true });
  const status = h("p", { class: "message tl-status", role: "status", "aria-live": "polite", id: `${id}-status` });
  const errors = h("div", { class: "tl-errors", id: `${id}-errors` });
  const result = h("div", { class: "tl-result", id: `${id}-result` });
  const send = h(
    "button",
    { type: "button", class: "primary", id: `${id}-send` },
    "Compare with the reference's trees",
  );
  const say = (kind, ...content) => {
    status.dataset.kind = kind;
    status.replaceChildren(...content);
  };
  const images = { student: sub.files?.["render.png"], reference: sub.files?.["reference.png"] };
  const show = async (answer) => {
    const { showTreeAnswers } = await import("./treecompare.js");
    showTreeAnswers(result, answer, { as: "student", images, auth: { token: ctx.token }, probes });
  };
  file.addEventListener("change", async () => {
    const f = file.files[0];
    file.value = "";
    if (!f) return;
    if (f.size > MAX_LOG)
      return say(
        "error",
        `${f.name} is ${(f.size / 1e6).toFixed(1)} MB: a tree log may be 4 MB at most (log fewer pixels).`,
      );
    text.value = await f.text();
    say("info", `Opened ${f.name}: Compare sends it.`);
  });
  send.addEventListener("click", async () => {
    const log = text.value;
    errors.replaceChildren();
    if (!log.trim()) return say("error", "The log is empty: paste your tracer's tree log, or open its file.");
    if (new Blob([log]).size > MAX_LOG) return say("error", "The log is over 4 MB: log fewer pixels.");
    send.disabled = true;
    say(
      "info",
      "Comparing your trees with the reference's (the reference's are traced the first time a pixel is asked for)…",
    );
    try {
      const answer = await api.send(log);
      say("", "");
      await show(answer);
    } catch (err) {
      if (err instanceof ApiError && err.status === 422) {
        const n = err.errors.length;
        say(
          "error",
          `The log has ${n} error${n === 1 ? "" : "s"}: nothing was compared. Fix ${n === 1 ? "it" : "them"} and send it again.`,
        );
        errors.replaceChildren(problemList(err.errors, { title: "Errors, at their place in the log's JSON:" }));
      } else
        say(
          "error",
          err instanceof ApiError && err.status
            ? `Not compared: ${err.errors.map((e) => e.message).join("; ")}.`
            : `Not compared: ${err.message}`,
        );
    } finally {
      send.disabled = false;
    }
  });
  const list = probes.length
    ? h(
        "ol",
        { class: "tl-probes", id: `${id}-probes` },
        probes.map((p) =>
          h("li", { dataset: { x: p.x, y: p.y } }, h("strong", {}, `(${p.x}, ${p.y})`), p.why ? ` ${p.why}` : ""),
        ),
      )
    : h(
        "p",
        { class: "hint", id: `${id}-probes` },
        "No probe pixels: your image differs nowhere the error map shows. A log of any pixel of the image is compared all the same.",
      );
  const section = h(
    "section",
    { class: "tl", id, "aria-labelledby": `${id}-h`, dataset: { sid: sub.id } },
    h("h4", { id: `${id}-h` }, "Explain it with your tracer's ray trees"),
    h(
      "p",
      { class: "hint", id: `${id}-help` },
      "Log, with your own tracer, the ray tree of the ray through the centre of each of the probe pixels (x from the left, y from the top), as a tree log (",
      h(
        "a",
        { href: "/reference/assignments.md#your-own-tracers-ray-trees", target: "_blank", rel: "noopener" },
        "the format",
      ),
      "), and send it: each tree is compared with the reference's there, and the first difference is named.",
    ),
    list,
    probes.length
      ? h("p", { class: "hint" }, "The pixels as a list: ", h("code", { class: "tl-pixel-list" }, pixelList(probes)))
      : null,
    h("label", { for: text.id, class: "grade-label" }, "Your tracer's tree log (paste it here, or open its file)"),
    text,
    h(
      "div",
      { class: "a-go" },
      h("button", { type: "button", onclick: () => file.click() }, "Open a .json file…"),
      file,
      send,
    ),
    status,
    errors,
    result,
  );
  return section;
}
