// A submission's feedback as the policy lets its student see it: each test's status and output (a hidden test
// as its name, its points and when it will be shown), an invalid submission's errors at their JSON paths, the
// metrics against the noise baseline, and its pictures (render, difference map, rejected pixels, reference).
// A pixel of a scene submission's difference map, clicked (or chosen with the keyboard), shows the student's
// ray tree beside the reference's at that pixel (compare.js, loaded at the first click). A graded image from
// the student's own tracer lists its probe pixels and takes their tracer's tree log (owntracer.js), or says
// when the probes appear (`probes_hidden`). What the policy hides now (a hidden image test hides the error map,
// the rejected pixels and the metrics too) is said with when it appears (`withheld`, withheldNotice).
import { showImage } from "../api.js";
import { h, num } from "../util.js";
import { localTime, pts } from "./brief.js";
import { treeLogSection } from "./owntracer.js";
import { regradeControls } from "./regrade.js";

const PICTURES = [
  ["render.png", (sub) => (sub.kind === "scene" ? "your scene, rendered at the assignment's settings" : "your image")],
  [
    "error_map.png",
    (sub) =>
      `the difference map (FLIP error: black is none, white the most)${sub.kind === "scene" ? ". Click a pixel to compare your ray tree with the reference's there" : ""}`,
  ],
  // the grader's own caption when it has one: red beyond noise, pale yellow as much as noise makes (its shares)
  [
    "rejected.png",
    (sub) =>
      sub.feedback?.metrics?.captions?.rejected ||
      "pixels the z test rejected: red where they differ by more than noise explains",
  ],
  ["reference.png", () => "the reference"],
];
const METRICS = [
  ["flip", "FLIP (lower is closer)", (x) => num(x, 4)],
  ["ssim", "SSIM (higher is closer)", (x) => num(x, 4)],
  ["psnr", "PSNR, dB (higher is closer)", (x) => num(x, 4)],
  ["rejected", "pixels rejected", (x) => `${num(100 * x, 3)} %`],
];

/** What the feedback policy hides now and when it appears (the server's `withheld` groups: their `parts` in
 * words, `when` and `at`), as one sentence a group: "The result of “pixels match the reference”, the error map
 * and the rejected pixels are shown after the deadline (Wed, Dec 9, 2026, 12:00 PM EST)." Null when nothing is. */
export function withheldNotice(groups, { who = "your" } = {}) {
  if (!Array.isArray(groups) || !groups.length) return null;
  const join = (xs) => (xs.length === 1 ? xs[0] : `${xs.slice(0, -1).join(", ")} and ${xs[xs.length - 1]}`);
  const lines = groups.map((g) => {
    const what = join(g.parts || []);
    const first = what.charAt(0).toUpperCase() + what.slice(1);
    const later =
      g.when === "never"
        ? [" are never shown to students for this assignment (the instructor sees them)."]
        : [` are shown after ${who} deadline (`, h("time", { datetime: g.at, title: g.at }, localTime(g.at)), ")."];
    return h("li", { dataset: { when: g.when } }, first, ...later);
  });
  return h(
    "div",
    { class: "message a-withheld", dataset: { kind: "info" } },
    h("strong", {}, "Not shown yet: "),
    h("ul", {}, lines),
  );
}

