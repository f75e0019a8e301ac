// The brief of an assignment as its student sees it (GET /api/assignments/{id} with their token): the name and
// description, what earns points and when its feedback is shown, the limits, the reference image, the deadline
// in the student's own time zone and the time left, counting down on the page from the server's `time_left`.
import { showImage } from "../api.js";
import { $, h, num } from "../util.js";

export const IMAGE_TESTS = {
  flip: "FLIP against the reference (how different it looks)",
  ssim: "SSIM against the reference (structure)",
  psnr: "PSNR against the reference (signal to noise)",
  pixels: "pixels match the reference (z test)",
};
export const SHOWN = { now: "shown now", after_deadline: "after the deadline", never: "instructor only" };

/** A score without trailing zeros: 13, 6.5. */
export function pts(x) {
  return typeof x === "number" ? num(Math.round(x * 1000) / 1000, 4) : "–";
}

/** An instant in the student's own time zone: "Tue, Dec 8, 2026, 11:59 PM EST". */
export function localTime(iso) {
  const d = new Date(iso);
  if (Number.isNaN(d.getTime())) return String(iso);
  return d.toLocaleString(undefined, {
    weekday: "short",
    year: "numeric",
    month: "short",
    day: "numeric",
    hour: "numeric",
    minute: "2-digit",
    timeZoneName: "short",
  });
}

/** Seconds as "2 days 3 h 5 min", "3 h 12 min", "12 min 5 s", "45 s". */
export function duration(s) {
  s = Math.max(0, Math.floor(s));
  const d = Math.floor(s / 86400);
  const hr = Math.floor((s % 86400) / 3600);
  const m = Math.floor((s % 3600) / 60);
  const sec = s % 60;
  if (d) return `${d} day${d > 1 ? "s" : ""} ${hr} h ${m} min`;
  if (hr) return `${hr} h ${m} min ${sec} s`;
  if (m) return `${m} min ${sec} s`;
  return `${sec} s`;
}

const ORDER = ["now", "after_deadline", "never"];

/** When the score is shown (server/course/policy.py score_when): the policy's `score`, else the latest of the
 * tests' (a score would tell a hidden test's points). */
export function scoreWhen(feedback) {
  if (!feedback) return "now";
  if (feedback.score) return feedback.score;
  const all = [feedback.default || "now", ...Object.values(feedback.tests || {})];
  return all.reduce((a, b) => (ORDER.indexOf(b) > ORDER.indexOf(a) ? b : a), "now");
}

const when = (brief, test) => brief.feedback?.tests?.[test] || brief.feedback?.default || "now";

function timeEl(iso) {
  return h("time", { datetime: iso, title: iso }, localTime(iso));
}

/** Fill the brief's section; `onPhase(phase)` is called when the countdown passes the deadline or the cut-off
 * (the page then reads the brief again: the server says what changed). Returns the countdown's stop(). */