/** One test of a check or a submission: passed / failed with its points and output, or hidden. */
export function testItem(t) {
  if (t.hidden) {
    return h(
      "li",
      { class: "grade-test a-hidden", dataset: { test: t.test, status: "hidden" } },
      h(
        "div",
        { class: "grade-test-head" },
        h("span", { class: "pf", "aria-hidden": "true" }, "?"),
        h("strong", {}, t.name),
        h("span", { class: "badge", title: t.shown_at ? localTime(t.shown_at) : null }, t.hidden),
        h("span", { class: "pts" }, `– / ${pts(t.max_score)}`),
      ),
    );
  }
  const ok = t.status === "passed";
  const out = String(t.output ?? "");
  return h(
    "li",
    { class: `grade-test ${ok ? "pass" : "fail"}`, dataset: { test: t.test, status: t.status } },
    h(
      "div",
      { class: "grade-test-head" },
      h("span", { class: "pf", "aria-hidden": "true" }, ok ? "✓" : "✗"),
      h("strong", {}, t.name),
      h("span", { class: `badge ${ok ? "passed" : "failed"}` }, ok ? "passed" : "failed"),
      h("span", { class: "pts" }, `${pts(t.score)} / ${pts(t.max_score)}`),
    ),
    out
      ? out.includes("\n")
        ? h("pre", { class: "grade-output" }, out)
        : h("p", { class: "grade-output" }, out)
      : null,
  );
}

/** Errors (or warnings) at their JSON paths; `jump(e)`, when given, makes each a button to its place. */
export function problemList(list, { kind = "error", title, jump } = {}) {
  return h(
    "div",
    { class: "message grade-problems", dataset: { kind } },
    h("strong", {}, title),
    h(
      "ul",
      { class: "a-problems" },
      list.map((e) => {
        const where = e.path ? h("code", {}, e.path) : h("code", {}, "(the whole submission)");
        const line = jump ? jump.lineOf(e) : null;
        return h(
          "li",
          { dataset: { path: e.path || "" } },
          line
            ? h("button", { type: "button", class: "small a-jump", onclick: () => jump.go(e) }, `line ${line}`)
            : null,
          where,
          " ",
          e.message,
        );
      }),
    ),
  );
}

/** The detail of one submission (its state, its tests, its pictures), into `root`. `ctx`: {aid, token,
 * compareBox}. */