export function showBrief(root, brief, token, { onPhase } = {}) {
  $("#a-name", root).textContent = brief.name;
  document.title = `${brief.name} · Ray tracing for teaching`;
  const s = brief.student;
  $("#a-who", root).replaceChildren(
    s
      ? h(
          "span",
          {},
          "You are ",
          h("strong", { id: "a-student" }, s.name),
          ` (${s.id}${s.self_declared ? ", self-declared" : ""})`,
          brief.inactive
            ? h(
                "strong",
                { id: "a-inactive", class: "badge inactive" },
                " inactive: you are no longer in this course in the LMS; your submissions and grades are kept, new submissions are not taken",
              )
            : null,
        )
      : h("span", {}, "The instructor's view"),
  );
  $("#a-description", root).textContent = brief.description || "";

  $("#a-deadline", root).replaceChildren(timeEl(brief.deadline), h("small", { class: "muted" }, " (your local time)"));
  const late = $("#a-late-row", root);
  late.hidden = !brief.late_until;
  if (brief.late_until) {
    const penalty = brief.late_penalty
      ? `${num(100 * brief.late_penalty, 3)} % of a late submission's points taken off`
      : "no penalty";
    $("#a-late", root).replaceChildren("until ", timeEl(brief.late_until), `, ${penalty}`);
  }
  const left = brief.submissions_left;
  $("#a-left", root).textContent =
    left === null || left === undefined
      ? `no limit (${brief.attempts_used || 0} used)`
      : `${left} of ${brief.max_submissions} (an invalid submission, or one that cannot be graded, costs none)`;
  $("#a-left", root).dataset.left = left === null || left === undefined ? "" : String(left);
  showTokens(root, brief);
  $("#a-counts", root).textContent =
    brief.counts === "best" ? "your best graded submission (after any late penalty)" : "your last graded submission";

  // what earns points, and when each test's feedback is shown
  const rows = [
    h(
      "tr",
      { dataset: { test: "validity" } },
      h("th", { scope: "row" }, "valid scene (or a readable image)"),
      h("td", { class: "num" }, pts(brief.validity?.points)),
      h("td", {}, SHOWN[when(brief, "validity")]),
    ),
  ];
  for (const r of brief.requirements || []) {
    rows.push(
      h(
        "tr",
        { dataset: { test: r.name } },
        h("th", { scope: "row" }, r.name, r.description ? h("small", { class: "a-req-desc" }, r.description) : null),
        h("td", { class: "num" }, pts(r.points)),
        h("td", {}, SHOWN[when(brief, r.name)]),
      ),
    );
  }
  for (const t of brief.image_tests || []) {
    rows.push(
      h(
        "tr",
        { dataset: { test: t.name } },
        h("th", { scope: "row" }, IMAGE_TESTS[t.name] || t.name),
        h("td", { class: "num" }, pts(t.points)),
        h("td", {}, SHOWN[when(brief, t.name)]),
      ),
    );
  }
  $("#a-points tbody", root).replaceChildren(...rows);
  const imagePts = (brief.image_tests || []).reduce((a, t) => a + t.points, brief.validity?.points || 0);
  $("#a-max", root).replaceChildren(h("strong", {}, pts(brief.max_score)));
  const imageNote =
    brief.requirements?.length && brief.image_tests?.length
      ? `An image from your own ray tracer is out of ${pts(imagePts)}: the requirements apply to scenes.`
      : "";
  // a hidden image test hides the error map and the rejected pixels too (server/course/policy.py map_shown)
  const maps = (brief.image_tests || [])
    .map((t) => when(brief, t.name))
    .reduce((a, b) => (ORDER.indexOf(b) > ORDER.indexOf(a) ? b : a), "now");
  const cut = brief.late_until || brief.deadline;
  const mapsNote =
    maps === "now"
      ? null
      : maps === "never"
        ? h(
            "span",
            { id: "a-maps-note" },
            "The error map, the rejected pixels and the metrics are never shown to students for this assignment: they would tell a hidden test's result.",
          )
        : h(
            "span",
            { id: "a-maps-note" },
            "The error map, the rejected pixels and the metrics are shown after your deadline (",
            timeEl(cut),
            "): before, they would tell a hidden test's result.",
          );
  $("#a-points-note", root).replaceChildren(imageNote, imageNote && mapsNote ? " " : "", mapsNote || "");

  const limits = brief.limits || {};
  const render = brief.render || {};
  const kv = [
    [
      "film",
      render.width && render.height
        ? `${render.width} × ${render.height} pixels (every render is graded at this size)`
        : null,
    ],
    ["seed", render.seed],
    ["samples per pixel", render.spp ?? (limits.max_spp ? `yours, at most ${limits.max_spp}` : null)],
    ["render time", limits.max_seconds ? `at most ${num(limits.max_seconds)} s` : null],
    ["size", limits.max_width ? `at most ${limits.max_width} × ${limits.max_height}` : null],
    ["bounces (max_depth)", limits.max_depth ? `at most ${limits.max_depth}` : null],
    ["light samples", limits.max_light_samples ? `at most ${limits.max_light_samples}` : null],
    ["primitives", limits.max_primitives ? `at most ${limits.max_primitives}` : null],
  ].filter(([, v]) => v !== null && v !== undefined);
  $("#a-limits", root).replaceChildren(...kv.map(([k, v]) => h("div", {}, h("dt", {}, k), h("dd", {}, String(v)))));

  const fig = $("#a-reference-fig", root);
  const img = $("#a-reference", root); // kept in the figure: the brief is shown again (refreshBrief) with it
  $("#a-reference-wait", fig)?.remove();
  if (brief.reference_image) {
    fig.hidden = false;
    img.hidden = false;
    showImage(img, brief.reference_image, { token }).then((ok) => {
      if (ok || $("#a-reference-wait", fig)) return;
      img.hidden = true;
      fig.prepend(
        h(
          "p",
          { class: "hint", id: "a-reference-wait" },
          "The reference image is not ready yet (it is being rendered): reload the page in a moment.",
        ),
      );
    });
  } else fig.hidden = true;

  return countdown(root, brief, onPhase);
}