export function showFeedback(root, sub, ctx) {
  const parts = [];
  const fb = sub.feedback;
  if (sub.status === "queued")
    parts.push(
      h("p", { class: "hint" }, "Waiting to be graded (renders in the workspace go first). This updates by itself."),
    );
  else if (sub.status === "grading")
    parts.push(
      h(
        "p",
        { class: "hint" },
        sub.kind === "scene"
          ? "Being graded: your scene is rendered and compared with the reference…"
          : "Being graded: your image is compared with the reference…",
      ),
    );
  if (sub.status === "invalid" && fb?.errors?.length) {
    const n = fb.errors.length;
    parts.push(
      problemList(fb.errors, {
        title:
          sub.kind === "scene"
            ? `The scene is invalid (${n} error${n > 1 ? "s" : ""}): it costs no attempt. Fix it and submit again.`
            : "The image could not be read: it costs no attempt.",
        jump: ctx.jump,
      }),
    );
  } else if (sub.status === "failed") {
    parts.push(
      h(
        "div",
        { class: "message", dataset: { kind: "error" } },
        "It could not be graded (this is not your fault): it costs no attempt. Try again, or tell your instructor.",
      ),
    );
    if (fb?.errors?.length) parts.push(problemList(fb.errors, { title: "What went wrong:" }));
  }
  if (fb?.warnings?.length) parts.push(problemList(fb.warnings, { kind: "warn", title: "Warnings:" }));
  if (["graded", "invalid", "failed"].includes(sub.status)) {
    if (sub.score === null || sub.score === undefined) {
      const later =
        ctx.scoreWhen === "never"
          ? "The score is not shown to students: your instructor has it."
          : "The score is not shown yet: the feedback policy shows it after the deadline.";
      parts.push(h("p", { class: "a-score-note" }, later));
    } else if (sub.penalty)
      parts.push(
        h(
          "p",
          { class: "a-score-note" },
          `Late: ${num(100 * sub.penalty, 3)} % of the points taken off (${pts(sub.raw_score)} before the penalty).`,
        ),
      );
  }
  if (["graded", "invalid", "failed"].includes(sub.status)) {
    const notice = withheldNotice(fb?.withheld);
    if (notice) parts.push(notice);
  }
  const files = sub.files || {};
  const names = PICTURES.filter(([name]) => files[name]);
  if (names.length) {
    const figs = names.map(([name, caption]) => {
      const img = h("img", { alt: `${caption(sub).split(".")[0]}`, dataset: { picture: name } });
      showImage(img, files[name], { token: ctx.token });
      const fig = h(
        "figure",
        { class: "grade-fig a-fig", dataset: { picture: name } },
        h("div", { class: "a-fig-box" }, img),
        h("figcaption", {}, caption(sub)),
      );
      if (name === "error_map.png" && sub.kind === "scene") pickable(img, fig, sub, ctx);
      return fig;
    });
    parts.push(h("div", { class: "grade-figs a-figs" }, figs));
  }
  const m = fb?.metrics;
  if (m) {
    const base = m.baseline || {};
    const rows = METRICS.filter(([k]) => typeof m[k] === "number").map(([k, label, f]) =>
      h(
        "tr",
        {},
        h("th", { scope: "row" }, label),
        h("td", { class: "num" }, f(m[k])),
        h("td", { class: "num" }, typeof base[k] === "number" ? f(base[k]) : "–"),
      ),
    );
    if (rows.length) {
      parts.push(
        h(
          "table",
          { class: "grade-metrics a-metrics" },
          h(
            "caption",
            {},
            "Against the reference. The noise baseline is the reference scene rendered again as yours was (same samples, another seed): how far noise alone is.",
          ),
          h(
            "thead",
            {},
            h(
              "tr",
              {},
              h("th", { scope: "col" }, "metric"),
              h("th", { scope: "col", class: "num" }, "yours"),
              h("th", { scope: "col", class: "num" }, "noise baseline"),
            ),
          ),
          h("tbody", {}, rows),
        ),
      );
    }
  }
  if (sub.kind !== "scene" && sub.status === "graded") {
    if (Array.isArray(fb?.probes)) parts.push(treeLogSection(sub, ctx));
    else if (fb?.probes_hidden)
      parts.push(
        h(
          "p",
          { class: "hint tl-hidden" },
          `Your own tracer's ray trees against the reference's: ${fb.probes_hidden}.`,
        ),
      );
  }
  if (fb?.tests?.length) {
    const list = h("ol", { class: "grade-tests a-tests" }, fb.tests.map(testItem));
    // an invalid submission's tests were not checked: folded, the errors above say it all
    if (sub.status === "invalid")
      parts.push(
        h(
          "details",
          { class: "a-unchecked" },
          h("summary", {}, "Tests (not checked: the submission is invalid)"),
          list,
        ),
      );
    else parts.push(h("h4", {}, "Tests"), list);
  }
  if (sub.manual && ["graded", "invalid", "failed"].includes(sub.status)) parts.push(manualSection(sub));
  root.replaceChildren(...parts);
  // the submission that is the grade: "Request a regrade" beside each result, the requests and answers; another
  // graded one: the requests asked while it was the grade, if any (regrade.js)
  if (sub.status === "graded" && ctx.aid) root.append(regradeControls(root, sub, ctx));
}

/** The staff-graded items of a submission (docs/assignments.md, "Staff-graded items"): each item's points and
 * the grader's comment, and the total, once the instructor released them; before, that they come later. */