/** The student's late tokens (server/course/tokens.py): how many are left in the course and what a submission now
 * would spend (whole days past their deadline, less those already spent on this assignment), before they submit. */
function showTokens(root, brief) {
  const row = $("#a-tokens-row", root);
  const left = brief.tokens_left;
  row.hidden = left === undefined || left === null || (!left && !brief.late_tokens && !brief.tokens_spent_here);
  if (row.hidden) return;
  const dd = $("#a-tokens", root);
  dd.dataset.left = String(left);
  dd.dataset.needed = String(brief.tokens_needed_now || 0);
  const days = (n) => `${n} ${n === 1 ? "token" : "tokens"}`;
  const parts = [
    h("span", { id: "a-tokens-left" }, `${days(left)} left in this course`),
    " (a token is a day: a late submission spends what it needs, and is then on time). ",
  ];
  if (brief.tokens_needed_now)
    parts.push(
      h("strong", { id: "a-tokens-now" }, `A submission now spends ${days(brief.tokens_needed_now)}`),
      ", and is not late.",
    );
  else if (brief.tokens_missing_now)
    parts.push(
      h(
        "strong",
        { id: "a-tokens-now" },
        `A submission now would need ${days(brief.tokens_missing_now)}: you have too few, so it spends none`,
      ),
      brief.late_time_left ? " and is marked late." : " and is refused.",
    );
  else parts.push(h("span", { id: "a-tokens-now" }, "A submission now spends none."));
  if (brief.tokens_spent_here)
    parts.push(
      ` You spent ${days(brief.tokens_spent_here)} on this assignment: your deadline is `,
      timeEl(brief.tokens_deadline),
      ".",
    );
  dd.replaceChildren(...parts);
}

/** The time left, counting down each second from the server's `time_left` (its clock, not the browser's). */
function countdown(root, brief, onPhase) {
  const el = $("#a-time-left", root);
  const phaseEl = $("#a-phase", root);
  const t0 = performance.now();
  const phaseOf = (elapsed) => {
    if (brief.closed) return "closed";
    if (brief.time_left - elapsed > 0) return "open";
    if (brief.tokens_cover_now) return "tokens"; // past the deadline, on time by late tokens (the brief says how many)
    if (brief.late_time_left !== null && brief.late_time_left !== undefined && brief.late_time_left - elapsed > 0)
      return "late";
    return "closed";
  };
  const first = phaseOf(0);
  const tick = () => {
    const elapsed = (performance.now() - t0) / 1000;
    const phase = phaseOf(elapsed);
    el.dataset.phase = phase;
    if (phase === "open") el.textContent = duration(brief.time_left - elapsed);
    else if (phase === "tokens")
      el.textContent = `the deadline has passed; a submission now spends ${brief.tokens_needed_now || 0} late token(s)`;
    else if (phase === "late")
      el.textContent = `the deadline has passed; ${duration(brief.late_time_left - elapsed)} left to hand in late`;
    else el.textContent = "none: the assignment is closed";
    if (phase !== first) {
      stop();
      onPhase?.(phase);
    }
  };
  const timer = setInterval(tick, 1000);
  const stop = () => clearInterval(timer);
  tick();
  phaseEl.hidden = first === "open";
  phaseEl.dataset.kind = first === "late" || first === "tokens" ? "warn" : "error";
  phaseEl.textContent =
    first === "tokens"
      ? `The deadline has passed: a submission now spends ${brief.tokens_needed_now || "none"} of your late tokens and is on time.`
      : first === "late"
        ? `The deadline has passed: a submission now is marked late${brief.late_penalty ? ` and loses ${num(100 * brief.late_penalty, 3)} % of its points.` : "."}`
        : "The assignment is closed: submissions are no longer taken. Your submissions and their feedback stay below.";
  return stop;
}