export function manualSection(sub) {
  const m = sub.manual;
  if (!m.released)
    return h(
      "p",
      { class: "hint a-manual-later" },
      "Part of this assignment is graded by the course's staff: those points appear here once your instructor releases them.",
    );
  const items = m.items.map((i) =>
    h(
      "li",
      { class: "a-manual-item", dataset: { item: i.name } },
      h(
        "div",
        { class: "grade-test-head" },
        h("strong", {}, i.name),
        h("span", { class: "pts" }, `${pts(i.points ?? 0)} / ${pts(i.max_points)}`),
      ),
      i.rubric.length ? h("p", { class: "hint" }, i.rubric.join("; ")) : null,
      i.comment ? h("p", { class: "a-manual-comment" }, i.comment) : null,
    ),
  );
  const total =
    sub.total !== null && sub.total !== undefined
      ? h(
          "p",
          { class: "a-total" },
          `Total: ${pts(sub.total)} / ${pts(sub.total_max)} (the tests and the staff's grade together).`,
        )
      : null;
  return h(
    "section",
    { class: "a-manual", "aria-label": "Graded by the staff" },
    h("h4", {}, "Graded by the staff"),
    h("ol", { class: "grade-tests a-manual-items" }, items),
    total,
  );
}

/** The difference map as a picker of pixels: a click, or the arrow keys and Enter, asks for the two ray trees
 * at that pixel of the graded image (its natural size, whatever size it is shown at). */
function pickable(img, fig, sub, ctx) {
  const marker = h("span", { class: "a-pick", hidden: true, "aria-hidden": "true" });
  img.before(marker);
  img.classList.add("a-pickable");
  img.tabIndex = 0;
  img.title = "Click a pixel (or use the arrow keys and Enter) to compare your ray tree with the reference's there";
  let at = null; // [x, y] in image pixels
  const place = () => {
    if (!at || !img.naturalWidth) return (marker.hidden = true);
    const sx = img.clientWidth / img.naturalWidth;
    const sy = img.clientHeight / img.naturalHeight;
    marker.hidden = false;
    marker.style.left = `${img.offsetLeft + (at[0] + 0.5) * sx}px`;
    marker.style.top = `${img.offsetTop + (at[1] + 0.5) * sy}px`;
  };
  const go = async () => {
    place();
    const box = ctx.compareBox;
    fig.parentElement.after(box); // under the difference map, the width of the pictures
    box.hidden = false;
    box.dataset.sid = sub.id;
    box.dataset.x = String(at[0]);
    box.dataset.y = String(at[1]);
    box.replaceChildren(h("p", { class: "hint" }, `Tracing both ray trees at pixel (${at[0]}, ${at[1]})…`));
    let mod;
    try {
      mod = await import("./compare.js");
    } catch (err) {
      box.replaceChildren(h("p", { class: "compare-error" }, `Could not load the comparison: ${err.message}`));
      return;
    }
    await mod.showCompare(box, { aid: ctx.aid, sid: sub.id, x: at[0], y: at[1], as: "student", token: ctx.token });
  };
  img.addEventListener("click", (e) => {
    if (!img.naturalWidth) return;
    const r = img.getBoundingClientRect();
    const x = Math.min(
      img.naturalWidth - 1,
      Math.max(0, Math.floor(((e.clientX - r.left) / r.width) * img.naturalWidth)),
    );
    const y = Math.min(
      img.naturalHeight - 1,
      Math.max(0, Math.floor(((e.clientY - r.top) / r.height) * img.naturalHeight)),
    );
    at = [x, y];
    go();
  });
  img.addEventListener("keydown", (e) => {
    if (!img.naturalWidth) return;
    const step = e.shiftKey ? 10 : 1;
    const d = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] }[e.key];
    if (d) {
      e.preventDefault();
      at = at || [img.naturalWidth >> 1, img.naturalHeight >> 1];
      at = [
        Math.min(img.naturalWidth - 1, Math.max(0, at[0] + d[0])),
        Math.min(img.naturalHeight - 1, Math.max(0, at[1] + d[1])),
      ];
      place();
    } else if (e.key === "Enter" || e.key === " ") {
      e.preventDefault();
      at = at || [img.naturalWidth >> 1, img.naturalHeight >> 1];
      go();
    }
  });
  img.addEventListener("focus", () => {
    at = at || [img.naturalWidth >> 1, img.naturalHeight >> 1];
    place();
  });
  new ResizeObserver(place).observe(img);
}
